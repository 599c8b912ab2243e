"""Walking-path models and the OC solver (docs/methods.md sec. 5): analytic cases, invariances, solver agreement."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cobot_analysis.angles import angle_diff
from cobot_analysis.errors import InputError, SolverError
from cobot_analysis.distances import d_xy
from cobot_analysis.models import generate, resample, solve_model
from cobot_analysis.models.oc.duration import initial_duration, search_duration
from cobot_analysis.models.oc.problem import OCPShape, WalkerOCP, get_ocp
from cobot_analysis.models.presets import PRESETS, load_weights, weights_vector
from cobot_analysis.schema import TRAJECTORIES

GOAL = (0.0, 0.0, math.pi / 2)
PUBLISHED = weights_vector(PRESETS["walking-2021"])
#: strong terminal weights: the path must end at the goal, at rest.
STIFF = weights_vector({**PRESETS["walking-2021"], "b0": 1000.0, "b1": 1000.0, "b2": 100.0, "b3": 100.0})


def test_straight_start_goal_pair_gives_a_straight_path():
    df = generate("improved", (-3.0, 0.0, 0.0), (0.0, 0.0, 0.0), weights=dict(zip(
        ("a0", "a1", "a2", "a3", "a4", "b0", "b1", "b2", "b3"), STIFF[[0, 1, 2, 3, 4, 7, 8, 9, 10]])))
    assert np.abs(df["y"]).max() < 1e-6 and np.abs(df["theta"]).max() < 1e-6
    assert np.all(np.diff(df["x"]) >= -1e-9)  # monotone progress
    assert df["x"].iloc[-1] == pytest.approx(0.0, abs=0.01)


@pytest.mark.parametrize("start", [(-1.5, -3.4, 0.0), (-4.0, 0.6, math.pi / 2), (-0.6, -1.5, -math.pi / 2)])
def test_mirror_symmetric_starts_give_mirrored_paths(start):
    """Mirror x -> -x (goal heading pi/2 is its own mirror): theta -> pi - theta."""
    a = generate("improved", start, GOAL, convention="continuous")
    b = generate("improved", (-start[0], start[1], math.pi - start[2]), GOAL, convention="continuous")
    assert d_xy(a["x"], a["y"], -b["x"], b["y"]) < 2e-3
    assert np.abs(angle_diff(a["theta"], math.pi - b["theta"])).max() < 2e-2
    assert a["travel_time"].iloc[0] == pytest.approx(b["travel_time"].iloc[0], rel=1e-3)


@pytest.mark.parametrize("model", ["unicycle", "mombaur", "improved"])
def test_paths_start_at_rest_on_the_start_pose_and_end_near_the_goal(model):
    start = (-1.5, -3.4, 0.0)
    df = generate(model, start, GOAL, convention="continuous")
    first = df.iloc[0]
    assert (first.x, first.y, first.theta) == pytest.approx(start, abs=1e-9)
    assert (first.v_forw, first.v_orth, first.omega) == pytest.approx((0, 0, 0), abs=1e-9)
    # stated tolerance with the published weights: 0.25 m and 0.05 rad (soft terminal cost)
    last = df.iloc[-1]
    assert math.hypot(last.x, last.y) < 0.25 and abs(last.theta - math.pi / 2) < 0.05
    assert set(TRAJECTORIES.required) <= set(df.columns) and len(df) == 500


def test_stiff_terminal_weights_end_at_the_goal_at_rest():
    sol = solve_model("improved", (-1.5, -3.4, 0.0), GOAL, STIFF).check()
    assert np.hypot(*sol.X[-1, :2]) < 0.01 and abs(sol.X[-1, 2] - math.pi / 2) < 0.01
    assert np.abs(sol.X[-1, 3:]).max() < 0.1  # m/s, rad/s (b2 = 100 against a0 = 7.87 per second)


def test_free_duration_equals_the_one_dimensional_search():
    start = (-1.5, -3.4, 0.0)
    free = solve_model("improved", start, GOAL, PUBLISHED, duration="free")
    ocp = get_ocp(OCPShape(100, goal="constraint"))  # the continuous convention's goal rule
    found = search_duration(ocp, start, GOAL, PUBLISHED, initial_duration(start, GOAL), xatol=1e-4)
    assert free.success and found.success
    assert free.T == pytest.approx(found.T, rel=5e-3)
    assert free.cost == pytest.approx(found.cost, rel=1e-6)


def test_fatrop_and_ipopt_reach_the_same_optimum():
    # facing the goal's side: with the goal a constraint a start facing away (theta0 = pi) has several
    # local minima (fatrop and IPOPT end in different ones from the same guess, costs 48.7-53.3)
    start = (-4.0, 0.6, math.pi / 2)
    a = solve_model("improved", start, GOAL, PUBLISHED, solver="fatrop", guess="rest")
    b = solve_model("improved", start, GOAL, PUBLISHED, solver="ipopt", guess="rest")
    assert a.solver == "fatrop" and b.solver == "ipopt"
    assert a.cost == pytest.approx(b.cost, rel=1e-6)
    assert np.abs(a.X[:, :2] - b.X[:, :2]).max() < 1e-3


def test_long_mombaur_horizons_converge_where_the_walker_waits_at_the_goal():
    """The Mombaur grid up to 2 T0, warm-started upward as ``grid_duration``: past the best T the walker
    arrives early and waits, its last nodes within 1e-12 to 1e-7 m of the goal. fatrop converges at every
    horizon (with the bearing term's cut-off at 1e-8 m it cycled at five of them: docs/methods.md 5.3)."""
    start = (-4.0, -3.4, math.pi / 2)
    w = weights_vector(load_weights("mombaur-2010", "improved"))
    ocp = get_ocp(OCPShape(100, goal="constraint"))
    T0, prev, near = initial_duration(start, GOAL), "rest", []
    for i in range(21):
        sol = ocp.solve(start, GOAL, w, T0 * (1 + 0.05 * i), guess=prev, fallback=False).check()
        prev = sol.primal
        near.append(int(np.sum(np.hypot(*sol.X[:-1, :2].T) < 1e-7)))
    assert max(near) >= 3  # nodes waiting at the goal, the case the cut-off is about


def test_warm_start_reaches_the_cold_optimum_in_fewer_iterations():
    start = (-1.5, -3.4, math.pi / 2)
    ocp = get_ocp(OCPShape(100, free_time=True))
    base = ocp.solve(start, GOAL, PUBLISHED, 4.0)
    w = PUBLISHED * np.r_[1.0, 1.1, 0.9, 1.0, 1.1, 1, 1, 0.95, 1.05, 1.0, 1.0]
    cold = ocp.solve(start, GOAL, w, 4.0)
    warm = ocp.solve(start, GOAL, w, 4.0, guess=base.primal)
    assert warm.success and cold.success and warm.iterations < cold.iterations
    assert warm.cost == pytest.approx(cold.cost, rel=1e-6)
    assert np.abs(warm.X - cold.X).max() < 1e-3


def test_coarse_grid_matches_a_500_interval_solve():
    """Solving on 100 intervals and resampling to 500 samples is within 5 mm of the 500-interval path."""
    start = (-4.0, -3.4, 0.0)
    fine = solve_model("improved", start, GOAL, PUBLISHED, n_intervals=500)
    coarse = solve_model("improved", start, GOAL, PUBLISHED, n_intervals=100)
    a, b = resample(fine, 500), resample(coarse, 500)
    assert d_xy(a["x"], a["y"], b["x"], b["y"]) < 5e-3
    assert coarse.T == pytest.approx(fine.T, rel=1e-2)


def test_prediction_window_tracks_measured_poses_and_takes_initial_velocity():
    """The builder serves receding-horizon prediction: tracking on the first N0 nodes, free end."""
    ocp = get_ocp(OCPShape(100))
    w = np.array([7.9, 4.0, 20.1, 1e-6, 0, 0, 0, 0, 0, 0, 0])  # a0..a3, no psi, no terminal cost
    t = np.linspace(0, 2.0, 101)
    measured = np.c_[-3 + 1.0 * t, np.zeros_like(t), np.zeros_like(t)]  # walking along x at 1 m/s
    sol = ocp.solve(measured[0], (9.0, 9.0, 0.0), w, 2.0, start_velocity=(1.0, 0.0, 0.0), track=measured[:50],
                    guess="rest").check()
    assert np.abs(sol.X[:50, 0] - measured[:50, 0]).max() < 0.02
    assert np.abs(sol.X[:, 1]).max() < 1e-6  # the goal plays no role: a4 = b = 0
    assert sol.X[-1, 0] > measured[-1, 0] - 0.1  # keeps walking at about 1 m/s after the measured part


def test_non_converged_solve_is_flagged_and_raises():
    ocp = WalkerOCP(OCPShape(20, max_iter=2))
    sol = ocp.solve((-3.0, -2.0, 0.0), GOAL, PUBLISHED, 4.0, fallback=False)
    assert not sol.success
    with pytest.raises(SolverError, match="did not converge"):
        sol.check()


def test_a_fatrop_solve_that_does_not_end_is_abandoned_and_ipopt_solves(monkeypatch):
    """fatrop's inertia correction has no bound (problem.py's docstring): a solve past FATROP_CPU_LIMIT of CPU is
    abandoned (here a stand-in that spins in C, the GIL released, as the loop does), IPOPT solves from the same
    guess, and the next fatrop solve, on new buffers, is the one a fresh problem gives."""
    import hashlib
    import time

    from cobot_analysis.models.oc import problem

    start = (-3.0, -2.0, 0.0)
    reference = WalkerOCP(OCPShape(20)).solve(start, GOAL, PUBLISHED, 4.0).check()
    ocp = WalkerOCP(OCPShape(20))
    monkeypatch.setattr(problem, "FATROP_CPU_LIMIT", 0.3)
    stuck = ocp._call("fatrop")
    stuck.run = lambda: hashlib.pbkdf2_hmac("sha256", b"x", b"y", 10_000_000)  # about 2 s of C without the GIL
    t0 = time.process_time()
    sol = ocp.solve(start, GOAL, PUBLISHED, 4.0).check()
    assert sol.solver == "ipopt" and stuck.abandoned and ocp._call("fatrop") is not stuck
    assert time.process_time() - t0 < 3.0  # the spinning thread's CPU included: it was not waited for
    assert np.abs(sol.X - reference.X).max() < 1e-5  # the same optimum, by the other solver
    again = ocp.solve(start, GOAL, PUBLISHED, 4.0).check()
    assert again.solver == "fatrop" and np.array_equal(again.X, reference.X) and again.cost == reference.cost


def test_clothoid_joins_start_and_goal_with_tangent_heading():
    df = generate("clothoid", (-1.5, -3.4, 0.0), GOAL)
    assert (df.x.iloc[0], df.y.iloc[0], df.theta.iloc[0]) == pytest.approx((-1.5, -3.4, 0.0), abs=1e-9)
    assert (df.x.iloc[-1], df.y.iloc[-1], df.theta.iloc[-1]) == pytest.approx(GOAL, abs=1e-6)
    assert np.abs(df.gamma.iloc[:-1]).max() < 0.02  # faces along the path
    step = np.hypot(np.diff(df.x), np.diff(df.y))
    assert step.std() / step.mean() < 1e-3  # equally spaced in arc length


def test_presets_and_weights_files(tmp_path, caplog):
    assert load_weights("walking-2021")["a2"] == 20.15
    with pytest.raises(InputError, match="unknown preset"):
        load_weights("walking-2099")
    bad = tmp_path / "w.json"
    bad.write_text(json.dumps([1.0, 2.0, 3.0]))
    with pytest.raises(InputError, match="has 3 values, model 'improved' needs 11"):
        load_weights(bad)
    good = tmp_path / "g.json"
    good.write_text(json.dumps({"weights": PRESETS["table-2022"]}))
    assert load_weights(good) == PRESETS["table-2022"]
    with pytest.raises(InputError, match="another model"):
        load_weights("pair-2022", "improved")
    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({"weights": {k: v for k, v in PRESETS["walking-2021"].items() if k != "a1"}}))
    assert load_weights(partial)["a1"] == 0.0  # a weight a file leaves out is 0, said once (before: silently)
    assert f"{partial}: weights a1 of model 'improved' not given, taken as 0" in caplog.text


def test_start_equal_to_goal_is_refused():
    with pytest.raises(InputError, match="start equals goal"):
        generate("improved", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    with pytest.raises(InputError, match="NaN"):
        generate("improved", (np.nan, 0.0, 0.0), GOAL)


def test_discrete_step_matches_the_continuous_dynamics():
    """dynamics.step against a tight numerical integration of dynamics.rhs over one interval."""
    import casadi as ca
    from scipy.integrate import solve_ivp

    from cobot_analysis.models.dynamics import rhs, step

    X0 = np.array([0.3, -0.2, 0.4, 1.2, 0.1, 0.8])
    U = np.array([0.5, -0.3, 1.5])
    for kind in ("walker", "unicycle"):
        f = lambda t, x: np.asarray(rhs(ca.DM(x), ca.DM(U), kind)).ravel()  # noqa: E731
        for dt in (0.05, 0.01):
            exact = solve_ivp(f, (0, dt), X0, rtol=1e-12, atol=1e-12).y[:, -1]
            approx = np.asarray(step(ca.DM(X0), ca.DM(U), dt, kind)).ravel()
            assert np.abs(approx[2:] - exact[2:]).max() < 1e-12  # heading and velocities exact
            assert np.abs(approx[:2] - exact[:2]).max() < 0.1 * dt**3  # midpoint rule: O(dt^3) per step


def test_coupled_carriers_start_at_rest_and_mirror_problems_give_mirrored_paths():
    """Pair-study-like start (table at the origin heading pi/2, carriers 0.9 m ahead and behind,
    facing it) to a goal 3.7 m away, and its mirror image x -> -x (theta -> pi - theta)."""
    from cobot_analysis.angles import angle_diff
    from cobot_analysis.models.oc.coupled import solve_pair

    w = weights_vector(PRESETS["pair-2022"], "coupled")
    start = np.array([(0.0, 0.9, -math.pi / 2), (0.0, -0.9, math.pi / 2)])
    goal = np.array([(-2.17, -2.25, math.pi), (-3.97, -2.25, 0.0)])
    mirror = lambda p: np.c_[-p[:, 0], p[:, 1], math.pi - p[:, 2]]  # noqa: E731
    a = solve_pair(start, goal, w, n_intervals=60).check()
    b = solve_pair(mirror(start), mirror(goal), w, n_intervals=60).check()
    assert a.X[0, [0, 1, 2, 6, 7, 8]] == pytest.approx(start.ravel(), abs=1e-9)
    assert np.abs(a.X[0, [3, 4, 5, 9, 10, 11]]).max() < 1e-9  # at rest
    assert a.cost == pytest.approx(b.cost, rel=1e-6)
    assert np.abs(a.X[:, [0, 6]] + b.X[:, [0, 6]]).max() < 1e-3 and np.abs(a.X[:, [1, 7]] - b.X[:, [1, 7]]).max() < 1e-3
    assert np.abs(angle_diff(a.X[:, [2, 8]], math.pi - b.X[:, [2, 8]])).max() < 1e-3
    ends = np.hypot(a.X[-1, [0, 6]] - goal[:, 0], a.X[-1, [1, 7]] - goal[:, 1])
    assert ends.max() < 0.2  # m, soft terminal cost with the published weights


# -- the compiled NLP functions (ocp._nlp_functions, ocp.compiled_library) ------------------------

@pytest.mark.parametrize("shape", [OCPShape(7), OCPShape(6, "unicycle", free_time=True), OCPShape(5, free_time=True, goal="constraint")])
def test_hand_assembled_derivatives_equal_casadi_ad_of_the_nlp(shape, monkeypatch):
    """f, g, grad f, jac g and the Lagrangian's gradient and Hessian that fatrop gets (assembled
    from per-stage derivatives) equal casadi's AD of the whole NLP, values and sparsity."""
    import casadi as ca

    monkeypatch.setenv("COBOT_ANALYSIS_OCP_COMPILE", "0")
    ocp = WalkerOCP(shape)
    fs = ocp._nlp_functions()
    nlp = fs["nlp"].expand()
    x, p = ca.SX.sym("x", ocp.n_vars), ca.SX.sym("p", ocp.n_params)
    lf, lg = ca.SX.sym("lf"), ca.SX.sym("lg", ocp.n_cons)
    f, g = nlp(x, p)
    H, gL = ca.hessian(lf * f + ca.dot(lg, g), x)
    ref = ca.Function("ref", [x, p, lf, lg], [f, g, ca.gradient(f, x), ca.jacobian(g, x), gL, H])
    rng = np.random.default_rng(1)
    for _ in range(3):
        xv, pv = rng.normal(size=ocp.n_vars), rng.normal(size=ocp.n_params)
        lfv, lgv = rng.uniform(0.5, 2), rng.normal(size=ocp.n_cons)
        pv[6 + 3] = rng.uniform(1, 4)  # T > 0
        want = ref(xv, pv, lfv, lgv)
        got = [*fs["nlp"](xv, pv), fs["nlp_grad_f"](xv, pv), fs["nlp_jac_g"](xv, pv)[1], *fs["nlp_hess_l"](xv, pv, lfv, lgv)]
        for a, b in zip(got, want):
            assert a.sparsity() == b.sparsity()
            assert np.allclose(np.asarray(ca.densify(a)), np.asarray(ca.densify(b)), rtol=1e-12, atol=1e-12)
        assert np.array_equal(np.asarray(fs["nlp_jac_g"](xv, pv)[0]), np.asarray(want[1]))


def test_compiled_and_virtual_machine_solvers_give_the_same_solution(tmp_path, monkeypatch):
    monkeypatch.setenv("COBOT_ANALYSIS_CACHE", str(tmp_path))
    compiled = WalkerOCP(OCPShape(40, free_time=True))
    assert len(list((tmp_path / "ocp").glob("walker_ocp_*.so"))) == 1
    monkeypatch.setenv("COBOT_ANALYSIS_OCP_COMPILE", "0")
    vm = WalkerOCP(OCPShape(40, free_time=True))
    for start in [(-1.5, -3.4, 0.0), (-0.6, -1.5, -math.pi / 2)]:
        a, b = compiled.solve(start, GOAL, PUBLISHED, 3.0), vm.solve(start, GOAL, PUBLISHED, 3.0)
        assert a.success and b.success and a.solver == b.solver == "fatrop"
        assert a.iterations == b.iterations
        assert a.cost == pytest.approx(b.cost, rel=1e-10) and a.T == pytest.approx(b.T, rel=1e-8)
        assert np.abs(a.X - b.X).max() < 1e-7


def test_compiled_library_is_reused_and_a_failing_compiler_falls_back(tmp_path, monkeypatch):
    monkeypatch.setenv("COBOT_ANALYSIS_CACHE", str(tmp_path))
    WalkerOCP(OCPShape(8))
    (lib,) = (tmp_path / "ocp").glob("walker_ocp_*.so")
    (saved,) = (tmp_path / "ocp").glob("walker_ocp_*_fatrop_*.casadi")  # the fatrop solver, serialised
    built = lib.stat().st_mtime_ns, saved.stat().st_mtime_ns
    again = WalkerOCP(OCPShape(8))  # same problem: the cached library and solver are loaded, not rebuilt
    assert (lib.stat().st_mtime_ns, saved.stat().st_mtime_ns) == built and len([p for p in (tmp_path / "ocp").iterdir() if p.name != "digests"]) == 2
    monkeypatch.setenv("CC", "false")  # a "compiler" that always fails
    fallback = WalkerOCP(OCPShape(8))
    assert len([p for p in (tmp_path / "ocp").iterdir() if p.name != "digests"]) == 2  # nothing half-written left behind
    monkeypatch.setenv("CC", "cc")
    (tmp_path / "file").write_text("")
    monkeypatch.setenv("COBOT_ANALYSIS_CACHE", str(tmp_path / "file"))  # cache not creatable
    unwritable = WalkerOCP(OCPShape(8))
    for ocp in (fallback, unwritable):
        assert getattr(ocp, "_nlp", None) is not None and getattr(again, "_nlp", None) is None  # SX NLP built: VM in use
        a, b = again.solve((-1.0, -1.0, 0.0), GOAL, PUBLISHED, 2.0), ocp.solve((-1.0, -1.0, 0.0), GOAL, PUBLISHED, 2.0)
        assert a.success and b.success and a.cost == pytest.approx(b.cost, rel=1e-10)


def test_saved_solver_is_checked_and_a_damaged_one_rebuilt(tmp_path, monkeypatch):
    """The serialised fatrop solver beside the library carries the SHA-256 of its text: a damaged file is
    not loaded but rebuilt, and every variant solves to the same optimum."""
    monkeypatch.setenv("COBOT_ANALYSIS_CACHE", str(tmp_path))
    built = WalkerOCP(OCPShape(12))
    (saved,) = (tmp_path / "ocp").glob("*.casadi")
    good = saved.read_bytes()
    loaded = WalkerOCP(OCPShape(12))
    damaged = bytearray(good)
    damaged[len(good) // 2] ^= 0x01  # one flipped bit in the serialised text
    import casadi as ca

    calls = []
    real = ca.Function.deserialize
    monkeypatch.setattr(ca.Function, "deserialize", lambda *a: calls.append(1) or real(*a))
    for content in (bytes(damaged), good[:len(good) // 3], b"", b"\xff\xfe not utf-8"):
        saved.write_bytes(content)
        rebuilt = WalkerOCP(OCPShape(12))
        assert not calls  # the damaged text never reaches casadi
        assert saved.read_bytes() == good  # rewritten whole
        for ocp in (built, loaded, rebuilt):
            sol = ocp.solve((-1.0, -1.0, 0.0), GOAL, PUBLISHED, 2.0).check()
            ref = built.solve((-1.0, -1.0, 0.0), GOAL, PUBLISHED, 2.0)
            assert sol.solver == "fatrop" and sol.iterations == ref.iterations and np.array_equal(sol.X, ref.X)
    WalkerOCP(OCPShape(12))
    assert calls == [1]  # the intact file is loaded
    assert not list((tmp_path / "ocp").glob("*.tmp"))


def test_guesses_rest_and_line():
    ocp = get_ocp(OCPShape(100, free_time=True))
    rest = ocp.guess((-1.0, -2.0, 0.5), GOAL, 3.0, "rest", start_velocity=(0.5, 0.0, 0.1))
    line = ocp.guess((-1.0, -2.0, 0.5), GOAL, 3.0, "line")
    assert np.all(rest[ocp._xi[:, :6]] == [-1.0, -2.0, 0.5, 0.5, 0.0, 0.1]) and np.all(rest[ocp._ui] == 0)
    assert line[ocp._xi[0, :3]] == pytest.approx([-1.0, -2.0, 0.5]) and line[ocp._xi[-1, :3]] == pytest.approx(GOAL)
    assert line[ocp._xi[50, :3]] == pytest.approx([-0.5, -1.0, (0.5 + math.pi / 2) / 2])
    assert np.all(line[ocp._xi[:, 3:6]] == 0) and np.all(rest[ocp._xi[:, 6]] == math.log(3.0))


@pytest.mark.parametrize("free", [False, True])
def test_coarse_guess_reaches_the_rest_guess_optimum(free):
    """guess='coarse' (a 50-interval solve, interpolated) is a cold solve: on these starts it ends in
    the optimum the rest guess ends in, in fewer fine-grid iterations."""
    ocp = get_ocp(OCPShape(200, free_time=free))
    for start in [(-1.5, -3.4, 0.0), (-4.0, -0.9, -math.pi / 2)]:
        rest = ocp.solve(start, GOAL, PUBLISHED, 3.0, guess="rest").check()
        coarse = ocp.solve(start, GOAL, PUBLISHED, 3.0, guess="coarse").check()
        assert coarse.cost == pytest.approx(rest.cost, rel=1e-8) and coarse.T == pytest.approx(rest.T, rel=1e-6)
        assert np.abs(coarse.X - rest.X).max() < 1e-4
        assert coarse.iterations < rest.iterations
    with pytest.raises(ValueError, match="tracking"):
        ocp.solve((-1.5, -3.4, 0.0), GOAL, PUBLISHED, 3.0, guess="coarse", track=np.zeros((10, 3)))
