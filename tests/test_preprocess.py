"""Preprocess: gaps, filter conventions, segmentation, normalisation, the stage and its bad input."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_analysis.preprocess import filtering, gaps, normalisation, pairs, segmentation
from cobot_analysis.schema import MARKERS, TRAJECTORIES, TRIALS, read_table, write_table

RATE = 200.0
PELVIS = {"LASI": (0.08, 0.12, 0.0), "RASI": (0.08, -0.12, 0.0), "LPSI": (-0.08, 0.045, 0.02),
          "RPSI": (-0.08, -0.045, 0.02)}
TABLE = {"TAB1": (-0.61, -0.40), "TAB2": (0.61, -0.40), "TAB3": (-0.61, 0.40)}


# ---- filtering ------------------------------------------------------------------------------------
def _gain_and_lag(freq: float, sos: np.ndarray, seconds: float = 20.0):
    t = np.arange(0, seconds, 1 / RATE)
    x = np.sin(2 * np.pi * freq * t)
    y = filtering.lowpass(x[:, None], sos)[:, 0]
    mid = slice(len(t) // 4, 3 * len(t) // 4)
    # least-squares fit y = a sin + b cos over the middle: gain sqrt(a^2+b^2), phase atan2(b, a)
    basis = np.column_stack([np.sin(2 * np.pi * freq * t[mid]), np.cos(2 * np.pi * freq * t[mid])])
    (a, b), *_ = np.linalg.lstsq(basis, y[mid], rcond=None)
    return np.hypot(a, b), np.arctan2(b, a)


@pytest.mark.parametrize("convention, gain_at_cutoff", [("design", 0.5), ("effective", 2 ** -0.5)])
def test_filter_gain_at_cutoff_follows_the_convention_and_is_zero_phase(convention, gain_at_cutoff):
    sos = filtering.butter_sos(10.0, RATE, 4, convention)
    gain, phase = _gain_and_lag(10.0, sos)
    assert gain == pytest.approx(gain_at_cutoff, abs=2e-3)
    assert abs(phase) < 1e-3
    low, low_phase = _gain_and_lag(2.0, sos)
    assert low == pytest.approx(1.0, abs=2e-3) and abs(low_phase) < 1e-3
    # forward-backward gain = |H|^2 = 1 / (1 + (tan(pi f/fs) / tan(pi f_d/fs))^(2 n_d)) (bilinear Butterworth)
    n_d, f_d = filtering.design_cutoff(10.0, RATE, 4, convention)
    for f in (5.0, 15.0, 30.0):
        r = np.tan(np.pi * f / RATE) / np.tan(np.pi * f_d / RATE)
        assert _gain_and_lag(f, sos)[0] == pytest.approx(1 / (1 + r ** (2 * n_d)), abs=2e-3)
    assert _gain_and_lag(30.0, sos)[0] < 0.03


def test_filter_effective_order_is_four_and_design_order_is_eight():
    """Roll-off far above the cut-off: gain ~ w^(-n_eff), w = tan(pi f / fs) the pre-warped frequency."""
    for convention, n_eff in (("design", 8), ("effective", 4)):
        sos = filtering.butter_sos(10.0, RATE, 4, convention)
        g30, _ = _gain_and_lag(30.0, sos)
        g60, _ = _gain_and_lag(60.0, sos)
        slope = np.log(g30 / g60) / np.log(np.tan(np.pi * 60 / RATE) / np.tan(np.pi * 30 / RATE))
        assert slope == pytest.approx(n_eff, rel=0.05)


def test_filtfilt_equals_scipy_sosfiltfilt():
    from scipy.signal import sosfiltfilt

    x = np.random.default_rng(0).normal(size=(300, 4)).cumsum(axis=0)
    for convention in filtering.CONVENTIONS:
        sos = filtering.butter_sos(10.0, RATE, 4, convention)
        for pad in (0, 5, 27, 299):
            np.testing.assert_allclose(filtering.filtfilt(sos, x, pad), sosfiltfilt(sos, x, axis=0, padlen=pad), atol=1e-12)


def test_filter_bad_parameters():
    with pytest.raises(ValueError, match="even order"):
        filtering.butter_sos(10.0, RATE, 3, "effective")
    with pytest.raises(ValueError, match="Nyquist"):
        filtering.butter_sos(150.0, RATE, 4, "design")


def test_filter_keeps_nan_gaps_and_filters_each_segment():
    t = np.arange(0, 6, 1 / RATE)
    x = np.column_stack([np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 0.5 * t)])
    x[500:600, 0] = np.nan  # a long gap in one column only
    y = filtering.lowpass(x, filtering.butter_sos(10.0, RATE))
    assert np.isnan(y[500:600, 0]).all() and not np.isnan(np.delete(y[:, 0], range(500, 600))).any()
    assert not np.isnan(y[:, 1]).any()
    ok = ~np.isnan(x)
    np.testing.assert_allclose(y[ok], x[ok], atol=1e-2)  # a slow signal passes through (odd padding at edges)
    inner = np.r_[50:450, 650:1150]  # away from the segment ends: unchanged
    np.testing.assert_allclose(y[inner], x[inner], atol=1e-4)


# ---- gaps -----------------------------------------------------------------------------------------
def test_find_gaps_runs():
    miss = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], dtype=bool)
    starts, lengths = gaps.find_gaps(miss)
    assert starts.tolist() == [0, 4, 6] and lengths.tolist() == [2, 1, 3]
    assert gaps.fillable(starts, lengths, len(miss), 2).tolist() == [False, True, False]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=300), st.integers(1, 30))
def test_gaps_partition_the_missing_frames_and_filling_keeps_valid_samples(missing, max_frames):
    missing = np.array(missing)
    starts, lengths = gaps.find_gaps(missing)
    rebuilt = np.zeros_like(missing)
    for s0, k in zip(starts, lengths):
        assert missing[s0:s0 + k].all() and not rebuilt[s0:s0 + k].any()
        rebuilt[s0:s0 + k] = True
    assert (rebuilt == missing).all()
    n = len(missing)
    xyz = np.column_stack([np.sin(np.arange(n) / 7.0)] * 3)
    xyz[missing] = np.nan
    out, mask, _, _, done = gaps.fill_gaps(xyz, RATE, max_frames / RATE)
    np.testing.assert_array_equal(out[~missing], xyz[~missing])
    assert not np.isnan(out[mask]).any() and np.isnan(out[missing & ~mask]).all()
    expected = np.zeros(n, dtype=bool)
    if (~missing).sum() >= 4:
        for s0, k, d in zip(starts, lengths, gaps.fillable(starts, lengths, n, max_frames)):
            expected[s0:s0 + k] = d
    assert (mask == expected).all()


def test_short_gap_filled_exactly_on_a_cubic_long_and_edge_gaps_kept():
    t = np.arange(400) / RATE
    xyz = np.column_stack([t**3 - 2 * t, 0.5 * t**2, np.full_like(t, 0.9)])
    truth = xyz.copy()
    xyz[0:5] = np.nan  # edge gap: nothing to interpolate from on one side
    xyz[100:120] = np.nan  # 20 frames = 0.1 s: filled
    xyz[200:221] = np.nan  # 21 frames: too long
    out, mask, starts, lengths, done = gaps.fill_gaps(xyz, RATE, 0.1)
    assert starts.tolist() == [0, 100, 200] and lengths.tolist() == [5, 20, 21]
    assert done.tolist() == [False, True, False]
    np.testing.assert_allclose(out[100:120], truth[100:120], atol=1e-9)
    assert mask.sum() == 20 and mask[100:120].all()
    assert np.isnan(out[200:221]).all() and np.isnan(out[:5]).all()
    assert np.isnan(xyz[100:120]).all()  # the input is not modified


# ---- segmentation ---------------------------------------------------------------------------------
def _lift_profile():
    """Height: floor 0.77 m; forward carriage 3-9 s; return 12-17 s; a 0.2 s bump at 10.5 s."""
    t = np.arange(0, 20, 1 / RATE)
    h = np.full_like(t, 0.77)

    def ramp(t0, t1, t2, t3):
        return np.clip((t - t0) / (t1 - t0), 0, 1) * np.clip((t3 - t) / (t3 - t2), 0, 1)

    h += 0.15 * ramp(3.0, 3.4, 8.6, 9.0) + 0.15 * ramp(12.0, 12.4, 16.6, 17.0) + 0.02 * ramp(10.5, 10.6, 10.6, 10.7)
    return t, h


def test_carriages_on_an_analytic_height_profile():
    t, h = _lift_profile()
    found, h0 = segmentation.carriages(h, RATE, threshold=0.005)
    assert h0 == pytest.approx(0.77)
    # crossings of 0.775 m: 3 + 0.4 * 5/150 s after the ramp starts, symmetric at the end
    dt = 0.4 * 0.005 / 0.15
    expected = [(3.0 + dt, 9.0 - dt), (12.0 + dt, 17.0 - dt)]
    assert len(found) == 2  # the 0.2 s bump is shorter than min_duration
    for (a, b), (ta, tb) in zip(found, expected):
        assert t[a] == pytest.approx(ta, abs=1 / RATE) and t[b] == pytest.approx(tb, abs=1 / RATE)
        assert h[a] > 0.775 >= h[a - 1] and h[b] > 0.775 >= h[b + 1]
    # a higher threshold shortens the carriages; a bump threshold above 0.02 m ignores it anyway
    found_hi, _ = segmentation.carriages(h, RATE, threshold=0.05)
    assert found_hi[0][0] > found[0][0] and found_hi[0][1] < found[0][1]


def test_walking_bounds_by_speed():
    t = np.arange(0, 6, 1 / RATE)
    speed = np.where((t >= 1.0) & (t <= 4.5), 1.0, 0.02)
    speed[(t > 5.0) & (t < 5.2)] = 0.3  # a short shuffle after stopping: ignored
    a, b = segmentation.walking_bounds(speed, RATE, 0.1, 0.5)
    assert t[a] == pytest.approx(1.0) and t[b] == pytest.approx(4.5)
    assert segmentation.walking_bounds(np.zeros(100), RATE) is None
    # hysteresis: a linear ramp 0 -> 1 m/s over 1 s is found at 0.1 m/s and extended to 0.05 m/s
    ramp = np.clip(np.minimum(t - 1.0, 5.0 - t), 0, 1)
    a, b = segmentation.walking_bounds(ramp, RATE, 0.1, 0.5, rest_speed=0.05)
    assert t[a] == pytest.approx(1.05, abs=1 / RATE) and t[b] == pytest.approx(4.95, abs=1 / RATE)
    a, b = segmentation.walking_bounds(ramp, RATE, 0.1, 0.5, rest_speed=0.1)
    assert t[a] == pytest.approx(1.1, abs=1 / RATE) and t[b] == pytest.approx(4.9, abs=1 / RATE)


@pytest.mark.parametrize("stand, apart", [(0.5, False), (0.9, False), (1.1, True), (3.0, True)])
def test_walks_are_apart_when_the_subject_stands_still_long_enough(stand, apart):
    """Two runs of walking with the subject standing still (0.02 m/s) for ``stand`` s between them: one walk below
    --min-rest (1 s: a hesitation), two above it; a gap in the data (NaN) of the same length is no rest."""
    t = np.arange(0, 8 + stand, 1 / RATE)
    speed = np.where(((t >= 1.0) & (t <= 3.0)) | ((t >= 3.0 + stand) & (t <= 6.0 + stand)), 1.0, 0.02)
    found = segmentation.walks(speed, RATE)
    got = np.array([(t[a], t[b]) for a, b in found])
    expected = np.array([(1.0, 3.0), (3.0 + stand, 6.0 + stand)] if apart else [(1.0, 6.0 + stand)])
    assert got.shape == expected.shape and np.allclose(got, expected, atol=1.01 / RATE), got
    gap = np.where((t > 3.0) & (t < 3.0 + stand), np.nan, speed)
    assert len(segmentation.walks(gap, RATE)) == 1
    assert segmentation.walking_bounds(speed, RATE) == (found[0][0], found[-1][1])  # the walk to the table: one span
    assert len(segmentation.walks(speed, RATE, min_rest=np.inf)) == 1


def test_a_recording_that_walks_back_to_the_start_keeps_the_walk_to_the_goal(tmp_path, cli):
    """Rest, 3 m to the goal, 2 s standing there turning round, 3 m back, rest: one trajectory to the goal and back,
    10.7 s long with the stop, ended at its start, flagged ok. Now the first walk is the trial (3 m, 2.7 s), flagged
    later_walks, and the stage's results say so; a turn on the spot of 0.5 s stays inside one walk (--min-rest)."""
    def there_and_back(trial, stop):
        t = np.arange(0, 9 + stop, 1 / RATE)
        s = 3.0 * (_min_jerk(t, 1.0, 4.0) - _min_jerk(t, 4.0 + stop, 7.0 + stop))
        return _rows(trial, "walker", pelvis(s, 0 * s, np.pi * _min_jerk(t, 4.0, 4.0 + stop)))

    ws = tmp_path / "ws"
    write_workspace(ws, there_and_back("B1", 2.0) + there_and_back("B2", 0.5),
                    [trials_row("B1", subject="S01"), trials_row("B2", subject="S02")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    per = traj.groupby("trial").agg(T=("travel_time", "first"), end=("x", "last"), far=("x", "max"), q=("quality", "first"))
    assert per.loc["B1", "q"] == "later_walks" and per.loc["B1", "T"] == pytest.approx(2.74, abs=0.01)
    assert per.loc["B1", "end"] == pytest.approx(3.0, abs=0.01) == per.loc["B1", "far"]
    assert per.loc["B2", "q"] == "ok" and per.loc["B2", "end"] == pytest.approx(0.0, abs=0.01)  # one walk, there and back
    assert "1 trajectories are `later_walks`: their recording holds more walks after the first" in \
        (ws / "preprocess" / "results.md").read_text()


# ---- normalisation --------------------------------------------------------------------------------
def test_phase_endpoints_and_spacing():
    ph = normalisation.phase(500)
    assert ph[0] == 0.0 and ph[-1] == 100.0 and ph[1] == pytest.approx(100 / 499)


@settings(max_examples=50, deadline=None)
@given(on=st.integers(0, 50), length=st.integers(1, 400), n=st.integers(2, 600),
       a=st.floats(-5, 5), b=st.floats(-5, 5))
def test_normalise_reproduces_linear_signals_and_endpoints(on, length, n, a, b):
    frames = np.arange(on + length + 10)
    values = np.column_stack([a + b * frames, -b * frames])
    res = normalisation.normalise(values, on, on + length, n)
    assert res.shape == (n, 2)
    np.testing.assert_allclose(res[0], values[on], atol=1e-9)
    np.testing.assert_allclose(res[-1], values[on + length], atol=1e-9)
    pos = on + length * np.arange(n) / (n - 1)
    np.testing.assert_allclose(res[:, 0], a + b * pos, atol=1e-8)


def test_normalise_nan_next_to_a_missing_frame_only():
    values = np.arange(10.0)
    values[5] = np.nan
    res = normalisation.normalise(values, 0, 9, 10)  # exactly on the frames
    assert np.isnan(res[5]) and np.isnan(res).sum() == 1
    res = normalisation.normalise(values, 0, 9, 19)  # half-way points around frame 5 are NaN too
    assert np.isnan(res).sum() == 3


# ---- the stage ------------------------------------------------------------------------------------
def _min_jerk(t, t0, t1):
    tau = np.clip((t - t0) / (t1 - t0), 0, 1)
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5


def _rows(trial, entity, markers):
    n = len(next(iter(markers.values())))
    parts = []
    for name, xyz in markers.items():
        parts.append(pd.DataFrame({
            "trial": trial, "frame": np.arange(n), "time": np.arange(n) / RATE, "entity": entity, "marker": name,
            "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "occluded": np.isnan(xyz).any(axis=1)}))
    return parts


def pelvis(x, y, theta, z=0.95):
    c, s = np.cos(theta), np.sin(theta)
    return {k: np.column_stack([x + c * a - s * b, y + s * a + c * b, np.full_like(x, z + h)])
            for k, (a, b, h) in PELVIS.items()}


def walking_trial(trial="W1", duration=5.0, start=1.0, stop=4.0, length=3.0, heading=0.5):
    """Rest 1 s, min-jerk walk of ``length`` m along ``heading`` between start and stop, rest."""
    t = np.arange(0, duration, 1 / RATE)
    s = length * _min_jerk(t, start, stop)
    return _rows(trial, "walker", pelvis(np.cos(heading) * s, np.sin(heading) * s, np.full_like(t, heading)))


def pair_recording(trial="P1"):
    """Table carried 3 m along +x (3-9 s) and back (12-18 s); subjects at its short ends facing it.

    Subject 1 first walks 2 m (backwards, facing -x) to its end of the table (0.5-2.5 s)."""
    t = np.arange(0, 20, 1 / RATE)
    s = 3.0 * (_min_jerk(t, 3.2, 8.8) - _min_jerk(t, 12.2, 17.8))
    lift = 0.15 * (_min_jerk(t, 3.0, 3.4) - _min_jerk(t, 8.6, 9.0) + _min_jerk(t, 12.0, 12.4) - _min_jerk(t, 17.6, 18.0))
    parts = []
    for name, (a, b) in TABLE.items():
        xyz = np.column_stack([s + a, np.full_like(t, b), 0.77 + lift])
        parts += _rows(trial, "table", {name: xyz})
    approach = 2.0 * (1 - _min_jerk(t, 0.5, 2.5))
    parts += _rows(trial, "subject1", pelvis(s + 0.96 + approach, 0 * t, np.full_like(t, np.pi)))
    parts += _rows(trial, "subject2", pelvis(s - 0.96, 0 * t, np.zeros_like(t)))
    return parts


def trials_row(trial, **kw):
    row = {"study": "test", "trial": trial, "kind": "trial", "n_trials": 1, "subject": None, "pair": None,
           "condition": "c1", "direction": None, "scenario": None, "configuration": None, "end_orientation": None,
           "repetition": 1, "file": f"{trial}.c3d", "sha256": "0", "source_format": "c3d", "source_units": "mm",
           "rate": RATE, "n_frames": 0}
    row.update(kw)
    return row


def write_workspace(ws, parts, rows):
    markers = pd.concat(parts, ignore_index=True)
    write_table(markers, ws / "import" / "markers.parquet", MARKERS, rate=RATE)
    trials = pd.DataFrame(rows)
    for c in ("scenario", "repetition", "n_trials", "n_frames"):
        trials[c] = trials[c].astype("Int64")
    trials["end_orientation"] = trials["end_orientation"].astype(float)
    write_table(trials, ws / "import" / "trials.parquet", TRIALS)


def test_stage_walking_trial_end_to_end(tmp_path, cli):
    ws = tmp_path / "ws"
    parts = walking_trial("W1")
    lasi = parts[0]  # a short gap (0.05 s) in LASI and a long one (0.5 s) in RPSI, mid-walk
    lasi.loc[300:309, ["x", "y", "z"]] = np.nan
    lasi.loc[300:309, "occluded"] = True
    rpsi = parts[3]
    rpsi.loc[400:499, ["x", "y", "z"]] = np.nan
    rpsi.loc[400:499, "occluded"] = True
    parts += walking_trial("W2", heading=-2.0, length=2.0)
    write_workspace(ws, parts, [trials_row("W1", subject="S01"), trials_row("W2", subject="S02")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--samples", "101", "--orientation-markers", "asis")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert len(traj) == 2 * 101 and set(traj["entity"]) == {"walker"}
    w1 = traj[traj["trial"] == "W1"].sort_values("sample")
    assert w1["quality"].iloc[0] == "short_gaps_filled;long_gap;com_rigid_fill"
    assert w1["subject"].iloc[0] == "S01" and w1["kind"].iloc[0] == "trial"
    # min-jerk over 3 m in 3 s: speed 30 tau^2 (1 - tau)^2 m/s; the walk found at 0.1 m/s is
    # extended to the rest speed 0.05 m/s, reached at tau0 (analytic root)
    tau0 = (1 - np.sqrt(1 - 4 * np.sqrt(0.05 / 30))) / 2
    tt = w1["travel_time"].iloc[0]
    assert tt == pytest.approx(3.0 * (1 - 2 * tau0), abs=0.02)
    assert w1["record_time"].iloc[0] == pytest.approx(1.0 + 3.0 * tau0, abs=0.01)
    assert w1["phase"].iloc[-1] == 100.0 and w1["time"].iloc[-1] == pytest.approx(tt)
    # positions follow the straight line, theta the heading, gamma 0
    np.testing.assert_allclose(np.arctan2(w1["y"], w1["x"]), 0.5, atol=1e-3)
    np.testing.assert_allclose(w1["theta"], 0.5, atol=1e-3)
    np.testing.assert_allclose(w1["gamma"], 0.0, atol=1e-3)
    s0 = 10 * tau0**3 - 15 * tau0**4 + 6 * tau0**5
    assert w1["travelled_distance"].iloc[0] == pytest.approx(3.0 * (1 - 2 * s0), abs=2e-3)
    w2 = traj[traj["trial"] == "W2"]
    assert (w2["quality"] == "ok").all()
    np.testing.assert_allclose(w2["theta"], -2.0, atol=1e-3)
    gaps_df = read_table(ws / "preprocess" / "gaps.parquet", gaps.GAPS)
    assert gaps_df[["marker", "start_frame", "n_frames", "filled"]].values.tolist() == [
        ["LASI", 300, 10, True], ["RPSI", 400, 100, False]]
    assert gaps_df["duration"].tolist() == [0.05, 0.5]
    manifest = json.loads((ws / "preprocess" / "manifest.json").read_text())
    assert manifest["params"]["order_convention"] == "effective" and manifest["params"]["cutoff"] == 10.0
    assert manifest["params"]["n_samples"] == 101 and manifest["params"]["max_gap"] == 0.1
    results = (ws / "preprocess" / "results.md").read_text()
    assert "2 recordings -> 2 trials, 2 trajectories" in results
    assert "| walker | LASI | 1 | 1 | 0 | 0 |" in results and "| walker | RPSI | 1 | 0 | 1 | 100 |" in results
    # unchanged inputs and parameters: skipped
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--samples", "101", "--orientation-markers", "asis")
    assert code == 0 and "up to date" in err
    # default: a long gap on any pelvis marker (here RPSI) makes the orientation missing; position kept
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--samples", "101")
    assert code == 0 and "up to date" not in err
    traj2 = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    w1b = traj2[traj2["trial"] == "W1"].sort_values("sample")
    assert w1b["quality"].iloc[0] == "short_gaps_filled;long_gap;com_rigid_fill;orientation_missing"
    assert w1b["theta"].isna().all() and w1b["gamma"].isna().all()
    np.testing.assert_allclose(w1b[["x", "y"]], w1[["x", "y"]], atol=1e-12)


def test_stage_orientation_missing_keeps_position(tmp_path, cli):
    ws = tmp_path / "ws"
    parts = walking_trial("W1")
    parts[1].loc[400:499, ["x", "y", "z"]] = np.nan  # RASI long gap: no theta for the trajectory
    write_workspace(ws, parts, [trials_row("W1")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert traj["quality"].iloc[0] == "long_gap;com_rigid_fill;orientation_missing"
    assert traj["theta"].isna().all() and traj["gamma"].isna().all()
    assert not traj[["x", "y"]].isna().any().any()
    np.testing.assert_allclose(np.arctan2(traj["y"], traj["x"])[1:], 0.5, atol=1e-3)


def test_stage_pair_recording_forward_and_return(tmp_path, cli):
    ws = tmp_path / "ws"
    write_workspace(ws, pair_recording("P1"), [trials_row("P1", pair="P01", scenario=1, configuration="gris",
                                                          end_orientation=0.0, condition="d1_p4_gris")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--keep-approach")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    per = traj.drop_duplicates(["trial", "entity"]).set_index(["trial", "entity"])
    assert sorted(per.index) == [("P1_approach", "subject1"),
                                 ("P1_forward", "subject1"), ("P1_forward", "subject2"), ("P1_forward", "table"),
                                 ("P1_return", "subject1"), ("P1_return", "subject2"), ("P1_return", "table")]
    # subject 2 stands still before the lift: no approach trial; subject 1 walks 2 m backwards
    app = per.loc[("P1_approach", "subject1")]
    assert app["direction"] == "approach" and app["travelled_distance"] == pytest.approx(2.0, abs=0.01)
    assert app["travel_time"] == pytest.approx(2.0, abs=0.3)
    assert per.loc[("P1_forward", "table"), "scenario"] == 1 and per.loc[("P1_return", "table"), "scenario"] == 3
    assert per.loc[("P1_forward", "table"), "direction"] == "forward"
    assert per.loc[("P1_return", "table"), "direction"] == "return"
    dt = 0.4 * 0.005 / 0.15  # crossing of 5 mm on the lift ramp (min-jerk: a little later)
    fwd = per.loc[("P1_forward", "table")]
    assert fwd["travel_time"] == pytest.approx(6.0 - 2 * dt, abs=0.12)
    assert per.loc[("P1_forward", "subject1"), "travel_time"] == fwd["travel_time"]
    assert fwd["travelled_distance"] == pytest.approx(3.0, abs=1e-3)
    ret = traj[(traj["trial"] == "P1_return") & (traj["entity"] == "table")]
    assert ret["x"].iloc[0] == pytest.approx(3.0, abs=1e-3) and ret["x"].iloc[-1] == pytest.approx(0.0, abs=1e-3)
    np.testing.assert_allclose(ret["theta"], 0.0, atol=1e-6)
    s1 = traj[(traj["trial"] == "P1_forward") & (traj["entity"] == "subject1")]
    np.testing.assert_allclose(s1["x"] - traj[(traj["trial"] == "P1_forward") & (traj["entity"] == "table")]["x"].to_numpy(),
                               0.96, atol=1e-6)
    # subject 1 walks backwards (faces -x while the table moves +x): gamma = pi
    np.testing.assert_allclose(np.abs(s1["gamma"]), np.pi, atol=1e-3)
    assert per.loc[("P1_return", "table"), "end_orientation"] == pytest.approx(0.0, abs=1e-6)


# ---- bad input: one line, exit 2, no stage directory ----------------------------------------------
def _bad(tmp_path, cli, parts, rows, expected):
    ws = tmp_path / "ws"
    write_workspace(ws, parts, rows)
    code, out, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and expected in lines[0], err
    line = lines[0]
    assert ".c3d: " in line or "markers.parquet" in line or "trials.parquet" in line  # the raw file when the trial has one
    assert not (ws / "preprocess").exists()
    assert not [p for p in ws.iterdir() if p.name.startswith(".preprocess")]


def test_bad_nan_only_trial(tmp_path, cli):
    parts = walking_trial("W1")
    for p in parts:
        p[["x", "y", "z"]] = np.nan
    _bad(tmp_path, cli, parts, [trials_row("W1")], "trial W1: every pelvis and table marker sample is NaN")


def test_bad_empty_trial(tmp_path, cli):
    _bad(tmp_path, cli, walking_trial("W1"), [trials_row("W1"), trials_row("W2")], "trial W2 has no pelvis or table marker samples")


def test_bad_all_nan_marker(tmp_path, cli):
    parts = walking_trial("W1")
    parts[2][["x", "y", "z"]] = np.nan
    _bad(tmp_path, cli, parts, [trials_row("W1")], "marker LPSI of walker is NaN in every frame")


def test_bad_missing_pelvis_markers(tmp_path, cli):
    _bad(tmp_path, cli, walking_trial("W1")[:2], [trials_row("W1")], "walker lacks markers ['LPSI', 'RPSI']")


def test_bad_units_in_millimetres(tmp_path, cli):
    parts = walking_trial("W1")
    for p in parts:
        p[["x", "y", "z"]] *= 1000
    _bad(tmp_path, cli, parts, [trials_row("W1")], "looks like millimetres")


def test_bad_no_walk_and_wrong_number_of_carriages(tmp_path, cli):
    _bad(tmp_path, cli, walking_trial("W1", length=0.0), [trials_row("W1")],
         "trial W1: nobody walks (static recording?): the pelvis CoM stays within 0.000 m over 5 s, top speed 0.00 m/s")


def test_bad_pair_recording_with_one_carriage(tmp_path, cli):
    parts = pair_recording("P1")
    for p in parts:
        if p["entity"].iloc[0] == "table":
            p.loc[p["frame"] > 2200, "z"] = 0.77  # the return is never lifted
    _bad(tmp_path, cli, parts, [trials_row("P1")], "found 1 table carriages")


def _table(parts, change):
    """``change(marker rows)`` applied to each table corner of a recording's parts."""
    for p in parts:
        if p["entity"].iloc[0] == "table":
            change(p)
    return parts


def _regrip(p):
    """The table set down for 0.5 s (5.5-6.0 s) in the middle of the forward carriage, then lifted again."""
    t = p["time"].to_numpy()
    p["z"] -= 0.15 * (_min_jerk(t, 5.5, 5.7) - _min_jerk(t, 5.8, 6.0))


def test_a_forward_carriage_set_down_to_regrip_is_no_return(tmp_path, cli):
    """The recording stops before the return: the two lifts of the forward carriage were a forward and a
    'return' to the goal (scenario 3, its end orientation measured) without a word."""
    parts = [p[p["frame"] < 11 * RATE].copy() for p in _table(pair_recording("P1"), _regrip)]
    _bad(tmp_path, cli, parts, [trials_row("P1", pair="P01", scenario=1)],
         "trial P1: the second table carriage (5.8-8.9 s) ends 3.00 m from where the first (3.1-5.7 s) started and "
         "1.83 m from where it ended: it does not carry the table back to the start")
    ws = tmp_path / "ws2"  # the remedy: one forward carriage, its two lifts joined
    write_workspace(ws, parts, [trials_row("P1", pair="P01", scenario=1, direction="forward")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--min-set-down", "0.2")
    assert code == 0, err
    table = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES).query("entity == 'table'")
    assert set(table["trial"]) == {"P1_forward"} and table["travel_time"].iloc[0] == pytest.approx(5.87, abs=0.01)


def test_a_regrip_is_named_and_min_set_down_joins_the_lifts(tmp_path, cli):
    parts = _table(pair_recording("P1"), _regrip)
    _bad(tmp_path, cli, parts, [trials_row("P1", pair="P01", scenario=1)],
         "found 3 table carriages (3.1-5.7 s, 5.8-8.9 s, 12.1-17.9 s; set down 0.17 s, 3.13 s between them)")
    ws = tmp_path / "ws"
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert "join the lifts with --min-set-down 0.2;" in err
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--min-set-down", "0.2")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    table = traj[traj["entity"] == "table"].groupby("trial")
    assert table["travel_time"].first().to_dict() == pytest.approx({"P1_forward": 5.87, "P1_return": 5.87}, abs=0.01)
    assert table["x"].last().to_dict() == pytest.approx({"P1_forward": 3.0, "P1_return": 0.0}, abs=1e-3)


@pytest.mark.parametrize("row, expected", [
    (dict(configuration="gris", end_orientation=np.pi),
     "trial P1: end_orientation 3.142 rad in the trials table, but the table ended its forward carriage at 0.000 rad "
     "(the direction TAB1 -> TAB2), a half turn off"),
    (dict(configuration="gris", end_orientation=-np.pi / 2),
     "a quarter turn off"),
    (dict(configuration="gris", end_orientation=15.0), "(degrees?)"),
    (dict(configuration="jaune", end_orientation=0.0),
     "trial P1: end_orientation 0.000 rad is no end orientation of configuration jaune (1.571 or -1.571 rad)"),
])
def test_end_orientation_contradicting_the_table_or_its_configuration(tmp_path, cli, row, expected):
    """The table ends its forward carriage at 0 rad: a declared end half or a quarter turn off (or in degrees), or
    one that is no orientation of its configuration family, grouped the trial by a configuration it did not end in."""
    _bad(tmp_path, cli, pair_recording("P1"), [trials_row("P1", pair="P01", scenario=1, **row)], expected)


def _turned(parts, angle):
    """The recording turned by ``angle`` about the vertical through the origin (the table ends its forward carriage at
    ``angle`` rad)."""
    c, s = np.cos(angle), np.sin(angle)
    return [q.assign(x=c * q["x"] - s * q["y"], y=s * q["x"] + c * q["y"]) for q in parts]


def test_a_forward_carriage_without_end_orientation_takes_the_measured_one(tmp_path, cli):
    """Returns took the measured end orientation; a forward carriage without one was refused by average ("no
    'end_orientation' value"). It now takes the table's orientation at its end, snapped to the nearer of its
    configuration's two (as returns are), flagged end_orientation_measured: P1 ends at 0.05 rad (gris: 0), P2 at
    pi - 0.3 (gris: pi)."""
    ws = tmp_path / "ws"
    parts = _turned(pair_recording("P1"), 0.05) + [q.assign(x=q["x"] + 20) for q in _turned(pair_recording("P2"), np.pi - 0.3)]
    rows = [trials_row(t, pair=f"P0{i + 1}", scenario=1, configuration="gris", condition="d1_p4_gris") for i, t in enumerate(("P1", "P2"))]
    write_workspace(ws, parts, rows)
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 0, err
    per = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES).drop_duplicates(["trial", "entity"])
    fwd = per[per["direction"] == "forward"].set_index(["trial", "entity"])
    assert fwd["end_orientation"].to_dict() == {(t, e): v for t, v in (("P1_forward", 0.0), ("P2_forward", np.pi))
                                                for e in ("table", "subject1", "subject2")}
    assert fwd["quality"].str.contains("end_orientation_measured").all()
    assert not per.loc[per["direction"] == "return", "quality"].str.contains("end_orientation_measured").any()
    text = " ".join((ws / "preprocess" / "results.md").read_text().split())
    assert ("2 forward carriages had no end_orientation in the trials table: each took the table's orientation at its "
            "end, snapped to the nearer of its configuration's two (flagged `end_orientation_measured`; at most 0.300 rad "
            "from it, refused beyond 0.785)") in text
    code, _, err = cli("average", "--out", ws)
    assert code == 0, err


def test_a_forward_carriage_without_end_orientation_between_its_configurations_is_refused(tmp_path, cli):
    """Ending at 0 rad, a jaune trial (pi/2 or -pi/2) is a quarter turn from both: no orientation to take."""
    _bad(tmp_path, cli, pair_recording("P1"), [trials_row("P1", pair="P01", scenario=1, configuration="jaune")],
         "trial P1: no end_orientation in the trials table, and the table ended its forward carriage at 0.000 rad, "
         "1.571 rad from both orientations of configuration jaune (1.571 or -1.571 rad); write the orientation the "
         "table ended in (radians, TAB1 -> TAB2) as its end_orientation in the trials table, or correct its "
         "configuration (gris ends at 0.000), and re-import")


def _swap_subjects(parts):
    """The recording's Subject 1 and Subject 2 labels swapped (the other pair member's labels)."""
    swap = {"subject1": "subject2", "subject2": "subject1"}
    return [p.assign(entity=swap.get(p["entity"].iloc[0], p["entity"].iloc[0])) for p in parts]


def test_subjects_swapped_in_one_recording_are_refused(tmp_path, cli):
    """Subject 1 holds the TAB2 end of the table in P1 and P2, the TAB1 end in P3: its S1 and S2 are swapped, and
    its scenario 1 (Subject 1 leads) was Subject 2 leading, pooled with the others without a word."""
    ws = tmp_path / "ws"
    parts = pair_recording("P1") + pair_recording("P2") + _swap_subjects(pair_recording("P3"))
    write_workspace(ws, parts, [trials_row(t, pair="P01", scenario=1) for t in ("P1", "P2", "P3")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 3, err
    assert ("P3 (P3.c3d): Subject 1 holds the TAB1 end of the table, Subject 2 the TAB2 end, the other way round "
            "in 2 other pair recordings: S1 and S2 swapped in this file?") in err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert sorted(set(traj["trial"])) == ["P1_forward", "P1_return", "P2_forward", "P2_return"]
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--strict", "--force")
    assert code == 2 and "P3" in err and "P1" not in err.replace("P1.c3d", "")
    # one recording each way: which is right cannot be told, both are refused; an unknown end (0) is no vote
    tie = pairs.swapped_subjects([("A", "a.c3d", 1), ("B", "b.c3d", -1), ("C", "c.c3d", 0)])
    assert [r.trial for r in tie] == ["A", "B"] and "which is right cannot be told" in tie[0].reason


def test_a_table_already_lifted_in_the_floor_window_is_refused(tmp_path, cli):
    """The recording starts with the table held 8 cm up, then lifted to 15 cm for the forward carriage: the floor
    level was measured on the lifted table, and the forward carriage began at the second lift (3 s), not before the
    recording, without a word."""
    def held(p):
        p["z"] += 0.08 * (1 - _min_jerk(p["time"].to_numpy(), 3.0, 3.4))
    _bad(tmp_path, cli, _table(pair_recording("P1"), held), [trials_row("P1", pair="P01", scenario=1)],
         "trial P1: the table rests at 0.770 m at 8.8-12.2 s, 0.080 m below the floor level measured over the first "
         "0.5 s (0.850 m): it was lifted when the recording started, and its first carriage is cut off")


def test_a_table_carried_back_without_a_set_down_is_one_carriage_and_refused(tmp_path, cli):
    """No set-down at the goal: one carriage there and back, which cannot be split into forward and return."""
    def no_set_down(p):
        t = p["time"].to_numpy()
        p["z"] += 0.15 * (_min_jerk(t, 8.6, 9.0) - _min_jerk(t, 12.0, 12.4))
    _bad(tmp_path, cli, _table(pair_recording("P1"), no_set_down), [trials_row("P1", pair="P01", scenario=1)],
         "trial P1: found 1 table carriages (3.1-17.9 s), height above the floor level 0.770 m + 5 mm for 0.5 s; "
         "expected 2 (forward, return); if the file holds one carriage, give its direction (forward or return) in the "
         "trials table; if the table was carried back without being set down, its carriages cannot be told apart: "
         "leave the trial out")


@pytest.mark.parametrize("row, expected", [
    (dict(direction="Return"), "trial P1: direction 'Return' is neither 'forward' nor 'return'"),
    (dict(direction="forward", configuration="Gris"), "trial P1: configuration 'Gris' is neither 'gris' nor 'jaune'"),
    (dict(direction="forward", scenario=4), "trial P1: scenario 4 is not 1 (Subject 1 knows the goal), 2 (Subject 2) or 3 (both)"),
])
def test_pair_labels_outside_the_protocol_are_refused(tmp_path, cli, row, expected):
    """A direction 'Return' was a direction of its own (its scenario not set to 3, its end not measured), a scenario 4
    a scenario of its own, and a configuration 'Gris' no family: its returns, grouped by their measured end
    orientation instead of the configuration, made one mean each, without a word."""
    def one_carriage(p):
        p.loc[p["time"] > 10.0, "z"] = 0.77
    _bad(tmp_path, cli, _table(pair_recording("P1"), one_carriage), [trials_row("P1", pair="P01", **{"scenario": 1, **row})],
         expected)


def test_floor_level_from_the_first_seconds_the_table_is_seen():
    """The table unseen for the first second of the recording: the floor level is measured when it is first seen
    (before: NaN, and no carriage found)."""
    t, h = _lift_profile()
    h[t < 1.0] = np.nan
    found, h0 = segmentation.carriages(h, RATE, threshold=0.005)
    assert h0 == pytest.approx(0.77) and len(found) == 2


def test_a_file_with_a_direction_holding_both_carriages_is_told_to_leave_it_empty(tmp_path, cli):
    _bad(tmp_path, cli, pair_recording("P1"), [trials_row("P1", pair="P01", scenario=1, direction="forward")],
         "expected 1 (forward); if the file holds a forward and a return carriage, leave its direction empty in the "
         "trials table;")


def test_bad_markers_of_a_trial_not_in_trials(tmp_path, cli):
    _bad(tmp_path, cli, walking_trial("W1") + walking_trial("W9"), [trials_row("W1")], "marker rows of trials ['W9']")


@pytest.mark.parametrize("content", [b"PAR1 garbage", None])
def test_bad_corrupt_or_foreign_markers_file(tmp_path, cli, content):
    ws = tmp_path / "ws"
    write_workspace(ws, walking_trial("W1"), [trials_row("W1")])
    target = ws / "import" / "markers.parquet"
    if content is None:
        pd.DataFrame({"a": [1]}).to_parquet(target)  # a Parquet file, but not a markers table
    else:
        target.write_bytes(content)
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 2 and "markers.parquet" in err
    assert ("not a readable Parquet" if content else "has no cobot-analysis table metadata") in err
    assert not (ws / "preprocess").exists()


@pytest.mark.parametrize("args, expected", [(["--cutoff", "150"], "Nyquist"), (["--cutoff", "0"], "--cutoff 0.0 is not a finite number > 0"),
                                            (["--order", "3", "--order-convention", "effective"], "even order")])
def test_bad_filter_parameters_exit_2(tmp_path, cli, args, expected):
    ws = tmp_path / "ws"
    write_workspace(ws, walking_trial("W1"), [trials_row("W1")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", *args)
    assert code == 2 and expected in err and "--cutoff" in err
    assert not (ws / "preprocess").exists()


def test_missing_import_stage(tmp_path, cli):
    code, _, err = cli("preprocess", "--out", tmp_path / "ws")
    assert code == 2 and "no markers.parquet in the workspace" in err and "--markers" in err


# ---- issue #11: sacrum pelvis, truncated walks, every bad recording named, real files ------------
def test_sacrum_pelvis_gives_the_four_marker_barycentre(tmp_path, cli):
    """LASI RASI + SACR at the PSIS midpoint: same CoM and theta as the 4-marker pelvis; the markers used are named."""
    ws = tmp_path / "ws"
    four = walking_trial("W1")
    sacr = walking_trial("W2")
    lpsi, rpsi = sacr[2], sacr[3]
    mid = lpsi.copy()
    mid["marker"] = "SACR"
    mid[["x", "y", "z"]] = (lpsi[["x", "y", "z"]].to_numpy() + rpsi[["x", "y", "z"]].to_numpy()) / 2
    write_workspace(ws, four + sacr[:2] + [mid], [trials_row("W1"), trials_row("W2")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--samples", "101")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    a, b = (traj[traj["trial"] == t].sort_values("sample") for t in ("W1", "W2"))
    assert a["pelvis_markers"].iloc[0] == "LASI,RASI,LPSI,RPSI" and b["pelvis_markers"].iloc[0] == "LASI,RASI,SACR"
    np.testing.assert_allclose(b[["x", "y", "theta", "gamma", "travel_time"]], a[["x", "y", "theta", "gamma", "travel_time"]], atol=1e-9)
    assert (b["quality"] == "ok").all()
    results = (ws / "preprocess" / "results.md").read_text()
    assert "| LASI RASI SACR | 1 |" in results and "| LASI RASI LPSI RPSI | 1 |" in results


def test_sacrum_pelvis_gap_leaves_the_position_missing():
    """c = (LASI + RASI + 2 SACR) / 4; where one of the three is missing nothing is reconstructed."""
    from cobot_analysis import kinematics as kin

    lasi, rasi, sacr = (np.array([[0.0, 0.12, 1.0], [1.0, 0.12, 1.0]]), np.array([[0.0, -0.12, 1.0], [1.0, -0.12, 1.0]]),
                        np.array([[-0.16, 0.0, 1.0], [np.nan, np.nan, np.nan]]))
    xy, rigid = kin.sacrum_pelvis_com(lasi, rasi, sacr)
    np.testing.assert_allclose(xy[0], [-0.08, 0.0])
    assert np.isnan(xy[1]).all() and not rigid.any()


@pytest.mark.parametrize("start, hidden, label", [(-1.0, None, "walking at the first frame"),
                                                 (1.0, (0, 500), "markers unseen until mid-walk")])
def test_walk_running_off_the_recording_is_flagged_truncated(tmp_path, cli, start, hidden, label):
    ws = tmp_path / "ws"
    parts = walking_trial("W1", start=start, stop=start + 3.0)
    if hidden:
        for p in parts:
            p.loc[hidden[0]:hidden[1] - 1, ["x", "y", "z"]] = np.nan
            p.loc[hidden[0]:hidden[1] - 1, "occluded"] = True
    parts += walking_trial("W2")  # rests before and after: not truncated
    write_workspace(ws, parts, [trials_row("W1"), trials_row("W2")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--samples", "101")
    assert code == 0, err
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    w1, w2 = (traj[traj["trial"] == t].iloc[0] for t in ("W1", "W2"))
    assert "truncated" in w1["quality"].split(";"), label
    assert "truncated" not in w2["quality"].split(";")
    assert w1["record_time"] == pytest.approx(0.0 if hidden is None else 2.5, abs=0.01)
    results = (ws / "preprocess" / "results.md").read_text()
    assert "| truncated | 1 |" in results and "1 trajectories are `truncated`: they run off the start or end" in results


def test_cut_off_at_the_edges_and_next_to_missing_samples():
    s = np.array([np.nan, 0.5, 1.0, 0.02, 0.0, 0.3, 0.3])
    assert segmentation.cut_off(s, 1, 2)  # after a missing sample
    assert not segmentation.cut_off(s, 2, 2) and segmentation.cut_off(s, 5, 6)  # ends at the last sample
    assert not segmentation.cut_off(s, 5, 6, end=False)
    assert segmentation.cut_off(s[1:], 0, 1)  # starts at the first sample


def test_bad_recordings_are_skipped_and_listed_or_named_in_one_error_with_strict(tmp_path, cli):
    ws = tmp_path / "ws"
    parts = walking_trial("W1") + walking_trial("W2", length=0.0) + walking_trial("W3")[:3]
    write_workspace(ws, parts, [trials_row("W1"), trials_row("W2"), trials_row("W3")])
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1", "--strict")
    assert code == 2
    line = " ".join(err.split())
    assert "2 of 3 trials refused (--strict), nothing written: W2 (" in line and "): nobody walks" in line
    assert "W3 (" in line and "): walker lacks markers ['RPSI'] (or SACR instead of LPSI and RPSI)" in line
    assert not (ws / "preprocess").exists()
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "2")
    assert code == 3, err
    text = " ".join(err.split())
    assert "preprocess: 2 of 3 trials refused and left out, the other 1 went on" in text and "W2 (" in text
    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert set(traj["trial"]) == {"W1"}
    results = (ws / "preprocess" / "results.md").read_text()
    assert "Refused and left out: 2 of 3 trials" in results and "| W2 |" in results and "| W3 |" in results


@pytest.mark.parametrize("value, expected", [(np.inf, "trial W1: infinite marker coordinates: walker:RASI (frame 300"),
                                             (-1e30, "trial W1: implausible marker positions, up to 1e+30 m"),
                                             (0.5, "trial W1: implausible jump of marker walker:RASI: ")])
def test_implausible_values_reaching_preprocess(tmp_path, cli, value, expected):
    parts = walking_trial("W1")
    parts[1].loc[300, "y"] = value
    _bad(tmp_path, cli, parts, [trials_row("W1")], expected)


def test_realdata_walks(realdata, tmp_path, cli):
    """Gait-lab walks cross the capture volume: flagged truncated; Gait.c3d's pelvis is LASI RASI VSAC."""
    expected = {"FunctionalWalk": ("LASI,RASI,LPSI,RPSI", 438 / 120), "PiG_Motion-FlatFoot-Full": ("LASI,RASI,LPSI,RPSI", 3.14),
                "Gait": ("LASI,RASI,SACR", 1.91)}
    for name, (pelvis_markers, travel_time) in expected.items():
        ws = tmp_path / name
        proto = tmp_path / f"{name}.yaml"
        proto.write_text(f"study: realdata\nallow_outside: true\ntrials:\n  - {{trial: t1, file: {realdata / 'c3d' / name}.c3d, condition: c1}}\n")
        assert cli("import", proto, "--out", ws, "--jobs", "1")[0] == 0
        code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
        assert code == 0, err
        first = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES).iloc[0]
        assert first["pelvis_markers"] == pelvis_markers and "truncated" in first["quality"].split(";")
        assert first["travel_time"] <= travel_time + 1e-9 and first["travelled_distance"] > 2.5


def test_realdata_static_recording_is_reported_as_such(realdata, tmp_path, cli):
    proto = tmp_path / "static.yaml"
    proto.write_text(f"study: realdata\nallow_outside: true\ntrials:\n  - {{trial: static, file: {realdata / 'c3d/pyomeca_markers_analogs.c3d'}, condition: c1}}\n"
                     "marker_map: {'Daphnee:ASISr': RASI, 'Daphnee:ASISl': LASI, 'Daphnee:PSISr': RPSI, 'Daphnee:PSISl': LPSI}\n")
    assert cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1")[0] == 0
    code, _, err = cli("preprocess", "--out", tmp_path / "ws", "--jobs", "1")
    line = " ".join(err.split())  # the only trial: the run is refused, naming the raw file and the remedy once
    assert code == 2 and "pyomeca_markers_analogs.c3d: trial static: nobody walks (static recording?)" in line
    assert "markers.parquet" not in line and line.count("leave it out") == 1


def test_the_api_summary_says_which_recordings_were_refused(tmp_path):
    """With skip_bad (the default) the refused recordings are left out: the result's summary said only "1 trajectories
    from 1 recordings", so a notebook user did not see that 2 of 3 were refused (the command line lists them)."""
    from cobot_analysis.api import preprocess

    ws = tmp_path / "ws"
    parts = walking_trial("W1") + walking_trial("W2", length=0.0) + walking_trial("W3")[:3]
    write_workspace(ws, parts, [trials_row("W1"), trials_row("W2"), trials_row("W3")])
    result = preprocess(ws / "import" / "markers.parquet", jobs=1)
    assert result.summary() == "1 trajectories from 1 recordings, 2 recordings refused and left out (why: .refused)"
    assert sorted(r.trial for r in result.refused) == ["W2", "W3"]
