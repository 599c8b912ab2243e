# Reproduce the reports of each study (see README.md).
#   make walking        published walking-2020: import, means, distances, statistics, models, IOC (bi-level and
#                       single-level, each with the bootstrap of its weights), prediction, report;
#                       the model stages under both conventions (continuous -> STAGE/, published -> STAGE-published/)
#   make walking-subjects  per-subject IOC fits on walking-2020 (after walking)
#   make pairs          published pair-carriage-2022 (means; the table model generated on every table mean under both
#                       conventions, as on walking) and the per-trial synthetic pair study
#                       (prediction on every 10th synthetic table trial: SPREDICT_ARGS= for all 1080)
#   make localisation   synthetic robot runs (ROS1, ROS2, MCAP); real runs: make localisation BAGS="a.bag b.bag"
#   make all            all of them, then docs/results.md and docs/schemas.md
#   make regression     metric regression: each study's key numbers vs tests/baselines (run by .ci/run)
#   make regression-update  rewrite the baselines after an intended change, printing every changed value
# DATASETS defaults to ../shared/datasets ($COBOT_DATASETS wins). Workspaces go under OUT.
PYTHON ?= python
CLI ?= cobot-analysis
DATASETS ?= $(or $(COBOT_DATASETS),../shared/datasets)
OUT ?= cobot-out
JOBS ?= 2
BAGS ?=
IOC_ARGS ?=
PUBLISHED_IOC_ARGS ?=
# the table model under the published convention (65 means on up to 1100 Euler nodes) runs to Powell's own end: 213
# evaluations, 9.4 min with JOBS=2 (2026-11-26; the evaluations whose lower levels fail take about 6 s each); D 0.4785,
# where the budget of 130 evaluations it had before stopped at 0.4874 (PUBLISHED_TABLE_IOC_ARGS="--max-evaluations 130")
PUBLISHED_TABLE_IOC_ARGS ?=
PREDICT_ARGS ?=
PUBLISHED_PREDICT_ARGS ?=
# the goal-aware predictor beside the thesis OC and the baselines, and the horizon sweep (docs/methods.md sec. 7.1, 7.2);
# on walking with the weights fitted under the continuous convention (weights are used in the convention they were fitted in):
# its oc, cv and ctrv rows are the thesis OC with the fitted weights (a predict-fitted stage of its own would repeat them)
GOAL_PREDICT_ARGS ?= --settings 50:100 --predictors oc,goal,cv,ctrv --horizons 5,10,25,50,100,200,all
SUBJECT_IOC_ARGS ?= --subjects 10 --max-evaluations 600
# the single-level IOC beside each bi-level fit over the means (docs/methods.md sec. 6.1; published convention: at the
# bi-level fit's held horizons, and its steps also started at the bi-level fit's end, a row of the side-by-side table:
# 21-28 s more on the table and walking means, 2026-11-26),
# with the bootstrap of the weights' intervals and verdicts (--bootstrap, default 200, sec. 6.3); its own stage
# fit-ioc-single/, whose report shows both fits side by side. The feasible-path stage took 33 s on the 37 walking means
# with its bootstrap and profiles, the fit alone 5.2 s where the bi-level fit took 31.7 s (2026-11-26, docs/benchmarks.md);
# --max-evaluations N caps its steps
SINGLE_IOC_ARGS ?=
COUPLED_IOC_ARGS ?= --max-evaluations 600
SPREDICT_ARGS ?= --every 10
RESULTS_NOTE ?=
LOC_ARGS ?=
STUDIES ?=
MAP ?= synthetic

WALK := $(OUT)/walking-2020
PAIRS := $(OUT)/pair-carriage-2022
SPAIRS := $(OUT)/synthetic-pairs
LOC := $(OUT)/localisation

.PHONY: install demo test regression regression-update bench walking walking-subjects pairs pairs-published pairs-synthetic localisation results schemas all

install:
	$(PYTHON) -m pip install -e ".[dev]"

demo:
	$(CLI) demo --out $(OUT)

test:
	$(PYTHON) -m pytest

# STUDIES="walking-2020 localisation" restricts both to some studies (tests/regression.py -h)
regression:
	$(PYTHON) tests/regression.py --jobs $(JOBS) $(STUDIES)

regression-update:
	$(PYTHON) tests/regression.py --update --jobs $(JOBS) $(STUDIES)

# the speed targets of docs/benchmarks.md, each against its reference measured in the same run (the
# bench extra installs the reference libraries kineticstoolkit and pyomeca); the suite (bench_suite.py)
# and the Makefile targets (bench_make.py) are timed on their own
bench:
	$(PYTHON) -m pip install --quiet -e ".[dev,bench]"
	$(PYTHON) benchmarks/bench_startup.py
	$(PYTHON) benchmarks/bench_localisation.py
	$(PYTHON) benchmarks/bench_import_minimal.py --scaling --one-pass --jobs $(JOBS)
	$(PYTHON) benchmarks/bench_foundation.py --jobs $(JOBS)
	$(PYTHON) benchmarks/bench_analysis.py
	$(PYTHON) benchmarks/bench_models.py solver
	$(CLI) import-published walking-2020 $(DATASETS)/walking-2020 --out $(WALK)
	$(PYTHON) benchmarks/bench_predict.py windows $(WALK)/import-published/trajectories.parquet
	$(PYTHON) benchmarks/bench_predict.py published-floor $(WALK)/import-published/trajectories.parquet
	$(PYTHON) benchmarks/bench_predict.py goal $(WALK)/import-published/trajectories.parquet

walking:
	$(CLI) import-published walking-2020 $(DATASETS)/walking-2020 --out $(WALK)
	$(CLI) average --out $(WALK)
	$(CLI) fit-ioc --out $(WALK) --jobs $(JOBS) $(IOC_ARGS)
	$(CLI) fit-ioc --out $(WALK) --convention published --jobs $(JOBS) $(PUBLISHED_IOC_ARGS)
	$(CLI) fit-ioc --out $(WALK) --method single-level --no-compare --jobs $(JOBS) $(SINGLE_IOC_ARGS)
	$(CLI) fit-ioc --out $(WALK) --method single-level --convention published --no-compare --jobs $(JOBS) $(SINGLE_IOC_ARGS)
	$(CLI) generate --out $(WALK) --study walking-2020 --weights $(WALK)/fit-ioc/weights.json --jobs $(JOBS)
	$(CLI) generate --out $(WALK) --study walking-2020 --convention published --jobs $(JOBS)
	$(CLI) compare --out $(WALK) --against $(WALK)/generate/generated.parquet --comparison model
	$(CLI) compare --out $(WALK) --against $(WALK)/generate-published/generated.parquet --comparison model --convention published
	$(CLI) stats --out $(WALK)
	$(CLI) stats --out $(WALK) --convention published
	$(CLI) predict --out $(WALK) --kind trial --convention continuous --jobs $(JOBS) $(PREDICT_ARGS)
	$(CLI) predict --out $(WALK) --kind trial --convention published --jobs $(JOBS) $(PUBLISHED_PREDICT_ARGS)
	$(CLI) predict --out $(WALK) --kind trial --convention continuous --weights $(WALK)/fit-ioc/weights.json --stage-name predict-goal --jobs $(JOBS) $(GOAL_PREDICT_ARGS)
	$(CLI) report walking-2020 --out $(WALK) --to reports/walking

# per-subject IOC (after walking): one fit per subject over its trials, started from the fit over the means
walking-subjects:
	$(CLI) fit-ioc --out $(WALK) --per subject --start-weights $(WALK)/fit-ioc/weights.json --no-compare --jobs $(JOBS) $(SUBJECT_IOC_ARGS)
	$(CLI) fit-ioc --out $(WALK) --per subject --method single-level --start-weights $(WALK)/fit-ioc/weights.json --no-compare --jobs $(JOBS) $(SUBJECT_IOC_ARGS)

pairs: pairs-published pairs-synthetic

pairs-published:
	$(CLI) import-published pair-carriage-2022 $(DATASETS)/pair-carriage-2022 --out $(PAIRS)
	$(CLI) average --out $(PAIRS)
	$(CLI) fit-ioc --out $(PAIRS) --model table --jobs $(JOBS) $(IOC_ARGS)
	$(CLI) fit-ioc --out $(PAIRS) --model table --convention published --jobs $(JOBS) $(PUBLISHED_TABLE_IOC_ARGS) $(PUBLISHED_IOC_ARGS)
	$(CLI) generate --out $(PAIRS) --study pair-carriage-2022 --weights $(PAIRS)/fit-ioc/weights.json --jobs $(JOBS)
	$(CLI) generate --out $(PAIRS) --study pair-carriage-2022 --convention published --jobs $(JOBS)
	$(CLI) compare --out $(PAIRS) --against $(PAIRS)/generate/generated.parquet --comparison model
	$(CLI) compare --out $(PAIRS) --against $(PAIRS)/generate-published/generated.parquet --comparison model --convention published
	$(CLI) stats --out $(PAIRS)
	$(CLI) reconstruct --out $(PAIRS) --wrt-table $(DATASETS)/pair-carriage-2022
	$(CLI) fit-ioc --out $(PAIRS) --model coupled --jobs $(JOBS) $(COUPLED_IOC_ARGS)
	$(CLI) fit-ioc --out $(PAIRS) --model table --method single-level --no-compare --jobs $(JOBS) $(SINGLE_IOC_ARGS)
	$(CLI) fit-ioc --out $(PAIRS) --model table --method single-level --convention published --no-compare --jobs $(JOBS) $(SINGLE_IOC_ARGS)
	$(CLI) predict --out $(PAIRS) --entity table --convention continuous --jobs $(JOBS) $(PREDICT_ARGS)
	$(CLI) predict --out $(PAIRS) --entity table --convention published --jobs $(JOBS) $(PUBLISHED_PREDICT_ARGS)
	$(CLI) predict --out $(PAIRS) --entity table --convention continuous --stage-name predict-goal --jobs $(JOBS) $(GOAL_PREDICT_ARGS) --predictors oc,goal,goal-inferred,cv,ctrv
	$(CLI) report pair-carriage-2022 --out $(PAIRS) --to reports/pairs

pairs-synthetic:
	$(CLI) synth pairs --out $(SPAIRS) --jobs $(JOBS)
	$(CLI) import $(SPAIRS)/synth-pairs/protocol.yaml --out $(SPAIRS) --preprocess --jobs $(JOBS)
	$(CLI) average --out $(SPAIRS)
	$(CLI) compare --out $(SPAIRS)
	$(CLI) stats --out $(SPAIRS)
	$(CLI) reconstruct --out $(SPAIRS)
	$(CLI) predict --out $(SPAIRS) --entity table --kind trial --convention continuous --jobs $(JOBS) $(SPREDICT_ARGS)
	$(CLI) report synthetic-pairs --out $(SPAIRS) --to reports/synthetic-pairs

localisation:
	$(CLI) synth localisation --out $(LOC)
	$(CLI) localisation --out $(LOC) --map-name $(MAP) $(BAGS) $(LOC_ARGS)

results:
	$(CLI) results $(wildcard $(WALK) $(PAIRS) $(SPAIRS) $(LOC)) --to docs/results.md \
	  --preface "What the pipeline computes from the published datasets (walking-2020, pair-carriage-2022), from the \
	  per-trial synthetic pair study and from the synthetic robot runs: one section per stage, written by the stage \
	  itself (\`make walking pairs localisation results\`). Each section states its choices and, where docs/methods.md or \
	  the dataset READMEs give them, the published values beside ours. $(RESULTS_NOTE)"

schemas:
	$(CLI) schemas > docs/schemas.md

all: walking walking-subjects pairs localisation results schemas
