"""Synthetic studies: design counts, determinism, marker geometry against the truth, gaps, rest."""

from __future__ import annotations

import functools
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_analysis.angles import angle_diff
from cobot_analysis.design import PAIR_GOALS
from cobot_analysis.io.protocol import PELVIS_MARKERS, SUBJECT_MARKERS, load_protocol
from cobot_analysis.distances import d_xy
from cobot_analysis.schema import read_table
from cobot_analysis.synth import body as bd
from cobot_analysis.synth import pairs, paths, walking
from cobot_analysis.synth.truth import TRUTH, TRUTH_TRIALS

SMALL = ["N1500", "S4015", "O-0640"]  # 3 conditions: near / far, facing / away from the goal


def read_c3d(path):
    """(labels, xyz (frames, markers, 3) in m with NaN where occluded, rate, units, residuals), each file read
    once per session (the study fixtures write their files once; the arrays are read-only)."""
    labels, *rest = _read_c3d(str(path))
    return [list(labels), *rest]


@functools.lru_cache(maxsize=None)
def _read_c3d(path: str):
    import ezc3d

    c = ezc3d.c3d(path)
    pts = c["data"]["points"]
    labels = tuple(c["parameters"]["POINT"]["LABELS"]["value"])
    units = c["parameters"]["POINT"]["UNITS"]["value"][0]
    rate = c["parameters"]["POINT"]["RATE"]["value"][0]
    xyz, residuals = np.transpose(pts[:3], (2, 1, 0)) / 1000.0, c["data"]["meta_points"]["residuals"][0].T
    xyz.flags.writeable = residuals.flags.writeable = False
    return labels, xyz, rate, units, residuals


@pytest.fixture(scope="module")
def small_walking(tmp_path_factory):
    d = tmp_path_factory.mktemp("walk")
    protocol = walking.generate(d, seed=7, n_subjects=2, n_trials=1, conditions=SMALL)
    return protocol


# ---- walking: design and files ---------------------------------------------------------------
def test_walking_design_counts_and_protocol(small_walking):
    proto = load_protocol(small_walking)
    assert proto.study == "synthetic-walking" and proto.rate == 200.0
    assert len(proto.trials) == 2 * 3 * 1
    assert sorted(proto.trials.columns) == ["condition", "file", "repetition", "subject", "trial"]
    assert set(proto.trials["condition"]) == set(SMALL) and set(proto.trials["subject"]) == {"S01", "S02"}
    assert proto.trials.loc[proto.trials.trial == "S01_S4015_1", "file"].item() == "raw/S01_S4015_1.c3d"
    assert list(proto.subjects.columns) == ["id", "sex", "weight", "height"]
    assert proto.subjects["height"].between(1.5, 2.0).all() and proto.subjects["weight"].between(40, 110).all()
    truth = read_table(small_walking.parent / "truth.parquet", TRUTH)
    tt = read_table(small_walking.parent / "truth_trials.parquet", TRUTH_TRIALS)
    assert set(truth["trial"]) == set(proto.trials["trial"]) == set(tt["trial"])
    assert (truth["entity"] == "walker").all()
    assert truth.attrs["cobot_analysis"]["columns"]["x"]["unit"] == "m"


def test_c3d_header_units_rate_labels(small_walking):
    labels, xyz, rate, units, residuals = read_c3d(small_walking.parent / "raw" / "S02_O-0640_1.c3d")
    assert labels == list(SUBJECT_MARKERS) and rate == 200.0 and units == "mm"
    assert xyz.shape[1:] == (14, 3)
    gone = np.isnan(xyz).any(axis=-1)
    assert np.array_equal(gone, residuals < 0)  # Vicon convention: occluded = NaN + residual -1
    # pelvis at about 0.95 m, head near the subject's height: the file is really in mm
    pelvis_z = np.nanmean(xyz[:, :4, 2])
    assert 0.8 < pelvis_z < 1.1 and 1.4 < np.nanmean(xyz[:, -4:, 2]) < 2.0


def test_pelvis_markers_give_true_com_and_theta(small_walking):
    truth = read_table(small_walking.parent / "truth.parquet", TRUTH)
    for trial, g in truth.groupby("trial", observed=True):
        _, xyz, *_ = read_c3d(small_walking.parent / "raw" / f"{trial}.c3d")
        pel = xyz[:, [SUBJECT_MARKERS.index(m) for m in PELVIS_MARKERS]]
        com = pel.mean(axis=1)[:, :2]
        ok = ~np.isnan(com).any(axis=1)
        err = np.hypot(*(com[ok] - g[["x", "y"]].to_numpy()[ok]).T)
        assert err.mean() < 0.0006 and err.max() < 0.003  # noise 0.7 mm / 2 per barycentre
        lasi, rasi = pel[:, 0], pel[:, 1]
        lx, ly = (lasi - rasi)[:, 0], (lasi - rasi)[:, 1]
        theta = np.arctan2(-lx, ly)
        ok = ~np.isnan(theta)
        assert np.abs(angle_diff(theta[ok], g["theta"].to_numpy()[ok])).max() < 0.03
        assert ok.mean() > 0.5


def test_gaps_match_truth_flags(small_walking):
    truth = read_table(small_walking.parent / "truth.parquet", TRUTH)
    n_lost = 0
    for trial, g in truth.groupby("trial", observed=True):
        _, xyz, *_ = read_c3d(small_walking.parent / "raw" / f"{trial}.c3d")
        pel_gone = np.isnan(xyz[:, :4]).any(axis=-1)
        assert np.array_equal(pel_gone.sum(axis=1), g["pelvis_occluded"].to_numpy())
        lost = g["orientation_lost"].to_numpy()
        assert pel_gone[lost].any(axis=1).all()  # a pelvis marker is missing wherever orientation is lost
        if lost.any():
            n_lost += 1
            run = lost.sum() / 200.0
            assert bd.LONG_GAP_RANGE[0] - 0.01 <= run <= bd.LONG_GAP_RANGE[1] + 0.01
            assert (g["segment"].to_numpy()[lost] == "walk").all()  # long gaps happen while walking
    assert n_lost >= 1  # seed 7 plants at least one long gap among the 6 trials


def test_walks_start_and_end_at_rest_at_the_goal(small_walking):
    truth = read_table(small_walking.parent / "truth.parquet", TRUTH)
    tt = read_table(small_walking.parent / "truth_trials.parquet", TRUTH_TRIALS).set_index("trial")
    for trial, g in truth.groupby("trial", observed=True):
        seg = g["segment"].to_numpy()
        walk = np.flatnonzero(seg == "walk")
        before, after = g.iloc[: walk[0]], g.iloc[walk[-1] + 1:]
        assert len(before) >= 100 and len(after) >= 160  # >= 0.5 s standing before, >= 0.8 s after
        v = np.hypot(*np.gradient(g[["x", "y"]].to_numpy(), 1 / 200.0, axis=0).T)
        for rest in (before, after):  # standing: postural sway of a few mm only, no turning
            assert np.ptp(rest["x"]) < 0.012 and np.ptp(rest["y"]) < 0.012 and np.ptp(rest["theta"]) < 1e-9
            assert v[rest.index - g.index[0]].max() < 0.012
        assert v[walk[:3]].max() < 0.012 and v[walk[-3:]].max() < 0.012
        assert np.median(v[walk]) > 0.3  # walking in between (0.8 m walks included)
        end = g.iloc[-1]
        assert math.hypot(end.x, end.y) < 0.15  # the goal is at the origin
        assert abs(angle_diff(end.theta, math.pi / 2)) < 0.25
        row = tt.loc[trial]
        assert row.onset == pytest.approx(walk[0] / 200.0) and row.offset == pytest.approx(walk[-1] / 200.0)
        assert 0.6 < row.peak_speed < 1.4
        cond = walking.walking_condition(row.condition)
        assert math.hypot(row.x0 - cond.start[0], row.y0 - cond.start[1]) < 0.5
        assert abs(angle_diff(row.theta0, cond.theta0)) < 0.4


def test_same_seed_same_bytes_and_subset_equals_full_study(small_walking, tmp_path):
    walking.generate(tmp_path, seed=7, n_subjects=2, n_trials=1, conditions=["S4015"])
    for name in ("S01_S4015_1", "S02_S4015_1"):
        assert (tmp_path / "raw" / f"{name}.c3d").read_bytes() == (small_walking.parent / "raw" / f"{name}.c3d").read_bytes()
    full = read_table(small_walking.parent / "truth.parquet", TRUTH)
    sub = read_table(tmp_path / "truth.parquet", TRUTH)
    a = full[full["trial"] == "S02_S4015_1"].reset_index(drop=True)
    b = sub[sub["trial"] == "S02_S4015_1"].reset_index(drop=True)
    pd.testing.assert_frame_equal(a[["x", "y", "theta", "frame"]], b[["x", "y", "theta", "frame"]])
    other = tmp_path / "other"
    walking.generate(other, seed=8, n_subjects=1, n_trials=1, conditions=["S4015"])
    assert (other / "raw" / "S01_S4015_1.c3d").read_bytes() != (tmp_path / "raw" / "S01_S4015_1.c3d").read_bytes()


@pytest.fixture(scope="module")
def walking_truth_only(tmp_path_factory):
    """5 subjects x 40 conditions x 1 trial, truth only (no C3D): enough for study-level properties."""
    d = tmp_path_factory.mktemp("walk_truth")
    walking.generate(d, seed=2, n_subjects=5, n_trials=1, write_raw=False)
    tt = read_table(d / "truth_trials.parquet", TRUTH_TRIALS)
    tt.attrs["directory"] = d
    return tt


def test_walking_study_level_properties(walking_truth_only):
    from scipy import stats

    tt = walking_truth_only
    assert len(tt) == 200 and tt["condition"].nunique() == 40
    # long gaps (orientation lost) in about P_LONG_GAP of the trials: binomial, n = 200
    share = tt["orientation_lost"].mean()
    assert abs(share - walking.P_LONG_GAP) < 3 * math.sqrt(walking.P_LONG_GAP * (1 - walking.P_LONG_GAP) / len(tt))
    # subjects keep their own style: peak speed differs between subjects (Kruskal), and travel time
    # grows with the path length at a walking pace
    assert stats.kruskal(*[g["peak_speed"] for _, g in tt.groupby("subject")]).pvalue < 1e-3
    long = tt[tt["path_length"] > 3]
    assert long["peak_speed"].between(0.85, 1.5).all() and 1.05 < long["peak_speed"].mean() < 1.25
    assert stats.pearsonr(tt["path_length"], tt["travel_time"]).statistic > 0.9
    pace = long["path_length"] / long["travel_time"]
    assert pace.between(0.6, 1.3).all()
    # paths bend: longer than the start-goal distance, but not absurdly so
    straight = np.hypot(tt["xf"] - tt["x0"], tt["yf"] - tt["y0"])
    assert (tt["path_length"] >= straight - 0.01).all()  # (ends include the postural sway) and (tt["path_length"] < 1.6 * straight + 0.3).all()


@pytest.mark.datasets
def test_walking_starts_and_ends_match_the_published_means(walking_truth_only, datasets):
    """Mean synthetic start / end per condition vs the first / last sample of the published mean."""
    tt = walking_truth_only.groupby("condition")[["x0", "y0", "xf", "yf"]].mean()
    start_err, end_err = [], []
    for code, row in tt.iterrows():
        mean = np.loadtxt(datasets / "walking-2020" / f"{code}.dat", max_rows=2)  # rows x, y of the mean block
        start_err.append(math.hypot(mean[0, 0] - row.x0, mean[1, 0] - row.y0))
        end_err.append(math.hypot(mean[0, -1] - row.xf, mean[1, -1] - row.yf))
    assert np.mean(start_err) < 0.1 and max(start_err) < 0.25  # 5 subjects, start sd ~0.1 m
    assert max(end_err) < 0.1


def _by_arc_length(x, y, n=500):
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    u = np.linspace(0.0, s[-1], n)
    return np.interp(u, s, x), np.interp(u, s, y)


@pytest.mark.datasets
def test_walking_paths_resemble_the_published_ones(walking_truth_only, datasets):
    """Per condition, the synthetic mean path is about as far from the published mean as a published
    subject is (d_xy ~0.1 m), and synthetic trials spread around their mean like the published ones.

    The published walking-2020 samples are evenly spaced along the path (their spacing varies by
    < 1 % in mid-path although rows vx, vy show a bell-shaped speed), so paths are compared after
    resampling by arc length, not by time.
    """
    truth = read_table(walking_truth_only.attrs["directory"] / "truth.parquet", TRUTH, columns=["trial", "x", "y", "segment"])
    truth = truth[truth["segment"] == "walk"]
    to_mean, ours_spread, published_spread = [], [], []
    for code, trials in walking_truth_only.groupby("condition")["trial"]:
        paths_ = np.array([_by_arc_length(g.x.to_numpy(), g.y.to_numpy())
                           for _, g in truth[truth["trial"].isin(set(trials))].groupby("trial", observed=True)])
        mean = paths_.mean(axis=0)
        published = np.loadtxt(datasets / "walking-2020" / f"{code}.dat")
        to_mean.append(d_xy(mean[0], mean[1], published[0], published[1]))
        ours_spread += [d_xy(p[0], p[1], mean[0], mean[1]) for p in paths_]
        published_spread += [d_xy(published[6 * k], published[6 * k + 1], published[0], published[1]) for k in range(1, 11)]
    assert np.mean(to_mean) < 0.15
    assert 0.5 < np.mean(ours_spread) / np.mean(published_spread) < 1.5


# ---- building blocks ---------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(duration=st.floats(1.0, 15.0), up=st.floats(0.05, 0.7), down=st.floats(0.05, 0.7))
def test_asymmetric_profile_is_monotone_and_front_loaded_when_it_accelerates_faster(duration, up, down):
    t = np.linspace(0.0, duration, 401)
    s = paths.arc_fraction(t, duration, up * duration, down * duration)
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0) and np.all(np.diff(s) >= -1e-12)
    half = paths.arc_fraction(duration / 2, duration, up * duration, down * duration)
    if up + 0.05 < down:  # accelerates faster than it decelerates: more than half the way at mid-time
        assert half > 0.5
    elif down + 0.05 < up:
        assert half < 0.5


@settings(max_examples=40, deadline=None)
@given(length=st.floats(0.3, 8.0), v_peak=st.floats(0.5, 1.5), t_ramp=st.floats(0.5, 2.0))
def test_speed_profile_reaches_the_end_at_rest_with_the_peak_speed(length, v_peak, t_ramp):
    T = paths.motion_duration(length, v_peak, t_ramp)
    pts = np.column_stack([np.linspace(0, length, 50), np.zeros(50)])
    p = paths.along(pts, T, t_ramp, 200.0)
    assert p.xy[0, 0] == 0.0 and p.xy[-1, 0] == pytest.approx(length)
    assert np.all(np.diff(p.xy[:, 0]) >= -1e-12)  # never walks backward
    assert p.speed[0] == 0 and p.speed[-1] == 0
    assert p.speed.max() <= v_peak * 1.03  # the profile never exceeds the planned peak
    if length / v_peak >= t_ramp + 0.1:  # long enough to reach it
        assert p.speed.max() == pytest.approx(v_peak, rel=0.03)


@settings(max_examples=40, deadline=None)
@given(x=st.floats(-5, 5), y=st.floats(-5, 5), phi0=st.floats(-3.1, 3.1), phi1=st.floats(-3.1, 3.1),
       bulge=st.floats(-0.3, 0.3))
def test_hermite_meets_both_poses(x, y, phi0, phi1, bulge):
    if math.hypot(x, y) < 0.2:
        return
    # sampled finely enough that the end chords are the end tangents within 1e-3 rad: at the default 600 samples a
    # bulge larger than the chord (x=0, y=-0.25, phi1=2, bulge=0.28) turns the last chord 0.0204 rad off the tangent
    pts = paths.hermite((0.0, 0.0), (x, y), phi0, phi1, bulge=bulge, n=20001)
    assert np.allclose(pts[0], 0.0) and np.allclose(pts[-1], (x, y))
    d0, d1 = pts[1] - pts[0], pts[-1] - pts[-2]
    assert abs(angle_diff(math.atan2(d0[1], d0[0]), phi0)) < 0.02  # the bulge keeps the end tangents
    assert abs(angle_diff(math.atan2(d1[1], d1[0]), phi1)) < 0.02


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), n_frames=st.integers(200, 3000), long=st.booleans())
def test_gap_plan_short_gaps_stay_short_and_long_gap_stays_in_window(seed, n_frames, long):
    rng = np.random.default_rng(seed)
    window = (n_frames // 4, n_frames - n_frames // 4)
    missing, gaps = bd.plan_gaps(rng, n_frames, 14, long_markers=(0, 1, 2, 3) if long else (), long_window=window,
                                 short_rate=2.0, p_end=0.5)
    assert len(gaps) == int(long)
    for m in range(14):
        col = np.concatenate([[False], missing[:, m], [False]]).astype(int)
        starts, stops = np.flatnonzero(np.diff(col) == 1), np.flatnonzero(np.diff(col) == -1)
        for a, b in zip(starts, stops):
            if gaps and gaps[0].marker == m and (a, b) == (gaps[0].start, gaps[0].stop):
                assert window[0] < a and b <= window[1]
                assert b - a <= bd.LONG_GAP_RANGE[1] * 200
            else:
                assert b - a <= bd.SHORT_GAP_MAX


def test_rigid_pelvis_barycentre_is_the_com_and_normal_is_theta():
    rng = np.random.default_rng(1)
    body = bd.Body.draw(rng, 1.80)
    n = 50
    com = rng.normal(size=(n, 2))
    theta = rng.uniform(-np.pi, np.pi, n)
    xyz = bd.subject_markers(np.arange(n) / 200, com, np.zeros(n), theta, np.zeros(n), body, bd.Gait())
    assert np.allclose(xyz[:, :4, :2].mean(axis=1), com)
    l = xyz[:, 0] - xyz[:, 1]
    assert np.allclose(angle_diff(np.arctan2(-l[:, 0], l[:, 1]), theta), 0.0)
    assert np.allclose(np.hypot(l[:, 0], l[:, 1]), body.asis_width)
    tab = bd.table_markers(com, theta, np.full(n, 0.77))
    centre = (tab[:, 1] + tab[:, 2]) / 2
    axis = tab[:, 1] - tab[:, 0]
    assert np.allclose(centre[:, :2], com) and np.allclose(tab[..., 2], 0.77)
    assert np.allclose(angle_diff(np.arctan2(axis[:, 1], axis[:, 0]), theta), 0.0)
    assert np.allclose(np.hypot(axis[:, 0], axis[:, 1]), 1.22)


# ---- CLI -------------------------------------------------------------------------------------
def test_cli_synth_walking_small_study_and_skip(cli, tmp_path):
    out = tmp_path / "ws"
    args = ("synth", "walking", "--out", out, "--subjects", "2", "--conditions", "E4015,N1500", "--repetitions", "1",
            "--jobs", "1", "--seed", "3")
    code, _, err = cli(*args)
    assert code == 0, err
    stage = out / "synth-walking"
    proto = load_protocol(stage / "protocol.yaml")
    assert len(proto.trials) == 4 and len(list((stage / "raw").glob("*.c3d"))) == 4
    assert (stage / "manifest.json").is_file() and (stage / "results.md").read_text().startswith("## Synthetic walking")
    code, _, err = cli(*args)
    assert code == 0 and "up to date" in err


@pytest.mark.parametrize("args, message", [
    (("--subjects", "0"), "error: --subjects must be a whole number >= 1, got 0; e.g. --subjects 1"),
    (("--repetitions", "0"), "error: --repetitions must be a whole number >= 1, got 0; e.g. --repetitions 1"),
    (("--conditions", "X1500"), "unknown value"),
    (("--conditions", "41"), "between 1 and 40"),
    (("--seed", "-1"), "error: --seed must be a whole number >= 0, got -1; e.g. --seed 0"),
])
def test_cli_synth_walking_bad_usage_exits_2_without_output(cli, tmp_path, args, message):
    out = tmp_path / "ws"
    code, _, err = cli("synth", "walking", "--out", out, *args)
    assert code == 2 and message in err
    assert not (out / "synth-walking").exists()
    assert not out.exists() or not any(out.iterdir())


# ---- pairs -----------------------------------------------------------------------------------

PAIR_SMALL = ["d1_p4_jaune", "d3_p7_gris"]  # a half-turn goal and a straight one


@pytest.fixture(scope="module")
def small_pairs(tmp_path_factory):
    d = tmp_path_factory.mktemp("pairs")
    return pairs.generate(d, seed=5, n_pairs=2, goals=PAIR_SMALL)


@pytest.fixture(scope="module")
def pair_truth(small_pairs):
    return (read_table(small_pairs.parent / "truth.parquet", TRUTH),
            read_table(small_pairs.parent / "truth_trials.parquet", TRUTH_TRIALS))


def test_pairs_design_counts_and_protocol(small_pairs, pair_truth):
    proto = load_protocol(small_pairs)
    assert len(proto.trials) == 2 * 2 * 3
    assert {"pair", "condition", "scenario", "configuration", "end_orientation", "repetition"} <= set(proto.trials.columns)
    assert proto.entities["S1"] == "subject1" and proto.entities["Table"] == "table"
    assert proto.pairs.to_dict("list") == {"id": ["P01", "P02"], "subject1": ["S01", "S03"], "subject2": ["S02", "S04"]}
    assert len(proto.subjects) == 4
    for _, row in proto.trials.iterrows():
        goal = next(g for g in PAIR_GOALS if g.stem == row.condition)
        assert row.configuration == goal.family
        assert any(abs(row.end_orientation - th) < 1e-12 for th in goal.end_orientations)
    truth, tt = pair_truth
    assert set(truth["entity"]) == {"subject1", "subject2", "table"}
    # per recording: 2 walks to the table, and 3 entities x (forward, return)
    counts = tt.groupby("segment").size().to_dict()
    assert counts == {"walk_to_table": 24, "forward": 36, "return": 36}
    assert (tt.loc[tt.segment == "return", "scenario"] == 3).all()
    labels, xyz, rate, units, _ = read_c3d(small_pairs.parent / "raw" / "P02_d3_p7_gris_s2.c3d")
    assert rate == 200.0 and units == "mm" and len(labels) == 31
    assert labels[0] == "S1:LASI" and labels[14] == "S2:LASI" and labels[-3:] == ["Table:TAB1", "Table:TAB2", "Table:TAB3"]


def test_table_height_above_5mm_exactly_during_carriages(small_pairs, pair_truth):
    truth, tt = pair_truth
    for trial, g in truth[truth.entity == "table"].groupby("trial", observed=True):
        seg = g["segment"].to_numpy()
        carried = np.isin(seg, ["forward", "return"])
        assert np.array_equal(g["z"].to_numpy() - 0.77 > pairs.LIFT_THRESHOLD, carried)
        # one forward then one return, each contiguous, separated by a pause
        runs = [s for i, s in enumerate(seg) if i == 0 or s != seg[i - 1]]
        assert runs == ["rest", "forward", "pause", "return", "rest"]
        _, xyz, *_ = read_c3d(small_pairs.parent / "raw" / f"{trial}.c3d")
        height = np.nanmean(xyz[:, -3:, 2], axis=1) - 0.77  # measured: noisy, some corners occluded
        on_floor = g["z"].to_numpy() == 0.77
        assert on_floor.sum() > 0.2 * len(seg) and np.abs(height[on_floor]).max() < 0.003
        assert np.nanmin(height[carried]) > 0.001 and np.median(height[carried]) > 0.08
        mismatch = np.flatnonzero((height > pairs.LIFT_THRESHOLD) != carried)
        assert len(mismatch) <= 8  # only at the 4 threshold crossings


def test_carriage_geometry_goal_reached_subjects_face_each_other(pair_truth):
    truth, tt = pair_truth
    table = tt[tt.entity == "table"].set_index(["trial", "segment"])
    for trial, g in truth.groupby("trial", observed=True):
        goal = next(gl for gl in PAIR_GOALS if gl.stem in trial)
        fwd, ret = table.loc[(trial, "forward")], table.loc[(trial, "return")]
        assert math.hypot(fwd.xf - goal.position[0], fwd.yf - goal.position[1]) < 0.12
        assert abs(angle_diff(fwd.thetaf, fwd.end_orientation)) < 0.12
        assert math.hypot(ret.xf, ret.yf) < 0.1 and abs(angle_diff(ret.thetaf, goal.start_pose[2])) < 0.1
        s1, s2 = (g[g.entity == e].reset_index(drop=True) for e in ("subject1", "subject2"))
        carry = np.isin(s1["segment"].to_numpy(), ["forward", "return"])
        dist = np.hypot(s2.x - s1.x, s2.y - s1.y)[carry]
        assert dist.min() > 1.6 and dist.max() < 2.1  # docs/methods.md 5.6: 1.6 < d < 2.1 m
        bearing = np.arctan2(s2.y - s1.y, s2.x - s1.x)[carry]
        assert np.median(np.abs(angle_diff(s1.theta[carry], bearing))) < 0.4  # Subject 1 faces Subject 2
        assert np.median(np.abs(angle_diff(s2.theta[carry], bearing + np.pi))) < 0.4


def test_return_follows_the_forward_path_backwards_table_closer_than_subjects(pair_truth):
    """Arc-length resampled: the reversed return retraces the forward path (table within a few cm,
    subjects less closely); time-normalised, the front-loaded speed profiles make them differ by
    about 0.3 m, as the published mean paths do (0.2-0.6 m for the table)."""
    truth, tt = pair_truth
    tt = tt.set_index(["trial", "entity", "segment"])
    by_arc = {"table": [], "subject1": [], "subject2": []}
    by_time = {"table": [], "subject1": [], "subject2": []}
    for (trial, entity), g in truth.groupby(["trial", "entity"], observed=True):
        t, x, y = g.time.to_numpy(), g.x.to_numpy(), g.y.to_numpy()
        f, r = tt.loc[(trial, entity, "forward")], tt.loc[(trial, entity, "return")]
        sf, sr = np.linspace(f.onset, f.offset, 500), np.linspace(r.onset, r.offset, 500)
        fx, fy, rx, ry = np.interp(sf, t, x), np.interp(sf, t, y), np.interp(sr, t, x)[::-1], np.interp(sr, t, y)[::-1]
        by_time[entity].append(float(d_xy(fx, fy, rx, ry)))
        (ax, ay), (bx, by) = _by_arc_length(fx, fy), _by_arc_length(rx, ry)
        by_arc[entity].append(float(d_xy(ax, ay, bx, by)))
    assert max(by_arc["table"]) < 0.05
    assert np.mean(by_arc["table"]) < 0.6 * min(np.mean(by_arc["subject1"]), np.mean(by_arc["subject2"]))
    assert 0.15 < np.mean(by_time["table"]) < 0.6


def test_planted_effects_recorded_per_carriage(pair_truth):
    _, tt = pair_truth
    carr = tt[tt.segment.isin(["forward", "return"])]
    assert (carr["time_factor"] == carr["scenario"].map(pairs.SCENARIO_TIME_FACTOR)).all()
    assert carr["duration_noise"].between(0.6, 1.6).all()
    # optimal flag and probability follow the nominal D1 + D2 of the two configurations
    assert (carr["optimal"] == (carr["distance_chosen"] <= carr["distance_other"] + 1e-9)).all()
    p_expected = 1 / (1 + np.exp(-pairs.CONFIG_BETA * (carr["distance_other"] - carr["distance_chosen"])))
    assert np.allclose(carr["p_chosen"], p_expected)


@pytest.fixture(scope="module")
def pair_truth_only(tmp_path_factory):
    """4 pairs x 9 goals x scenarios 1 and 3, truth only (no C3D): enough to see the planted effects."""
    d = tmp_path_factory.mktemp("pairs_truth")
    pairs.generate(d, seed=11, n_pairs=4, scenarios=(1, 3), write_raw=False)
    tt = read_table(d / "truth_trials.parquet", TRUTH_TRIALS)
    tt.attrs["directory"] = d
    return tt


def test_planted_effects_are_detectable(pair_truth_only):
    from scipy import stats

    tt = pair_truth_only
    table = tt[tt.entity == "table"]
    fwd = table[table.segment == "forward"].set_index(["pair", "condition", "scenario"])["travel_time"].unstack()
    ratio = fwd[3] / fwd[1]  # same pair and goal, scenario 3 vs scenario 1
    assert 0.85 < np.exp(np.log(ratio).mean()) < 0.95  # planted factor 0.9
    assert stats.wilcoxon(fwd[3], fwd[1]).pvalue < 1e-3
    # configuration choices favour the distance-minimising one (goals with unequal distances)
    choice = table[(table.segment == "forward") & (table.distance_chosen != table.distance_other).abs().astype(bool)]
    unequal = choice[np.abs(choice.distance_chosen - choice.distance_other) > 1e-6]
    assert stats.binomtest(int(unequal["optimal"].sum()), len(unequal), 0.5).pvalue < 1e-3
    # long gaps in about P_LONG_GAP of the recordings (72 recordings: binomial bounds)
    lost = tt[tt.entity != "table"].groupby("trial")["orientation_lost"].any()
    assert abs(lost.mean() - pairs.P_LONG_GAP) < 3 * math.sqrt(pairs.P_LONG_GAP * (1 - pairs.P_LONG_GAP) / len(lost))
    # no pair effect on travel time (relative to the goal and scenario mean)
    fwd_all = table[table.segment == "forward"].copy()
    fwd_all["rel"] = fwd_all["travel_time"] / fwd_all.groupby(["condition", "scenario"])["travel_time"].transform("mean")
    assert stats.kruskal(*[g["rel"] for _, g in fwd_all.groupby("pair")]).pvalue > 0.01
    # table paths vary less across pairs than subjects' paths: spread of the end-to-end path length
    for seg in ("forward", "return"):
        s = tt[tt.segment == seg]
        spread = s.groupby("entity")["path_length"].apply(
            lambda v: (v / s.loc[v.index].groupby(["condition", "end_orientation"])["path_length"].transform("mean")).std())
        assert spread["table"] < spread["subject1"] and spread["table"] < spread["subject2"]


def test_pairs_same_seed_same_bytes(small_pairs, tmp_path):
    pairs.generate(tmp_path, seed=5, n_pairs=2, goals=["d3_p7_gris"], scenarios=(2,))
    name = "P02_d3_p7_gris_s2.c3d"
    assert (tmp_path / "raw" / name).read_bytes() == (small_pairs.parent / "raw" / name).read_bytes()


def test_cli_synth_pairs_small_study(cli, tmp_path):
    out = tmp_path / "ws"
    code, _, err = cli("synth", "pairs", "--out", out, "--pairs", "1", "--goals", "d2_p7_jaune", "--scenarios", "3",
                       "--jobs", "1")
    assert code == 0, err
    proto = load_protocol(out / "synth-pairs" / "protocol.yaml")
    assert proto.trials["trial"].tolist() == ["P01_d2_p7_jaune_s3"]
    assert (out / "synth-pairs" / "results.md").read_text().startswith("## Synthetic pair-carriage study")


@pytest.mark.parametrize("args, message", [
    (("--pairs", "0"), "error: --pairs must be a whole number >= 1, got 0; e.g. --pairs 1"),
    (("--goals", "d9_p1_gris"), "unknown value"),
    (("--scenarios", "4"), "unknown value"),
    (("--scenarios", ""), "unknown value"),
    (("--seed", "-3"), "error: --seed must be a whole number >= 0, got -3; e.g. --seed 0"),
])
def test_cli_synth_pairs_bad_usage_exits_2_without_output(cli, tmp_path, args, message):
    out = tmp_path / "ws"
    code, _, err = cli("synth", "pairs", "--out", out, *args)
    assert code == 2 and message in err
    assert not (out / "synth-pairs").exists()


@pytest.mark.datasets
def test_pair_durations_speeds_and_places_match_the_published_data(pair_truth_only, datasets):
    import json

    folder = datasets / "pair-carriage-2022"
    files = {1: "time_and_vel_sub1_leader.json", 3: "time_and_vel_sub1_2_leader.json"}
    tt = pair_truth_only
    table = tt[(tt.entity == "table") & (tt.segment == "forward")]
    for scenario, name in files.items():
        published = json.loads((folder / name).read_text())
        rows = [v for trials in published.values() for k, v in trials.items() if k.endswith("_1")]
        duration = np.median([r["Duration (s)"] for r in rows])
        speed = np.median([r["Mean_velocity (m.s^-1)"] for r in rows])
        ours = table[table.scenario == scenario]
        assert abs(ours["travel_time"].median() / duration - 1) < 0.2
        assert abs((ours["path_length"] / ours["travel_time"]).median() / speed - 1) < 0.25
    # subjects' place at the table: distance of each pelvis to the table centre at the onset
    on = tt[tt.segment == "forward"].set_index(["trial", "entity"])
    for entity, k in (("subject1", 1), ("subject2", 2)):
        rel = np.loadtxt(folder / f"subject{k}_wrt_table.dat")  # rows x_fwd x_ret y_fwd y_ret th_fwd th_ret
        published = math.hypot(rel[0, 0], rel[2, 0])
        dist = np.hypot(on.xs(entity, level=1).x0 - on.xs("table", level=1).x0,
                        on.xs(entity, level=1).y0 - on.xs("table", level=1).y0)
        assert abs(dist.median() - published) < 0.1


def test_pair_gaps_match_truth_flags_per_entity(small_pairs, pair_truth):
    truth, _ = pair_truth
    proto = load_protocol(small_pairs)
    for trial, g in truth.groupby("trial", observed=True):
        labels, xyz, *_ = read_c3d(small_pairs.parent / "raw" / f"{trial}.c3d")
        owner = [proto.resolve_label(lab) for lab in labels]  # "S2:LASI" -> ("subject2", "LASI")
        gone = np.isnan(xyz).any(axis=-1)
        for entity, e in g.groupby("entity", observed=True):
            names = PELVIS_MARKERS if entity != "table" else ("TAB1", "TAB2", "TAB3")
            cols = [owner.index((entity, m)) for m in names]
            assert np.array_equal(gone[:, cols].sum(axis=1), e["pelvis_occluded"].to_numpy())
            lost = e["orientation_lost"].to_numpy()
            assert gone[lost][:, cols].any(axis=1).all()
            if entity == "table":
                assert not lost.any()
            elif lost.any():  # long gaps fall in a carriage (up to its first or last few frames)
                assert np.isin(e["segment"].to_numpy()[lost], ["forward", "return"]).mean() > 0.8


@pytest.mark.datasets
def test_pair_mean_paths_resemble_the_published_means(pair_truth_only, datasets):
    """Synthetic mean forward / return paths per goal and end configuration (time-normalised from
    onset to offset) vs the published ``All data`` means: the table closest, then the subjects."""
    import json

    truth = read_table(pair_truth_only.attrs["directory"] / "truth.parquet", TRUTH, columns=["trial", "entity", "time", "x", "y"])
    series = {key: (g.time.to_numpy(), g.x.to_numpy(), g.y.to_numpy())
              for key, g in truth.groupby(["trial", "entity"], observed=True)}
    names = {"subject1": "Sujet 1", "subject2": "Sujet 2", "table": "Table"}
    found = {e: [] for e in names}
    tt = pair_truth_only[pair_truth_only.segment.isin(["forward", "return"])]
    for (segment, stem, entity, end), rows in tt.groupby(["segment", "condition", "entity", "end_orientation"]):
        doc = json.loads((datasets / "pair-carriage-2022" / f"{stem}_{1 if segment == 'forward' else 2}_mean.json").read_text())
        means = doc["Trajectoires_Moyennes"][names[entity]]["All data"]
        key = next((k for k in means if abs(float(k.split(":")[1]) - end) < 1e-6), None)
        if key is None or means[key]["nb"] < 3:  # rare configurations: noisy published means
            continue
        runs = []
        for _, r in rows.iterrows():
            t, x, y = series[(r.trial, entity)]
            s = np.linspace(r.onset, r.offset, 500)
            runs.append([np.interp(s, t, x), np.interp(s, t, y)])
        mean = np.mean(runs, axis=0)
        found[entity].append(float(d_xy(mean[0], mean[1], np.array(means[key]["x"]), np.array(means[key]["y"]))))
    assert all(len(v) >= 15 for v in found.values())
    assert np.median(found["table"]) < 0.2
    assert np.median(found["subject1"]) < 0.3 and np.median(found["subject2"]) < 0.3


# ---- protocols -----------------------------------------------------------------------------------
@pytest.mark.parametrize("study", ["walking", "pairs"])
def test_protocols_explain_every_key_and_import(study, small_walking, small_pairs, tmp_path, cli):
    import yaml

    from cobot_analysis.schema import MARKERS

    proto = small_walking if study == "walking" else small_pairs
    text = proto.read_text()
    doc = yaml.safe_load(text)
    keys = ["study", "rate", "entities", "marker_map", "subjects", "trials"]
    if study == "pairs":
        keys.insert(5, "pairs")
    assert list(doc) == keys and doc["marker_map"] == {}
    assert doc["entities"] == ({} if study == "walking" else {"S1": "subject1", "S2": "subject2", "Table": "table"})
    lines = text.splitlines()
    assert lines[0].startswith("# Protocol of a synthetic") and "docs/protocol.md" in " ".join(lines[:2])
    for key in keys:  # each key is preceded by its comment
        i = next(n for n, line in enumerate(lines) if line.startswith(f"{key}:"))
        assert lines[i - 1].startswith("# "), key
    assert "LASI" in text.split("marker_map:")[0].split("entities:")[1]  # the marker_map comment names the canonical labels
    code, _, err = cli("-q", "import", proto, "--out", tmp_path)
    assert code == 0, err
    markers = read_table(tmp_path / "import" / "markers.parquet", MARKERS)
    expected = {"walker"} if study == "walking" else {"subject1", "subject2", "table"}
    assert set(markers["entity"]) == expected
    assert set(markers["marker"]) == set(SUBJECT_MARKERS) | (set() if study == "walking" else {"TAB1", "TAB2", "TAB3"})
