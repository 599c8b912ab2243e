"""Every figure of the pipeline, rendered on small inputs and checked as a reviewer would: axis
labels with units, a legend naming each series where an axes shows several, orientation arrows
visible at the panel size, n under each box, overlaid sources both visible, one panel per run.
``figures.check_figure`` does the generic part; its own tests make it fail on bad figures."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.reports import builders, figures
from cobot_analysis.reports.figures import check_figure

from cobot_analysis.plotting import pyplot

plt = pyplot()


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def reviewable(fig) -> None:
    """Fail with every problem ``check_figure`` finds."""
    problems = check_figure(fig)
    assert problems == [], "\n".join(problems)


def legend_texts(fig) -> list[str]:
    return [t.get_text() for lg in [*fig.legends, *(a.get_legend() for a in fig.axes)] if lg is not None for t in lg.get_texts()]


def data_axes(fig) -> list:
    return [a for a in fig.axes if a.get_visible() and (a.lines or a.collections or a.patches)]


def arrow_pixels(fig, quiver) -> float:
    """Length on the page (pixels at 150 dpi) of the longest arrow of a quiver."""
    fig.set_dpi(150)
    fig.canvas.draw()
    ax = quiver.axes
    xy = quiver.XY
    tip = xy + np.column_stack([quiver.U, quiver.V]) / quiver.scale
    a, b = ax.transData.transform(xy), ax.transData.transform(tip)
    return float(np.max(np.hypot(*(b - a).T)))


def pixels_of(fig, ax, rgb, alpha: float = 1.0, tol: float = 0.12) -> int:
    """Pixels inside ``ax`` of the colour ``rgb`` drawn at ``alpha`` over white."""
    from matplotlib.colors import to_rgb

    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0
    h = img.shape[0]
    bb = ax.get_window_extent()
    crop = img[int(h - bb.y1):int(h - bb.y0), int(bb.x0):int(bb.x1)]
    want = alpha * np.asarray(to_rgb(rgb)) + (1 - alpha)
    return int((np.abs(crop - want).max(axis=-1) < tol).sum())


# ---- the checker itself ----------------------------------------------------------------------------
def test_unit_pattern():
    for ok in ("x (m)", "time [s]", "yaw error (rad)", "cost J(d) / min J (-)", "d_xy individual vs mean (m) "):
        assert figures.UNIT.search(ok), ok
    for bad in ("x", "J(d) / min J", "x ()", "samples", "(m) x"):
        assert not figures.UNIT.search(bad), bad


def test_checker_accepts_a_good_figure_and_names_what_is_wrong_in_bad_ones():
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1], label="measured")
    ax.plot([0, 1], [1, 0], label="model")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("x (m)")
    ax.legend()
    assert check_figure(fig) == []

    ax.set_xlabel("time")  # no unit
    ax.get_legend().remove()  # two series, no legend
    problems = check_figure(fig)
    assert len(problems) == 3
    assert "x label 'time' gives no unit" in problems[0]
    assert all("2 series" in p and "named by no legend" in p for p in problems[1:])

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    assert [p.split(": ", 1)[1] for p in check_figure(fig)] == ["no x label", "no y label"]  # one series: no legend needed


def test_checker_wants_every_series_named():
    fig, ax = plt.subplots()
    ax.set(xlabel="x (m)", ylabel="y (m)")
    ax.plot([0, 1], [0, 1], color="k", label="measured mean")
    ax.quiver([0], [0], [1], [1], color="k")  # arrows nobody explains
    ax.legend()
    problems = check_figure(fig)
    assert len(problems) == 1 and "Quiver" in problems[0]


def test_checker_accepts_figure_legends_shared_labels_and_categories():
    fig, axes = plt.subplots(1, 2, sharey=True)
    for ax in axes:  # the same two series in both panels, named once in a figure legend
        ax.plot([0, 1], [0, 1], color="k", label="measured")
        ax.hist(np.arange(10.0), histtype="bar", color="tab:blue", label="errors")  # bars after the first are '_nolegend_'
        ax.set_xlabel("x (m)")
    axes[0].set_ylabel("count (-)")  # the right panel shares it
    h, lab = axes[0].get_legend_handles_labels()
    fig.legend(h, lab)
    assert check_figure(fig) == []

    fig, ax = plt.subplots()  # a box plot: its ticks name its boxes, no legend needed
    ax.boxplot([[1, 2, 3], [2, 3, 5]])
    ax.set_xticks([1, 2], ["a\n(n = 3)", "b\n(n = 3)"])
    ax.set(xlabel="group", ylabel="d_xy (m)")
    assert check_figure(fig) == []
    ax.set_xticks([1, 2], ["a", ""])
    assert any("empty x tick label" in p for p in check_figure(fig))

    fig, ax = plt.subplots()  # a log scale is numeric: its label needs a unit
    ax.plot([0, 1], [1, 100])
    ax.set_yscale("log")
    ax.set(xlabel="delay (s)", ylabel="J(d) / min J")
    assert len(check_figure(fig)) == 1 and "y label" in check_figure(fig)[0]

    fig, ax = plt.subplots()  # pies have no axes to label
    ax.pie([1, 2])
    assert check_figure(fig) == []


def test_checker_refuses_the_old_path_and_box_figures():
    """The figures the issue complained about: unexplained arrows and thin lines, boxes without x label."""
    fig, ax = plt.subplots()
    t = np.linspace(0, 1, 50)
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection([np.column_stack([t, t ** 2])], colors="tab:blue", linewidths=0.5, alpha=0.35))
    ax.plot(t, t ** 2, color="tab:blue", lw=2, label="walker")
    ax.quiver(t[::10], t[::10] ** 2, np.ones(5), np.ones(5), color="tab:blue", scale=18)
    fig.legend()
    fig.supxlabel("x (m)")
    fig.supylabel("y (m)")
    problems = check_figure(fig)
    assert sorted(p.split("one (")[1].split(" ")[0] for p in problems) == ["LineCollection", "Quiver"]


# ---- path panels ---------------------------------------------------------------------------------
def walking_panels(rng, n_subjects=4, with_theta=True):
    """Path panels of the 40 walking conditions: straight-ish paths from the nominal start to the goal."""
    from cobot_analysis.design import WALKING_CONDITIONS, walking_condition

    panels = []
    s = np.linspace(0, 1, 100)
    for code in WALKING_CONDITIONS:
        x0, y0, th0 = walking_condition(code).start
        lines = [(x0 * (1 - s) + rng.normal(0, 0.05) * np.sin(np.pi * s), y0 * (1 - s), "walker") for _ in range(n_subjects)]
        x, y = x0 * (1 - s), y0 * (1 - s)
        th = th0 + (math.pi / 2 - th0) * s if with_theta else np.full_like(s, np.nan)
        panels.append({"title": figures.walking_title(code), "lines": lines, "means": [(x, y, th, "walker")], "key": (code,)})
    return panels


def test_walking_grid_orders_start_positions_by_distance():
    from cobot_analysis.design import WALKING_CONDITIONS

    grid = figures.walking_grid(WALKING_CONDITIONS, WALKING_CONDITIONS)
    assert grid["N1500"] == (0, 0) and grid["E1500"] == (0, 1) and grid["S1500"] == (0, 2) and grid["O1500"] == (0, 3)
    assert grid["O4040"] == (9, 3)
    assert sorted(grid.values()) == [(r, c) for r in range(10) for c in range(4)]
    assert figures.walking_grid(["d1_p4_gris"], WALKING_CONDITIONS) is None
    assert figures.walking_grid(["N1500", "S1020"], ["N1500"]) is None  # S1020: a lab's own label, no code of its data


def test_walking_paths_grid_legend_and_visible_arrows():
    rng = np.random.default_rng(1)
    panels = walking_panels(rng)
    grid = figures.walking_grid([p["key"][0] for p in panels], [p["key"][0] for p in panels])
    for p in panels:
        p["cell"] = grid[p["key"][0]]
    fig = figures.paths(panels, share="row", size=2.4, col_titles=list(figures.WALKING_COLUMNS.values()),
                        names={"means": "mean of the subjects"}, title="walking")
    reviewable(fig)
    axes = data_axes(fig)
    assert len(axes) == 40
    assert set(legend_texts(fig)) == {"individual trajectories", "mean of the subjects", "orientation θ of the mean",
                                      "start of a mean path"}
    # one scale per row: the 4 orientations of a start position share their window
    first = axes[0]
    row = [a for a in axes if a.get_subplotspec().rowspan.start == first.get_subplotspec().rowspan.start]
    assert len(row) == 4 and all(a.get_xlim() == first.get_xlim() and a.get_ylim() == first.get_ylim() for a in row)
    assert "start facing N" in first.get_title() and "N1500" in first.get_title()
    for ax in axes:
        assert ax.get_aspect() == 1.0
        (q,) = [c for c in ax.collections if type(c).__name__ == "Quiver"]
        assert q.scale_units == "xy" and q.N == 8
        side = ax.get_xlim()[1] - ax.get_xlim()[0]
        assert np.allclose(np.hypot(q.U, q.V), 0.07 * side)  # arrows in metres: 7 % of the window
    # visible at the panel size: the shortest row (0.9 m start) still gets arrows of > 10 pixels at 150 dpi
    assert arrow_pixels(fig, [c for c in first.collections if type(c).__name__ == "Quiver"][0]) > 10


def test_paths_without_orientation_say_so():
    panels = walking_panels(np.random.default_rng(2), with_theta=False)[:3]
    fig = figures.paths(panels, ncols=3)
    reviewable(fig)
    for ax in data_axes(fig):
        assert not [c for c in ax.collections if type(c).__name__ == "Quiver"]
        assert [t.get_text() for t in ax.texts] == ["no orientation: no arrows"]


def test_pair_paths_name_entities_scenarios_and_arrows():
    s = np.linspace(0, 1, 60)
    panels = []
    for goal, end in (("d1_p4_gris", 0.0), ("d1_p4_gris", math.pi)):
        lines, means = [], []
        for k, ent in enumerate(("subject1", "subject2", "table")):
            for sc in (1, 2, 3):
                x, y, th = -3 * s + 0.3 * k, -2 * s + 0.05 * sc, np.full_like(s, end * s[-1])
                lines.append((x + 0.02, y, ent))
                means.append((x, y, th, ent, builders.SCENARIO_STYLE[sc], f"mean of scenario {sc}"))
        panels.append({"title": builders._end_title((goal, end)), "lines": lines, "means": means})
    fig = figures.paths(panels, ncols=6, arrows=6, names={"lines": "individual trials"})
    reviewable(fig)
    texts = legend_texts(fig)
    for name in ("Subject 1", "Subject 2", "table"):
        assert f"{name}: individual trials" in texts and f"{name}: orientation θ of the mean" in texts
        assert all(f"{name}: mean of scenario {sc}" in texts for sc in (1, 2, 3))
    assert fig.legends[0]._ncols == 4  # one column per entity, then the start marker
    assert [a.get_title() for a in data_axes(fig)] == ["d1_p4_gris, table ends at 0°", "d1_p4_gris, table ends at 180°"]


# ---- box plots -----------------------------------------------------------------------------------
def test_boxplots_show_n_and_the_tukey_whiskers():
    base = np.arange(1.0, 11.0)
    fig = figures.boxplots({"a": np.r_[base, 30.0], "b": [1.0, 2.0, np.nan, 4.0]}, "d_xy (m)", xlabel="subject")
    reviewable(fig)
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["a\n(n = 11)", "b\n(n = 3)"]  # NaN not counted
    values = np.r_[base, 30.0]
    q1, q3 = np.percentile(values, [25, 75])
    whisker_tops = [line.get_ydata()[1] for line in ax.lines[1:4:2]]  # whiskers of box a: low, high
    assert whisker_tops[1] == values[values <= q3 + 1.5 * (q3 - q1)].max() == 10.0
    fliers = [line for line in ax.lines if line.get_marker() == "o" and len(line.get_ydata())]
    assert [list(f.get_ydata()) for f in fliers] == [[30.0]]


def test_model_boxplots_count_each_metric():
    from cobot_analysis.reports.models import figure_boxplots

    df = pd.DataFrame({"model": ["unicycle"] * 5 + ["improved OC (fitted)"] * 4,
                       "d_xy": [0.1, 0.2, 0.3, 0.2, 0.1, 0.2, 0.25, 0.3, np.nan],
                       "d_gamma": [0.1, np.nan, np.nan, 0.2, 0.3, 0.1, 0.2, 0.3, 0.4]})
    fig = figure_boxplots(df, "gamma")
    reviewable(fig)
    ticks = [[t.get_text() for t in ax.get_xticklabels()] for ax in fig.axes]
    assert ticks == [["unicycle\n(n = 5)", "improved OC\n(fitted)\n(n = 3)"], ["unicycle\n(n = 3)", "improved OC\n(fitted)\n(n = 4)"]]
    assert [ax.get_ylabel() for ax in fig.axes] == ["d_xy to the measured path (m)", "d_gamma to the measured path (rad)"]


# ---- model path figures (fit-ioc) ----------------------------------------------------------------
def walking_targets():
    from cobot_analysis.design import WALKING_CONDITIONS, walking_condition
    from cobot_analysis.models.ioc.targets import Target

    s = np.linspace(0, 1, 200)
    out = []
    for code in WALKING_CONDITIONS[:12]:
        x0, y0, th0 = walking_condition(code).start
        out.append(Target(f"mean:{code}", code, "", x0 * (1 - s), y0 * (1 - s), th0 + (math.pi / 2 - th0) * s,
                          orientation=code[0]))  # a walking-2020 code its path agrees with (as targets_from_table says)
    return out


def test_model_paths_figure():
    from cobot_analysis.reports.models import figure_paths

    targets = walking_targets()
    shift = lambda t, d: pd.DataFrame({"x": t.x + d, "y": t.y, "theta": t.theta})  # noqa: E731
    gen = {"published": [shift(t, 0.05) for t in targets], "fitted": [None] + [shift(t, -0.05) for t in targets[1:]]}
    fig = figure_paths(targets, gen, "mean (black) vs improved OC: published, fitted")
    reviewable(fig)
    texts = set(legend_texts(fig))
    assert texts == {"measured", "model, published weights", "model, fitted weights", "measured: orientation θ",
                     "model, published weights: orientation θ", "model, fitted weights: orientation θ"}
    axes = data_axes(fig)
    assert len(axes) == 12  # 3 start positions x 4 orientations
    notes = {a.get_title().split("\n")[-1]: [t.get_text() for t in a.texts] for a in axes if a.texts}
    assert notes == {"N1500, 0.9 m from the goal": ["no solution: model, fitted weights"]}  # the target without a fit
    q = [c for c in axes[0].collections if type(c).__name__ == "Quiver"][0]
    assert q.scale_units == "xy" and arrow_pixels(fig, q) > 10

    labelled = figure_paths(targets[:2], {"fitted": [shift(t, 0.1) for t in targets[:2]]}, "t", labels={"fitted": "improved OC, fitted"})
    assert "improved OC, fitted" in legend_texts(labelled)
    reviewable(figure_paths([], {}, "nothing"))


def test_coupled_pair_paths_figure():
    from cobot_analysis.models.ioc.targets import PairTarget, Target
    from cobot_analysis.reports.models import figure_pair_paths

    s = np.linspace(0, 1, 150)
    targets = []
    for k, direction in enumerate(("forward", "return")):
        c1 = Target("subject1", "d1_p4_gris", "", -3 * s, -2 * s + 0.4, np.full_like(s, 0.3 * k))
        c2 = Target("subject2", "d1_p4_gris", "", -3 * s, -2 * s - 0.4, np.full_like(s, 0.3 * k))
        targets.append(PairTarget(f"d1_p4_gris_{direction}_sc3", "d1_p4_gris", (c1, c2), direction=direction))
    paths = {"published": [[{"x": c.x + 0.1, "y": c.y, "theta": c.theta} for c in t.carriers] for t in targets],
             "fitted": [None, [{"x": c.x - 0.1, "y": c.y, "theta": c.theta} for c in targets[1].carriers]]}
    fig = figure_pair_paths(targets, paths, "scenario-3 means vs coupled OC")
    reviewable(fig)
    texts = legend_texts(fig)
    for name in ("measured mean", "model, published weights", "model, fitted weights"):
        assert {f"{name}: carrier 1", f"{name}: carrier 2", f"{name}: orientation θ"} <= set(texts)
    assert "carrier 1 = Subject 1 on forward paths" in fig.legends[0].get_title().get_text()
    assert [t.get_text() for t in data_axes(fig)[0].texts] == ["not converged: model, fitted weights"]


# ---- report builders -----------------------------------------------------------------------------
class FakeStage:
    """Collects the figures a report builder saves."""

    def __init__(self, tmp: Path):
        self.figs, self.tmp = {}, tmp

    def savefig(self, fig, stem):
        self.figs[stem] = fig

    def path(self, name):
        return self.tmp / name


def trajectory_set(panels) -> SimpleNamespace:
    """A trajectory set (meta, x, y, theta) from walking panels: subjects as trials, and the means."""
    rows, xs, ys, ths = [], [], [], []
    for p in panels:
        code = p["key"][0]
        for j, (x, y, _) in enumerate(p["lines"]):
            rows.append({"study": "walking-2020", "kind": "trial", "condition": code, "entity": "walker", "subject": f"S{j + 1:02d}"})
            xs.append(x), ys.append(y), ths.append(np.full_like(x, math.nan if j == 0 else 0.5))
    trials = SimpleNamespace(meta=pd.DataFrame(rows), x=np.array(xs), y=np.array(ys), theta=np.array(ths))
    means = SimpleNamespace(meta=pd.DataFrame([{"study": "walking-2020", "kind": "mean", "condition": p["key"][0], "entity": "walker"}
                                               for p in panels]),
                            x=np.array([p["means"][0][0] for p in panels]), y=np.array([p["means"][0][1] for p in panels]),
                            theta=np.array([p["means"][0][2] for p in panels]))
    return trials, means


def _sections(study, data, stage) -> list[str]:
    lines: list[str] = []
    builders._data_section(study, data, lines, [])
    builders._paths_section(study, data, stage, lines)
    builders._distance_section(study, data, stage, lines)
    builders._carriage_section(study, data, stage, lines)
    return lines


def test_walking_report_figures_from_synthetic_tables(tmp_path):
    from cobot_analysis import study as st

    panels = walking_panels(np.random.default_rng(3))
    ts, means = trajectory_set(panels)
    rng = np.random.default_rng(4)
    n = len(ts.meta)
    dist = pd.DataFrame({"comparison": ["individual-mean"] * n + ["model"] * 40, "kind": "trial", "study": "walking-2020",
                         "entity": "walker", "subject": list(ts.meta["subject"]) + [None] * 40,
                         "condition": list(ts.meta["condition"]) + [p["key"][0] for p in panels],
                         "global_distance": rng.uniform(0.9, 5.2, n + 40), "d_xy": rng.gamma(2, 0.05, n + 40),
                         "d_gamma": rng.gamma(2, 0.1, n + 40)})
    stage = FakeStage(tmp_path)
    study = st.load(Path(st.PIPELINES) / "walking-2020.toml")
    lines = _sections(study, {"ts": ts, "means": means, "distances": dist}, stage)
    assert set(stage.figs) == {"paths", "box_d_xy_subject", "box_d_gamma_subject", "box_d_xy_condition", "box_d_xy_start_orientation",
                               "scatter_d_xy_global", "box_model", "box_model_conditions"}
    for stem, fig in stage.figs.items():
        assert check_figure(fig) == [], stem
    assert len(data_axes(stage.figs["paths"])) == 40
    scatter = stage.figs["scatter_d_xy_global"].axes[0]  # says what d_xy it plots, like the boxes beside it
    assert (scatter.get_title(), scatter.get_ylabel()) == ("Individual vs mean d_xy against the global distance",
                                                           "d_xy individual vs mean (m)")
    ticks = [t.get_text() for t in stage.figs["box_d_xy_subject"].axes[0].get_xticklabels()]
    assert ticks == [f"S{j:02d}\n(n = 40)" for j in range(1, 5)]
    text = "\n".join(lines)  # captions cite the study file's questions and explain the letters
    assert "W1.1" in text and "W1.5" in text
    assert any("N = facing north" in a for a in study.abbreviations())  # the letters, explained at the top of the report


def foreign_study_data():
    """A study that is not ours: 3 participants x 3 floors x 3 repetitions, and its study file."""
    from cobot_analysis import study as st

    foreign = st.parse({"study": "lab-gait", "title": "Gait on three floors", "entities": ["walker"], "factor": [
        {"column": "subject", "label": "participant"},
        {"column": "condition", "label": "floor", "short": "fl", "levels": {"1": "carpet", "2": "wood", "3": "tiles"}}]})
    rng = np.random.default_rng(0)
    s = np.linspace(0, 1, 60)
    rows, xs, ys, ths = [], [], [], []
    for subj in ("P1", "P2", "P3"):
        for floor in ("1", "2", "3"):
            for _ in range(3):
                rows.append({"kind": "trial", "condition": floor, "entity": "walker", "subject": subj, "study": "lab-gait"})
                xs.append(4 * s + rng.normal(0, 0.05))
                ys.append(0.3 * np.sin(np.pi * s) * rng.normal(1, 0.2))
                ths.append(0 * s)
    ts = SimpleNamespace(meta=pd.DataFrame(rows), x=np.array(xs), y=np.array(ys), theta=np.array(ths))
    n = len(rows)
    dist = pd.DataFrame({"comparison": "individual-mean", "kind": "trial", "study": "lab-gait", "entity": "walker",
                         "subject": ts.meta["subject"], "condition": ts.meta["condition"], "global_distance": rng.uniform(3, 5, n),
                         "d_xy": rng.gamma(2, 0.05, n), "d_theta": rng.gamma(2, 0.05, n), "d_gamma": rng.gamma(2, 0.1, n)})
    return foreign, ts, dist


def test_report_figures_of_a_study_that_is_not_ours(tmp_path):
    """Its labels on the figures, no CoBot question, every figure kind a reviewer accepts (paths,
    boxes by each factor, proportions with intervals)."""
    foreign, ts, dist = foreign_study_data()
    stage = FakeStage(tmp_path)
    lines = _sections(foreign, {"ts": ts, "distances": dist}, stage)
    assert set(stage.figs) == {"paths", "box_d_xy_subject", "box_d_xy_condition", "box_d_theta_subject", "box_d_gamma_subject",
                               "scatter_d_xy_global"}
    for stem, fig in stage.figs.items():
        assert check_figure(fig) == [], stem
    ticks = [t.get_text().split("\n")[0] for t in stage.figs["box_d_xy_condition"].axes[0].get_xticklabels()]
    assert ticks == ["fl1", "fl2", "fl3"]
    assert stage.figs["box_d_xy_condition"].axes[0].get_xlabel() == "floor"
    text = "\n".join(lines)
    assert "W1" not in text and "Q1" not in text
    assert foreign.abbreviations() == ["floor: fl1 = carpet; fl2 = wood; fl3 = tiles"]  # listed once at the top of the report
    bars = figures.proportions({"optimal for Subj. 1": {"optimal": 7, "not optimal": 3}, "patterns": {"a": 1, "b": 2, "c": 9}},
                               "choices", chance={"optimal for Subj. 1": 0.5})
    reviewable(bars)
    assert bars.axes[0].get_shared_y_axes().joined(bars.axes[0], bars.axes[1])  # one 0-100 % axis
    bars.savefig(tmp_path / "bars.png")


def test_wilson_interval_by_hand():
    lo, hi = figures.wilson(7, 10)  # Wilson 1927: 0.3968, 0.8922 for 7 of 10
    assert abs(lo - 0.3968) < 1e-3 and abs(hi - 0.8922) < 1e-3
    assert figures.wilson(0, 5)[0] == 0.0 and figures.wilson(5, 5)[1] == 1.0


@pytest.mark.slow
def test_report_figures_of_the_published_data(datasets, tmp_path, cli):
    """walking-2020 and pair-carriage-2022 as the pipeline reads them: every report figure passes."""
    from cobot_analysis import study as st

    for study, dataset, n_paths in (("walking", "walking-2020", {"paths": 40}),
                                    ("pairs", "pair-carriage-2022", {"paths_forward": 18, "paths_return": 18})):
        ws = tmp_path / study
        for args in (["import-published", dataset, datasets / dataset], ["average"], ["compare"]):
            code, _, err = cli("-q", *args, "--out", ws)
            assert code == 0, err
        stage = FakeStage(tmp_path)
        _sections(st.load(Path(st.PIPELINES) / f"{dataset}.toml"), builders._load(builders.report_inputs(ws)), stage)
        for stem, fig in stage.figs.items():
            assert check_figure(fig) == [], stem
        for stem, count in n_paths.items():
            assert len(data_axes(stage.figs[stem])) == count, stem
        plt.close("all")


def test_a_few_named_paths_get_their_own_colour_and_start(tmp_path):
    """Three walks of three labs in one panel: each in its own colour, named by the legend, its start
    marked (faint lines of one colour hid who walked where and which way); a crowd stays faint."""
    t = np.linspace(0, 1, 50)
    lines = [(x0 + sgn * 3.6 * t, y0 + 0.05 * np.sin(6 * t), "walker", who)
             for x0, y0, sgn, who in ((-2.0, 0.3, 1, "BTK-A"), (-1.8, 0.6, 1, "BTK-B"), (2.2, 0.0, -1, "BTK-C"))]
    fig = figures.paths([{"title": "walk", "lines": lines, "means": []}], ncols=1, share=True)
    reviewable(fig)
    ax = data_axes(fig)[0]
    drawn = {line.get_label(): line for line in ax.lines}
    assert {"BTK-A", "BTK-B", "BTK-C", "start of a path"} <= set(drawn)
    assert len({drawn[n].get_color() for n in ("BTK-A", "BTK-B", "BTK-C")}) == 3
    assert {"BTK-A", "BTK-B", "BTK-C"} <= set(legend_texts(fig))
    starts = [line for line in ax.lines if line.get_label() == "start of a path"]
    assert sorted(float(s.get_xdata()[0]) for s in starts) == [-2.0, -1.8, 2.2]
    crowd = [(x, y, e, f"S{k:02d}") for k in range(4) for x, y, e, _ in lines]  # 12 paths: one faint collection
    fig = figures.paths([{"title": "walk", "lines": crowd, "means": []}], ncols=1)
    reviewable(fig)
    ax = data_axes(fig)[0]
    assert not ax.lines and len(ax.collections) == 1


# ---- localisation --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def loc_results(tmp_path_factory):
    """Two short synthetic robot runs (2 goals each), analysed; the second twice under another label
    (identical runs: drawn in one axes they would hide each other)."""
    from cobot_analysis.localisation import synth
    from cobot_analysis.localisation.analysis import Options, analyse_run
    from cobot_analysis.localisation.goals import StopRule

    d = tmp_path_factory.mktemp("loc")
    res = []
    for seed in (0, 1):
        synth.write_mcap(synth.make_run(synth.SynthParams(seed=seed, n_goals=2, stop=4.0)), d / f"r{seed}.mcap")
    opts = Options(rule=StopRule(min_duration=2.0))
    for label, f in (("run A", "r0.mcap"), ("run B", "r1.mcap"), ("run B again", "r1.mcap")):
        res.append(analyse_run((str(d / f), label, "synthetic", opts)))
    return res


def test_localisation_figures_are_reviewable(loc_results):
    from cobot_analysis.reports import localisation as report

    figs = {"paths": report.figure_paths(loc_results), "error_time": report.figure_error_time(loc_results),
            "error_distribution": report.figure_error_distribution(loc_results), "delay": report.figure_delay(loc_results),
            "timeseries": report.figure_timeseries(loc_results[0])}
    for stem, fig in figs.items():
        assert check_figure(fig) == [], stem
    runs = [r["run"] for r in loc_results]
    # one panel (row) per run where runs would hide each other; each names its run
    for stem, per_run in (("paths", 1), ("error_time", 2), ("error_distribution", 4), ("delay", 1)):
        axes = data_axes(figs[stem])
        assert len(axes) == per_run * len(runs), stem
        names = [a.get_title().split(":")[0].split(" (")[0] for a in axes]
        assert [names.count(r) for r in runs] == [per_run] * 3, stem
    titles = [a.get_title() for a in data_axes(figs["error_distribution"])]
    assert titles[0].startswith("run A: x, mean") and titles[0].endswith(f"(n = {len(loc_results[0]['samples'])})")
    assert "goals" in " ".join(legend_texts(figs["paths"]))


def test_motion_capture_line_stays_visible_over_the_icp(loc_results):
    """Pixels of both sources in every panel of the time series: the truth line is drawn above the dots."""
    from cobot_analysis.reports import localisation as report

    fig = report.figure_timeseries(loc_results[0])
    fig.set_dpi(100)
    for ax in fig.axes:
        truth = next(line for line in ax.lines if line.get_label().startswith("motion capture"))
        icp = next(line for line in ax.lines if line.get_label().startswith("ICP"))
        assert truth.get_zorder() > icp.get_zorder()
        assert pixels_of(fig, ax, truth.get_color()) > 300, ax.get_ylabel()
        assert pixels_of(fig, ax, icp.get_color(), alpha=icp.get_alpha(), tol=0.2) > 100, ax.get_ylabel()


def _noisy_runs(n_runs: int = 3, n: int = 1414, rate: float = 10.0, seed: int = 0) -> list[dict]:
    """Runs as the localisation stage hands them to its figures: white errors of the synthetic robot's
    size (sd 6 mm per axis, 4 mrad in yaw) at an ICP's 10 Hz over about 140 s."""
    rng = np.random.default_rng(seed)
    runs = []
    for i in range(n_runs):
        e = {a: rng.normal(0, 0.006 if a != "yaw" else 0.0041, n) for a in ("x", "y", "z", "yaw")}
        s = pd.DataFrame({"t_truth": 100.0 + np.arange(n) / rate, **{f"err_{a}": v for a, v in e.items()},
                          "err_xyz": np.sqrt(e["x"] ** 2 + e["y"] ** 2 + e["z"] ** 2)})
        runs.append({"run": f"run{i}.mcap", "samples": s})
    return runs


def test_error_distribution_yaw_ticks_do_not_overlap():
    """Yaw errors of a few milliradians: drawn in rad their ticks ("-0.015-0.010") ran into each other;
    in mrad they do not, and no title says "-0.0"."""
    from cobot_analysis.reports import localisation as report

    fig = report.figure_error_distribution(_noisy_runs(seed=1))  # in rad: '−0.015' and '−0.010' overlap
    reviewable(fig)
    yaw = [ax for ax in fig.axes if ax.get_xlabel().startswith("error yaw")]
    assert len(yaw) == 1 and yaw[0].get_xlabel().endswith("(mrad)")
    ticks = [float(t.get_text().replace("\u2212", "-")) for t in yaw[0].get_xticklabels() if t.get_text()]
    assert max(abs(v) for v in ticks) >= 5  # mrad, not rad
    assert not any("-0.0," in ax.get_title() for ax in fig.axes)


def test_rolling_band_is_the_running_median_and_quantiles():
    from cobot_analysis.reports.localisation import rolling_band

    t = np.arange(200) / 10.0  # 20 s at 10 Hz
    e = np.where(t < 10, 1.0, 3.0) + np.tile([-0.5, 0.5], 100)
    b = rolling_band(t, e, window=2.0, band=(0.1, 0.9))
    far = ((np.abs(b["t"] - 10) > 1.5) & b["t"].between(1.5, 18.5)).to_numpy()  # whole windows, off the step
    assert np.allclose(b["median"][far], np.where(b["t"][far] < 10, 1.0, 3.0))
    assert np.allclose(b["low"][far], np.where(b["t"][far] < 10, 0.5, 2.5))
    assert np.allclose(b["high"][far], np.where(b["t"][far] < 10, 1.5, 3.5))
    # time based: a gap in the stamps does not widen the window to the samples beyond it
    t2 = np.r_[np.arange(50) / 10.0, 100 + np.arange(50) / 10.0]
    b2 = rolling_band(t2, np.r_[np.zeros(50), np.ones(50)], window=2.0)
    assert b2["median"].iloc[49] == 0.0 and b2["median"].iloc[50] == 1.0


def test_error_time_is_a_running_median_and_band_over_light_points():
    """The raw errors of every pose drawn as light points (a line joining white noise is a solid band),
    the running median a steady line: its spread is a fraction of the raw error's."""
    from cobot_analysis.reports import localisation as report

    runs = _noisy_runs()
    fig = report.figure_error_time(runs)
    reviewable(fig)
    assert len(data_axes(fig)) == 2 * len(runs)
    for ax in fig.axes:
        raw = next(line for line in ax.lines if line.get_label() == "error of each ICP pose")
        assert raw.get_linestyle() == "None" and raw.get_marker() == "."
        med = next(line for line in ax.lines if line.get_label().startswith("running median"))
        assert np.std(med.get_ydata()) < 0.3 * np.std(raw.get_ydata())
        assert any(type(c).__name__ in ("PolyCollection", "FillBetweenPolyCollection") for c in ax.collections)
    yaw = [ax for ax in fig.axes if ax.get_ylabel() == "yaw error (mrad)"]
    assert len(yaw) == len(runs) and "RMSE 4.1 mrad" in yaw[0].get_title()


def test_checker_finds_overlapping_tick_labels():
    fig, ax = plt.subplots(figsize=(3, 2))
    labels = [f"condition number {i}" for i in range(12)]
    ax.bar(range(12), np.arange(12.0))
    ax.set_xticks(range(12), labels)
    ax.set(xlabel="condition", ylabel="d_xy (m)")
    assert any("x tick labels 'condition number 0' and 'condition number 1' overlap" in p for p in check_figure(fig))
    ax.set_xticks(range(12), labels, rotation=90)
    assert check_figure(fig) == []


@pytest.mark.parametrize("layout", ["constrained", None])
def test_save_lays_out_once_and_writes_what_savefig_tight_writes(tmp_path, layout):
    """``plotting.save`` lays the figure out (until its axes stop moving: three passes here) and finds its tight box
    once: the PNG has the pixels of ``savefig(dpi=150, bbox_inches="tight")`` of the figure laid out so, the PDF's page
    is the PNG's size (72 / 150 pt per pixel), and the figure keeps that layout (equal-aspect panels and an outside
    legend: what a draw moves)."""
    import re

    from matplotlib.layout_engine import PlaceHolderLayoutEngine
    from PIL import Image

    from cobot_analysis.plotting import save

    def draw():
        fig, axes = plt.subplots(1, 2, figsize=(7, 3), layout=layout)
        t = np.linspace(0, 2 * np.pi, 400)
        for ax, k in zip(axes, (1, 3)):
            ax.plot(np.cos(t), np.sin(k * t), label=f"k = {k}")
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)"), ax.set_ylabel("y (m)")
        fig.legend(loc="outside upper center" if layout else "upper center", ncols=2)
        return fig

    save(fig := draw(), [tmp_path / "once.png", tmp_path / "once.pdf"])
    reference = draw()
    reference.set_dpi(150)
    for _ in range(3):  # savefig's own passes then find the layout settled, as save leaves it
        reference.draw_without_rendering()
    reference.savefig(tmp_path / "tight.png", dpi=150, bbox_inches="tight")
    once, tight = (np.asarray(Image.open(tmp_path / f"{n}.png")) for n in ("once", "tight"))
    assert once.shape == tight.shape and (once == tight).all()
    page = [float(v) for v in re.search(rb"/MediaBox \[ *([\d. ]+)\]", (tmp_path / "once.pdf").read_bytes()).group(1).split()]
    assert page[:2] == [0, 0] and np.allclose(np.array(page[2:]) * 150 / 72, [once.shape[1], once.shape[0]], atol=1)
    assert isinstance(fig.get_layout_engine(), (type(None), PlaceHolderLayoutEngine))  # the layout is fixed


def test_layout_passes_stop_when_the_axes_stop_moving(monkeypatch):
    """``settle_layout`` draws again only while a pass moves an axes edge by ``SETTLED_PX`` pixels or more: a panel
    with its title is settled after one pass (the second finds it moved by round-off only, 1e-13 px, where comparing
    the bounds exactly drew a third time); equal-aspect panels under an outside legend still move in the second pass:
    three passes; without a layout engine, one."""
    from matplotlib.figure import Figure

    from cobot_analysis import plotting

    passes = []
    draw = Figure.draw_without_rendering
    monkeypatch.setattr(Figure, "draw_without_rendering", lambda fig: (passes.append(fig), draw(fig)))

    def count(fig):
        passes.clear()
        plotting.settle_layout(fig)
        return len(passes)

    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.plot([0, 1], [0, 1])
    ax.set(title="one panel", xlabel="x (m)")
    assert count(fig) == 2
    fig, axes = plt.subplots(1, 2, figsize=(7, 3), layout="constrained")
    for ax in axes:
        ax.plot([-1, 1], [-1, 1])
        ax.set_aspect("equal")
    fig.legend(["a", "b"], loc="outside upper center", ncols=2)
    fig.set_dpi(150)
    assert count(fig) == 3
    fig, ax = plt.subplots(figsize=(4, 3))
    assert count(fig) == 1
    fig = plt.figure(figsize=(4, 3), layout="constrained")  # a layout engine and nothing to lay out: settled
    fig.suptitle("no axes")
    assert count(fig) == 2


def test_checker_finds_a_panel_title_on_the_ticks_of_the_panel_above():
    fig = plt.figure(figsize=(3, 4))
    top, bottom = fig.add_axes((0.2, 0.56, 0.7, 0.4)), fig.add_axes((0.2, 0.1, 0.7, 0.4))
    for ax, title in ((top, "above"), (bottom, "below")):
        ax.plot([0, 1], [0, 1])
        ax.set(title=title, xlabel="x (m)", ylabel="y (m)")
    assert any(p.startswith("axes 0 ('above') and axes 1 ('below'): texts") for p in check_figure(fig))


def test_saved_grid_of_tall_panels_has_no_title_on_the_panel_above(tmp_path):
    """The coupled fit's ``pair_paths`` (8 paths 4.5 m long in square panels, 2 rows): laid out once, each title of the
    second row sat on the x tick labels of the panel above it; ``plotting.save`` lays out until the axes stop moving."""
    from cobot_analysis.plotting import save
    from cobot_analysis.reports.models import figure_pair_paths

    s = np.linspace(0.0, 1.0, 100)
    targets, paths = [], {"published": [], "fitted": []}
    for j in range(8):
        x0, y0 = -0.9 - 0.4 * (j % 4), -4.5 + 0.3 * (j // 4)
        carriers = [SimpleNamespace(x=a + (b - a) * s + 0.3 * np.sin(np.pi * s), y=y0 + (0.9 - y0) * s, theta=np.full(100, 1.2))
                    for a, b in ((x0, 0.0), (x0 + 0.9, 0.9))]
        targets.append(SimpleNamespace(carriers=carriers, trial=f"d{j}_p7_gris_forward_end+180_sc3"))
        for lab in paths:
            paths[lab].append([{"x": c.x + 0.1, "y": c.y, "theta": c.theta} for c in carriers])
    fig = figure_pair_paths(targets, paths, "scenario-3 means vs coupled OC")
    save(fig, [tmp_path / "pair_paths.png"])
    assert check_figure(fig) == []


def test_long_condition_names_of_a_study_of_ones_own_do_not_run_into_the_next_panel():
    """A lab's condition 'lab hall start 03 towards the goal, normal pace' as a panel title: wrapped to the panel,
    not written over the titles of its neighbours."""
    t = np.linspace(0, 1, 20)
    panels = [{"title": f"lab hall start {i:02d} towards the goal, normal pace", "lines": [(t * 4 - 4, t, "walker")]}
              for i in range(12)]
    fig = figures.paths(panels, ncols=6)
    assert check_figure(fig) == []
    assert fig.axes[0].get_title() == "lab hall start 00 towards the\ngoal, normal pace"


def test_the_scatter_gives_r_and_n_not_a_p_of_its_own():
    """The p of a correlation is the statistics table's (Holm-corrected, with its note on repeated measures): the
    figure's legend gave a p of its own, uncorrected (0.00065 where the table said 0.0013)."""
    x = np.arange(10.0)
    fig = figures.scatter_r({"walker": (x, x + np.sin(x))}, "global distance (m)", "d_xy (m)")
    r = np.corrcoef(x, x + np.sin(x))[0, 1]
    assert legend_texts(fig) == [f"walker: r = {r:.2f} (n = 10)"]
