"""Single-level IOC (models/ioc/single_level.py) and recovery of known weights (models/ioc/recovery.py):
small problems (20 intervals, 100 samples, 6-8 paths)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.models.ioc import IOCSpec, solve_target
from cobot_analysis.models.presets import load_weights, names_for, weights_vector

W = weights_vector(load_weights("walking-2021", "improved"), "improved")
SPEC = IOCSpec(model="improved", start_weights=tuple(W), n_intervals=20, fitted=("a2", "a4"))  # a0, a1 fix the scale and time scale, b unused: the goal is a constraint


def _perturbed(spec, factor=2.0):
    w = np.array(spec.start_weights)
    for n in spec.fitted:
        w[names_for(spec.model).index(n)] *= factor
    return replace(spec, start_weights=tuple(w))


def test_hermite_resampling_matches_oc_resample():
    """The NLP's linear resampling reproduces oc.resample (cubic Hermite in time) to round-off."""
    from cobot_analysis.models.oc import resample
    from cobot_analysis.models.ioc.recovery import starts
    from cobot_analysis.models.ioc.resampled_distance import hermite_matrices
    from cobot_analysis.models.dynamics import world_velocity
    from cobot_analysis.models.ioc.targets import Target

    s = starts(3)[1]
    t = Target("t", "c", "", np.array([s[0], 0.0]), np.array([s[1], 0.0]), np.array([s[2], np.pi / 2]),
               goal_pose=(0.0, 0.0, np.pi / 2), start_pose=s)
    _, sol = solve_target(SPEC, W, t, ("rest", "line"))
    r = resample(sol, 77)
    H0, H1 = hermite_matrices(SPEC.n_intervals, 77)
    vx, _ = world_velocity(sol.X[:, 2], sol.X[:, 3], sol.X[:, 4], "walker")
    np.testing.assert_allclose(H0 @ sol.X[:, 0] + sol.T * (H1 @ vx), r["x"], atol=1e-12)
    np.testing.assert_allclose(H0 @ sol.X[:, 2] + sol.T * (H1 @ sol.X[:, 5]), r["theta"], atol=1e-12)


def _symbolic_distance(ocp, M, angle, angle_weight, eps):
    """The smoothed D of ``resampled_distance`` written symbolically in casadi (its definition), with its
    gradient and Hessian by casadi: the reference of the chain-rule derivatives."""
    import casadi as ca

    from cobot_analysis.models.dynamics import N_STATE
    from cobot_analysis.models.ioc.resampled_distance import hermite_matrices

    z, data = ca.SX.sym("z", ocp.n_vars), ca.SX.sym("data", 4 * M)
    x, y, th, vf, vo, om = (z[ocp._xi[:, i].tolist()] for i in range(N_STATE))
    T = ca.exp(z[int(ocp._xi[0, N_STATE])])
    H0, H1 = (ca.DM(H) for H in hermite_matrices(ocp.N, M))
    vx, vy = ca.cos(th) * vf - ca.sin(th) * vo, ca.sin(th) * vf + ca.cos(th) * vo
    xs, ys, ths = H0 @ x + T * (H1 @ vx), H0 @ y + T * (H1 @ vy), H0 @ th + T * (H1 @ om)
    mx, my, mth, mg = data[:M], data[M:2 * M], data[2 * M:3 * M], data[3 * M:]
    sabs = lambda a: ca.sqrt(a**2 + eps**2) - eps  # noqa: E731
    d_xy = ca.sum1(ca.sqrt((xs - mx)**2 + (ys - my)**2 + eps**2) - eps) / M
    if angle == "gamma":
        dx, dy = xs[1:] - xs[:-1], ys[1:] - ys[:-1]
        a = mg[:-1] + ths[:-1]
        d_ang = ca.sum1(sabs(ca.atan2(ca.sin(a) * dx - ca.cos(a) * dy, ca.cos(a) * dx + ca.sin(a) * dy))) / (M - 1)
    else:
        d_ang = ca.sum1(sabs(ca.atan2(ca.sin(mth - ths), ca.cos(mth - ths)))) / M
    D = d_xy + angle_weight * d_ang
    H, g = ca.hessian(D, z)
    return ca.Function("Dgh", [z, data], [D, g, H])


@pytest.mark.parametrize("angle", ["gamma", "theta"])
def test_resampled_distance_derivatives_match_casadi(angle):
    """D, its gradient and its Hessian by the chain rule (``ResampledDistance``, full Hessian with S = I,
    and projected on 3 directions) equal casadi's symbolic derivatives of the same D to 1e-9 relative,
    at a lower-level path perturbed off the optimum (both angle terms: walker gamma, table theta)."""
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.resampled_distance import SMOOTHING, ResampledDistance
    from cobot_analysis.models.ioc.single_level import lower_level, target_data

    ocp = lower_level(SPEC)
    rng = np.random.default_rng(3)
    for t in synthetic_targets(SPEC, W, 3, noise=0.02)[:2]:
        M = len(t.x)
        _, sol = solve_target(SPEC, W, t, ("rest", "line"))
        z, data = sol.primal + rng.normal(0.0, 1e-2, ocp.n_vars), target_data(t)
        D0, g0, H0 = (np.asarray(a.full() if hasattr(a, "full") else a) for a in
                      _symbolic_distance(ocp, M, angle, 0.5, SMOOTHING)(z, data))
        rd = ResampledDistance(ocp, M, angle, 0.5)
        D, g, H = rd(z, data, np.eye(ocp.n_vars))
        assert D > 0.01 and abs(D - D0.item()) <= 1e-12 * D
        np.testing.assert_allclose(g, g0.ravel(), rtol=0, atol=1e-9 * abs(g0).max())
        np.testing.assert_allclose(H, H0, rtol=0, atol=1e-9 * abs(H0).max())
        S = rng.normal(size=(ocp.n_vars, 3))
        np.testing.assert_allclose(rd(z, data, S)[2], S.T @ H0 @ S, rtol=1e-9, atol=1e-9 * abs(S.T @ H0 @ S).max())


def test_kkt_holds_at_a_lower_level_solution():
    """The KKT conditions built from the OC problem's own NLP vanish at its solution (least-squares
    multipliers), and not at the same path under other weights."""
    from cobot_analysis.models.dynamics import N_STATE
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import kkt_functions, lower_level, multipliers
    from cobot_analysis.models.oc.duration import initial_duration

    t = synthetic_targets(SPEC, W, 2)[0]
    ocp = lower_level(SPEC)
    kkt, grads = kkt_functions(ocp)
    _, sol = solve_target(SPEC, W, t, ("rest", "line"))
    p = ocp.parameters(t.start, t.goal, W, initial_duration(t.start, t.goal))
    iT = int(ocp._xi[0, N_STATE])
    lam, nu = multipliers(grads, sol.primal, W, p, iT)
    r = np.asarray(kkt(sol.primal, lam, W, p)).ravel()
    r[iT] += nu
    assert np.abs(r).max() < 1e-6
    w2 = W.copy()
    w2[1] *= 3
    lam2, nu2 = multipliers(grads, sol.primal, w2, p, iT)
    r2 = np.asarray(kkt(sol.primal, lam2, w2, p)).ravel()
    r2[iT] += nu2
    assert np.abs(r2).max() > 1e-3


def test_band_lu_solves_the_kkt_system_and_its_transpose():
    """``_Factor`` (LAPACK's band LU of the RCM-ordered KKT matrix) solves K x = b and K' x = b as a general sparse
    solver does, on a lower level's KKT matrix, for one and for several right-hand sides; a singular K raises
    RuntimeError (the branch's correction then fails: a fold)."""
    from scipy.sparse.linalg import spsolve

    from cobot_analysis.models.ioc.buffered import BufferedCall
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import _Factor, _Permutation, lower_level, newton_functions
    from cobot_analysis.models.oc.duration import initial_duration

    t = synthetic_targets(SPEC, W, 2)[0]
    ocp = lower_level(SPEC)
    newton = BufferedCall(newton_functions(ocp, [names_for("improved").index(n) for n in SPEC.fitted])[0])
    _, sol = solve_target(SPEC, W, t, ("rest", "line"))
    v = np.concatenate([sol.primal, np.full(ocp.n_cons, 0.1)])
    F, K, Fw = newton(v, W, ocp.parameters(t.start, t.goal, W, initial_duration(t.start, t.goal)))
    K = K.copy()
    K.data *= 1 + 0.1 * np.random.default_rng(1).standard_normal(K.nnz)  # K is symmetric: made not, to tell K from K'
    perm = _Permutation(K)
    assert 0 < perm.kl < 50 and 0 < perm.ku < 50 < K.shape[0] / 4  # a band, far narrower than K
    lu = _Factor(K, perm)
    B = np.column_stack([F, Fw.reshape(len(v), -1)])
    for b in (F, B):
        for trans, A in ((False, K), (True, K.T.tocsc())):
            x, ref = lu.solve(b, trans=trans), spsolve(A, b)
            np.testing.assert_allclose(x, ref.reshape(x.shape), rtol=1e-8, atol=1e-10 * np.abs(ref).max())
    K.data[K.indices == 0] = 0.0  # the first row emptied: singular
    with pytest.raises(RuntimeError, match="singular"):
        _Factor(K, perm)


def test_bad_inputs_are_refused():
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import check_spec

    with pytest.raises(InputError, match="not weights of the model"):
        check_spec(replace(SPEC, fitted=("a1", "zz")), 10)
    with pytest.raises(InputError, match="cannot determine 2 weights"):
        check_spec(SPEC, 1)
    with pytest.raises(InputError, match="--method bilevel"):
        check_spec(replace(SPEC, convention="published", hold_duration=False), 10)  # published: held horizons only
    assert synthetic_targets(SPEC, W, 1)  # one path is fine to generate


def test_verdicts_on_known_curvatures():
    """Analytic Hessians: a flat common-scale direction gives a ratio verdict, a flat axis 'not
    determined', a curved axis 'determined'; a weight on the search limit says so."""
    from cobot_analysis.models.ioc.uncertainty import verdicts

    w = {"a1": 1.0, "a2": 2.0, "b1": 1e3}
    H = np.array([[1.0, -1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 0.0]]) + np.diag([0.0, 0.0, 0.0])
    v = verdicts(("a1", "a2", "b1"), H, D=0.1, weights=w)
    assert v["a1"] == "only its ratio to a2 is determined"
    assert v["a2"] == "only its ratio to a1 is determined"
    assert v["b1"] == "not determined by these data (at the search limit 1000)"
    v = verdicts(("a1", "a2", "b1"), np.diag([1.0, 2.0, 3.0]), D=0.1, weights={**w, "b1": 3.0})
    assert set(v.values()) == {"determined"}
    assert set(verdicts(("a1", "a2"), np.eye(2), 0.1, w, lack=0.3).values()) == {
        "not judged: D is not smooth at the fit (a quadratic leaves 30 % of its change over the stencil unexplained)"}


def test_time_scale_gauge_is_reported_as_a_ratio():
    """a1 and a2 scaled together by c^4 (a3 ~ 0, a0 held) only rescale time: the paths D compares are
    the same, so the curvature of D along (1, 1) in log10 is ~0 and each weight gets the ratio verdict
    and the search box as its interval, while a4 stays determined with a finite interval."""
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.uncertainty import bootstrap, curvature, verdicts

    spec = replace(SPEC, fitted=("a1", "a2", "a4"))
    # 5 paths: with 4, the third path's lower level changes branch within the stencil (a1 x 1.12), and D is
    # then rightly "not judged" (lack of fit 0.55)
    targets = synthetic_targets(spec, W, 5, noise=0.02)
    names = names_for("improved")
    c = curvature(spec, targets, {n: float(W[names.index(n)]) for n in names})
    mu, V = np.linalg.eigh(c.H)
    gauge = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    assert abs(gauge @ c.H @ gauge) < 1e-2 * mu.max()  # flat along the gauge (a3 ~ 1e-6 not scaled, solver tolerance)
    assert c.lack_of_fit < 0.02  # D is smooth here: a quadratic explains it on the stencil
    v = verdicts(spec.fitted, c.H, c.D, {n: float(W[names.index(n)]) for n in names}, lack=c.lack_of_fit)
    assert v == {"a1": "only its ratio to a2 is determined", "a2": "only its ratio to a1 is determined", "a4": "determined"}
    b = bootstrap(c, n_resamples=50)
    assert b["intervals"]["a1"] == (1e-7, 1e3)  # the gauge direction is not bounded by the data
    lo4, hi4 = b["intervals"]["a4"]
    assert lo4 <= W[names.index("a4")] * 1.2 and hi4 >= W[names.index("a4")] / 1.2 and hi4 / lo4 < 10


def test_quadratic_bootstrap_on_known_curvatures():
    """Targets with exact quadratic D_i = 0.5 (y - m_i)' A (y - m_i): each resample's refit is the mean
    of its m_i, so the intervals are those of the bootstrap mean of the m_i; a zero-curvature axis spans
    the search box."""
    from cobot_analysis.models.ioc.uncertainty import Curvature, bootstrap, quadratic_refit

    rng = np.random.default_rng(1)
    n, y0 = 40, np.array([0.5, -1.0])
    m = y0 + 0.1 * rng.standard_normal((n, 2))
    A = np.diag([4.0, 1.0])
    gi = -(m - y0) @ A
    c = Curvature(("a2", "a4"), y0, 0.5 * np.einsum("ij,jk,ik->i", m - y0, A, m - y0), gi, np.repeat(A[None], n, 0), 0)
    counts = np.bincount(rng.integers(0, n, n), minlength=n).astype(float)
    np.testing.assert_allclose(quadratic_refit(c, counts), counts @ m / counts.sum(), atol=1e-5)
    b = bootstrap(c, 400, seed=2)
    assert b["on_box"] == 0  # positive definite: every resample's minimum inside the box
    for j, name in enumerate(("a2", "a4")):
        lo, hi = np.log10(b["intervals"][name])
        se = m[:, j].std(ddof=1) / np.sqrt(n)
        assert lo < m[:, j].mean() < hi and abs((hi - lo) / (2 * 1.96 * se) - 1) < 0.25
    flat = Curvature(("a2", "a4"), y0, c.Di, gi * [1, 0], np.repeat(np.diag([4.0, 0.0])[None], n, 0), 0)
    b = bootstrap(flat, 20)
    assert b["intervals"]["a4"] == (1e-7, 1e3) and b["sd_log10"]["a4"] == np.inf
    lo, hi = np.log10(b["intervals"]["a2"])
    assert lo < m[:, 0].mean() < hi


def test_bootstrap_reports_a_weight_held_by_a_search_limit():
    """Exact quadratics whose minima lie beyond a2's upper limit (y = 3, where the fit stopped). As on subject
    S03's walking fit: one determined direction, mostly a4 with a little a2, the other flat (held at the fit);
    every resample's refit is pinned by a2's limit, and a4, "determined" by the curvature, would get a
    zero-width interval: it gets the box and "not determined", saying why. With both directions determined
    and a4 independent of a2, a2 is pinned on its limit but a4 keeps a finite interval and its verdict."""
    from cobot_analysis.models.ioc.uncertainty import Curvature, bootstrap, determined, interval_verdicts

    rng = np.random.default_rng(4)
    n, y0 = 30, np.array([3.0, -1.0])
    m = np.array([3.5, -0.5]) + 0.05 * rng.standard_normal((n, 2))  # each target's minimum, a2's beyond the box
    v = np.array([0.25, 0.97]) / np.hypot(0.25, 0.97)
    for A, coupled in ((4.0 * np.outer(v, v), True), (np.diag([4.0, 1.0]), False)):
        c = Curvature(("a2", "a4"), y0, 0.5 * np.einsum("ij,jk,ik->i", m - y0, A, m - y0), -(m - y0) @ A,
                      np.repeat(A[None], n, 0), 0)
        b = bootstrap(c, 200, seed=1)
        assert b["on_box"] == 200  # every resample's minimum beyond a2's limit
        ok = determined(c.H, c.D)
        v_in = {"a2": "determined" if ok[0] else "not determined by these data", "a4": "determined"}
        verdict = interval_verdicts(v_in, b["intervals"], b["held"])
        if coupled:  # a4 moves only with a2: the same value in every resample, pinned by the box
            assert list(ok) == [False, True] and list(b["held"]) == ["a4"]
            assert b["intervals"]["a4"] == (1e-7, 1e3) and b["sd_log10"]["a4"] == np.inf
            assert verdict["a4"] == ("not determined by these data (the search box holds its refit in 200 of 200 "
                                     "resamples: a2 on its search limit 1000 in 200)")
        else:  # a2 pinned on its limit; a4 around the fit (intervals are centred on it) with the targets' spread
            assert list(b["held"]) == ["a2"] and verdict["a2"].startswith("not determined by these data (the search box")
            lo, hi = np.log10(b["intervals"]["a4"])
            assert lo < y0[1] < hi and 0.01 < hi - lo < 0.1 and verdict["a4"] == "determined"


def test_stencil_is_warm_from_the_centre_path_only(monkeypatch):
    """The curvature's centre is solved from the two cold guesses, every other stencil point from the centre's
    path only (one guess: that primal vector), as docs/methods.md sec. 6.3 says; ``solve_target``'s guesses:
    a primal vector with the two cold guesses, a tuple exactly as given."""
    import cobot_analysis.models.oc as oc
    from cobot_analysis.models.ioc import uncertainty
    from cobot_analysis.models.ioc.recovery import synthetic_targets

    spec = replace(SPEC, fitted=("a2", "a4"))
    targets = synthetic_targets(spec, W, 2, noise=0.01)
    calls, solve = [], oc.solve_model

    def recorded(*args, **kw):
        sol = solve(*args, **kw)
        calls.append((kw["guess"], sol.primal))
        return sol

    monkeypatch.setattr(oc, "solve_model", recorded)
    uncertainty.curvature(spec, targets, dict(zip(names_for("improved"), map(float, W))))
    assert len(calls) == 2 * 7 and [g for g, _ in calls[:2]] == [("rest", "line")] * 2
    for i, (guess, _) in enumerate(calls[2:]):
        assert isinstance(guess, tuple) and len(guess) == 1 and np.array_equal(guess[0], calls[i % 2][1])
    primal = calls[0][1]
    calls.clear()
    solve_target(spec, W, targets[0], primal)
    assert calls[0][0][0] is primal and calls[0][0][1:] == ("rest", "line")


def test_curvature_centre_is_the_fits_own_branch(monkeypatch):
    """Given the fit's paths (``centre``), the curvature's centre is solved as the fit evaluates D: from the fit's
    path and the two cold guesses, the least cost kept (its D: ``solve_target``'s from that path); without a path for a
    target, the cold guesses; the rest of the stencil warm from the centre's path."""
    import cobot_analysis.models.oc as oc
    from cobot_analysis.models.ioc import uncertainty
    from cobot_analysis.models.ioc.recovery import synthetic_targets

    spec = replace(SPEC, fitted=("a2", "a4"))
    targets = synthetic_targets(spec, W, 2, noise=0.01)
    w = dict(zip(names_for("improved"), map(float, W)))
    _, ref = solve_target(spec, W, targets[0], ("rest",))
    calls, solve = [], oc.solve_model

    def recorded(*args, **kw):
        calls.append(kw["guess"])
        return solve(*args, **kw)

    monkeypatch.setattr(oc, "solve_model", recorded)
    c = uncertainty.curvature(spec, targets, w, centre=[ref.primal, None])
    assert calls[0][0] is ref.primal and calls[0][1:] == ("rest", "line")  # the fit's path first, then the cold guesses
    assert calls[1] == ("rest", "line")  # no path for that target: the cold guesses, as without a centre
    assert len(calls) == 2 * 7 and all(isinstance(g, tuple) and len(g) == 1 for g in calls[2:])
    calls.clear()
    monkeypatch.setattr(oc, "solve_model", solve)
    d0 = [solve_target(spec, W, t, g)[0]["D"] for t, g in zip(targets, (ref.primal, ("rest", "line")))]
    assert c.D == pytest.approx(np.mean(d0), rel=1e-12)


def test_subjects_differ_on_planted_weights():
    """Planted per-subject estimates with known standard errors: equal true weights reject at about
    the nominal 5 % over many draws; a weight that differs between subjects is detected; a subject
    where the weight is not determined is left out of its test."""
    from cobot_analysis.models.ioc.uncertainty import subjects_differ

    rng = np.random.default_rng(3)
    S, sd = 10, 0.05
    sds = {f"s{i}": {"a2": sd, "a4": sd} for i in range(S)}

    def draw(shift):
        return {f"s{i}": {"a2": 10 ** (0.4 + shift * (i - S / 2) / S + sd * rng.standard_normal()),
                          "a4": 10 ** (1.0 + sd * rng.standard_normal())} for i in range(S)}

    rejections = sum(any(r["differ"] for r in subjects_differ(draw(0.0), sds)) for _ in range(300))
    assert 3 <= rejections <= 30  # Holm over 2 weights: family-wise rate <= 5 % (300 draws: ~15 expected at most)
    rows = {r["weight"]: r for r in subjects_differ(draw(1.0), sds)}
    assert rows["a2"]["differ"] and rows["a2"]["p_holm"] < 1e-6 and rows["a2"]["df"] == S - 1
    assert not rows["a4"]["differ"]
    verdict = {s: {"a2": "determined", "a4": "not determined by these data"} for s in sds}
    verdict["s0"]["a2"] = "only its ratio to a4 is determined"
    rows = {r["weight"]: r for r in subjects_differ(draw(1.0), sds, verdict)}
    assert rows["a2"]["subjects"] == S - 1 and rows["a4"]["subjects"] == 0 and rows["a4"]["differ"] is None


def test_method_and_bootstrap_checks():
    from cobot_analysis.models.ioc.single_level import check_method

    check_method("bilevel")
    check_method("single-level", 200)
    with pytest.raises(InputError, match="unknown --method 'one-level'"):
        check_method("one-level")
    with pytest.raises(InputError, match="at least 2"):
        check_method("single-level", 1)


def test_fit_ioc_refuses_an_unknown_method(cli, tmp_path):
    code, out, err = cli("fit-ioc", "--out", tmp_path, "--method", "one-level", "--no-compare")
    assert code == 2
    assert "--method" in err and "single-level" in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())
    code, out, err = cli("fit-ioc", "--out", tmp_path, "--bootstrap", "1", "--no-compare")
    assert code == 2 and "--bootstrap 1" in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())


@pytest.mark.slow  # end to end: a bi-level and a single-level fit through the command (about 7 s idle)
def test_fit_ioc_single_level_end_to_end_and_too_few_paths(cli, tmp_path):
    """fit-ioc --method single-level on 4 model paths (as means): the stage writes its weights and a report
    that names the method; fitting more weights than paths is refused (exit 2, nothing written)."""
    import json

    import pandas as pd

    from cobot_analysis.design import WALKING_GOAL, walking_condition
    from cobot_analysis.models import generate
    from cobot_analysis.schema import TRAJECTORIES, write_table

    frames = []
    for c in ("E4015", "O1515", "N-0615", "S4040"):
        df = generate("improved", walking_condition(c).start, WALKING_GOAL, weights="walking-2021", n_samples=100,
                      n_intervals=20, convention="continuous")
        base = df[list(TRAJECTORIES.columns.keys() & set(df.columns))].copy()
        frames.append(base.assign(study="test-walking", trial=f"mean_{c}", kind="mean", n_trials=1, subject=None))
    src = write_table(pd.concat(frames, ignore_index=True), tmp_path / "trajectories.parquet", TRAJECTORIES)
    bad = tmp_path / "bad"
    code, _, err = cli("fit-ioc", "--out", bad, "--trajectories", src, "--method", "single-level",
                       "--fit", "a0,a1,a2,a3,a4", "--intervals", "20", "--no-compare", "-j", "1")
    assert code == 2 and "4 paths cannot determine 5 weights" in err and len(err.strip().splitlines()) == 1
    assert not (bad / "fit-ioc").exists()
    out = tmp_path / "ws"
    start = tmp_path / "start.json"  # twice the true a2 and a4
    start.write_text(json.dumps({"convention": "continuous", "weights": {**dict(zip(names_for("improved"), W)),
                                                                          "a2": 2 * W[2], "a4": 2 * W[4]}}))
    common = ("--out", out, "--trajectories", src, "--fit", "a2,a4", "--start-weights", start, "--intervals", "20",
              "--no-compare", "-j", "1")
    code, _, err = cli("fit-ioc", *common, "--max-evaluations", "4", "--bootstrap", "0")
    assert code == 0, err
    bilevel = (out / "fit-ioc" / "weights.json").read_text()
    code, _, err = cli("fit-ioc", *common, "--method", "single-level")
    assert code == 0, err
    assert (out / "fit-ioc" / "weights.json").read_text() == bilevel  # the bi-level fit is not overwritten
    single = json.loads((out / "fit-ioc-single" / "weights.json").read_text())
    fit, b = single["fits"]["all"], json.loads(bilevel)["fits"]["all"]
    assert single["method"] == "single-level" and fit["objective"] < fit["start_objective"], fit
    text = (out / "fit-ioc-single" / "results.md").read_text()
    assert "Single-level IOC (docs/methods.md sec. 6.1)" in text
    assert f"| all | bi-level | {b['objective']:.4f} | {b['seconds']:.1f} |" in text
    assert f"| all | single-level | {fit['objective']:.4f} |" in text
    assert set(fit["uncertainty"]["verdicts"]) == {"a2", "a4"} and "| all | a2 |" in text


def test_curvature_resumes_from_its_checkpoint(tmp_path, monkeypatch):
    """The stencil's points are logged one by one: a finished log is reused without a solve, an
    interrupted one is completed to the same values (--resume of the bootstrap)."""
    import json

    from cobot_analysis.models.ioc import uncertainty
    from cobot_analysis.models.ioc.recovery import synthetic_targets

    spec = replace(SPEC, fitted=("a2", "a4"))
    targets = synthetic_targets(spec, W, 2, noise=0.01)
    weights = dict(zip(names_for("improved"), map(float, W)))
    ck = tmp_path / "all.curvature.json"
    full = uncertainty.curvature(spec, targets, weights, checkpoint=ck)
    data = json.loads(ck.read_text())
    assert len(data["points"]) == 7  # 1 + 2k + k(k-1)
    data["points"] = data["points"][:3]  # interrupted after 3 of 7 points
    ck.write_text(json.dumps(data))
    again = uncertainty.curvature(spec, targets, weights, checkpoint=ck, resume=True)
    np.testing.assert_allclose(again.Hi, full.Hi, atol=1e-9)

    def no_solve(*_a, **_k):
        raise AssertionError("a finished checkpoint needs no solve")

    monkeypatch.setattr(uncertainty, "solve_target", no_solve)
    done = uncertainty.curvature(spec, targets, weights, checkpoint=ck, resume=True)
    np.testing.assert_allclose(done.H, full.H) and np.testing.assert_allclose(done.gi, full.gi)


def test_curvature_on_a_pool_gives_the_in_process_values():
    """The stencil solved on a pool of 2 processes (centre first, then the other points at once) gives the
    in-process values exactly."""
    from cobot_analysis.models.ioc import uncertainty
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.parallel import executor

    spec = replace(SPEC, fitted=("a2", "a4"))
    targets = synthetic_targets(spec, W, 2, noise=0.01)
    weights = dict(zip(names_for("improved"), map(float, W)))
    inline = uncertainty.curvature(spec, targets, weights)
    with executor(2) as pool:
        pooled = uncertainty.curvature(spec, targets, weights, pool=pool, chunks=2)
    np.testing.assert_array_equal(pooled.Di, inline.Di)
    np.testing.assert_array_equal(pooled.Hi, inline.Hi)
    assert pooled.lack_of_fit == inline.lack_of_fit


def test_trust_region_step_on_analytic_models():
    """The model step: Newton's step inside the radius, on the radius otherwise (|s| = r, the
    Moré-Sorensen shift), and along the negative curvature of an indefinite model."""
    from cobot_analysis.models.ioc.single_level import trust_region_step

    H, g = np.diag([1.0, 4.0]), np.array([-1.0, -4.0])
    np.testing.assert_allclose(trust_region_step(g, H, 10.0), [1.0, 1.0], atol=1e-12)
    s = trust_region_step(g, H, 0.5)
    assert abs(np.linalg.norm(s) - 0.5) < 1e-9 and (s > 0).all()
    s = trust_region_step(np.array([0.0, 1e-3]), np.diag([-2.0, 1.0]), 0.3)  # saddle: go down the -2 direction
    assert abs(np.linalg.norm(s) - 0.3) < 1e-9 and abs(s[0]) > 0.29


def test_a_rejected_step_is_not_tried_again():
    """After a rejected step the radius is divided by 4, and by 4 again while the model's step at the
    smaller radius is the rejected step itself (the Newton step inside the radius, or a step held by
    the search box): the fit never repeats a step it has just rejected from the same point."""
    from cobot_analysis.models.ioc.fit import LOG_BOUNDS
    from cobot_analysis.models.ioc.single_level import GRID, box_step, shrunk_radius

    H = np.diag([1.0, 4.0])
    g = -H @ np.array([0.006, 0.008])  # Newton step (0.006, 0.008): |s| = 0.01
    y = np.zeros(2)
    step = lambda r: box_step(g, H, y, r)  # noqa: E731
    s = step(1.0)
    np.testing.assert_allclose(s, [0.006, 0.008], rtol=1e-12)
    r = shrunk_radius(step, s, 1.0, 1e-3)
    assert r == 1 / 256  # 1/4, 1/16, 1/64 give the same step; 1/256 < 0.01 the first that does not
    assert abs(np.linalg.norm(step(r)) - r) < GRID  # on the radius, to the grid the steps end on
    on = step(0.005)  # a step on the radius: radius / 4 once
    assert abs(np.linalg.norm(on) - 0.005) < GRID and shrunk_radius(step, on, 0.005, 1e-3) == 0.005 / 4
    assert shrunk_radius(step, s, 1.0, 0.02) == 1 / 64  # below xtol: the fit stops there
    held = lambda r: box_step(np.array([1.0, -1.0]), H, np.array(LOG_BOUNDS), r)  # noqa: E731
    np.testing.assert_array_equal(held(0.3), [0.0, 0.0])  # both weights on a limit D pushes them past
    assert shrunk_radius(held, held(0.3), 0.3, 1e-3) < 1e-3


def test_branch_derivatives_match_finite_differences():
    """Along one lower-level branch (Newton's method on its KKT conditions), the sensitivity-based
    gradient and exact Hessian of the smoothed D in the fitted weights match central differences of
    D on the branch re-corrected at w +- h (noisy target: D and its derivatives are not zero)."""
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.buffered import BufferedCall
    from cobot_analysis.models.ioc.single_level import _Branch, lower_level, newton_functions, target_data
    from cobot_analysis.models.ioc.resampled_distance import ResampledDistance
    from cobot_analysis.models.oc.duration import initial_duration

    t = synthetic_targets(SPEC, W, 3, noise=0.02)[1]
    ocp = lower_level(SPEC)
    fi = [names_for("improved").index(n) for n in SPEC.fitted]
    newton, second = newton_functions(ocp, fi)
    calls = (BufferedCall(newton), BufferedCall(second), ResampledDistance(ocp, len(t.x), SPEC.angle, SPEC.angle_weight))
    b = _Branch(calls, ocp.parameters(t.start, t.goal, W, initial_duration(t.start, t.goal)), target_data(t), ocp.n_vars)
    _, sol = solve_target(SPEC, W, t, ("rest", "line"))
    assert b.correct(np.concatenate([sol.primal, np.zeros(ocp.n_cons)]), W, 1e-9)
    v0, g, H = b.v.copy(), b.g.copy(), b.H.copy()
    assert abs(g).max() > 1e-4  # a real gradient (the target is noisy, the weights its truth)

    def at(dw):
        w = W.copy()
        w[fi] += dw
        assert b.correct(v0 + b0S @ dw, w, 1e-10)
        return b.D, b.g.copy()

    b0S = b.S.copy()
    for j in range(len(fi)):
        h = 1e-4 * W[fi[j]]
        e = np.zeros(len(fi))
        e[j] = h
        (Dp, gp), (Dm, gm) = at(e), at(-e)
        assert abs((Dp - Dm) / (2 * h) - g[j]) < 1e-4 * abs(g[j]) + 1e-9, (j, (Dp - Dm) / (2 * h), g[j])
        np.testing.assert_allclose((gp - gm) / (2 * h), H[:, j], rtol=1e-3, atol=1e-6 * abs(H).max())


def test_feasible_path_recovers_noise_free_weights():
    """fit-ioc's single-level method (feasible-path SQP): noise-free paths, the fit from twice the
    truth; the weights come back within 1 %, D ~ 0 re-solved, the KKT conditions held throughout."""
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import fit_feasible_path

    targets = synthetic_targets(SPEC, W, 6)
    r = fit_feasible_path(_perturbed(SPEC), targets)
    assert r.success and r.failed == 0 and r.objective < 1e-4 < 1e-3 < r.start_objective, (r.objective, r.status)
    assert r.kkt_residual < 1e-8
    for n in SPEC.fitted:
        true = W[names_for("improved").index(n)]
        assert abs(r.weights[n] / true - 1) < 0.01, (n, r.weights[n], true)


def test_feasible_path_steps_do_not_follow_the_round_off_of_the_linear_algebra(monkeypatch):
    """The steps end on a grid of log10 w (``single_level.GRID``): the same fit, its KKT solves perturbed by
    1e-12 relative (another LU or BLAS would), takes the same steps to the same weights and D, to the last
    bit (without the grid, a difference of 1e-12 grew along the weights D hardly determines until the route
    changed: docs/benchmarks.md)."""
    from cobot_analysis.models.ioc import single_level as sl
    from cobot_analysis.models.ioc.recovery import synthetic_targets

    targets = synthetic_targets(SPEC, W, 6, noise=0.02)  # noisy: D stays above 0, the steps go on until xtol
    exact = sl.fit_feasible_path(_perturbed(SPEC), targets, probe=False)
    solve = sl._Factor.solve
    rng = np.random.default_rng(0)
    monkeypatch.setattr(sl._Factor, "solve", lambda self, b, trans=False: solve(self, b, trans) * (1 + 1e-12 * rng.standard_normal()))
    rounded = sl.fit_feasible_path(_perturbed(SPEC), targets, probe=False)
    assert rounded.iterations == exact.iterations > 3 and rounded.status == exact.status
    assert rounded.weights == exact.weights and rounded.objective == exact.objective
    assert rounded.nlp_objective != exact.nlp_objective  # the paths did differ by the round-off


def test_interval_reaching_a_search_limit_is_not_determined():
    """A weight the curvature calls determined but whose bootstrap interval reaches either search limit
    becomes "not determined"; one inside the box keeps its verdict; other verdicts are untouched."""
    from cobot_analysis.models.ioc.uncertainty import interval_verdicts

    v = {"a2": "determined", "a3": "determined", "a4": "determined", "a1": "only its ratio to a2 is determined"}
    out = interval_verdicts(v, {"a2": (7.3, 7.6), "a3": (1e-7, 586.0), "a4": (1.2, 1000.0), "a1": (1e-7, 1e3)})
    assert out["a2"] == "determined" and out["a1"] == v["a1"]
    assert out["a3"] == "not determined by these data (its 95 % interval reaches the search limit 1e-07)"
    assert out["a4"] == "not determined by these data (its 95 % interval reaches the search limit 1000)"


def test_subjects_at_the_start_weights_are_left_out_of_the_comparison():
    """Subjects whose fit ended at the shared start weights carry no evidence of agreement: with them the
    test would see identical estimates (Q = 0); without them it compares the subjects that moved."""
    from cobot_analysis.models.ioc.uncertainty import subjects_differ

    est = {"s1": {"a2": 10 ** 0.2}, "s2": {"a2": 10 ** 0.8}, "s3": {"a2": 10 ** 0.5}, "s4": {"a2": 10 ** 0.5}}
    sd = {s: {"a2": 0.05} for s in est}
    both = subjects_differ(est, sd)[0]
    moved = subjects_differ(est, sd, at_start={"s3", "s4"})[0]
    assert both["subjects"] == 4 and moved["subjects"] == 2 and moved["at_start"] == ["s3", "s4"]
    assert moved["Q"] == pytest.approx(0.6 ** 2 / 0.05 ** 2 / 2)  # two subjects, equal sd: Q = (y1 - y2)^2 / (2 s^2)
    assert moved["differ"] is True


def test_screen_keeps_the_points_below_the_bound():
    """The probes' screening (``single_level.screen``) on tables of D_i: the points below the bound and their
    D are those of solving every path at every point, a failed lower level drops its point, and no path is
    solved twice."""
    from cobot_analysis.models.ioc.single_level import screen

    rng = np.random.default_rng(3)
    for trial in range(40):
        m, n = 6, 12
        D = rng.uniform(0.2, 0.6, (m, n))
        D_now = rng.uniform(0.2, 0.6, n)
        bound = float(D_now.mean())
        fail = (2, 5) if trial % 4 == 0 else None
        calls = []

        def solve(pairs):
            calls.extend(len(p) for _, p in pairs)
            return [{i: (D[j, i], None if (j, i) == fail else f"z{j},{i}") for i in paths} for j, paths in pairs]

        found = screen(m, bound, D_now, solve)
        means = {j: D[j].mean() for j in range(m) if D[j].mean() < bound and (fail is None or j != fail[0])}
        assert sorted(found) == sorted(means) and sum(calls) <= m * n
        for j in means:
            assert found[j][0] == pytest.approx(means[j], rel=1e-12) and found[j][1] == {i: f"z{j},{i}" for i in range(n)}


def test_escape_probes_lie_in_the_plane_of_the_flattest_directions():
    """The escape probes of a converged point: 8 directions (axes and diagonals) in the plane of the two
    least-curved eigenvectors at each distance, none along the stiff one; clipped to the search box
    without duplicates; one fitted weight: +-d along its axis."""
    from cobot_analysis.models.ioc.fit import LOG_BOUNDS
    from cobot_analysis.models.ioc.single_level import PROBE_DISTANCES, escape_probes, on_grid

    y = np.array([0.5, -1.0, -2.0])
    pts = escape_probes(y, np.diag([5.0, 0.01, 0.04]))
    assert len(pts) == 8 * len(PROBE_DISTANCES)
    d = np.array(pts) - y
    np.testing.assert_allclose(d[:, 0], 0.0, atol=1e-12)  # the stiff direction is left alone
    np.testing.assert_allclose(sorted(set(np.round(np.linalg.norm(d, axis=1), 5))), PROBE_DISTANCES)
    assert np.array_equal(np.array(pts), on_grid(pts))  # on the grid the steps end on
    at_limit = escape_probes(np.array([LOG_BOUNDS[0]]), np.array([[0.1]]))  # one weight on the lower limit
    np.testing.assert_allclose(np.ravel(at_limit), [LOG_BOUNDS[0] + d for d in PROBE_DISTANCES])


def test_feasible_path_fits_the_time_gauge_to_measured_durations():
    """With the subjects' durations (here the truth's walked 1.25 times slower), the fit starts at the
    durations' time gauge and reports its own, as the bi-level fit: the weights come back as the truth
    with a1..a3 x c^4, c = 1.25 to 1e-3, every duration c times the truth's, D ~ 0."""
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import fit_feasible_path

    targets = synthetic_targets(SPEC, W, 6)
    T = np.array([solve_target(SPEC, W, t, ("rest", "line"))[0]["T"] for t in targets])
    r = fit_feasible_path(_perturbed(SPEC), targets, measured_T=1.25 * T)
    assert abs(r.pace["c_start"] * r.pace["c"] / 1.25 - 1) < 1e-3  # a1 held: the start's gauge and the fit's make 1.25
    np.testing.assert_allclose(r.pace["calibrated_T"], 1.25 * T, rtol=1e-3)
    assert r.objective < 1e-4 and r.failed == 0, (r.objective, r.status)
    names = names_for("improved")
    for n in ("a1", *SPEC.fitted):
        scale = 1.25 ** 4 if n in ("a1", "a2", "a3") else 1.0
        assert abs(r.weights[n] / (W[names.index(n)] * scale) - 1) < 0.01, (n, r.weights[n], W[names.index(n)] * scale)


def test_probe_chunk_solves_warm_from_the_given_path():
    """An escape probe's lower level (``probe_chunk``): warm from a path solved at the same weights it returns
    that path and the D of ``fit.solve_target``; at weights 30 times larger in a2 it converges to a path of
    those weights (another D; here the least-cost one, so the same as solve_target's from that path and the
    two cold guesses)."""
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import probe_chunk

    t = synthetic_targets(SPEC, W, 2)[1]
    d, sol = solve_target(SPEC, W, t, ("rest", "line"))
    (D, z), = probe_chunk((SPEC, W, [(t, sol.primal)]))
    assert D == pytest.approx(d["D"], rel=1e-9) and np.abs(z - sol.primal).max() < 1e-6
    w2 = W.copy()
    w2[2] *= 30
    (D2, z2), = probe_chunk((SPEC, w2, [(t, sol.primal)]))
    d2, sol2 = solve_target(SPEC, w2, t, sol.primal)  # warm and the two cold guesses, the least cost kept
    assert abs(D2 - d["D"]) > 1e-4 and np.isfinite(D2)
    assert np.abs(sol2.primal - z2).max() < 1e-6 and D2 == pytest.approx(d2["D"], rel=1e-9)  # here the least-cost one


def test_per_subject_fits_are_submitted_longest_first(monkeypatch):
    """api.fit_ioc(per="subject", method="single-level") submits one whole fit per subject (``fit_task``), the
    subjects with the most paths first (ties in subject order), so the short fits fill the workers' ends."""
    from cobot_analysis.api.models import fit_ioc
    from cobot_analysis.models.ioc import single_level
    from cobot_analysis.synth.tables import walking_table

    trials = walking_table(n_subjects=3, n_conditions=3, n_trials=1, missing_theta=0.0)
    trials = trials[trials["kind"] == "trial"]
    subjects = sorted(trials["subject"].unique())
    assert len(subjects) == 3
    keep = {subjects[0]: 2, subjects[1]: 3, subjects[2]: 2}  # paths per subject: 2, 3, 2
    trials = trials[[t in trials[trials["subject"] == s]["trial"].unique()[:keep[s]]
                     for s, t in zip(trials["subject"], trials["trial"])]]
    submitted = []

    class Submitted(Exception):
        pass

    def record(task):
        submitted.append((task[1][0].subject, len(task[1])))
        raise Submitted

    monkeypatch.setattr(single_level, "fit_task", record)
    with pytest.raises(Submitted):
        fit_ioc(trials, trials=trials, per="subject", method="single-level", fit=["a2"], intervals=20, compare=False, jobs=1,
                bootstrap=0)
    assert submitted == [(subjects[1], 3), (subjects[0], 2), (subjects[2], 2)]


def test_a_fit_that_ends_above_its_start_keeps_the_start(monkeypatch):
    """When no round ends below the start's D (re-solved D, as the bi-level fit solves the lower levels), the
    fit keeps the start: its weights, its paths and its D, and says so (success False). Here every re-solve
    at a round's end is made to cost 1 more per path than it does."""
    import importlib

    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import fit_feasible_path

    fit_module = importlib.import_module("cobot_analysis.models.ioc.fit")  # the package's ``fit`` is the function
    solve = fit_module.evaluate_chunk

    def dearer(task):
        return [({**d, "D": d["D"] + 1.0}, z) for d, z in solve(task)]

    targets = synthetic_targets(SPEC, W, 4)
    spec = _perturbed(SPEC)
    monkeypatch.setattr(fit_module, "evaluate_chunk", dearer)
    r = fit_feasible_path(spec, targets, probe=False)
    assert not r.success and "no round ended below the start" in r.status, r.status
    assert r.objective == r.start_objective < 1.0, (r.objective, r.start_objective)
    names = names_for(spec.model)
    assert all(r.weights[n] == spec.start_weights[names.index(n)] for n in spec.fitted), r.weights
    monkeypatch.setattr(fit_module, "evaluate_chunk", solve)
    honest = fit_feasible_path(spec, targets, probe=False)  # the same fit, its re-solves as they are
    assert honest.success and honest.objective < honest.start_objective and "no round" not in honest.status
