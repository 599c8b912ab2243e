"""Trajectory prediction (docs/methods.md sec. 7): the ``Predictor`` interface and the receding-horizon
optimal-control predictor.

A predictor sees the measured poses ``C_k = (cx, cy, ctheta)``, one every ``T_OC`` seconds, and at
each sample ``k >= N0 - 1`` (0-based) predicts the poses ``k .. k + H``, ``H = N_OC - N0``, from the
last ``N0`` poses (the window's measured past ``n+1 .. k``, ``n = k - N0``). Two ways to use it:

    p = make_predictor("oc", n0=50, n_oc=100, dt=0.01)
    for pose in stream:                      # online, e.g. on the robot
        path = p.update(pose)                # (H + 1, 3) array, or None (not enough past / skipped)
    predictions = p.predict_offline(poses)   # whole trajectory: (N - N0 + 1, H + 1, 3), NaN = skipped

``predict_offline`` is ``update`` in a loop, so both modes give identical predictions.
A window is skipped (NaN prediction, counted in ``skipped``) when its past holds a NaN position, or
counted in ``failed`` when the OC solver does not converge. A NaN orientation is not a skip: the
walker's theta is then unknown and the OC predictor tracks the direction of travel in its place (see ``OCPredictor``).
"""

from __future__ import annotations


import numpy as np

from cobot_analysis.errors import InputError
from cobot_analysis.models.dynamics import coast
from cobot_analysis.models.prediction.base import Predictor
from cobot_analysis.models.prediction.goal import quadratic_fit

PREDICTORS = ("oc", "cv", "ctrv", "goal", "goal-inferred")
# m: the body's scale for the direction of travel (``heading``): about a foot length, the base of support within
# which the pelvis stays while a person steps round on the spot (docs/methods.md sec. 7)
BODY_RADIUS = 0.25


def make_predictor(name: str, n0: int, n_oc: int, dt: float = 1.0, *, convention="continuous", **options) -> Predictor:
    """A predictor by name: ``oc`` (options: weights, g0, g1, ...; ``convention``, docs/methods.md
    sec. 11), ``cv`` or ``ctrv`` (one step per sample: the same under both conventions), ``goal``
    (options: goal, weights) or ``goal-inferred`` (options: candidates, weights), docs/methods.md
    sec. 7.1, continuous convention only."""
    from cobot_analysis.models.prediction.baselines import ConstantTurnRateVelocity, ConstantVelocity
    from cobot_analysis.models.prediction.goal import GoalInferencePredictor, GoalPredictor

    if name == "cv":
        return ConstantVelocity(n0, n_oc, dt)
    if name == "ctrv":
        return ConstantTurnRateVelocity(n0, n_oc, dt)
    if name == "oc":
        return OCPredictor(n0, n_oc, dt, convention=convention, **options)
    if name in ("goal", "goal-inferred"):
        from cobot_analysis import conventions

        if conventions.get(convention).name != "continuous":
            raise InputError(f"the {name} predictor is ours, defined under the continuous convention only",
                             remedy="pass --convention continuous or leave it out of --predictors")
        cls = GoalPredictor if name == "goal" else GoalInferencePredictor
        return cls(n0, n_oc, dt, **options)
    raise InputError(f"--predictors: unknown predictor {name!r}", remedy=f"use some of {', '.join(PREDICTORS)}")


class OCPredictor(Predictor):
    """Receding-horizon OC predictor of docs/methods.md sec. 7 on the OC solver of ``models.oc.problem``.

    Window at sample k: ``N_OC - 1`` intervals of ``T_OC`` (nodes = samples n+1 .. n+N_OC) with the
    running cost ``a0 + a1 u1^2 + a2 u2^2 + a3 u3^2``, the tracking cost
    ``g0 ((cx_i - x_i)^2 + (cy_i - y_i)^2) + g1 (ctheta_i - theta_i)^2`` on the first N0 nodes (the
    measured past) and nothing else: no goal, no terminal cost (a4 = a5 = a6 = b = 0), a free end.

    How it is solved: the future nodes carry no state cost, so whatever the state X_k reached at
    the last measured node, the future's optimal controls are zero (cost a0 per interval, a
    constant). The window problem therefore separates exactly into (1) the OC problem over the
    measured past alone (N0 - 1 intervals, tracking on every node, free end), solved with the shared
    solver of ``models.oc.problem``, and (2) the coast of ``dynamics.coast`` from X_k over the H future
    samples (``step`` with U = 0). Same optimum as the whole window (tests/test_predict.py), with
    N0 instead of N_OC nodes in the NLP.
    The cost weights a0..a3 come from a preset or a fitted-weights file (``presets.load_weights``;
    the walking-2021 preset is docs/methods.md's a = (7.9, 4.0, 20.1, 1e-6) unrounded).

    The convention (``conventions.Convention.prediction``, docs/methods.md sec. 11) fixes the node
    step, the start and the warm start; the step scheme is that of the convention's improved model:

    - ``continuous``: node step = the sample period ``dt``, exact-in-time step (``midpoint``),
      integrated costs, start velocity estimated (below), warm starts;
    - ``published`` (the authors' code): node step 0.1 s whatever ``dt``, explicit Euler, costs
      summed per node, every window from rest at its first measured pose made the origin,
      ``X_0 = (0, 0, ctheta_{n+1}, 0, 0, 0)``, tracking ``(cx_i - cx_{n+1}, cy_i - cy_{n+1}, ctheta_i)``,
      cold solves, the Euler coast ``x_{j+1} = x_j + 0.1 R(theta_j) v``, ``theta_{j+1} = theta_j + 0.1 omega``.

    Under both the window separates (same argument: no state cost on the future).

    Tracking weights, continuous. The thesis's problem (published convention) makes each sample a node
    of h = 0.1 s and sums ``a1 u^2 + g0 e^2`` per node. Written in real time (sample period dt, time
    stretched by h / dt), its controls are ``u = u_real (dt / h)^2``, so the same optimum in the
    continuous form ``sum dt [a1 u_real^2 + g0' e^2]`` needs ``g0' = g0 (h / dt)^4`` (g1 likewise).
    Integrating the thesis's g0 = 10 as a rate instead (as before) made the tracking so light that the
    window's estimate at sample k was the coast of the window's start state, 4-11 cm off the measured
    pose, and the further off the longer the window N0: an error that grew as the horizon shrank.

    Initial state, continuous (node 0 = the measured pose C_{n+1}; "at rest" is not assumed): the velocities are
    the derivative at node 0 of a least-squares quadratic through the first ``fit`` measured poses
    (x, y, unwrapped theta) of the window, rotated into the walker frame:
    ``v_forw = cos(th) x' + sin(th) y'``, ``v_orth = -sin(th) x' + cos(th) y'``, ``omega = theta'``.

    Missing orientation (theta NaN anywhere in the window), both conventions: the walker faces where
    it goes (gamma = 0, as the start heading of the models assumes), so the window tracks the
    direction of travel ``heading(past)`` as its theta, with the same g1: the tracked-theta problem
    with a derived theta; the direction of travel is the path's tangent, or, in a window whose path curves
    tighter than the body (``BODY_RADIUS``: a turn on the spot), its displacement at the body's scale.
    (Tracking positions only, g1 = 0, left theta free but for R(theta), and
    omega nearly free with a3 = 1e-6: the solution could spin the body through full turns inside a
    window while x, y tracked, and which of the many 2 pi windings the solver found, hence the
    prediction, depended on its initial guess.) The predicted theta is then the model's, not a
    measurement's.

    The first predicted point, continuous: the coast starts from X_k moved onto the state estimate at
    sample k (position of the least-squares quadratic through the last ``fit`` poses, as the goal
    planner's ``goal.state_estimate``), heading and body-frame velocities those of X_k. X_k itself is
    the free end of a compromise: a pelvis yaw swaying with the gait, which the model walker cannot
    walk, pulled it 1-2.7 cm (median per trial, walking-2020) off the measured pose. The published convention coasts from X_k (thesis).

    Warm start: the previous window's solution shifted by one node (the last node extrapolated
    with its own velocity), its theta moved by the whole turns that put its node 0 on x0's branch;
    cold start (first window, after a skipped or failed window): the
    measured past on the first N0 nodes, then the last measured displacement extrapolated.
    What the prediction is, then: the walker coasting with the body-frame velocities
    (v_forw, v_orth, omega) reached at sample k: a circular arc whose curvature is omega / speed.
    With the walking weights a3 = 1e-6 the arc follows the turn rate of the tracked theta at k,
    a swaying gait's included (see docs/results.md for the measured errors against the baselines).

    A window whose solve fails (fatrop, then IPOPT) gives no prediction and is counted in ``failed``.
    ``warm_start=False`` solves every window cold (same optimum, for comparison and benchmarks).
    """

    name = "oc"
    min_past = 3

    def __init__(self, n0: int, n_oc: int, dt: float = 1.0, *, weights: str | dict | None = "walking-2021",
                 g0: float = 10.0, g1: float = 10.0, fit: int = 5, tol: float = 1e-8, solver: str = "fatrop",
                 convention="continuous", warm_start: bool | None = None):
        from cobot_analysis import conventions
        from cobot_analysis.models.oc.problem import OCPShape, get_ocp
        from cobot_analysis.models.presets import load_weights

        conv = conventions.get(convention)
        rule = conv.prediction
        self.convention = conv
        self.rest_start = rule.start == "rest"
        self.scheme = conv.oc_rule("improved").scheme
        w = load_weights(weights, "improved")
        # running control cost only: no bearing, goal or heading terms, no terminal cost (free end)
        self.weights = np.array([w["a0"], w["a1"], w["a2"], w["a3"]] + [0.0] * 7)
        self.g = (float(g0), float(g1))
        self.fit = int(fit)
        self.warm_start = rule.warm_start if warm_start is None else bool(warm_start)
        # the measured past (see above)
        self.ocp = get_ocp(OCPShape(n_intervals=n0 - 1, tol=tol, solver=solver, scheme=self.scheme))
        super().__init__(n0, n_oc, dt)
        self.step = float(rule.node_dt) if rule.node_dt is not None else self.dt  # seconds per node
        # g0, g1 are the thesis's weights per node of its 0.1 s step; in real time (continuous) the same
        # problem tracks with g (h / dt)^4 against the integrated control costs (see the class docstring)
        scale = 1.0 if rule.node_dt is not None else (conventions.PUBLISHED.prediction.node_dt / self.step) ** 4
        self.track_weights = (self.g[0] * scale, self.g[1] * scale)
        # derivative at t = 0 of the least-squares quadratic c0 + c1 t + c2 t^2 through the first
        # ``fit`` samples of a window: c1 = d . p (a fixed filter, computed once)
        t = np.arange(min(self.fit, self.n0)) * self.step
        self._derivative = np.linalg.pinv(np.vander(t, 3, increasing=True))[1]
        self._estimate = quadratic_fit(min(self.fit, self.n0), self.dt)[0]  # position at the last of ``fit`` samples
        self._travel = travel_filters(self.n0, self.fit)  # direction of travel (positions only)

    def reset(self) -> None:
        super().reset()
        self._warm: np.ndarray | None = None
        self.last_solution = None

    def on_skip(self) -> None:
        self._warm = None

    # -- initial state ------------------------------------------------------------------------------
    def initial_state(self, past: np.ndarray) -> tuple[np.ndarray, bool]:
        """Start state X0 = (x, y, theta, v_forw, v_orth, omega) at node 0, and whether theta was
        measured; at rest under the published convention (``rest_start``)."""
        return self._initial_state(past, *self._orientation(past))

    def _orientation(self, past: np.ndarray) -> tuple[np.ndarray, bool]:
        """The theta the window tracks: the measured one, else ``heading(past)``; and whether measured."""
        has_theta = bool(np.isfinite(past[:, 2]).all())
        if has_theta:
            return past[:, 2], True
        travel = self._travel if len(past) == self.n0 else travel_filters(len(past), self.fit)
        return heading(past, travel), False

    def _initial_state(self, past: np.ndarray, angles: np.ndarray, has_theta: bool) -> tuple[np.ndarray, bool]:
        d = self._derivative
        m = len(d)
        theta = angles[0]
        if self.rest_start:
            return np.array([past[0, 0], past[0, 1], theta, 0.0, 0.0, 0.0]), has_theta
        vx, vy, omega = d @ past[:m, 0], d @ past[:m, 1], d @ angles[:m]
        c, s = np.cos(theta), np.sin(theta)
        return np.array([past[0, 0], past[0, 1], theta, c * vx + s * vy, -s * vx + c * vy, omega]), has_theta

    def _cold_guess(self, track: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """The tracked past at x0's velocities, zero controls."""
        ocp = self.ocp
        w = np.zeros(ocp.n_vars + ocp.nu)  # layout x0 u0 ... x_N (u_N): the nodes as the rows of one view
        nodes = w.reshape(ocp.N + 1, ocp.nx + ocp.nu)
        nodes[:, :3] = track  # node k of the N0 - 1 intervals = tracked sample k
        nodes[:, 3:6] = x0[3:6]
        return w[: ocp.n_vars]

    def _shifted(self, previous: np.ndarray) -> np.ndarray:
        """Previous primal shifted by one node: new node j = old node j + 1; the last node moves on."""
        ocp = self.ocp
        stride = ocp.nx + ocp.nu
        size = len(previous)  # layout x0 u0 x1 u1 ... x_{N-1} u_{N-1} x_N
        w = previous.copy()  # keeps u_{N-1} in place: new u_{N-1} = old u_{N-1}
        w[: size - stride] = previous[stride:]  # new x_j, u_j = old x_{j+1}, u_{j+1}; new x_{N-1} = old x_N
        w[-ocp.nx:] = coast(previous[-ocp.nx:], self.step, 1, scheme=self.scheme)[1]  # the last node coasts on by one node
        return w

    # -- one window ---------------------------------------------------------------------------------
    def predict(self, past: np.ndarray) -> np.ndarray | None:
        angles, has_theta = self._orientation(past)
        x0, _ = self._initial_state(past, angles, has_theta)
        origin = np.array([x0[0], x0[1], 0.0]) if self.rest_start else np.zeros(3)  # published: first pose at the origin
        track = past - origin
        if not has_theta:
            track[:, 2] = angles
        x0[:3] -= origin  # x0 is this window's own array
        if self._warm is None:
            guess = self._cold_guess(track, x0)
        else:
            guess = self._shifted(self._warm)
            turns = np.round((x0[2] - guess[2]) / (2 * np.pi))
            if turns:  # the shifted guess onto x0's branch (a derived heading starts in (-pi, pi])
                guess[self.ocp._xi[:, 2]] += 2 * np.pi * turns
        guess[:6] = x0
        far = (x0[0] + 1e3, x0[1] + 1e3, 0.0)  # the goal enters no cost (zero weights); kept away from psi's singularity
        T = self.step if self.scheme == "euler" else (self.n0 - 1) * self.step  # euler: the parameter is the node step
        sol = self.ocp.solve(x0[:3], far, self.weights, T, guess=guess, start_velocity=x0[3:],
                             track=track, track_weights=self.track_weights,
                             n_track=self.n0, stats=False)  # converged or not is all a window needs
        self.last_solution = sol
        if not sol.success:
            self._warm = None
            return None
        self._warm = sol.primal if self.warm_start else None
        start = sol.X[-1].copy()
        if not self.rest_start:  # continuous: from the state estimate at k (class docstring)
            start[:2] = self._estimate @ past[-len(self._estimate):, :2]
        return coast(start, self.step, self.horizon, scheme=self.scheme)[:, :3] + origin


def travel_filters(n: int, fit: int = 5) -> np.ndarray:
    """(2, n, n) matrices D1, D2: ``D1 @ p``, ``D2 @ p`` are, at each of n samples, the first and second derivatives per
    sample of the least-squares quadratic through the ``fit`` samples around it (Savitzky-Golay; at the ends, through
    the first or last ``fit``)."""
    from scipy.signal import savgol_filter

    m = min(fit, n)
    return np.stack([savgol_filter(np.eye(n), m, min(2, m - 1), deriv=d, axis=0, mode="interp") for d in (1, 2)])


def heading(past: np.ndarray, travel: np.ndarray, radius: float = BODY_RADIUS) -> np.ndarray:
    """The direction of travel at every sample of ``past`` (x, y in m), unwrapped from its first value in (-pi, pi].
    No time enters: the same on any time base (docs/methods.md sec. 7).

    Where the path curves no tighter than the body, radius of curvature ``|p'|^3 / |p' x p''| > radius`` at every
    sample (``(p', p'') = travel @ p``, ``travel_filters``; a path that does not move has none), it is the tangent
    ``atan2(y', x')``. Elsewhere the pelvis steps round a spot (a turn on the spot, a loop) and its tangent is not
    where the body goes: the whole window takes the direction of the path's displacement at the body's scale, ``atan2`` of
    ``V_i = sum_j w(|m_j - p_i| / radius) (p_{j+1} - p_j)`` (``m_j`` the middle of step j, ``w(u) = (1 - u^2)^2``
    for u < 1, else 0), in which a loop inside the disc adds up to about nothing."""
    p = past[:, :2]
    d1, d2 = travel @ p
    if (np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) * radius < np.hypot(d1[:, 0], d1[:, 1]) ** 3).all():
        return unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
    step = p[1:] - p[:-1]
    x, y = past[:, 0].copy(), past[:, 1].copy()
    dx = 0.5 * (x[1:] + x[:-1]) - x[:, None]  # (sample i, step j): m_j - p_i, in place below (no temporaries)
    dy = 0.5 * (y[1:] + y[:-1]) - y[:, None]
    dx *= dx
    dy *= dy
    u2 = np.add(dx, dy, out=dx)  # |m_j - p_i|^2 / radius^2
    u2 /= radius ** 2
    w = np.subtract(1.0, u2, out=u2)
    np.maximum(w, 0.0, out=w)
    w *= w
    v = w @ step
    return unwrap(np.arctan2(v[:, 1], v[:, 0]))


def unwrap(a: np.ndarray) -> np.ndarray:
    """``np.unwrap(a)`` (period 2 pi) bit for bit, with its corrections skipped where no step reaches pi (they are all
    zero then; np.unwrap still adds them, which makes a -0.0 after the first sample 0.0)."""
    if (np.abs(a[1:] - a[:-1]) < np.pi).all():
        out = a + 0.0
        out[:1] = a[:1]
        return out
    return np.unwrap(a)
