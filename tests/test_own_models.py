"""The model stages on a walking study of one's own (not the published walking-2020 files): its frame, labels,
time base and orientation as a lab records them. Each case is a path the model itself walks, so the right
answer is known."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.models.presets import load_weights, names_for, weights_vector

W = dict(zip(names_for("improved"), map(float, weights_vector(load_weights("walking-2021", "improved"), "improved"))))
CONDITIONS = ("E4015", "O1515", "N-0615")
SHIFT = (3.0, 2.0)  # the lab's goal: the walking-2020 frame moved by this


def own_means(shift=SHIFT, labels=None, heading=None) -> pd.DataFrame:
    """The improved model's own paths at ``W`` from the walking-2020 design starts to its goal (its heading pi/2, or
    ``heading``), moved by ``shift``, as the means of a study (condition codes, or ``labels``)."""
    from cobot_analysis.design import WALKING_GOAL, walking_condition
    from cobot_analysis.models import generate
    from cobot_analysis.schema import TRAJECTORIES

    frames = []
    for i, c in enumerate(CONDITIONS):
        start = np.add(walking_condition(c).start, (*shift, 0.0))
        goal = np.add((*WALKING_GOAL[:2], WALKING_GOAL[2] if heading is None else heading), (*shift, 0.0))
        df = generate("improved", tuple(start), tuple(goal), weights=W, n_samples=100, n_intervals=20, convention="continuous")
        label = labels[i] if labels else c
        frames.append(df[list(TRAJECTORIES.columns.keys() & set(df.columns))].assign(
            study="own-walking", trial=f"mean_{label}", condition=label, kind="mean", n_trials=2, subject=None))
    return pd.concat(frames, ignore_index=True)


@pytest.fixture(scope="module")
def shifted() -> pd.DataFrame:
    return own_means()


def test_fit_ioc_auto_goal_is_the_measured_goal_in_a_frame_of_ones_own(shifted):
    """Design condition codes, the goal at (3, 2): the model's own paths are fitted at D ~ 0 (the design goal
    (0, 0) put every OC problem 3.6 m off and gave D = 1.98 without a word)."""
    from cobot_analysis.api import fit_ioc

    fit = fit_ioc(shifted, fit=["a2", "a4"], max_evaluations=1, intervals=20, compare=False, jobs=1)
    assert fit.results["all"].start_objective < 0.05
    assert all(np.hypot(t.goal[0] - SHIFT[0], t.goal[1] - SHIFT[1]) < 1e-6 for t in fit.mean_targets)


def test_fit_ioc_design_goal_refused_where_the_paths_end_elsewhere(shifted):
    from cobot_analysis.api import fit_ioc

    with pytest.raises(InputError, match=r"--goal design: the paths end at \(3\.00, 2\.00\).*--goal end"):
        fit_ioc(shifted, goal="design", max_evaluations=1, intervals=20, compare=False, jobs=1)


def test_generate_study_refuses_the_design_goal_on_means_that_end_elsewhere(shifted, tmp_path, cli):
    """``generate --study walking-2020`` on such means walked every path to (0, 0), 3.6 m from where the
    subjects went, "all at their goal"; refused in one line naming the goal that works, nothing written."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    means = write_table(shifted, tmp_path / "means.parquet", TRAJECTORIES)
    common = ("generate", "--out", str(tmp_path / "ws"), "--study", "walking-2020", "--means", str(means),
              "--convention", "continuous", "--intervals", "20", "--samples", "50", "--jobs", "1")
    code, _, err = cli(*common)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert str(means) in err and "--goal 3.00 2.00" in err
    assert not (tmp_path / "ws" / "generate").exists()
    code, _, err = cli(*common, "--goal", "3", "2", "1.5708")
    assert code == 0, err
    gen = pd.read_parquet(tmp_path / "ws" / "generate" / "generated.parquet")
    ends = gen.sort_values("sample").groupby("trial").last()
    assert np.allclose(ends[["x", "y"]].to_numpy(), SHIFT, atol=0.01)


def test_own_condition_labels_fit_to_their_measured_ends():
    """Labels that are no walking-2020 code ("c1", "left-turn"): each path's last measured pose is its goal."""
    from cobot_analysis.api import fit_ioc

    fit = fit_ioc(own_means(shift=(0.0, 0.0), labels=["c1", "left-turn", "c3"]), fit=["a2", "a4"], max_evaluations=1,
                  intervals=20, compare=False, jobs=1)
    assert fit.results["all"].start_objective < 0.05


@pytest.mark.parametrize("predictor, remedy", [("goal", "--goal x,y"), ("goal-inferred", "--candidates x,y")])
def test_predict_refuses_the_walking_goal_for_a_walking_study_in_a_frame_of_its_own(shifted, tmp_path, cli, predictor, remedy):
    """A study named walking-... whose paths end at (3, 2): the goal-aware predictors planned every window to the
    walking-2020 goal (0, 0) (goal-inferred: its only candidate) without a word; refused, naming the option."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    table = write_table(shifted.assign(study="walking-lab"), tmp_path / "trajectories.parquet", TRAJECTORIES)
    code, _, err = cli("predict", "--out", str(tmp_path / "ws"), "--trajectories", str(table), "--predictors", predictor,
                       "--kind", "mean", "--settings", "10:20", "--limit", "1", "--jobs", "1", "--convention", "continuous")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "walking-lab/mean_E4015" in err and remedy in err
    assert not (tmp_path / "ws" / "predict").exists()


def test_trials_without_duration_or_velocity_have_no_subject_duration_quietly():
    """No travel time and no velocity rows (a lab's export without them): no duration, and no RuntimeWarning
    ("Mean of empty slice") on the terminal beside fit-ioc's lines."""
    import warnings

    from cobot_analysis.models.ioc.pace import subject_durations

    trials = own_means(shift=(0.0, 0.0)).assign(travel_time=np.nan, vx=np.nan, vy=np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert subject_durations(trials).empty
    assert len(subject_durations(trials.assign(vx=0.5, vy=0.0))) == len(CONDITIONS)


@pytest.mark.parametrize("per", ["all", "subject"])
def test_fit_ioc_on_paths_without_orientation_names_it_with_a_remedy_that_works(per):
    """theta missing on every path: refused, saying so and naming the markers (the remedy was 'pass the means of
    average' on the means of average, or 'check the input table')."""
    from cobot_analysis.api import fit_ioc

    means = own_means(shift=(0.0, 0.0)).assign(theta=np.nan, gamma=np.nan)
    trials = means.assign(kind="trial", subject="S01")
    with pytest.raises(InputError, match=r"theta missing on every one.*--orientation-markers asis"):
        fit_ioc(means, trials=trials, per=per, max_evaluations=1, intervals=20, compare=False, jobs=1)


def test_prediction_at_k_shows_windows_of_a_recording_shorter_than_the_horizon(tmp_path):
    """A horizon longer than what follows N0 in the recording (60 samples, N0 = 20, N_OC = 140: a study with fewer
    samples than the settings assumed): each panel shows a window k >= N0 - 1, its past N0 measured samples (the
    panels' k went down to -20, the past empty and the predictions of windows counted from the end; an index error
    on 60 samples at 50:200)."""
    from test_predict_cli import trajectories_table

    from cobot_analysis.models.prediction.sweep import SweepConfig, WorkDir, run_sweep, trajectories_from_table
    from cobot_analysis.reports.prediction import figures

    config = SweepConfig(settings=((20, 140),), predictors=("cv",))
    trajs = trajectories_from_table(trajectories_table(n_traj=1), config)
    metrics, _, _ = run_sweep(trajs, config, WorkDir(tmp_path), jobs=1)
    figs = figures(metrics, trajs[0], config)
    try:
        panels = [ax for ax in figs["prediction_at_k"].axes if ax.get_visible() and ax.get_title()]
        assert panels and all(int(ax.get_title().split()[2]) >= 19 for ax in panels)
        for ax in panels:
            past = next(line for line in ax.lines if line.get_label() == "measured past (N0 samples)")
            assert len(past.get_xdata()) == 20
    finally:
        import matplotlib.pyplot as plt

        for fig in figs.values():
            plt.close(fig)


def test_results_say_when_the_horizon_is_longer_than_the_recordings(tmp_path):
    """60 samples at (20, 140): no window has its whole horizon in the recording, so delta_xy compares the few
    samples that remain; results.md said nothing of it (ADE and FDE n/a alone). (8, 20) fits: no line."""
    from test_predict_cli import trajectories_table

    from cobot_analysis.models.prediction.sweep import SweepConfig, WorkDir, run_sweep, trajectories_from_table
    from cobot_analysis.reports.prediction import horizon_cut_lines

    config = SweepConfig(settings=((8, 20), (20, 140)), predictors=("cv",))
    metrics, _, _ = run_sweep(trajectories_from_table(trajectories_table(n_traj=2), config), config, WorkDir(tmp_path), jobs=1)
    lines = horizon_cut_lines(metrics.drop_duplicates(["study", "trial", "entity", "n0", "n_oc"]))
    assert lines[1:] == [
        "(N0, N_OC) = (20, 140): 0 of 82 windows have their whole horizon (120 samples) inside the recording, which holds "
        "40-40 samples after N0: delta_xy and delta_theta compare the samples that remain (fewer the later the window), "
        "ADE and FDE only the whole horizons. Shorten N_OC (--settings) to compare the horizon itself."]


def test_a_frame_beyond_the_lab_bound_is_refused_before_the_fit_naming_the_means(tmp_path, cli):
    """A lab whose origin lies 12 m away: fit-ioc ran the whole fit, then its model comparison stopped on
    '--start (11.9, -0.9) lies outside the lab; give --start ...', an option never given, nothing written. Now
    refused before any solve naming the means file and the mean, with remedies that work (the frame, --no-compare)."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    paths = own_means(shift=(0.0, 0.0))
    means = write_table(paths.assign(x=paths["x"] + 12.0), tmp_path / "means.parquet", TRAJECTORIES)
    common = ("fit-ioc", "--out", str(tmp_path / "ws"), "--means", str(means), "--fit", "a2,a4", "--max-evaluations", "1",
              "--intervals", "20", "--jobs", "1", "--bootstrap", "0")
    code, _, err = cli("-q", *common)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{means}: the start of mean_E4015 (" in err and "--no-compare" in err and "--start" not in err
    assert not (tmp_path / "ws" / "fit-ioc").exists()
    code, _, err = cli("-q", *common, "--no-compare")
    assert code == 0, err
    code, _, err = cli("-q", "generate", "--out", str(tmp_path / "ws"), "--study", "walking-2020", "--means", str(means),
                       "--goal", "12", "0", "1.5708", "--convention", "continuous", "--jobs", "1")
    assert code == 2 and f"{means}: the start of N-0615 (" in err and "--start" not in err, err  # design order


def test_generate_study_on_own_condition_labels_says_what_it_needs(tmp_path, cli):
    """Labels that are no walking-2020 code: the remedy was 'pass the walking-2020 means', which a study of its
    own does not have; now the labels found and what works for them."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    means = write_table(own_means(shift=(0.0, 0.0), labels=["c1", "left-turn", "c3"]), tmp_path / "means.parquet", TRAJECTORIES)
    code, _, err = cli("-q", "generate", "--out", str(tmp_path / "ws"), "--study", "walking-2020", "--means", str(means),
                       "--convention", "continuous")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "its conditions are c1, c3, left-turn" in err and "fit-ioc compares the models on every mean" in err


def test_fit_ioc_refuses_trials_of_another_study_than_the_means(tmp_path):
    """A workspace holding walking-2020's import-published beside one's own study: fit-ioc's default --trajectories
    (import-published's) went with the own means, the published subjects fitted (--per subject) and their durations
    taken for the time gauge without a word."""
    from cobot_analysis.api import fit_ioc
    from cobot_analysis.schema import TRAJECTORIES, write_table

    means = own_means(shift=(0.0, 0.0))
    published = write_table(means.assign(study="walking-2020", kind="trial", subject="S01"), tmp_path / "t.parquet", TRAJECTORIES)
    with pytest.raises(InputError, match=r"t\.parquet: the trajectories are of walking-2020, the means of own-walking; "
                                         r"pass the trials of own-walking with --trajectories"):
        fit_ioc(means, trials=published, per="subject", max_evaluations=1, intervals=20, compare=False, jobs=1)


def test_generate_study_takes_no_pace_from_another_studys_trials(tmp_path):
    """generate --study walking-2020 on one's own means (no travel time) in a workspace that also holds walking-2020's
    import: the published subjects' durations were reported as the subjects' pace of the own means."""
    from cobot_analysis.schema import TRAJECTORIES, write_table
    from cobot_analysis.stages.models import generate

    means = own_means(shift=(0.0, 0.0)).assign(travel_time=np.nan, vx=np.nan, vy=np.nan)
    (tmp_path / "ws" / "import-published").mkdir(parents=True)
    trials = means.assign(kind="trial", subject="S01", travel_time=10.0)
    write_table(trials.assign(study="walking-2020"), tmp_path / "ws" / "import-published" / "trajectories.parquet", TRAJECTORIES)
    path = write_table(means, tmp_path / "means.parquet", TRAJECTORIES)
    done = generate(tmp_path / "ws", study="walking-2020", means=path, convention="continuous", intervals=20, samples=50, jobs=1)
    assert done.result.measured == {}
    write_table(trials, tmp_path / "ws" / "import-published" / "trajectories.parquet", TRAJECTORIES)  # the same study's
    done = generate(tmp_path / "ws", study="walking-2020", means=path, convention="continuous", intervals=20, samples=50, jobs=1,
                    force=True)
    assert {c: T for c, (T, _) in done.result.measured.items()} == {c: 10.0 for c in CONDITIONS}


# ---- the goal arrow elsewhere (goal at the origin, the design's start grid, final heading not pi/2) ----------------
def facing(heading: float) -> pd.DataFrame:
    """The model's own paths from the design's starts to (0, 0) facing ``heading``: a lab whose goal arrow is not +y."""
    return own_means(shift=(0.0, 0.0), heading=heading)


@pytest.mark.parametrize("heading", [0.0, np.pi, -np.pi / 2])
def test_fit_ioc_auto_goal_is_the_measured_heading_where_the_goal_arrow_is_not_the_designs(heading):
    """The goal arrow along +x (0), -x (pi) or -y (-pi/2): the OC problems took the design heading pi/2, a quarter or
    half turn off the walkers' (D 0.031, 0.026, 0.097 at the model's own weights, 0.000 at pi/2); now each path's
    measured end, D ~ 0."""
    from cobot_analysis.angles import angle_diff
    from cobot_analysis.api import fit_ioc

    fit = fit_ioc(facing(heading), fit=["a2", "a4"], max_evaluations=1, intervals=20, compare=False, jobs=1)
    assert fit.results["all"].start_objective < 0.005
    assert all(abs(angle_diff(t.goal[2], heading)) < 1e-6 for t in fit.mean_targets)


def test_fit_ioc_design_goal_refused_where_the_goal_arrow_is_not_the_designs():
    from cobot_analysis.api import fit_ioc

    with pytest.raises(InputError, match=r"--goal design: the paths end facing 0\.00 rad .*--goal end"):
        fit_ioc(facing(0.0), goal="design", max_evaluations=1, intervals=20, compare=False, jobs=1)


def test_generate_study_refuses_the_design_heading_where_the_goal_arrow_is_not_the_designs(tmp_path, cli):
    """``generate --study walking-2020`` walked means ending facing 0 to the heading pi/2; refused in one line naming
    the goal that works, nothing written; that goal then gives paths ending facing 0."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    means = write_table(facing(0.0), tmp_path / "means.parquet", TRAJECTORIES)
    common = ("generate", "--out", str(tmp_path / "ws"), "--study", "walking-2020", "--means", str(means),
              "--convention", "continuous", "--intervals", "20", "--samples", "50", "--jobs", "1")
    code, _, err = cli(*common)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert str(means) in err and "facing 0.00 rad" in err and "--goal 0.00 0.00 0.00" in err
    assert not (tmp_path / "ws" / "generate").exists()
    code, _, err = cli(*common, "--goal", "0", "0", "0")
    assert code == 0, err
    gen = pd.read_parquet(tmp_path / "ws" / "generate" / "generated.parquet")
    assert np.allclose(gen.sort_values("sample").groupby("trial")["theta"].last(), 0.0, atol=0.01)


def test_predict_refuses_the_walking_goal_heading_where_the_goal_arrow_is_not_the_designs(tmp_path, cli):
    """A study named walking-... ending at (0, 0) facing 0: the goal predictor planned every window to the heading
    pi/2; refused, naming --goal; goal-inferred (positions only: its candidate (0, 0) is right) still runs."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    table = write_table(facing(0.0).assign(study="walking-lab"), tmp_path / "trajectories.parquet", TRAJECTORIES)
    common = ("predict", "--trajectories", str(table), "--kind", "mean", "--settings", "10:20", "--limit", "1",
              "--jobs", "1", "--convention", "continuous")
    code, _, err = cli(*common, "--out", str(tmp_path / "ws"), "--predictors", "goal")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "walking-lab/mean_E4015" in err and "facing over 1.1 rad off pi/2" in err and "--goal x,y" in err
    code, _, err = cli(*common, "--out", str(tmp_path / "ws2"), "--predictors", "goal-inferred")
    assert code == 0, err


def test_the_published_walking_study_keeps_its_design_goal(datasets):
    """walking-2020 in its own frame: its means and trials end 0.50-0.75 rad off pi/2 (circular median of the last
    headings; subject S07 alone 2.1), under the 1.1 rad of ``DESIGN_HEADING_TOLERANCE``: the design goal stays; its
    40 labels are its codes (their paths start at most 0.39 m from the codes' starts, median per condition)."""
    from cobot_analysis.angles import angle_diff
    from cobot_analysis.api.models import goal_rule
    from cobot_analysis.design import WALKING_CONDITIONS, WALKING_GOAL, table_codes
    from cobot_analysis.io.published import read_walking_2020
    from cobot_analysis.models.comparison import end_heading

    df, _ = read_walking_2020(datasets / "walking-2020")
    for kind, off in (("mean", 0.745), ("trial", 0.505)):
        part = df[df["kind"] == kind]
        assert abs(abs(angle_diff(end_heading(part), np.pi / 2)) - off) < 0.001
        assert goal_rule("design", part) == goal_rule("auto", part) == WALKING_GOAL
        assert sorted(table_codes(part)[0]) == sorted(WALKING_CONDITIONS)


# ---- own condition labels that read as design codes ("S1020": a lab's session 1, trial 020) -----------------------
#: the design's starts of CONDITIONS under labels whose codes name other starts: (-2.0, -0.4), (-4.0, -0.4), (-1.0, -1.4)
LOOKALIKE = ["S1020", "S1040", "N2010"]


def test_labels_that_read_as_codes_but_start_elsewhere_are_own_labels():
    """Paths from E4015, O1515, N-0615's starts labelled S1020, S1040, N2010: the targets took the letter (S, S, N) as
    their start orientation, and the published convention its start heading (-pi/2 where the walkers started facing
    0 and pi); now no orientation letter, the measured start heading. The design's own labels keep theirs."""
    from cobot_analysis.models.ioc import targets_from_table

    own = targets_from_table(own_means(shift=(0.0, 0.0), labels=LOOKALIKE), convention="published")
    assert all(abs(t.start[2] - t.theta[0]) < 1e-9 for t in own)
    assert [t.orientation for t in own] == ["", "", ""]
    design = targets_from_table(own_means(shift=(0.0, 0.0)), convention="published")
    assert [(t.condition, t.orientation, t.start[2]) for t in design] == [
        ("E4015", "E", 0.0), ("N-0615", "N", np.pi / 2), ("O1515", "O", np.pi)]


def test_statistics_and_predict_take_no_start_orientation_from_own_labels():
    """stats' start_orientation groups and predict's start_orientation were the letters of the own labels (S, S, N)."""
    from cobot_analysis.api import trajectory_set
    from cobot_analysis.api.prediction import prediction_config
    from cobot_analysis.models.prediction.sweep import trajectories_from_table
    from cobot_analysis.stats.sources import build_sources

    for labels, letters in ((LOOKALIKE, [None, None, None]), (None, ["E", "N", "O"])):
        table = own_means(shift=(0.0, 0.0), labels=labels)
        first = table.groupby("trial", sort=True).first().reset_index()
        dist = first[["study", "trial", "condition", "entity", "kind"]].assign(
            comparison="individual-mean", d_xy=0.1, global_distance=2.0, scenario=np.nan, b_scenario=np.nan)
        assert build_sources(trajectory_set(table), dist)["distances"]["start_orientation"].tolist() == letters
        trajs = trajectories_from_table(table, prediction_config(settings="10:20", predictors="cv"))
        assert [t.meta["start_orientation"] for t in trajs] == [x or "" for x in letters]


def test_generate_study_refuses_labels_that_read_as_codes_but_start_elsewhere(tmp_path, cli):
    """Own labels among the 40 design codes (N4040, S1500, E0615 on paths from other starts): generate --study walked
    them as walking-2020's conditions; refused in one line naming the label and how far its paths start from its
    code's start, nothing written."""
    from cobot_analysis.schema import TRAJECTORIES, write_table

    means = write_table(own_means(shift=(0.0, 0.0), labels=["N4040", "S1500", "E0615"]), tmp_path / "means.parquet", TRAJECTORIES)
    code, _, err = cli("generate", "--out", str(tmp_path / "ws"), "--study", "walking-2020", "--means", str(means),
                       "--convention", "continuous", "--intervals", "20", "--samples", "50", "--jobs", "1")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "its label N4040 reads as the walking-2020 code of a start at (-4, -3.4)" in err and "fit-ioc" in err
    assert not (tmp_path / "ws" / "generate").exists()


def test_a_code_whose_paths_have_no_measured_start_is_not_judged(recwarn):
    """``design_codes`` on a label whose paths are all NaN (a trajectories table other checks refuse): before, numpy's
    'All-NaN slice' RuntimeWarning reached the user's terminal beside the one refusal line (predict's bad input)."""
    import numpy as np

    from cobot_analysis.design import design_codes

    nan = np.full((2, 2), np.nan)
    codes, why = design_codes(["N1500", "N1500"], nan, nan)
    assert list(codes) == ["N1500"] and why == ""
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
