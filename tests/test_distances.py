"""Distances, derived quantities and comparisons (docs/methods.md sec. 3): analytic cases and invariants."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from cobot_analysis import distances
from cobot_analysis.angles import angle_diff, circular_mean, circular_std
from cobot_analysis.averaging import mean_trajectories
from cobot_analysis.compare import any_vs_any, compare_sets, individual_vs_mean, pivot

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import pair_table, walking_table  # noqa: E402

N = 12
coords = arrays(np.float64, (3, N), elements=st.floats(-5, 5, allow_nan=False))
angles = arrays(np.float64, (2, N), elements=st.floats(-10, 10, allow_nan=False))


def test_analytic_distances():
    x = np.linspace(0, 1, 5)
    assert distances.d_xy(x, 0 * x, x, 0 * x + 0.3) == pytest.approx(0.3)
    assert distances.d_xy(x, 0 * x, x + 3, 0 * x + 4) == pytest.approx(5.0)
    # wrapping: 3.1 and -3.1 are 0.083 rad apart, not 6.2
    assert distances.d_theta(np.full(4, 3.1), np.full(4, -3.1)) == pytest.approx(2 * math.pi - 6.2)
    g1, g2 = np.array([0.1, 0.1, 0.1, 9.0]), np.zeros(4)
    assert distances.d_gamma(g1, g2) == pytest.approx(0.1)  # last sample left out, 1/(N-1)


@settings(max_examples=40, deadline=None)
@given(coords, coords)
def test_d_xy_symmetric_zero_and_triangle(a, b):
    c = (a + b) / 2 + 1.0
    ab = distances.d_xy(a[0], a[1], b[0], b[1])
    assert ab == pytest.approx(distances.d_xy(b[0], b[1], a[0], a[1]))
    assert distances.d_xy(a[0], a[1], a[0], a[1]) == 0.0
    assert ab <= distances.d_xy(a[0], a[1], c[0], c[1]) + distances.d_xy(c[0], c[1], b[0], b[1]) + 1e-9


@settings(max_examples=40, deadline=None)
@given(coords, coords, st.floats(-math.pi, math.pi), st.floats(-3, 3), st.floats(-3, 3))
def test_distances_invariant_to_common_rigid_motion(a, b, phi, tx, ty):
    c, s = math.cos(phi), math.sin(phi)
    a, b = a.copy(), b.copy()
    a[0] += 11.0 * np.arange(N)  # steps of at least 1 m (x in [-5, 5]): the heading of a step must be defined for gamma

    def move(p):
        return c * p[0] - s * p[1] + tx, s * p[0] + c * p[1] + ty, p[2] + phi

    ma, mb = move(a), move(b)
    assert distances.d_xy(ma[0], ma[1], mb[0], mb[1]) == pytest.approx(distances.d_xy(a[0], a[1], b[0], b[1]), abs=1e-9)
    assert distances.d_theta(ma[2], mb[2]) == pytest.approx(distances.d_theta(a[2], b[2]), abs=1e-9)
    # gamma of a generated path is frame independent
    np.testing.assert_allclose(distances.angle_diff(distances.gamma_from_path(*ma), distances.gamma_from_path(*a)), 0, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(angles)
def test_angular_distances_symmetric_zero_bounded(t):
    assert distances.d_theta(t[0], t[1]) == pytest.approx(distances.d_theta(t[1], t[0]))
    assert distances.d_theta(t[0], t[0]) == 0.0
    assert distances.d_theta(t[0], t[0] + 2 * math.pi * 3) == pytest.approx(0.0, abs=1e-9)
    assert 0 <= distances.d_gamma(t[0], t[1]) <= math.pi + 1e-12


def test_pair_distances_match_one_by_one_calls():
    rng = np.random.default_rng(1)
    a = {k: rng.normal(size=(5, N)) for k in ("x", "y", "theta", "gamma")}
    b = {k: rng.normal(size=(4, N)) for k in ("x", "y", "theta", "gamma")}
    ia, ib = np.array([0, 4, 2, 2]), np.array([3, 0, 1, 1])
    out = distances.pair_distances(a, b, ia, ib)
    for j, (i, k) in enumerate(zip(ia, ib)):
        assert out["d_xy"][j] == pytest.approx(distances.d_xy(a["x"][i], a["y"][i], b["x"][k], b["y"][k]))
        assert out["d_theta"][j] == pytest.approx(distances.d_theta(a["theta"][i], b["theta"][k]))
        assert out["d_gamma"][j] == pytest.approx(distances.d_gamma(a["gamma"][i], b["gamma"][k]))


def test_symmetry_travelled_distance_and_optimal_configuration():
    s = np.linspace(0, 1, N)
    x, y, th = 3 * s, 4 * s, np.full(N, 0.5)
    assert distances.travelled_distance(x, y) == pytest.approx(5.0)
    assert distances.path_length(x, y) == pytest.approx(5.0)
    rev = distances.reverse_time  # symmetry: the forward path against the time-reversed return (compare.forward_vs_return)
    assert distances.d_xy(x, y, rev(x[::-1]), rev(y[::-1])) == pytest.approx(0)  # return = exact reverse
    assert distances.d_theta(th, rev(th[::-1])) == pytest.approx(0)
    assert distances.d_xy(x, y, rev(x[::-1] + 0.2), rev(y[::-1])) == pytest.approx(0.2)
    assert distances.optimal_configurations({0.0: 4.0, 3.14: 5.0}) == {0.0}
    assert distances.optimal_configurations({0.0: 4.0, 3.14: 4.03}) == {0.0, 3.14}  # tie within 5 cm
    assert distances.optimal_configurations({0.0: float("nan")}) == set()


def test_means_recover_common_path_and_circular_angles():
    df = walking_table(seed=3, n_subjects=4, n_conditions=2, n_trials=2, missing_theta=0.0)
    ts = pivot(df)
    means = mean_trajectories(ts)
    assert means["trial"].nunique() == 2 and set(means["n_trials"]) == {8}
    m = pivot(means)
    first = ts.subset(ts.meta["condition"].eq(ts.meta["condition"].iloc[0]).to_numpy())
    np.testing.assert_allclose(m.x[0], first.x.mean(axis=0))
    # angles straddling +-pi average to pi, not 0
    ts.theta[:] = np.where(np.arange(len(ts))[:, None] % 2 == 0, math.pi - 0.1, -math.pi + 0.1)
    th = pivot(mean_trajectories(ts)).theta
    np.testing.assert_allclose(np.abs(distances.angle_diff(th, math.pi)), 0, atol=1e-9)
    assert (means["x_hi"] >= means["x_lo"]).all()
    ref = circular_mean(first.theta, axis=0)
    np.testing.assert_allclose(angle_diff(m.theta[0], ref), 0, atol=1e-12)
    np.testing.assert_allclose(means["theta_sd"].to_numpy()[:first.n_samples], circular_std(first.theta, axis=0), atol=1e-9)
    np.testing.assert_allclose(means["x_sd"].to_numpy()[:first.n_samples], first.x.std(axis=0, ddof=1), atol=1e-12)


def test_orientation_missing_trials_excluded_from_angle_mean_only():
    df = walking_table(seed=4, n_subjects=3, n_conditions=1, n_trials=3, missing_theta=0.5)
    ts = pivot(df)
    has = np.isfinite(ts.theta).all(axis=1)
    assert 0 < has.sum() < len(ts)
    means = mean_trajectories(ts)
    assert means["n_trials"].iloc[0] == len(ts) and means["n_theta"].iloc[0] == has.sum()
    d = individual_vs_mean(ts, pivot(means))
    assert d["d_xy"].notna().all() and d["d_theta"].isna().sum() == (~has).sum()


def test_compare_pairs_and_symmetry_on_planted_table():
    df = pair_table(seed=0, n_pairs=2, goals=2, n=N)
    ts = pivot(df)
    d = compare_sets(ts, pivot(mean_trajectories(ts)))
    counts = d["comparison"].value_counts()
    assert counts["individual-mean"] == len(ts)  # 2 pairs x 2 goals x 3 scenarios x 2 directions x 3 entities
    assert counts["symmetry"] == len(ts) // 2  # one forward/return pair per recording and entity
    sym = d[d["comparison"].eq("symmetry")]
    assert (sym["b_direction"] == "return").all() and (sym["direction"] == "forward").all()
    table = sym[sym["entity"].eq("table")]["d_xy"]
    assert table.max() < sym[sym["entity"].ne("table")]["d_xy"].median()  # planted: table paths nearly symmetric
    pairs = any_vs_any(ts, same=["study", "condition", "entity"])
    n = len(ts) // (2 * 3)  # trajectories per goal and entity
    assert len(pairs) == 2 * 3 * n * (n - 1) // 2
