# Reproduce the reports of each study. DATASETS defaults to ../shared/datasets ($COBOT_DATASETS wins).
PYTHON ?= python
CLI ?= cobot-analysis
DATASETS ?= $(or $(COBOT_DATASETS),../shared/datasets)
OUT ?= cobot-out

.PHONY: install demo test bench

install:
	$(PYTHON) -m pip install -e ".[dev]"

demo:
	$(CLI) demo --out $(OUT)/demo

test:
	$(PYTHON) -m pytest

bench:
	$(PYTHON) -m pytest benchmarks --benchmark-only -q
