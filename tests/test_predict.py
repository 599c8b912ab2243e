"""Prediction (docs/methods.md sec. 7): metrics by hand, baselines exact where they must be, the OC
predictor on its own model, step-by-step == offline, warm == cold starts."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_analysis.errors import InputError
from cobot_analysis.models.prediction.predictor import OCPredictor, make_predictor
from cobot_analysis.models.prediction.errors import summarise, truth_windows, window_errors


# ---- metrics ----------------------------------------------------------------------------------
def _ten_samples():
    """x_i = i, y = 0, theta = 0 (N = 10); N0 = 3, N_OC = 5 (H = 2): windows k = 2..9.
    Prediction of window k for sample k + j: x = k + j + 0.1 j, theta = 0.05 j."""
    poses = np.c_[np.arange(10.0), np.zeros(10), np.zeros(10)]
    k = np.arange(2, 10)[:, None]
    j = np.arange(3)[None, :]
    pred = np.stack([k + j + 0.1 * j, 0.0 * (k + j), 0.05 * j + 0.0 * k], axis=-1)
    return poses, pred


def test_metrics_match_hand_computation_on_ten_samples():
    poses, pred = _ten_samples()
    err = window_errors(poses, pred, n0=3)
    # N_k = min(k + 2, 9) - k + 1 = 3 for k = 2..7, 2 for k = 8, 1 for k = 9; error at j = 0.1 j
    np.testing.assert_allclose(err.error_xy, [0.1] * 6 + [0.05, 0.0])
    m = summarise(err)
    assert m.delta_xy == pytest.approx((6 * 0.1 + 0.05 + 0.0) / 8)  # 0.08125
    assert m.delta_theta == pytest.approx((6 * 0.05 + 0.025 + 0.0) / 8)  # 0.040625
    assert m.d_pred == pytest.approx(2.2)  # ||x*_k - x*_{k+2}|| = 2 + 0.2
    assert m.ade == pytest.approx(0.15)  # full horizons k = 2..7: mean of 0.1 and 0.2
    assert m.fde == pytest.approx(0.2)
    assert (m.n_windows, m.n_used, m.n_full) == (8, 8, 6)


def test_skipped_windows_are_left_out_and_counted():
    poses, pred = _ten_samples()
    pred[0] = np.nan  # window k = 2 skipped
    m = summarise(window_errors(poses, pred, n0=3))
    assert m.n_used == 7 and m.n_full == 5
    assert m.delta_xy == pytest.approx((5 * 0.1 + 0.05) / 7)


def test_truth_windows_pad_past_the_end():
    poses = np.c_[np.arange(6.0), np.zeros(6), np.zeros(6)]
    t = truth_windows(poses, n0=2, horizon=3)
    assert t.shape == (5, 4, 3)
    np.testing.assert_array_equal(t[0, :, 0], [1, 2, 3, 4])
    np.testing.assert_array_equal(t[-1, :, 0], [5, np.nan, np.nan, np.nan])


def test_angle_errors_are_wrapped():
    poses = np.c_[np.zeros(4), np.zeros(4), np.full(4, np.pi - 0.01)]
    pred = np.zeros((3, 2, 3))
    pred[..., 2] = -np.pi + 0.01  # 0.02 rad away across the cut
    assert summarise(window_errors(poses, pred, n0=2)).delta_theta == pytest.approx(0.02)


# ---- baselines --------------------------------------------------------------------------------
@settings(max_examples=30, deadline=None)
@given(x0=st.floats(-5, 5), y0=st.floats(-5, 5), speed=st.floats(0.0, 0.05), heading=st.floats(-np.pi, np.pi),
       th0=st.floats(-np.pi, np.pi), rate=st.floats(-0.05, 0.05))
def test_constant_velocity_is_exact_on_a_straight_constant_speed_path(x0, y0, speed, heading, th0, rate):
    i = np.arange(40.0)
    poses = np.c_[x0 + speed * i * np.cos(heading), y0 + speed * i * np.sin(heading), th0 + rate * i]
    m = summarise(window_errors(poses, make_predictor("cv", 5, 15).predict_offline(poses), 5))
    assert m.delta_xy < 1e-9 and m.delta_theta < 1e-9 and m.fde < 1e-9
    assert m.d_pred == pytest.approx(10 * speed, abs=1e-9)


@settings(max_examples=30, deadline=None)
@given(radius=st.floats(0.3, 10), step=st.floats(0.005, 0.05), turn=st.sampled_from([-1, 1]), phase=st.floats(-np.pi, np.pi))
def test_ctrv_is_exact_on_a_circle_at_constant_speed(radius, step, turn, phase):
    a = phase + turn * step * np.arange(60)
    poses = np.c_[radius * np.cos(a), radius * np.sin(a), a + turn * np.pi / 2]
    m = summarise(window_errors(poses, make_predictor("ctrv", 4, 20).predict_offline(poses), 4))
    assert m.delta_xy < 1e-9 * max(1, radius) and m.delta_theta < 1e-9
    cv = summarise(window_errors(poses, make_predictor("cv", 4, 20).predict_offline(poses), 4))
    assert cv.delta_xy > 1e3 * m.delta_xy  # the straight extrapolation leaves the circle


def test_baselines_offline_predict_every_window_at_once_bit_for_bit():
    """The baselines' offline path (all windows at once) gives the bits of ``predict`` window by window, on a
    path that stops (ctrv's w = 0 below STILL), turns across +-pi, loses theta and loses a position."""
    rng = np.random.default_rng(3)
    heading = np.pi - 0.3 + np.cumsum(rng.normal(0.02, 0.05, 80))  # crosses +pi
    step = np.r_[np.full(30, 0.02), np.zeros(10), np.full(40, 0.015)] * (1 + rng.normal(0, 0.1, 80))
    poses = np.c_[np.cumsum(step * np.cos(heading)), np.cumsum(step * np.sin(heading)), np.angle(np.exp(1j * heading))]
    poses[50, 2] = np.nan
    poses[60, 0] = np.nan
    for name in ("cv", "ctrv"):
        p = make_predictor(name, 6, 16)
        offline = p.predict_offline(poses)
        by_window = [p.predict(poses[w: w + 6].copy()) for w in range(len(poses) - 5)]
        expected = np.stack([np.full((11, 3), np.nan) if np.isnan(poses[w: w + 6, :2]).any() else P for w, P in enumerate(by_window)])
        assert p.skipped == 6 and np.isfinite(offline[:, :, :2]).sum() == (75 - 6) * 11 * 2
        np.testing.assert_array_equal(offline.view(np.int64), expected.view(np.int64))


def test_baselines_offline_are_exact_on_their_own_paths():
    """Every window's whole prediction at once: cv on a straight line at constant speed (x, y, theta linear in
    the sample), ctrv on a circle at a constant turn rate (the points of the circle, theta turning with them)."""
    i = np.arange(30.0)
    line = np.c_[1.0 + 0.03 * i, -2.0 + 0.04 * i, 0.5 + 0.01 * i]
    a = 0.4 + 0.05 * np.arange(30 + 10)
    circle = np.c_[2.0 * np.cos(a), 2.0 * np.sin(a), a + np.pi / 2]
    for name, poses, path in (("cv", line, np.c_[1.0 + 0.03 * np.arange(40), -2.0 + 0.04 * np.arange(40), 0.5 + 0.01 * np.arange(40)]),
                              ("ctrv", circle[:30], circle)):
        P = make_predictor(name, 5, 15).predict_offline(poses)  # H = 10: window k predicts samples k .. k + 10
        expected = np.stack([path[k: k + 11] for k in range(4, 30)])
        np.testing.assert_allclose(P, expected, rtol=0, atol=1e-12)


def test_baselines_do_not_need_orientation():
    i = np.arange(30.0)
    poses = np.c_[0.02 * i, 0.01 * i, np.full(30, np.nan)]
    for name in ("cv", "ctrv"):
        P = make_predictor(name, 5, 10).predict_offline(poses)
        assert np.isfinite(P[..., :2]).all() and np.isnan(P[..., 2]).all()


def test_unwrap_is_numpys_bit_for_bit():
    """predictor.unwrap skips np.unwrap's corrections where they are all zero: same bits, -0.0, steps of +-pi, NaN."""
    from cobot_analysis.models.prediction.predictor import unwrap

    below = np.nextafter(np.pi, 0)
    rng = np.random.default_rng(3)
    cases = [np.array([0.0, -0.0, -0.0, 1.0]), np.array([-0.0, -0.0]), np.array([0.0, np.pi, 0.0, -np.pi, 2 * np.pi]),
             np.array([1.0, np.nan, 2.0]), np.array([below, 0.0, -below, 0.0]), np.array([3.0]), np.array([])]
    cases += [rng.uniform(-np.pi, np.pi, rng.integers(1, 60)) * rng.choice([0.01, 0.5, 1.0, 3.0]) for _ in range(2000)]
    for a in cases:
        assert unwrap(a).view(np.int64).tolist() == np.unwrap(a).view(np.int64).tolist(), a
    assert np.signbit(unwrap(np.array([-0.0, -0.0]))).tolist() == [True, False]  # np.unwrap's zero correction kept


def test_bad_settings_are_input_errors():
    with pytest.raises(InputError, match="N_OC = 50 must be larger than N0 = 50"):
        make_predictor("cv", 50, 50)
    with pytest.raises(InputError, match="fewer than N0 = 25"):
        make_predictor("cv", 25, 100).predict_offline(np.zeros((20, 3)))
    with pytest.raises(InputError, match="unknown predictor 'kalman'"):
        make_predictor("kalman", 5, 10)
    with pytest.raises(InputError, match="unknown preset"):
        make_predictor("oc", 5, 10, weights="no-such-preset")


# ---- the OC predictor -------------------------------------------------------------------------
DT = 0.02


def model_path(n=90, v_forw=1.0, v_orth=0.2, omega=0.5, theta0=0.3):
    """A trajectory of the OC model itself: the holonomic walker with zero controls (the optimum of
    the free future for any weights), i.e. constant (v_forw, v_orth, omega), integrated exactly."""
    t = np.arange(n) * DT
    th = theta0 + omega * t
    x = (v_forw * np.sin(th) + v_orth * np.cos(th)) / omega
    y = (-v_forw * np.cos(th) + v_orth * np.sin(th)) / omega
    return np.c_[x - x[0], y - y[0], th]


def test_oc_predictor_error_is_near_zero_on_its_own_model():
    poses = model_path()
    oc = make_predictor("oc", 10, 30, DT, weights="walking-2021")
    m = summarise(window_errors(poses, oc.predict_offline(poses), 10))
    cv = summarise(window_errors(poses, make_predictor("cv", 10, 30, DT).predict_offline(poses), 10))
    assert oc.failed == 0 and m.n_used == 81
    assert m.delta_xy < 5e-4 and m.fde < 1e-3 and m.delta_theta < 1e-4  # mm-level over a 0.4 s horizon
    assert cv.delta_xy > 20 * m.delta_xy
    assert m.d_pred == pytest.approx(20 * DT * np.hypot(1.0, 0.2), rel=0.02)  # chord of a 0.4 s arc


def test_oc_predictor_tracks_positions_only_without_orientation():
    poses = model_path(v_orth=0.0)  # facing the direction of travel, as assumed without theta
    poses[:, 2] = np.nan
    oc = make_predictor("oc", 10, 30, DT)
    m = summarise(window_errors(poses, oc.predict_offline(poses), 10))
    assert oc.failed == 0 and m.delta_xy < 1e-3 and np.isnan(m.delta_theta)


def test_initial_state_estimates_the_velocity():
    poses = model_path()
    x0, has_theta = OCPredictor(10, 30, DT).initial_state(poses[:10])
    assert has_theta
    np.testing.assert_allclose(x0, [0, 0, 0.3, 1.0, 0.2, 0.5], atol=1e-3)


def test_step_by_step_equals_offline_and_warm_equals_cold():
    poses = model_path(n=60) + np.random.default_rng(1).normal(0, 0.003, (60, 3))
    poses[30] = np.nan  # skipped windows too
    results = {}
    for name in ("oc", "cv", "ctrv"):
        p = make_predictor(name, 8, 20, DT)
        offline = results[name] = p.predict_offline(poses)
        counts, after = (p.skipped, p.failed, p.n_seen), [q.copy() for q in p._past]
        p.reset()
        online = [p.update(pose) for pose in poses]
        assert all(o is None for o in online[:7])
        stacked = np.stack([np.full((13, 3), np.nan) if o is None else o for o in online[7:]])
        np.testing.assert_array_equal(stacked, offline)
        assert p.skipped == 8  # windows k = 30..37 hold sample 30 in their past
        assert (p.skipped, p.failed, p.n_seen) == counts  # offline leaves the online state of update in a loop
        np.testing.assert_array_equal(np.array(p._past), np.array(after))
    cold = OCPredictor(8, 20, DT, warm_start=False).predict_offline(poses)
    np.testing.assert_allclose(cold, results["oc"], atol=1e-6, equal_nan=True)


@pytest.mark.parametrize("convention", ["continuous", "published"])
def test_window_separates_into_past_solve_and_coast(convention):
    """The whole N_OC-node window (tracking on the first N0 nodes, free future) has the same optimum
    as the predictor's N0-node solve followed by the zero-control coast, under both conventions
    (published: Euler steps of 0.1 s, the window from rest at its first pose made the origin;
    continuous: the coast moved onto the state estimate at k)."""
    from cobot_analysis.models.oc.problem import OCPShape, get_ocp

    poses = model_path(n=40) + np.random.default_rng(3).normal(0, 0.01, (40, 3))  # noisy: controls are not zero
    n0, n_oc = 12, 30
    oc = OCPredictor(n0, n_oc, DT, convention=convention)
    past = poses[5:5 + n0]
    predicted = oc.predict(past)
    x0, _ = oc.initial_state(past)
    origin = np.r_[x0[:2], 0.0] if convention == "published" else np.zeros(3)
    shape, T = ((OCPShape(n_intervals=n_oc - 1, scheme="euler"), 0.1) if convention == "published"
                else (OCPShape(n_intervals=n_oc - 1), (n_oc - 1) * DT))
    whole = get_ocp(shape).solve(
        x0[:3] - origin, (x0[0] + 1e3, x0[1] + 1e3, 0.0), oc.weights, T, start_velocity=x0[3:], track=past - origin,
        track_weights=oc.track_weights, n_track=n0).check()
    assert np.abs(whole.U[n0 - 1:]).max() < 1e-5  # the future's optimal controls are zero
    assert np.abs(whole.U[: n0 - 1]).max() > 1e-2  # and the past's are not
    expected = whole.X[n0 - 1:, :3] + origin
    if convention == "continuous":  # the coast starts on the state estimate at k: the same arc, moved onto it
        from cobot_analysis.models.prediction.goal import quadratic_fit

        expected[:, :2] += quadratic_fit(5, DT)[0] @ past[-5:, :2] - expected[0, :2]
    np.testing.assert_allclose(predicted, expected, atol=1e-6)


# ---- the published convention -----------------------------------------------------------------
def straight_walk_by_hand(n0: int, n_oc: int, s: float, a0: float, a1: float, g0: float, dt: float = 0.1):
    """The published window on x_i = s i (theta = 0) solved by hand: from rest, Euler steps of dt,
    x_{k+1} = x_k + dt v_k, v_{k+1} = v_k + dt u_k, so x = M u with M[k, m] = dt^2 (k - 1 - m) for
    m <= k - 2; the cost (N0 - 1) a0 + a1 |u|^2 + g0 |c - M u|^2 is least at
    u* = (a1 I + g0 M'M)^-1 g0 M'c. Returns (prediction x_{k+j}, j = 0..H, cost)."""
    k, m = np.meshgrid(np.arange(n0), np.arange(n0 - 1), indexing="ij")
    M = np.where(m <= k - 2, dt**2 * (k - 1 - m), 0.0)
    c = s * np.arange(n0)
    u = np.linalg.solve(a1 * np.eye(n0 - 1) + g0 * M.T @ M, g0 * M.T @ c)
    x_last, v_last = (M @ u)[-1], dt * u.sum()
    cost = (n0 - 1) * a0 + a1 * u @ u + g0 * np.sum((c - M @ u) ** 2)
    return x_last + v_last * dt * np.arange(n_oc - n0 + 1), cost


def test_published_predictor_on_a_straight_walk_matches_the_hand_solution():
    """A straight walk at 0.02 m per sample: the published window starts at rest, so its last node
    lags the walk and its speed falls short of 0.2 m/s; the prediction is the hand-solved LQ problem
    (``straight_walk_by_hand``) whatever the real sample period. The continuous predictor, started
    at the estimated velocity, is exact on it."""
    n0, n_oc, s = 10, 30, 0.02
    poses = np.c_[1.0 + s * np.arange(60), np.full(60, -2.0), np.zeros(60)]
    w = OCPredictor(n0, n_oc, convention="published").weights
    expected, cost = straight_walk_by_hand(n0, n_oc, s, a0=w[0], a1=w[1], g0=10.0)
    for dt in (0.004, 0.5):  # one node of 0.1 s per sample, whatever the sampling period
        oc = OCPredictor(n0, n_oc, dt, convention="published")
        P = oc.predict_offline(poses)
        assert oc.failed == 0 and oc.last_solution.cost == pytest.approx(cost, rel=1e-6)
        np.testing.assert_allclose(P[:, :, 0] - (poses[: len(P), 0, None]), np.broadcast_to(expected, P[:, :, 0].shape), atol=1e-6)
        np.testing.assert_allclose(P[:, :, 1:], np.broadcast_to([-2.0, 0.0], P[:, :, 1:].shape), atol=1e-9)
    # what the rest start costs: over 0.9 s of nodes, reaching 0.2 m/s costs more control (a1 = 4)
    # than lagging costs tracking (g0 = 10): the last node is 0.156 m behind the 0.18 m walked and
    # coasts at 0.038 m/s; the error grows along the horizon
    lag = s * (n0 - 1) - expected[0]
    speed = (expected[1] - expected[0]) / 0.1
    assert 0.8 * 0.18 < lag < 0.18 and speed < 0.25 * s / 0.1
    m = summarise(window_errors(poses, P, n0))
    truth = s * (n0 - 1 + np.arange(n_oc - n0 + 1))
    assert m.fde == pytest.approx(truth[-1] - expected[-1], rel=1e-6)
    assert m.fde == pytest.approx(lag + (n_oc - n0) * (s - 0.1 * speed), rel=1e-6)
    cont = summarise(window_errors(poses, OCPredictor(n0, n_oc, 0.1).predict_offline(poses), n0))
    assert cont.delta_xy < 1e-6 and m.delta_xy > 1e3 * cont.delta_xy
    # with N0 = 50 nodes (5 s) the fit has caught up: a walk of 3.7 m over 500 samples, lag < 5 mm
    expected, _ = straight_walk_by_hand(50, 100, 0.0075, a0=w[0], a1=w[1], g0=10.0)
    assert abs(0.0075 * 49 - expected[0]) < 0.005 and (expected[1] - expected[0]) / 0.1 == pytest.approx(0.075, rel=0.05)


def test_published_predictor_solves_cold_from_rest():
    oc = OCPredictor(10, 30, DT, convention="published")
    assert (oc.warm_start, oc.rest_start, oc.step, oc.scheme) == (False, True, 0.1, "euler")
    x0, has_theta = oc.initial_state(model_path()[:10])
    assert has_theta and np.array_equal(x0[3:], np.zeros(3)) and x0[2] == pytest.approx(0.3)
    cont = OCPredictor(10, 30, DT)
    assert (cont.warm_start, cont.rest_start, cont.step, cont.scheme) == (True, False, DT, "midpoint")
    with pytest.raises(InputError, match="--convention 'authors' is not a convention"):
        OCPredictor(10, 30, DT, convention="authors")


@pytest.mark.parametrize("kind", ["walker", "unicycle"])
@pytest.mark.parametrize("scheme", ["midpoint", "euler"])
def test_coast_is_the_zero_control_step(kind, scheme):
    import casadi as ca

    from cobot_analysis.models.dynamics import coast, step

    X = np.array([0.3, -1.0, 2.0, 1.1, -0.2, 0.7])
    F = ca.Function("F", [x := ca.SX.sym("x", 6)], [step(x, ca.DM.zeros(3), 0.05, kind, scheme)])
    expected = [X]
    for _ in range(5):
        expected.append(np.asarray(F(expected[-1])).ravel())
    np.testing.assert_allclose(coast(X, 0.05, 5, kind, scheme), np.array(expected), atol=1e-12)
