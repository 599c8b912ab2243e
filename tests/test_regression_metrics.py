"""Metric regression (issue 13): stages write metrics.json; `metrics check` passes an unchanged run and
catches planted regressions; `metrics update` prints the diff; bad input exits 2 with one line."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.regression.baseline import load_baseline, load_rules, untolerated, baseline_metrics
from cobot_analysis.regression.extract import stage_convention, stage_metrics, write_stage_metrics
from cobot_analysis.schema import TRAJECTORIES, write_table

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import pair_table, walking_table  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BASELINES = ROOT / "tests" / "baselines"
D_XY = "compare.individual-mean.walker.d_xy.mean"
D_XY_KEY = D_XY + "@continuous"  # compare runs under a convention: the key carries it


def _records(stage_dir: Path) -> dict[str, dict]:
    return {m["name"]: m for m in json.loads((stage_dir / "metrics.json").read_text())["metrics"]}


@pytest.fixture(scope="module")
def walking_ws(tmp_path_factory):
    """A small synthetic walking study through average, compare and stats."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("walking") / "ws"
    write_table(walking_table(seed=3, n_subjects=4, n_conditions=8, n_trials=3, subject_effect=0.05), ws / "preprocess" / "trajectories.parquet",
                TRAJECTORIES)
    for cmd in ("average", "compare", "stats"):
        assert run(["-q", cmd, "--out", str(ws)]) == 0, cmd
    return ws


@pytest.fixture
def checked(walking_ws, tmp_path, cli):
    """A copy of the workspace, and a baseline of it written by `metrics update` beside the project's tolerances."""
    ws = tmp_path / "ws"
    shutil.copytree(walking_ws, ws)
    baseline = tmp_path / "baselines" / "walking.json"
    baseline.parent.mkdir()
    shutil.copy(BASELINES / "tolerances.toml", baseline.parent / "tolerances.toml")
    code, out, err = cli("metrics", "update", baseline, ws)
    assert code == 0, err
    assert f"added    {D_XY_KEY}: " in out and "written" in out
    return ws, baseline


def test_stages_write_their_headline_numbers(walking_ws):
    d = pd.read_parquet(walking_ws / "compare" / "distances.parquet")
    ind = d[d["comparison"] == "individual-mean"]
    rec = _records(walking_ws / "compare")
    assert rec[D_XY] == {"name": D_XY, "value": pytest.approx(ind["d_xy"].mean(), rel=1e-15), "unit": "m", "stage": "compare",
                         "convention": "continuous"}  # compare runs under a convention (docs/methods.md sec. 11)
    assert rec["compare.individual-mean.walker.d_xy.sd"]["value"] == pytest.approx(ind["d_xy"].std(ddof=1), rel=1e-15)
    assert rec["compare.individual-mean.walker.n"]["value"] == len(ind) == 96
    assert rec["compare.individual-mean.walker.d_theta.n"]["value"] == ind["d_theta"].notna().sum()
    stats = pd.read_parquet(walking_ws / "stats" / "stats.parquet").set_index("id")
    srec = _records(walking_ws / "stats")
    assert srec["stats.W1.1.p"]["value"] == stats.loc["W1.1", "p"] and srec["stats.W1.1.test"]["value"] == stats.loc["W1.1", "test"]
    assert srec["stats.W2.status"]["value"].startswith("skipped")  # no model rows: the reason is the metric
    assert _records(walking_ws / "average")["average.walker.means"]["value"] == 8
    # written inside the stage: listed (and hashed) in the manifest like every output
    manifest = json.loads((walking_ws / "compare" / "manifest.json").read_text())
    assert "metrics.json" in [o["path"] for o in manifest["outputs"]]


def test_unchanged_run_passes(checked, cli):
    ws, baseline = checked
    code, out, err = cli("metrics", "check", baseline, ws)
    assert code == 0, out + err
    assert out.splitlines()[1].split() == ["metric", "baseline", "now", "tolerance", "change", "status"]
    row = next(line for line in out.splitlines() if line.startswith(D_XY_KEY + " "))
    assert row.split()[-1] == "ok" and "rel 1e-06 + abs 1e-12" in row
    assert "passed: " in out and " 0 outside tolerance, 0 missing, 0 new" in out


def test_scaled_distance_fails_and_update_prints_the_diff(checked, cli, monkeypatch):
    """A planted regression in the code: every d_xy 10 % larger, through the real compare stage."""
    import cobot_analysis.distances as metrics

    ws, baseline = checked
    before = baseline_metrics(load_baseline(baseline))[D_XY_KEY].value
    real = metrics.d_xy
    monkeypatch.setattr(metrics, "d_xy", lambda *a: 1.1 * real(*a))
    assert cli("-q", "compare", "--out", ws, "--force")[0] == 0
    code, out, _ = cli("metrics", "check", baseline, ws)
    assert code == 1
    row = next(line for line in out.splitlines() if line.startswith(D_XY_KEY + " ")).split()
    assert row[-1] == "FAIL" and row[-3:-1] == ["+10", "%"]
    assert float(row[1]) == pytest.approx(before, rel=1e-5) and float(row[2]) == pytest.approx(1.1 * before, rel=1e-5)
    assert "FAILED: " in out and "metrics update" in out
    assert D_XY_KEY in out.split("not ok:")[1]
    # the explicit update step prints old -> new and makes the check pass again
    code, out, _ = cli("metrics", "update", baseline, ws)
    assert code == 0 and f"changed  {D_XY_KEY}: " in out and "(+10 %)" in out
    assert baseline_metrics(load_baseline(baseline))[D_XY_KEY].value == pytest.approx(1.1 * before, rel=1e-12)
    assert cli("metrics", "check", baseline, ws)[0] == 0


def _edit_stats(ws: Path, edit) -> None:
    f = ws / "stats" / "metrics.json"
    payload = json.loads(f.read_text())
    payload["metrics"] = edit(payload["metrics"])
    f.write_text(json.dumps(payload))


@pytest.mark.parametrize("plant, key, status", [
    (lambda ms: [{**m, "value": m["value"] * 3} if m["name"] == "stats.W1.1.p" else m for m in ms], "stats.W1.1.p", "FAIL"),
    (lambda ms: [m for m in ms if m["name"] != "stats.W1.1.statistic"], "stats.W1.1.statistic", "MISSING"),
    (lambda ms: ms + [{"name": "stats.W9.p", "value": 0.5, "unit": "", "stage": "stats", "convention": None}], "stats.W9.p", "NEW"),
    (lambda ms: [{**m, "value": "anova"} if m["name"] == "stats.W1.1.test" else m for m in ms], "stats.W1.1.test", "FAIL"),
])
def test_planted_regressions_are_caught(checked, cli, plant, key, status):
    ws, baseline = checked
    _edit_stats(ws, plant)
    code, out, _ = cli("metrics", "check", baseline, ws)
    assert code == 1
    key = key if status == "NEW" else f"{key}@continuous"  # the statistics run under a convention (stats-published/)
    rows = [line.split() for line in out.splitlines() if line.startswith(key + " ")]
    assert len(rows) == 1 and rows[0][-1] == status
    assert [line for line in out.splitlines() if line.endswith((" FAIL", " MISSING", " NEW"))] == \
        [line for line in out.splitlines() if line.startswith(key + " ")]  # nothing else flagged


def test_committed_tolerances_catch_the_issue_examples():
    """d_xy 0.100 -> 0.130 m, Kruskal p 1.5e-29 -> 1e-3 (or 1e-13), delay 0.551 -> 0.45 s all fail."""
    from cobot_analysis.regression.baseline import rule_for

    rules = load_rules(BASELINES / "walking-2020.json")
    cases = [(D_XY, "m", 0.100, 0.130), ("stats.Q1.1.p", "", 1.5e-29, 1e-3), ("stats.Q1.1.p", "", 1.5e-29, 1e-13),
             ("localisation.run.bag.delay", "s", 0.551, 0.45), ("fit-ioc.all.D.fitted@continuous", "", 0.4412, 0.46)]
    for key, unit, base, now in cases:
        rule = rule_for(rules, key, unit)
        assert not rule.passes(base, now) and rule.passes(base, base * (1 + 1e-7)), key
    assert rule_for(rules, "stats.W1.1.n", "count").passes(400, 400) and not rule_for(rules, "stats.W1.1.n", "count").passes(400, 401)


# ---- bad input: one line naming the file and the remedy, exit 2 ----------------------------------------
def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def test_baseline_that_is_not_json(checked, cli):
    ws, baseline = checked
    baseline.write_text('{"format": "cobot-analysis-metrics-baseline/1", "metrics": {')
    code, _, err = cli("metrics", "check", baseline, ws)
    assert code == 2 and f"{baseline}: baseline is not valid JSON" in _one_line(err) and "git checkout" in err


def test_metric_without_tolerance(checked, cli):
    ws, baseline = checked
    rules = baseline.with_name("tolerances.toml")
    rules.write_text(rules.read_text().replace('"average.*", ', ""))
    code, _, err = cli("metrics", "check", baseline, ws)
    line = _one_line(err)
    assert code == 2 and "have no tolerance, e.g. average." in line and str(rules) in line


def test_tolerance_rule_without_reason(checked, cli):
    ws, baseline = checked
    (baseline.with_name("walking.tolerances.toml")).write_text('[[rule]]\nmatch = "compare.*"\nrel = 0.1\n')
    code, _, err = cli("metrics", "check", baseline, ws)
    assert code == 2 and "walking.tolerances.toml: rule 1 (compare.*) gives no reason" in _one_line(err)


def test_workspace_missing_a_stage(checked, cli):
    ws, baseline = checked
    shutil.rmtree(ws / "stats")
    code, _, err = cli("metrics", "check", baseline, ws)
    line = _one_line(err)
    assert code == 2 and "no stage stats (convention continuous) in the workspaces" in line and "cobot-analysis stats" in line


def test_workspaces_of_different_studies(checked, cli, tmp_path):
    from cobot_analysis.cli import run

    ws, baseline = checked
    pairs = tmp_path / "pairs"
    write_table(pair_table(seed=1, n_pairs=2, goals=2, n=20), pairs / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert run(["-q", "average", "--out", str(pairs)]) == 0
    code, _, err = cli("metrics", "check", baseline, ws, pairs)
    line = _one_line(err)
    assert code == 2 and "different studies: synthetic-walking" in line and "synthetic-pairs" in line
    code, _, err = cli("metrics", "update", baseline, pairs)  # nor may an update switch a baseline's study
    assert code == 2 and "baseline is for study synthetic-walking" in _one_line(err)


def test_corrupt_metrics_file(checked, cli):
    ws, baseline = checked
    (ws / "average" / "metrics.json").write_text("[")
    code, _, err = cli("metrics", "check", baseline, ws)
    assert code == 2 and f"{ws / 'average' / 'metrics.json'}: not a valid metrics file" in _one_line(err)


# ---- conventions, extraction errors, older workspaces -------------------------------------------------
def test_model_metrics_carry_their_convention(tmp_path, cli):
    ws = tmp_path / "ws"
    code, _, err = cli("-q", "generate", "--out", ws, "--start", "-1.5", "-1", "0", "--convention", "continuous")
    assert code == 0, err
    rec = _records(ws / "generate")
    assert rec["generate.improved.paths"]["convention"] == "continuous" and rec["generate.improved.paths"]["value"] == 1
    g = pd.read_parquet(ws / "generate" / "generated.parquet")
    assert rec["generate.improved.end_error.max"]["value"] == pytest.approx(np.hypot(g["x"].iloc[-1], g["y"].iloc[-1]), rel=1e-12)
    # the convention of a model stage: its parameters, else its Parquet metadata, else continuous
    assert stage_convention("generate", ws / "generate", {"spec": {"convention": "published"}}) == "published"
    assert stage_convention("compare", ws / "generate", {"convention": "published"}) == "published"
    assert stage_convention("stats", ws / "generate", {"convention": "published"}) == "published"  # stats-published/ too
    assert stage_convention("average", ws / "generate", {"convention": "published"}) is None
    other = tmp_path / "ws-published"
    shutil.copytree(ws, other)
    payload = stage_metrics("generate", other / "generate", {"convention": "published"})
    (other / "generate" / "metrics.json").write_text(json.dumps(payload))
    baseline = tmp_path / "b.json"
    (tmp_path / "tolerances.toml").write_text('[[rule]]\nmatch = "*"\nrel = 0.02\nreason = "test"\n')
    assert cli("metrics", "update", baseline, ws, other)[0] == 0
    keys = load_baseline(baseline)["metrics"]
    assert {"generate.improved.T.mean@continuous", "generate.improved.T.mean@published"} <= set(keys)
    assert cli("metrics", "check", baseline, ws, other)[0] == 0
    code, _, err = cli("metrics", "check", baseline, ws)  # the published-convention stage is not there
    assert code == 2 and "no stage generate (convention published)" in _one_line(err)


def test_extraction_error_is_recorded_not_raised(tmp_path, cli, checked):
    stage = tmp_path / "compare"
    stage.mkdir()
    write_stage_metrics("compare", stage, {})  # no distances.parquet
    payload = json.loads((stage / "metrics.json").read_text())
    assert payload["metrics"] == [] and "distances.parquet" in payload["error"]
    ws, baseline = checked
    shutil.copy(stage / "metrics.json", ws / "compare" / "metrics.json")
    code, out, _ = cli("metrics", "check", baseline, ws)
    assert code == 1 and "metrics could not be computed" in out
    assert next(line for line in out.splitlines() if line.startswith(D_XY_KEY + " ")).split()[-1] == "MISSING"


def test_stage_without_metrics_file_is_read_from_its_outputs(checked, cli):
    ws, baseline = checked
    (ws / "compare" / "metrics.json").unlink()  # a workspace written before metrics.json existed
    assert cli("metrics", "check", baseline, ws)[0] == 0


# ---- the committed baselines -----------------------------------------------------------------------------
def test_committed_baselines_have_a_tolerance_for_every_metric_and_a_runner():
    from regression import STUDIES

    files = sorted(BASELINES.glob("*.json"))
    assert sorted(s.baseline for s in STUDIES.values()) == [f.name for f in files]
    for f in files:
        doc = load_baseline(f)
        metrics = baseline_metrics(doc)
        assert len(metrics) > 50 and doc["study"]
        assert untolerated(load_rules(f), metrics) == [], f
        values = [m.value for m in metrics.values()]
        assert all(v is not None and not (isinstance(v, float) and not np.isfinite(v)) for v in values)
    walking = baseline_metrics(load_baseline(BASELINES / "walking-2020.json"))
    assert walking[D_XY_KEY].value == pytest.approx(0.100, abs=5e-4)  # docs/results.md: 0.100 +- 0.062
    pairs = baseline_metrics(load_baseline(BASELINES / "pair-carriage-2022.json"))
    assert pairs["stats.Q1.1.p@continuous"].value == pytest.approx(1.47e-29, rel=1e-2)  # Kruskal, travel time by scenario
    loc = baseline_metrics(load_baseline(BASELINES / "localisation.json"))
    assert {k for k in loc if k.startswith("localisation.") and k.endswith(".delay")} == {f"localisation.{r}.delay" for r in ("run.bag", "run_ros2", "run.mcap")}
    assert all(v.value == pytest.approx(0.55, abs=0.01) for k, v in loc.items() if k.endswith(".delay"))  # planted 0.55 s


def test_a_stage_writes_its_results_own_numbers(tmp_path):
    """metrics.json is the run's API result's metrics() (Stage.result), not re-read from the stage's files
    (here there are none: reading them would record an error instead)."""
    from cobot_analysis.metrics.records import collect
    from cobot_analysis.workspace import Stage

    class Result:
        def metrics(self, *, stage):
            return collect(stage, lambda out: out.count("means", 7))

    with Stage(tmp_path, "average") as stage:
        stage.result = Result()
    payload = json.loads((tmp_path / "average" / "metrics.json").read_text())
    assert "error" not in payload
    assert payload["metrics"] == [{"name": "average.means", "value": 7, "unit": "count", "stage": "average", "convention": None}]
    with Stage(tmp_path, "compare-published", force=True) as stage:  # a model stage: its convention from its directory
        stage.result = Result()
    assert _records(tmp_path / "compare-published")["compare.means"]["convention"] == "published"
