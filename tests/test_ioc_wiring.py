"""The IOC fits wired into the reports and the metrics (issue 20): a tiny workspace (5 model paths as means,
2 subjects' noisy trials, 20 intervals) fitted by the bi-level method, the single-level method and per
subject, each with a 20-resample bootstrap; docs/results.md shows both methods side by side with each
weight's interval and verdict, the study report lists every fit, and the metrics record the intervals,
verdicts and the subjects-differ test exactly as weights.json holds them. The end-to-end tests share
the fits (about 16 s of CPU) and are marked slow."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.metrics.models import verdict_category
from cobot_analysis.models.presets import load_weights, names_for, weights_vector
from cobot_analysis.reports.models import p_text

W = dict(zip(names_for("improved"), map(float, weights_vector(load_weights("walking-2021", "improved"), "improved"))))
CONDITIONS = ("E4015", "O1515", "N-0615", "S4040", "E1500")
FITTED = ("a2", "a4")
#: the single-level fit's status after one step ("k of 1 NLPs accepted": trust-region sequence; "k of 1 steps": SQP)
ONE_STEP = re.compile(r"\b(\d+) of 1 (?:NLPs|steps) accepted")


def _table() -> pd.DataFrame:
    """The paths at the preset weights as means; subject S1's trials at the same weights, S2's at 3 x a2,
    each with a smooth 2 cm bump (seeded)."""
    from cobot_analysis.design import WALKING_GOAL, walking_condition
    from cobot_analysis.models import generate
    from cobot_analysis.schema import TRAJECTORIES

    rng = np.random.default_rng(0)
    frames = []
    for c in CONDITIONS:
        for who, weights in ((None, W), ("S1", W), ("S2", {**W, "a2": 3 * W["a2"]})):
            df = generate("improved", walking_condition(c).start, WALKING_GOAL, weights=weights, n_samples=100, n_intervals=20,
                          convention="continuous")
            base = df[list(TRAJECTORIES.columns.keys() & set(df.columns))].copy()
            if who is None:
                frames.append(base.assign(study="test-walking", trial=f"mean_{c}", kind="mean", n_trials=2, subject=None))
            else:
                bump = np.sin(np.linspace(0, np.pi, len(base)))
                frames.append(base.assign(study="test-walking", trial=f"{who}_{c}", kind="trial", n_trials=1, subject=who,
                                          x=base.x + rng.normal(0, 0.02) * bump, y=base.y + rng.normal(0, 0.02) * bump))
    return pd.concat(frames, ignore_index=True)


@pytest.fixture(scope="module")
def fits(tmp_path_factory):
    """(workspace, {stage directory: Outcome}) after the three fits."""
    from cobot_analysis.schema import TRAJECTORIES, write_table
    from cobot_analysis.stages import models

    tmp = tmp_path_factory.mktemp("ioc-wiring")
    src = write_table(_table(), tmp / "trajectories.parquet", TRAJECTORIES)
    start = tmp / "start.json"  # twice the preset's a2 (twice both would keep their ratio, all the means determine)
    start.write_text(json.dumps({"convention": "continuous", "weights": {**W, "a2": 2 * W["a2"]}}))
    out = tmp / "ws"
    common = dict(trajectories=src, fit=list(FITTED), start_weights=str(start), intervals=20, compare=False, jobs=1, bootstrap=20)
    runs = {"fit-ioc": models.fit_ioc(out, max_evaluations=6, **common)}
    runs["fit-ioc-single"] = models.fit_ioc(out, method="single-level", **common)
    runs["fit-ioc-subjects"] = models.fit_ioc(out, per="subject", max_evaluations=6, **common)
    assert {n: o.directory.name for n, o in runs.items()} == {n: n for n in runs}
    return out, runs


def _doc(out: Path, stage: str) -> dict:
    return json.loads((out / stage / "weights.json").read_text())


def _cells(u: dict | None, n: str) -> str:
    """The interval and verdict cells the report should print for weight n (from weights.json)."""
    if u is None:
        return "– | not computed (--bootstrap 0)"
    v, (lo, hi) = u["verdicts"][n], u["intervals"][n]
    return f"{f'{lo:.3g} .. {hi:.3g}' if v.startswith('determined') else '–'} | *{u['by'][n]}*: {v}"


def test_verdict_categories():
    assert verdict_category("determined") == "determined"
    assert verdict_category("determined (at the search limit 1e+03)") == "determined at the search limit"
    assert verdict_category("only its ratio to a4 is determined") == "ratio to a4"
    assert verdict_category("not determined by these data (at the search limit 1e-07)") == "not determined at the search limit"
    assert verdict_category("not judged: D is not smooth at the fit (a quadratic leaves 17 % of its change over the "
                            "stencil unexplained)") == "not judged"


@pytest.mark.parametrize("w, at", [(1.05e-7, True), (1.09e-7, True), (1.2e-7, False), (900.0, True), (850.0, False)])
def test_a_verdict_is_tagged_at_the_search_limit_where_the_report_warns(w, at):
    """One rule for "at the search limit": within a factor 1.12 (0.05 in log10) of 1e-7 or 1e3, in the verdict's tag and
    in the report's warning (per-subject fits ended at a3 = 1.09e-7 and 1.05e-7 with the warning and no tag)."""
    from cobot_analysis.models.ioc.uncertainty import verdicts
    from cobot_analysis.reports.models import weight_limit_flag

    v = verdicts(("a2", "a3"), np.eye(2), 0.1, {"a2": 5.0, "a3": w})
    assert v["a2"] == "determined" and v["a3"].endswith(f"(at the search limit {1e-7 if w < 1 else 1e3:g})") == at
    assert ("a3 = " in weight_limit_flag({"a2": 5.0, "a3": w}, ("a2", "a3"))) == at


@pytest.mark.slow  # the module's fits: about 16 s of CPU
def test_results_md_shows_both_methods_with_intervals_and_verdicts(fits, tmp_path):
    from cobot_analysis.reports.results import write_results

    out, _ = fits
    to = tmp_path / "results.md"
    write_results([out], to)
    text = to.read_text()
    bi, single = _doc(out, "fit-ioc")["fits"]["all"], _doc(out, "fit-ioc-single")["fits"]["all"]
    assert bi["uncertainty"] and single["uncertainty"]  # both bootstraps ran (20 resamples)
    assert bi["uncertainty"]["resamples"] == single["uncertainty"]["resamples"] == 20
    # the single-level section: D of both, then each weight by both methods with its interval and verdict
    assert f"| all | bi-level | {bi['objective']:.4f} | {bi['seconds']:.1f} |" in text
    assert f"| all | single-level | {single['objective']:.4f} |" in text
    # the bi-level weights re-solved also from the single-level paths (both D from the same candidate paths)
    assert np.isfinite(single["against_D"]) and single["against_D"] >= 0
    assert f"| all | bi-level weights, re-solved also from the single-level paths | {single['against_D']:.4f} |" in text
    for n in FITTED:
        row = (f"| all | {n} | {bi['weights'][n]:.3g} | {_cells(bi['uncertainty'], n)} | {single['weights'][n]:.3g} | "
               f"{_cells(single['uncertainty'], n)} |")
        assert row in text, row
        assert f"| all | {n} | {bi['weights'][n]:.3g} | {_cells(bi['uncertainty'], n)} |" in text  # the bi-level section's own table
    # weights with a real interval around their fitted value, printed in docs/results.md
    every = [f for s in ("fit-ioc", "fit-ioc-single", "fit-ioc-subjects") for f in _doc(out, s)["fits"].values()]
    determined = [(f["uncertainty"], n, f) for f in every for n in FITTED if f["uncertainty"]["verdicts"][n] == "determined"]
    assert determined
    for u, n, f in determined:
        lo, hi = u["intervals"][n]
        assert lo <= f["weights"][n] * (1 + 1e-9) and hi >= f["weights"][n] * (1 - 1e-9) and lo < hi, (n, lo, hi)
        assert f"| {f['weights'][n]:.3g} | {lo:.3g} .. {hi:.3g} | *curvature*: determined |" in text
    # one rule for both methods: each verdict names the analysis that gave it, a profile's only where the curvature
    # and the bootstrap disagree or D is not smooth (docs/methods.md sec. 6.3, "Which analysis judges")
    # paths generated at known weights (a2 and a4 determined by 5 means): both methods give the same verdicts
    assert {n: verdict_category(bi["uncertainty"]["verdicts"][n]) for n in FITTED} == \
        {n: verdict_category(single["uncertainty"]["verdicts"][n]) for n in FITTED} == {n: "determined" for n in FITTED}
    for f in (bi, single):
        u = f["uncertainty"]
        assert set(u["by"]) == set(FITTED) and set(u["by"].values()) <= {"curvature", "bootstrap", "profile"}
        profiled = {n for n, b in u["by"].items() if b == "profile"}
        assert profiled <= (set(u["profile"]["verdicts"]) if u["profile"] else set()), (u["by"], u["profile"])
    # the pipeline order: the bi-level section before the single-level one
    assert text.index("Bi-level IOC (docs/methods.md sec. 6)") < text.index("Single-level IOC (docs/methods.md sec. 6.1)")


def test_a_p_value_that_underflowed_is_printed_as_its_bound():
    """Cochran's Q of 1950 on 2 degrees of freedom (the make run's single-level subjects on 2026-11-26): chi2.sf is
    exp(-975), 0 in doubles; the table printed p = 0."""
    from scipy.stats import chi2

    assert chi2.sf(1950, 2) == 0 and p_text(chi2.sf(1950, 2)) == "< 1e-300"
    assert p_text(chi2.sf(15.5, 3)) == "0.00144" and p_text(1.0) == "1"


@pytest.mark.slow  # the module's fits: about 16 s of CPU
def test_per_subject_section_shows_each_subjects_interval_and_the_subjects_test(fits):
    out, _ = fits
    doc = _doc(out, "fit-ioc-subjects")
    text = (out / "fit-ioc-subjects" / "results.md").read_text()
    assert set(doc["fits"]) == {"S1", "S2"}
    for s, f in doc["fits"].items():
        for n in FITTED:
            assert f"| {s} | {n} | {f['weights'][n]:.3g} | {_cells(f['uncertainty'], n)} |" in text
    rows = doc["subjects_differ"]
    assert [r["weight"] for r in rows] == sorted(FITTED)
    assert "| weight | subjects | Q | df | p | p (Holm) | subjects differ |" in text
    for r in rows:
        if r["differ"] is None:
            assert f"| {r['weight']} | {r['subjects']} | – | – | – | – | – |" in text
        else:
            assert (f"| {r['weight']} | {r['subjects']} | {r['Q']:.3g} | {r['df']} | {p_text(r['p'])} | {p_text(r['p_holm'])} | "
                    f"{'yes' if r['differ'] else 'no'} |") in text


@pytest.mark.slow  # the module's fits: about 16 s of CPU
def test_metrics_record_intervals_verdicts_and_the_subjects_test(fits):
    """The result's numbers are the files' (as the regression reads them), and they hold each weight's
    verdict category, its interval when determined, and the subjects-differ statistics."""
    from test_api_metrics import check

    out, runs = fits
    recorded = 0
    for stage, outcome in runs.items():
        numbers = check(outcome).as_dict()
        doc = _doc(out, stage)
        for k, f in doc["fits"].items():
            assert numbers[f"{stage}.{k}.D.fitted"] == f["objective"]
            for n in FITTED:
                v = f["uncertainty"]["verdicts"][n]
                assert numbers[f"{stage}.{k}.weights.{n}"] == f["weights"][n]
                assert numbers[f"{stage}.{k}.verdict.{n}"] == verdict_category(v)
                if v.startswith("determined"):
                    assert [numbers[f"{stage}.{k}.weights.{n}.{e}"] for e in ("lo", "hi")] == f["uncertainty"]["intervals"][n]
                    recorded += 1
                else:
                    assert f"{stage}.{k}.weights.{n}.lo" not in numbers
    assert recorded
    for r in _doc(out, "fit-ioc-subjects")["subjects_differ"]:
        key = f"fit-ioc-subjects.subjects_differ.{r['weight']}"
        assert numbers[f"{key}.subjects"] == r["subjects"]
        if r["differ"] is None:
            assert f"{key}.p" not in numbers and f"{key}.differ" not in numbers
        else:
            assert (numbers[f"{key}.p"], numbers[f"{key}.p_holm"], numbers[f"{key}.differ"]) == (r["p"], r["p_holm"], r["differ"])


@pytest.mark.slow  # the module's fits: about 16 s of CPU
def test_study_report_lists_every_fit_side_by_side(fits):
    from cobot_analysis.reports.builders import ioc_stages, report_inputs
    from cobot_analysis.reports.models import ioc_overview

    out, _ = fits
    assert ioc_stages(out) == ["fit-ioc", "fit-ioc-single", "fit-ioc-subjects"]  # each method beside the other
    inputs = report_inputs(out)
    assert {k: v for k, v in inputs.items() if k.startswith("ioc:")} == {f"ioc:{s}": out / s / "weights.json" for s in ioc_stages(out)}
    text = "\n".join(ioc_overview({s: out / s / "weights.json" for s in ioc_stages(out)}))
    for stage, method in (("fit-ioc", "bi-level"), ("fit-ioc-subjects", "bi-level"), ("fit-ioc-single", "single-level")):
        for k, f in _doc(out, stage)["fits"].items():
            for n in FITTED:
                row = (f"| {stage} | {method} | continuous | {k} | {f['objective']:.4f} | {f['seconds']:.1f} | {n} | "
                       f"{f['weights'][n]:.3g} | {_cells(f['uncertainty'], n)} |")
                assert row in text, row
    assert "Do the subjects' weights differ (fit-ioc-subjects, Cochran's Q" in text
    assert ioc_overview({}) == []


@pytest.mark.slow  # the module's fits: about 16 s of CPU
def test_single_level_budget_caps_its_steps(fits, tmp_path):
    """--max-evaluations below the single-level method's own number of steps caps them (the regression's
    short single-level fit); the fit still starts from, and never ends above, the start weights' D."""
    from cobot_analysis.stages import models

    out, runs = fits
    src = runs["fit-ioc"].result.means_source
    start = json.loads((out / "fit-ioc" / "weights.json").read_text())["fits"]["all"]["spec"]["start_weights"]
    weights = tmp_path / "start.json"
    weights.write_text(json.dumps({"convention": "continuous", "weights": dict(zip(names_for("improved"), start))}))
    one = models.fit_ioc(tmp_path / "ws", trajectories=src, fit=list(FITTED), start_weights=str(weights), intervals=20,
                         compare=False, jobs=1, bootstrap=0, method="single-level", max_evaluations=1).result.results["all"]
    assert ONE_STEP.search(one.message) and not ONE_STEP.search(runs["fit-ioc-single"].result.results["all"].message)
    assert one.objective <= one.start_objective


def test_a_single_level_fit_that_accepts_no_step_still_writes_its_stage(tmp_path):
    """Started at the weights that drew the paths, the single-level fit cannot lower D (0 up to the lower
    level's solver tolerance): whether or not it accepts its one step, the stage is written (its distances
    table empty when no step was accepted: that raised KeyError 'condition' on the pair study's table
    means, 2026-11-24)."""
    from cobot_analysis.schema import TRAJECTORIES, write_table
    from cobot_analysis.stages import models

    table = _table()
    src = write_table(table[table["kind"] == "mean"], tmp_path / "means.parquet", TRAJECTORIES)
    outcome = models.fit_ioc(tmp_path / "ws", trajectories=src, fit=list(FITTED), intervals=20, compare=False, jobs=1,
                             bootstrap=0, method="single-level", max_evaluations=1)
    r = outcome.result.results["all"]
    assert ONE_STEP.search(r.message)  # the budget of one step held
    # walking-2021, the default start, drew the paths: D is 0 there, and stays 0 to the solver's tolerance
    assert r.start_objective < 1e-6 and r.objective < 1e-6
    if ONE_STEP.search(r.message).group(1) == "0":  # the trust-region sequence: no step accepted, the start weights kept
        assert {n: r.weights[n] for n in FITTED} == {n: W[n] for n in FITTED}
    assert len(outcome.result.distances) == len(r.per_target)
    assert (outcome.directory / "results.md").is_file() and (outcome.directory / "weights.json").is_file()


def test_fit_inputs_take_the_authors_mean_block_under_the_published_convention(tmp_path):
    """fit-ioc (and bench_ioc.py) read the means of average/ under the continuous convention and the authors' own
    mean block (import-published's trajectories) under the published one; without average/, the trajectories."""
    from cobot_analysis.stages.models import fit_inputs

    for stage, name in (("import-published", "trajectories.parquet"), ("average", "means.parquet")):
        (tmp_path / stage).mkdir()
        (tmp_path / stage / name).write_bytes(b"")
    traj, means = tmp_path / "import-published" / "trajectories.parquet", tmp_path / "average" / "means.parquet"
    assert fit_inputs(tmp_path, "published") == (traj, traj)
    assert fit_inputs(tmp_path, "continuous") == (means, traj)
    assert fit_inputs(tmp_path, "published", means=means) == (means, traj)  # given means win
    means.unlink()
    assert fit_inputs(tmp_path, "continuous") == (None, traj)
