"""The results of the public API carry their headline numbers (``.metrics()``) and their figures
(``.figures()``): a result's numbers are exactly those the metric regression extracts from the files the
stage wrote (``regression.extract``, read back from disk), for every stage of a small synthetic study;
the ``metrics.json`` the stage wrote is the result's own numbers; the figures render."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.models.outputs import GENERATED
from cobot_analysis.regression.extract import stage_metrics
from cobot_analysis.schema import TRAJECTORIES, write_table
from cobot_analysis.synth.tables import pair_table


def from_files(directory: Path) -> dict:
    """What the regression extracts from a stage directory's files (not its memory, nor its result)."""
    params = json.loads((directory / "manifest.json").read_text())["params"]
    return stage_metrics(directory.name, directory, params)


def check(outcome) -> list:
    """The outcome's result numbers equal the files' (names, values, units, conventions, study) and metrics.json."""
    directory, result = outcome.directory, outcome.result
    numbers = result.metrics(stage=directory.name)
    expected = from_files(directory)
    assert [m.to_json() for m in numbers] == expected["metrics"], directory.name
    assert (numbers.study, numbers.convention) == (expected["study"], expected["convention"])
    assert json.loads((directory / "metrics.json").read_text())["metrics"] == expected["metrics"]
    assert [m.to_json() for m in result.metrics()] == expected["metrics"]  # the default stage is the stage's own directory
    return numbers


@pytest.fixture(scope="module")
def walking(tmp_path_factory):
    """A synthetic walking study (2 subjects x 2 start conditions x 2 repetitions, C3D) from import to stats."""
    from cobot_analysis.stages import analysis, data

    out = tmp_path_factory.mktemp("walking")
    data.synth_walking(out, subjects=2, repetitions=2, conditions=["E1500", "N4015"], jobs=1)
    runs = {"import": data.import_markers(out, out / "synth-walking" / "protocol.yaml", jobs=1)}
    runs["preprocess"] = data.preprocess(out, jobs=1)
    runs["average"] = analysis.average(out)
    runs["compare"] = analysis.compare(out)
    runs["compare-published"] = analysis.compare(out, convention="published")
    runs["stats"] = analysis.statistics(out)
    return out, runs


@pytest.mark.parametrize("stage", ["import", "preprocess", "average", "compare", "compare-published", "stats"])
def test_data_and_analysis_results_give_the_regression_numbers(walking, stage):
    numbers = check(walking[1][stage])
    assert numbers and all(m.name.startswith(stage.split("-")[0] if stage != "compare-published" else "compare.") for m in numbers)


def test_result_numbers_are_the_tables(walking):
    runs = walking[1]
    got = runs["average"].result.metrics().as_dict()
    means = runs["average"].result.means
    first = means[means["sample"] == 0]
    assert got["average.means"] == len(first) == 2  # one per start condition
    assert got["average.walker.trials"] == first["n_trials"].sum() == 8  # 2 subjects x 2 repetitions x 2 conditions
    d = runs["compare"].result.distances
    ind = d[d["comparison"] == "individual-mean"]
    c = runs["compare"].result.metrics()
    assert c.convention == "continuous" and runs["compare-published"].result.metrics().convention == "published"
    assert c.as_dict()["compare.individual-mean.walker.d_xy.mean"] == ind["d_xy"].mean()
    assert c.as_dict()["compare.individual-mean.walker.n"] == len(ind)
    import pyarrow.parquet as pq  # the import stage streams its markers to the file (result.markers is None)

    rows = pq.ParquetFile(runs["import"].directory / "markers.parquet").metadata.num_rows
    assert runs["import"].result.metrics().as_dict()["import.marker_samples"] == runs["import"].result.n_samples == rows


def test_reconstruct_result(tmp_path):
    from cobot_analysis.stages import analysis

    write_table(pair_table(n_pairs=2, goals=1), tmp_path / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    outcome = analysis.reconstruct(tmp_path)
    counts = {k: v for k, v in check(outcome).as_dict().items() if k.endswith(".n")}
    assert len(counts) >= 2 and sum(counts.values()) == len(outcome.result.reconstruction)  # the groups partition the rows


def test_localisation_result(tmp_path):
    from cobot_analysis.stages.localisation import localisation, synth_localisation

    synth_localisation(tmp_path, goals_per_lap=1, stop=3.0, speed=0.3, formats="ros1")
    outcome = localisation(tmp_path, figures=False, jobs=1)
    numbers = check(outcome).as_dict()
    assert numbers["localisation.runs"] == 1
    assert numbers["localisation.run.delay"] == pytest.approx(0.55, abs=0.01)  # the planted delay
    figures = outcome.result.figures()
    assert set(figures) == {"paths", "error_time", "error_distribution", "delay_cost", "timeseries_run"}
    assert all(f.axes for f in figures.values())


@pytest.mark.slow
def test_model_and_prediction_results(walking):
    """generate (both conventions), fit-ioc (a short fit), velocity-commands and predict."""
    from cobot_analysis.stages import models, predict

    out = walking[0]
    for conv in ("continuous", "published"):
        means = out / "average" / "means.parquet"
        gen = models.generate(out, study="walking-2020", weights="walking-2021", convention=conv, jobs=1, intervals=20,
                              **({"means": means} if conv == "published" else {}))  # 20 intervals: the numbers, not the paths
        numbers = check(gen)
        assert numbers.convention == conv and gen.directory.name == ("generate" if conv == "continuous" else "generate-published")
        fit = models.fit_ioc(out, max_evaluations=2, intervals=20, compare=False, convention=conv, jobs=1)
        check(fit)
        pred = predict.predict(out, kind="trial", settings="50:100", every=4, convention=conv, jobs=1)
        check(pred)
        assert set(pred.result.figures()) and all(f.axes for f in pred.result.figures().values())
    # velocity commands of a continuous path (a published path's time law is refused: tests/test_models_goal.py)
    continuous = out / "generate" / "generated.parquet"
    trial = pd.read_parquet(continuous)["trial"].iloc[0]
    cmd = models.velocity_commands(out, generated=continuous, trial=trial)
    check(cmd)


def test_fit_ioc_and_velocity_commands_take_parquet_paths(walking):
    """The one input type: the documented table or the path of its Parquet file, same answer; the fit's figures."""
    import cobot_analysis.api as ca
    from cobot_analysis.reports.figures import check_figure

    out = walking[0]
    means = out / "average" / "means.parquet"
    by_path = ca.fit_ioc(means, trials=out / "preprocess" / "trajectories.parquet", intervals=20, max_evaluations=2, jobs=1)
    by_table = ca.fit_ioc(walking[1]["average"].result.means, intervals=20, max_evaluations=2, compare=False, jobs=1)
    assert by_path.results["all"].objective == by_table.results["all"].objective
    assert by_path.means_source == str(means)
    figures = by_path.figures()
    assert sorted(figures) == ["distances_boxplot", "paths"] and all(check_figure(f) == [] for f in figures.values())
    # each figure names the fitted model and the convention (the two conventions' PNGs sit side by side in a workspace)
    assert figures["distances_boxplot"].get_suptitle() == ("Distances of each model's paths to the mean paths (improved OC "
                                                           "fitted, continuous convention)")
    assert figures["paths"].legends[0].get_title().get_text() == ("mean (black) vs improved OC: published, fitted weights "
                                                                   "(continuous convention)")
    # the fit names its model paths that spin (converged, no walker's path), as generate's status does
    from dataclasses import replace

    from cobot_analysis.models import spin_status, spins
    from cobot_analysis.reports.models import fit_ioc_markdown

    paths = by_path.model_paths()
    assert len(paths.groupby("trial")) == len(by_path.mean_targets)
    assert by_path.spinning() == [c for c, g in paths.groupby("trial", sort=False) if spins(g["theta"].to_numpy())]
    first = by_path.paths["fitted"][0]
    theta = first["theta"].to_numpy() + 3 * np.pi * np.sin(np.linspace(0.0, np.pi, len(first)))  # 1.5 turns there and back
    spun = replace(by_path, paths={**by_path.paths, "fitted": [first.assign(theta=theta, status=spin_status(theta)),
                                                               *by_path.paths["fitted"][1:]]})
    name = by_path.mean_targets[0].condition
    assert spun.spinning() == [name, *by_path.spinning()] and spun.spinning("published") == by_path.spinning("published")
    # means that share a condition (the pair study's scenarios and directions) are named by their own names
    shared = replace(spun, mean_targets=[replace(t, condition="c") for t in by_path.mean_targets])
    assert shared.spinning()[0] == by_path.mean_targets[0].trial
    assert shared.model_paths().groupby("trial").ngroups == len(by_path.mean_targets)
    assert spun.summary().endswith(f"; at the fitted weights {len(spun.spinning())} of {len(by_path.mean_targets)} model paths "
                                   "spin (no walker's path: results.md)")

    class Stage:
        def savefig(self, fig, name):
            import matplotlib.pyplot as plt
            plt.close(fig)

    text = fit_ioc_markdown(spun, Stage(), optimizer="powell", intervals=20, v_nominal=1.0, durations=None)
    line = next(x for x in text.splitlines() if x.startswith("The model's paths at the fitted weights"))
    assert "**Heading: no walker's turn**" in line and "spin, their heading turning more than a full turn" in line and name in line
    assert "The model's paths at the published weights" in text
    generated = ca.generate("clothoid", start=(-1.5, -3.4, 0.0), jobs=1).generated
    path = write_table(generated, out / "clothoid.parquet", GENERATED)
    assert ca.velocity_commands(path).commands.equals(ca.velocity_commands(generated).commands)


def test_analysis_and_model_figures_render():
    """Each figure has data, units on its axes and a legend naming its series (reports.figures.check_figure)."""
    import cobot_analysis.api as ca
    from cobot_analysis.reports.figures import check_figure
    from cobot_analysis.synth.tables import walking_table

    walks = walking_table(n_subjects=3, n_conditions=2, n_trials=2)
    means = ca.average(walks)
    pairs = ca.average(pair_table(n_pairs=2, goals=1))
    figures = {"average": means.figures(), "pairs": pairs.figures(), "compare": ca.compare(walks, means.means).figures(),
               "generate": ca.generate("all", start=(-1.5, -3.4, 0.0), jobs=1).figures()}
    assert {k: sorted(v) for k, v in figures.items()} == {
        "average": ["means"], "pairs": ["means"], "compare": ["d_gamma", "d_theta", "d_xy"], "generate": ["paths"]}
    assert len(figures["average"]["means"].axes) >= 2  # one panel per mean (2 conditions), plus the legend's
    for name, figs in figures.items():
        for stem, fig in figs.items():
            assert check_figure(fig) == [], (name, stem)
    assert ca.fit_ioc(means.means, intervals=20, max_evaluations=2, compare=False, jobs=1).figures() == {}  # drawn with the comparison


def test_the_metrics_package_example_runs():
    import doctest

    import cobot_analysis.metrics

    result = doctest.testmod(cobot_analysis.metrics, report=True)
    assert result.attempted > 0 and result.failed == 0
