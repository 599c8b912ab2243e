"""Generated paths reach their goal at rest at a stated pace (docs/methods.md sec. 5.5, 11), a path
that misses is flagged, and fit-ioc's model comparison is the same answer as generate + compare."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.design import WALKING_CONDITIONS, WALKING_GOAL, walking_condition
from cobot_analysis.errors import InputError
from cobot_analysis.models import GOAL_TOLERANCE, generate, goal_check, refuse_unreached, resample, solve_model
from cobot_analysis.models.presets import PRESETS, weights_vector

#: walking starts: every start orientation, near and far, facing the goal and facing away from it
STARTS = [walking_condition(c).start for c in ("N1500", "S1500", "O-0615", "E4015", "S4040", "O0640", "N-0640", "E1540")]


# unicycle and mombaur are long solves (their 8 starts: about 7 s and 9 s of CPU, 2026-11-24 and 11-25), so they run with -m slow
@pytest.mark.parametrize("model", ["improved", pytest.param("unicycle", marks=pytest.mark.slow),
                                   pytest.param("mombaur", marks=pytest.mark.slow), "table"])
def test_continuous_paths_start_and_end_at_rest_on_their_poses(model):
    for start in STARTS:
        df = generate(model, start, WALKING_GOAL, convention="continuous")
        first, last = df.iloc[0], df.iloc[-1]
        assert (first.x, first.y, first.theta) == pytest.approx(start, abs=1e-9)
        assert (first.v_forw, first.v_orth, first.omega) == pytest.approx((0, 0, 0), abs=1e-9)
        assert math.hypot(last.x - WALKING_GOAL[0], last.y - WALKING_GOAL[1]) < GOAL_TOLERANCE[0]
        assert abs(last.theta - WALKING_GOAL[2]) < GOAL_TOLERANCE[1]
        assert (last.v_forw, last.v_orth, last.omega) == pytest.approx((0, 0, 0), abs=1e-6)
        assert bool(last.goal_reached) and bool(last.converged) and last.status == "ok"
        assert last.end_position_error < 1e-6 and last.end_heading_error < 1e-6  # a constraint, not a cost


def test_published_convention_keeps_the_terminal_cost():
    """The published convention reproduces the papers: the goal stays a weighted terminal cost."""
    df = generate("improved", (-1.5, -3.4, 0.0), WALKING_GOAL, weights="walking-2021", convention="published")
    last = df.iloc[-1]
    assert 1e-5 < last.end_position_error < 0.01  # near the goal, not on it
    assert last.mean_speed < 0.1  # the authors' duration rule: 20 s per metre


def test_published_weights_walk_at_a_human_pace_under_the_continuous_convention():
    """Mean speed (path length / T) between 0.5 and 2 m/s on the starts farther than 2 m; the
    shortest walks (under 1 m, with a turn of up to pi) are slower, above 0.3 m/s."""
    for c in WALKING_CONDITIONS[::3]:
        start = walking_condition(c).start
        last = generate("improved", start, WALKING_GOAL, weights="walking-2021", convention="continuous").iloc[-1]
        d = math.hypot(start[0], start[1])
        assert (0.5 if d > 2 else 0.3) < last.mean_speed < 2.0, (c, last.mean_speed)


def test_a_path_that_misses_its_goal_is_flagged_never_converged():
    df = generate("improved", (-4.0, 1.2, math.pi), WALKING_GOAL, weights="walking-2021", convention="continuous",
                  max_iter=2, on_failure="flag")
    last = df.iloc[-1]
    assert not last.converged and "did not converge" in last.status
    with pytest.raises(InputError, match="does not reach --goal"):
        refuse_unreached(df)
    # the check itself: 2 cm or 0.06 rad from the goal is a miss; the heading compared modulo 2 pi
    assert not goal_check([0.0, 0.02], [0.0, 0.0], [0.0, 2 * math.pi], (0.0, 0.0, 0.0))["goal_reached"]
    assert not goal_check([0.0, 0.0], [0.0, 0.0], [0.0, 0.06], (0.0, 0.0, 0.0))["goal_reached"]
    assert goal_check([0.0, 0.009], [0.0, 0.0], [0.0, 2 * math.pi + 0.04], (0.0, 0.0, 0.0))["goal_reached"]


def test_goal_outside_the_lab_is_refused():
    with pytest.raises(InputError, match="--goal .* outside the lab"):
        generate("improved", (0.0, 0.0, 0.0), (4000.0, 0.0, 0.0))
    from cobot_analysis.models.prediction.goal import check_goal

    with pytest.raises(InputError, match="outside the lab"):  # the goal predictor refuses the same goal
        check_goal((4000.0, 0.0, 0.0), "--goal")


@pytest.mark.parametrize("args, message", [
    # 40 m: inside the raw files' plausibility bound (100 m), outside the studies' frames: refused before any solve
    (["--start", "-1", "-1", "0", "--goal", "40", "0", "0"], "--goal (40, 0) lies outside the lab (|x|, |y| <= 10 m)"),
    # an iteration budget the solver cannot reach the goal in: the path is refused, never written as a result
    (["--start", "-4", "1.2", "3.14", "--convention", "continuous", "--max-iter", "2"], "does not reach --goal"),
])
def test_generate_refuses_a_goal_out_of_reach_in_one_line_without_output(cli, tmp_path, args, message):
    out = tmp_path / "ws"
    code, _, err = cli("-q", "generate", "--out", out, "-j", "1", *args)  # -q: no progress lines, the error alone
    assert code == 2 and message in err, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: ")
    assert not (out / "generate").exists() and not (out / "generate-published").exists()


def test_acceleration_weights_scaled_by_c4_time_scale_the_path():
    """Why the IOC holds a1 under the goal constraint: weights (a0, c^4 a1..a3, a4) give the same
    time-normalised path, c times slower (time and path terms grow as c, accelerations as c^-3)."""
    w = weights_vector(PRESETS["walking-2021"])
    c = 1.5
    w2 = w.copy()
    w2[1:4] *= c**4
    start = (-4.0, -1.4, 0.0)
    a = solve_model("improved", start, WALKING_GOAL, w).check()
    b = solve_model("improved", start, WALKING_GOAL, w2, guess=a.primal).check()
    assert b.T == pytest.approx(c * a.T, rel=1e-5)
    ra, rb = resample(a, 200), resample(b, 200)
    assert np.abs(ra["x"] - rb["x"]).max() < 1e-5 and np.abs(ra["theta"] - rb["theta"]).max() < 1e-5


def _means(conditions) -> pd.DataFrame:
    """Mean-like walking trajectories: a clothoid from near the design start to the goal, 500 samples."""
    rows = []
    for c in conditions:
        x0, y0, th0 = walking_condition(c).start
        df = generate("clothoid", (x0 + 0.05, y0 - 0.04, th0 + 0.1), WALKING_GOAL, n_samples=500)
        # a mean's recorded gamma (the mean of its trials' gammas) is not the gamma of the mean path
        rows.append(df.assign(study="walking-2020", trial=f"mean:{c}", kind="mean", condition=c, entity="walker",
                              n_trials=10, subject="", travel_time=np.nan, gamma=df["gamma"] + 0.2))
    return pd.concat(rows, ignore_index=True)


def test_fit_ioc_comparison_equals_generate_then_compare(tmp_path):
    """compare_models (inside fit-ioc) and generate --study + compare --against give the same d_xy,
    d_theta, d_gamma: same starts (study_cases), grid, goal and distances (a measured gamma from the
    path under the continuous convention, both ways)."""
    from cobot_analysis import conventions
    from cobot_analysis.compare import against_set, against_vs_mean, pivot
    from cobot_analysis.models.ioc import targets_from_table
    from cobot_analysis.models.outputs import GENERATED
    from cobot_analysis.models.comparison import compare_models, study_cases
    from cobot_analysis.schema import write_table

    conv = conventions.CONTINUOUS
    means = _means(["N1500", "O-0615", "E4015", "S4040"])
    targets = targets_from_table(means, goal=WALKING_GOAL, unoriented=True)
    inside = compare_models(targets, {"improved OC": ("improved", "walking-2021")}, jobs=1, convention=conv.name)
    frames = [generate("improved", s, g, weights="walking-2021", convention=conv, trial=f"improved_{c}", condition=c,
                       study="walking-2020") for c, s, g, *_ in study_cases(means, conv, WALKING_GOAL)]
    write_table(pd.concat(frames, ignore_index=True), tmp_path / "generated.parquet", GENERATED, convention=conv.name)
    mts = pivot(means).compared_as(conv.comparison)
    other = against_set(tmp_path / "generated.parquet", mts.n_samples, conv)
    outside = against_vs_mean(other, mts, ["study", "condition", "entity"], "model")
    a = inside.set_index("condition").sort_index()
    b = outside.set_index("condition").sort_index()
    for k in ("d_xy", "d_theta", "d_gamma"):
        assert np.allclose(a[k].to_numpy(float), b[k].to_numpy(float), rtol=1e-9, atol=1e-12), k


# ---- the time law fitted to the subjects' durations (models.ioc.pace, docs/methods.md sec. 6.4) -------------
def test_time_gauge_is_the_least_squares_scale():
    from cobot_analysis.models.ioc.pace import scale_time, time_gauge

    T = np.array([2.0, 3.0, 5.0, np.nan])
    assert time_gauge(T, 1.3 * T) == pytest.approx(1.3)
    M = np.array([2.4, 4.0, 6.0, 7.0])  # the nan pair is left out: c = sum T M / sum T^2
    assert time_gauge(T, M) == pytest.approx((2 * 2.4 + 3 * 4 + 5 * 6) / (4 + 9 + 25))
    assert np.isnan(time_gauge([np.nan], [1.0]))
    w = scale_time({"a0": 7.0, "a1": 1.0, "a2": 2.0, "a3": 3.0, "a4": 5.0}, 2.0)
    assert w == {"a0": 7.0, "a1": 16.0, "a2": 32.0, "a3": 48.0, "a4": 5.0}


def test_calibration_recovers_a_planted_time_scale():
    """Durations planted at 1.3 x the model's: c = 1.3, the re-solved paths take the planted durations, D unchanged."""
    from cobot_analysis.models.ioc import IOCSpec, targets_from_table
    from cobot_analysis.models.ioc.fit import solve_target
    from cobot_analysis.models.ioc.pace import calibrate
    from cobot_analysis.models.presets import WALKER_WEIGHTS

    targets = targets_from_table(_means(["N1500", "E4015", "S0640"]), goal=WALKING_GOAL)
    w = PRESETS["walking-2021"]
    spec = IOCSpec(model="improved", start_weights=tuple(weights_vector(w)), n_intervals=20)

    def solve(weights):
        return [solve_target(spec, weights_vector(weights), t, ("rest", "line"))[0] for t in targets]

    before = solve(w)
    planted = 1.3 * np.array([d["T"] for d in before])
    cal = calibrate(solve, w, before, planted)
    assert cal.c == pytest.approx(1.3, rel=1e-9)
    assert set(cal.weights) == set(WALKER_WEIGHTS) and cal.weights["a1"] == pytest.approx(w["a1"] * 1.3 ** 4)
    assert cal.weights["a0"] == w["a0"] and cal.weights["a4"] == w["a4"]
    assert np.allclose(cal.calibrated_T, planted, rtol=1e-4)
    assert cal.D_after == pytest.approx(cal.D_before, abs=1e-5)
    assert cal.at_bound == 0 and not cal.notes


def test_fitted_continuous_paths_walk_at_the_subjects_pace():
    """fit-ioc (continuous) on synthetic walks of known travel times: the weights it writes generate
    paths whose durations are the subjects' (one time scale for all: within 15 %) and speeds human."""
    from cobot_analysis.api import average, fit_ioc
    from cobot_analysis.models.ioc.pace import subject_durations
    from cobot_analysis.synth.tables import walking_table

    trials = walking_table(n_subjects=3, n_conditions=3, n_trials=2, missing_theta=0.0)
    fit = fit_ioc(average(trials).means, trials=trials, intervals=20, max_evaluations=3, compare=False, jobs=1)
    r = fit.results["all"]
    assert r.pace is not None and r.pace["n_measured"] == len(fit.mean_targets) and r.pace["at_bound"] == 0
    subjects = subject_durations(trials).groupby("condition")["duration"].mean()
    for t in fit.mean_targets:
        g = generate("improved", t.start, t.goal, weights=r.weights, convention="continuous").iloc[-1]
        assert g.goal_reached and g.status == "ok"
        assert g.travel_time == pytest.approx(subjects[t.condition], rel=0.15), t.condition
        assert 0.5 < g.mean_speed < 2.0
    from cobot_analysis.reports.models import pace_lines

    text = "\n".join(pace_lines(fit.mean_keys, fit.mean_targets, r.per_target, None, r.pace))
    n = len(fit.mean_targets)  # the subjects' durations on the model's paths: named as such, not as the subjects' speed
    assert f"0 of {n} model paths outside 0.5-2 m/s, in the subjects' durations 0 of {n}." in text
    assert "for the same paths walked in the subjects' durations" in text


def test_a_duration_on_its_bound_is_flagged():
    """Weights that price time at almost nothing ask for a duration beyond the search's upper bound: the
    path says so (status), and so does generate's summary."""
    from cobot_analysis.reports.models import generated_section

    w = dict(PRESETS["walking-2021"], a0=1e-9, a4=1e-9)
    df = generate("improved", (-4.0, -1.4, 0.0), WALKING_GOAL, weights=w, convention="continuous")
    last = df.iloc[-1]
    assert last.goal_reached and last.status.startswith("duration on a bound")
    text = "\n".join(generated_section(df, "continuous"))
    assert "1 durations on a bound" in text


def test_the_time_law_is_judged_against_the_subjects_own_pace():
    """The generate summary counts the subjects' means outside 0.5-2 m/s as it counts the model's, and gives
    the model's durations over the subjects': two paths, the subjects twice and half as slow as the model."""
    from cobot_analysis.reports.models import generated_section

    a = generate("improved", (-1.5, -3.4, 0.0), WALKING_GOAL, weights="walking-2021", convention="continuous").assign(trial="a")
    b = generate("improved", (-4.0, -1.4, 0.0), WALKING_GOAL, weights="walking-2021", convention="continuous").assign(trial="b")
    ta, tb = a["travel_time"].iloc[-1], b["travel_time"].iloc[-1]
    text = "\n".join(generated_section(pd.concat([a, b]), "continuous", {"a": (2 * ta, 0.3), "b": (0.5 * tb, 0.9)}))
    assert "1 of 2 outside 0.5-2 m/s; model T / subjects' T 0.50-2.00, median 1.25" in text


def test_fit_ioc_comparison_counts_a_path_that_misses_its_goal_as_not_converged(monkeypatch):
    """The model comparison of fit-ioc takes generate's verdict: a path generate flags (converged false: under
    the continuous convention, its goal missed) is a not-converged row, left out of the means, never a result."""
    import cobot_analysis.models as models
    from cobot_analysis.models.comparison import compare_task
    from cobot_analysis.models.ioc import targets_from_table

    target = targets_from_table(_means(["N1500"]), goal=WALKING_GOAL, unoriented=True)[0]
    real = models.generate

    def missing(*args, **kwargs):
        df = real(*args, **kwargs)
        return df.assign(converged=False, goal_reached=False, status="ends 0.2 m from its goal")

    spec = {"improved OC": ("improved", "walking-2021")}
    rows, kept = compare_task((target, spec, 20, 0.5, "gamma", "continuous", ("improved OC",)))
    assert rows[0]["converged"]
    # the path it kept (fit-ioc's figure draws it) is generate's, not solved again
    pd.testing.assert_frame_equal(kept["improved OC"], real("improved", target.start, target.goal, weights="walking-2021",
                                                           n_samples=len(target.x), n_intervals=20, convention="continuous"))
    monkeypatch.setattr(models, "generate", missing)
    row = compare_task((target, spec, 20, 0.5, "gamma", "continuous", ()))[0][0]
    assert row["converged"] is False and np.isfinite(row["d_xy"])


def test_generate_names_the_paths_whose_heading_no_walker_would_turn():
    """A start heading given a whole turn away from the goal's branch: the model walks that turn (a physical
    implausibility the solver calls converged), and generate's summary names the path; a path that turns the short
    way and one that spins (a turn and back) are told apart (``models.heading_turns``, ``reports.models.heading_line``)."""
    from cobot_analysis.models import heading_turns
    from cobot_analysis.reports.models import generated_section, heading_line

    h = heading_turns([0.0, 3.0, 6.0, 7.0, 6.5])
    assert (h["net"], h["excess"]) == (6.5, pytest.approx(1.0)) and h["shortest"] == pytest.approx(6.5 - 2 * math.pi)
    start = walking_condition("N4000").start  # facing the goal, 3.4 m straight ahead
    short = generate("improved", start, WALKING_GOAL, convention="continuous").assign(trial="short")
    long = generate("improved", (*start[:2], start[2] - 2 * math.pi), WALKING_GOAL, convention="continuous").assign(trial="long")
    assert bool(long.goal_reached.iloc[-1]) and heading_turns(long.theta)["net"] == pytest.approx(2 * math.pi, abs=0.05)
    assert abs(heading_turns(short.theta)["net"]) < 0.05
    assert "Heading: every path turns from its start to its goal heading within half a turn" in heading_line(short)
    text = "\n".join(generated_section(pd.concat([short, long]), "continuous"))
    assert "**Heading: no walker's turn**" in text and "1 of 2 paths turn from their start to their goal heading more " \
        "than half a turn beyond the shortest turn (long)" in text and "spin" not in text.split("no walker's turn")[1]
    spin = pd.DataFrame({"trial": "spin", "theta": np.r_[np.linspace(0.0, 7.0, 11), np.linspace(7.0, 0.5, 10)], "omega": 0.0})
    line = heading_line(pd.concat([short[["trial", "theta", "omega"]], spin]))
    assert "1 of 2 paths spin" in line and "(sum |d theta| - |theta_N - theta_0| > 2 pi; spin)" in line
    assert "turn from their start" not in line


def test_a_weight_the_time_gauge_moves_off_the_search_box_is_named():
    """The time gauge writes a1..a3 x c^4 (docs/methods.md sec. 6.4): a weight fitted on a search limit is written
    beyond it (walking-2020's single-level fit: a3 = 1e-7 x 0.991^4 = 9.64e-8 under 'bounds 1e-7..1e3'), and the
    report says why instead of leaving a weight outside its box unexplained."""
    from cobot_analysis.reports.models import gauge_limit_lines

    c = 0.991
    w = {"a2": 6.92, "a3": 1e-7 * c ** 4, "a4": 3.25}
    text = "\n".join(gauge_limit_lines(w, ("a2", "a3", "a4"), {"c": c}))
    assert "a1-a3 x c^4 = 0.9645: a3 = 9.64e-08 lies beyond the search limits 1e-7..1e3, fitted on a limit" in text
    assert gauge_limit_lines(dict(w, a3=1.1e-7), ("a2", "a3", "a4"), {"c": c}) == []
    assert gauge_limit_lines(w, ("a2", "a3", "a4"), None) == []


def test_continuous_walks_have_one_smooth_speed_bell():
    """No speed spike on a converged walk (the pace itself: the test above): with the published walking weights, from
    every start orientation near and far, the speed is one smooth bell, peak / mean 1.5 (the minimum-acceleration
    profile), no step between samples above 2 % of the peak."""
    for start in STARTS:
        df = generate("improved", start, WALKING_GOAL, weights="walking-2021", convention="continuous")
        speed = np.hypot(df["vx"], df["vy"]).to_numpy()
        assert speed.max() / df["mean_speed"].iloc[0] == pytest.approx(1.5, abs=0.1), start
        assert np.abs(np.diff(speed)).max() < 0.02 * speed.max(), start


# the continuous walking fit-ioc weights of the make workspace (walking-2020): a3 on its lower search limit
SPIN_WEIGHTS = {"a0": 7.87, "a1": 12.948, "a2": 7.821, "a3": 1.12e-07, "a4": 2.3418, "a5": 0.0, "a6": 0.0,
                "b0": 10.0, "b1": 10.0, "b2": 0.38, "b3": 3.36}
SPIN_START = (-3.876, -3.206, -2.9946)  # the O4040 mean's first pose


def test_a_converged_path_that_spins_says_so_and_is_not_exported_as_commands(tmp_path):
    """A converged path at its goal can still spin: at the walking fit's weights (a3 = 1.1e-7, the turning rate's
    changes almost free) the O4040 start's path turns 9.6 rad beyond its net turn, |omega| up to 63 rad/s at 50
    intervals (191 rad/s at 100). Before, its status said 'ok' and velocity-commands exported it (98 % saturated,
    exit 0). Now its status says it spins, the summary counts it, and velocity-commands refuses it with the remedy,
    which works: a3 = 0.1 gives a path that does not spin, exported."""
    from cobot_analysis.api import velocity_commands
    from cobot_analysis.api.models import GenerateResult
    from cobot_analysis.errors import InputError
    from cobot_analysis.models import heading_turns, spins

    spun = generate("improved", SPIN_START, WALKING_GOAL, weights=SPIN_WEIGHTS, convention="continuous", n_intervals=50)
    last = spun.iloc[-1]
    assert bool(last.converged) and bool(last.goal_reached)
    assert heading_turns(spun.theta)["excess"] == pytest.approx(9.58, abs=0.05) and spins(spun.theta)
    assert last.status.startswith("spins: its heading turns 9.6 rad beyond its net turn, its turning rate up to 63")
    summary = GenerateResult(generated=spun, models=["improved"], weights=SPIN_WEIGHTS, cases=[("", SPIN_START, WALKING_GOAL)],
                             convention="continuous", n_samples=500, n_intervals=50).summary()
    assert summary.startswith("1 trajectory, all at their goal, 1 that spin (no walker's path) (status in .generated)")
    with pytest.raises(InputError, match=r"trajectory 'improved' spins: .* a copy of the weights file with a3 = 0\.1"):
        velocity_commands(spun)
    calm = generate("improved", SPIN_START, WALKING_GOAL, weights=dict(SPIN_WEIGHTS, a3=0.1), convention="continuous",
                    n_intervals=50)
    assert calm.status.iloc[-1] == "ok" and not spins(calm.theta)
    assert len(velocity_commands(calm).commands) > 10


def test_velocity_commands_refuse_a_path_whose_solver_did_not_converge():
    """``generate --study`` keeps a path whose solver stopped (status, converged false) so the others go on; before,
    velocity-commands exported such a path's last iterate, exit 0. Now refused, naming its status."""
    from cobot_analysis.api import velocity_commands
    from cobot_analysis.errors import InputError

    stopped = generate("improved", SPIN_START, WALKING_GOAL, weights="walking-2021", convention="continuous",
                       max_iter=2, on_failure="flag")
    assert not bool(stopped.converged.iloc[-1]) and stopped.status.iloc[-1].startswith("solver did not converge")
    with pytest.raises(InputError, match=r"is no solution of its model: solver did not converge .*--max-iter"):
        velocity_commands(stopped)
