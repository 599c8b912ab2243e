"""Goal-aware prediction (docs/methods.md sec. 7.1): at each window, the walking model's OC from the
current state estimate to the goal, re-planned every window, read at the person's own pace.

Window at sample k (the measured past ``C_{k-N0+1} .. C_k``):

1. State estimate (``state_estimate``): the least-squares quadratic through the last ``fit`` poses
   (x, y, unwrapped heading), evaluated at sample k: position, world velocity ``(x', y')``, heading and
   its rate, rotated into the walker frame
   ``v_forw = cos(th) x' + sin(th) y'``, ``v_orth = -sin(th) x' + cos(th) y'``, ``omega = th'``. The
   heading is the direction of travel (so v_orth = 0), even where theta was measured: the measured
   pelvis orientation of walking-2020 swings with the gait at up to 50 rad/s, which put into the
   start state (omega) curls the plan. Below ``MIN_SPEED`` the walker stands: theta is the measured
   one (else the past's displacement direction) and omega = 0. The plan starts with omega = 0
   (``plan_start``): the rate of the direction of travel over a past shorter than a stride is the
   gait's sway, not a turn of the path the model walks.
2. Plan: the improved OC of docs/methods.md sec. 5.5 (continuous convention: integrated running cost,
   exact-in-time step, free duration, ``models.oc.problem``) on ``N_INTERVALS`` intervals from that
   state (pose *and* velocity: the path starts at the measured speed) to the goal pose at rest, a
   terminal constraint (``OCPShape(goal="constraint")``); solved afresh in every window, from rest at the start
   state, and, where that plan spins (``spins``: a full turn beyond its pose change), from the straight line to
   the goal too, the lower-cost plan kept; not warm-started from the previous window's plan: a warm start kept
   the plans in a local minimum, a loop near the goal, from window to window (docs/methods.md sec. 7.1).
   The turning weight a3 (price of the angular acceleration u3): the weights' own, unless they leave it
   undetermined (``turn_weight_undetermined``: on the fits' lower bound), then the one identified on
   the continuations of the study's mean paths (``identify_turn_weight``). Why: with a3 on its bound
   turning the body at a constant body-frame velocity is free, so a plan started in motion swings its
   direction of travel onto the goal at once (a human turns gradually); the fits started every path
   at rest, where turning on the spot is free anyway, and could not see a3.
   The goal heading is put on the branch nearest the current heading; an unknown one is the goal's
   bearing from x0. A plan that fails or misses the goal (``models.goal_check``) is no prediction.
3. Read at the person's pace: the plan's path (cubic Hermite in x, y, theta between its nodes) walked
   at the measured speed ``v_k = sqrt(v_forw^2 + v_orth^2)``: prediction j (sample k + j) is the plan's
   pose at arc length ``min(j T_s v_k, L)``, ``L`` the plan's length (the walker stops at the goal). The
   plan's own time law is not used (its speed scale is a0's, not identified by the published fits).

Candidate goals (``GoalInferencePredictor``, the goal not known): the same plan towards every candidate
g in G. The candidates are positions (heading: the bearing, as above). Evidence is
accumulated over disjoint segments of N0 samples: the plans made at a segment's first sample j are
kept (inside a segment only the plans the prediction needs are solved: the most probable goal's, the next
one's if it fails), and the segment's log-likelihood of g is ``-d_g^2 / 2 sigma^2`` with
``d_g = (1/(k - j + 1)) sum_{i=j..k} ||c_i - x*_g,i||``;
``log p(g | past) = sum over the finished segments + the current one's`` (normalised). ``sigma = SIGMA``
m, the size of the improved OC's path error against human paths (docs/methods.md sec. 5.5: d_xy about
0.08 m). The prediction is the plan towards the most probable goal.
"""

from __future__ import annotations

import math
import numpy as np

from cobot_analysis.errors import InputError
from cobot_analysis.models import GOAL_EXTENT as LAB_EXTENT  # the lab's bound on a goal, generate's too
from cobot_analysis.models import spins
from cobot_analysis.models.prediction.base import Predictor

N_INTERVALS = 20  # intervals of the plan: solved afresh every window
SIGMA = 0.08  # m: path error of the improved OC against human paths (docs/methods.md sec. 5.5)
ARRIVED = 0.01  # m: closer to the goal than this the walker is predicted to stay
DENSE = 200  # points of the plan's arc-length table
MAX_ITER = 100  # solver iterations per plan: a 20-interval plan converges in tens (some warm-started solves near a
# standing table ran for minutes without a bound)
MIN_SPEED = 0.05  # m/s: below this the walker stands: its direction of travel is undefined
PLAN_CPU_LIMIT = 1.0  # s of CPU per candidate plan (IPOPT's max_cpu_time): a plan takes milliseconds; one that does not
# is stopped and counted as failed (models.oc.problem: fatrop's solves have no such bound)
A3_UNDETERMINED = 1e-6  # a3 at or below this sits on a fit's lower bound (ours 1e-7, walking-2021's published 1e-6)
CONTINUATIONS = (0.25, 0.5, 0.75)  # where along a mean path the continuations of identify_turn_weight start
NOMINAL_SPEED = 1.0  # m/s: the duration guess's pace at least (the sweep's assumed mean walking speed): a guess from
# a walker barely moving (1.5 m in 30 s) made solves from rest run for minutes


def check_goal(goal, option: str = "--goal") -> tuple[float, float, float]:
    """A goal pose (x, y, theta) inside the lab (``LAB_EXTENT``), else ``InputError``."""
    g = tuple(float(v) for v in goal)
    if len(g) == 2:
        g = (*g, float("nan"))
    if len(g) != 3 or not (math.isfinite(g[0]) and math.isfinite(g[1])):
        raise InputError(f"{option} {goal!r} is not a goal x, y[, theta]", remedy=f"pass {option} as x,y or x,y,theta in metres and radians")
    if abs(g[0]) > LAB_EXTENT or abs(g[1]) > LAB_EXTENT:
        raise InputError(f"{option} ({g[0]:g}, {g[1]:g}) lies outside the lab (|x|, |y| <= {LAB_EXTENT:g} m in the study frame)",
                         remedy=f"give a goal in the study's frame, within {LAB_EXTENT:g} m of its origin")
    return g


def check_candidates(candidates, option: str = "--candidates") -> np.ndarray:
    """Candidate goal positions (M, 2), M >= 1, each inside the lab."""
    cands = [check_goal(c, option)[:2] for c in (() if candidates is None else candidates)]
    if not cands:
        raise InputError(f"{option}: the candidate-goal set is empty", remedy="give at least one candidate goal x,y (or use the goal-known predictor 'goal')")
    return np.array(cands, dtype=float)


def check_reachable(trajectories, goal, n0: int, weights_for, option: str = "--goal") -> None:
    """Refuse a goal the model does not reach: the plan (``Planner``, cold) from each trajectory's first
    window with a finite past (N0 samples) to ``goal`` must converge and end on it, else ``InputError``
    naming ``option`` and the trajectory."""
    for traj in trajectories:
        finite = np.isfinite(traj.poses[:, :2]).all(axis=1).astype(int)
        starts = np.flatnonzero(np.convolve(finite, np.ones(n0, dtype=int), mode="valid") == n0)
        if not starts.size or not traj.dt > 0:
            continue
        past = traj.seen[starts[0]: starts[0] + n0]
        planner = Planner(_weights(weights_for(traj.entity)), traj.dt)
        if plan_path(planner, plan_start(past, quadratic_fit(min(5, n0), traj.dt)), goal, 1) is None:
            raise InputError(f"{option} ({goal[0]:g}, {goal[1]:g}, {goal[2]:g}): the walking model cannot reach it from "
                             f"{traj.label} (its plan failed: {planner.status})",
                             remedy=f"give a goal the walker can reach, in the study frame (m, rad), or leave 'goal' out of --predictors")


def quadratic_fit(n: int, dt: float) -> np.ndarray:
    """(2, n) filter: rows give the value and the derivative at the last of ``n`` samples ``dt`` apart
    of the least-squares quadratic (a line when n < 3)."""
    t = (np.arange(n) - (n - 1)) * dt
    pinv = np.linalg.pinv(np.vander(t, min(3, n), increasing=True))
    return pinv[:2]


def state_estimate(past: np.ndarray, filt: np.ndarray, travel: bool = False) -> np.ndarray:
    """X_k = (x, y, theta, v_forw, v_orth, omega) at the last sample of ``past`` (see module docstring);
    ``travel``: theta is the direction of travel (v_orth = 0) even where it was measured. A walker
    slower than ``MIN_SPEED`` stands: its direction of travel is noise, so theta is the measured one
    (else the direction of the whole past's displacement) and omega = 0."""
    m = filt.shape[1]
    p = past[-m:]
    if np.isfinite(p[:, 2]).all() and not travel:
        angles = np.unwrap(p[:, 2])
    else:  # direction of travel
        angles = np.unwrap(np.arctan2(np.gradient(p[:, 1]), np.gradient(p[:, 0])))
    (x, vx), (y, vy), (th, om) = filt @ p[:, 0], filt @ p[:, 1], filt @ angles
    if math.hypot(vx, vy) < MIN_SPEED:
        om = 0.0
        if math.isfinite(past[-1, 2]):
            th = float(past[-1, 2])
        else:
            d = past[-1, :2] - past[np.isfinite(past[:, :2]).all(axis=1)][0, :2]
            th = math.atan2(d[1], d[0]) if np.hypot(*d) > 0 else th
    c, s = math.cos(th), math.sin(th)
    return np.array([x, y, th, c * vx + s * vy, -s * vx + c * vy, om])


def plan_start(past: np.ndarray, filt: np.ndarray) -> np.ndarray:
    """The goal plan's start state: ``state_estimate`` with the heading the direction of travel, and omega = 0.
    The model walker has no gait: its omega is the turn rate of the gait-averaged path, which a past shorter
    than a stride cannot separate from the gait's sway (on the walking-2020 trials, walked at 1 m/s, the
    rate of the direction of travel had a median of 1.6 rad/s from the last 5 samples and 2.1 rad/s from
    the whole past of 50: turning radii of 0.5 m). The turn is left to the plan (its a3 prices it).
    The heading is the local tangent even where the path curves tighter than the body: the OC predictor's
    body-scale heading (``predictor.heading``) predicted worse here at every horizon (docs/methods.md sec. 7.1)."""
    x0 = state_estimate(past, filt, travel=True)
    x0[5] = 0.0
    return x0


class Planner:
    """The improved OC from a state to a goal pose at rest, solved afresh every window (module
    docstring, 2-3)."""

    def __init__(self, weights: np.ndarray, dt: float, n_intervals: int = N_INTERVALS, tol: float = 1e-6,
                 solver: str = "fatrop", max_cpu_time: float = 0.0):
        from cobot_analysis.models.oc.problem import OCPShape, get_ocp

        self.ocp = get_ocp(OCPShape(n_intervals=n_intervals, free_time=True, tol=tol, goal="constraint", max_iter=MAX_ITER,
                                    solver=solver, max_cpu_time=max_cpu_time))
        self.weights, self.dt = weights, float(dt)
        self.status = ""  # why the last plan failed

    def plan(self, x0: np.ndarray, goal) -> "object | None":
        """The OC solution from ``x0`` to ``goal`` at rest, or None if it failed or missed the goal.

        The goal heading goes on the branch nearest x0's; an unknown heading (NaN) is the bearing of the
        goal from x0 (the walker arrives walking straight in)."""
        from cobot_analysis.models import goal_check

        gth = goal[2] if math.isfinite(goal[2]) else math.atan2(goal[1] - x0[1], goal[0] - x0[0])
        target = (goal[0], goal[1], x0[2] + math.remainder(gth - x0[2], 2 * math.pi))
        dist = math.hypot(goal[0] - x0[0], goal[1] - x0[1])
        speed = math.hypot(x0[3], x0[4])
        T0 = max(dist / max(speed, NOMINAL_SPEED), 10 * self.dt)  # a guess at a walking pace; T is free in [0.4, 2.5] T0
        sol = None
        for guess in ("rest", "line"):
            s = self.ocp.solve(x0[:3], target, self.weights, T0, guess=guess, start_velocity=x0[3:])
            if s.success and not goal_check(s.X[:, 0], s.X[:, 1], s.X[:, 2], target)["goal_reached"]:
                s.success, s.status = False, "plan misses the goal"  # a converged solve is not a result
            if sol is None or (s.success and (not sol.success or s.cost < sol.cost)):
                sol = s
            if sol.success and not spins(sol.X[:, 2]):  # a plausible plan: no second guess
                break
        self.status = "" if sol.success else f"{sol.solver}: {sol.status}"
        return sol if sol.success else None

    def read(self, sol, horizon: int, speed: float) -> np.ndarray:
        """Poses j = 0..horizon of the plan walked at ``speed`` (m/s): at arc length ``min(j dt speed, L)``."""
        dense = self._at(sol, np.linspace(0.0, sol.T, DENSE + 1))
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(dense[:, :2], axis=0).T))])
        sj = np.minimum(np.arange(horizon + 1) * self.dt * speed, s[-1])
        return np.column_stack([np.interp(sj, s, dense[:, c]) for c in range(3)])

    def _at(self, sol, tt: np.ndarray) -> np.ndarray:
        """The plan's poses at the times ``tt`` (cubic Hermite in x, y, theta with the plan's velocities)."""
        from cobot_analysis.models.dynamics import world_velocity

        X = sol.X
        t = np.linspace(0.0, sol.T, X.shape[0])
        horizon = len(tt) - 1
        vx, vy = world_velocity(X[:, 2], X[:, 3], X[:, 4])
        out = np.empty((horizon + 1, 3))
        i = np.clip(np.searchsorted(t, tt, side="right") - 1, 0, len(t) - 2)
        h = t[i + 1] - t[i]
        s = (tt - t[i]) / h
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        for col, d in ((0, vx), (1, vy), (2, X[:, 5])):
            v = X[:, col]
            out[:, col] = h00 * v[i] + h10 * h * d[i] + h01 * v[i + 1] + h11 * h * d[i + 1]
        return out


def _weights(weights, entity_default: str = "walking-2021", a3: float | None = None) -> np.ndarray:
    """The improved model's weight vector (its b0..b3 unused: the goal is a constraint), a3 replaced by
    ``a3`` when given."""
    from cobot_analysis.models.presets import load_weights, weights_vector

    w = weights_vector(load_weights(weights or entity_default, "improved"), "improved")
    if a3 is not None:
        w[3] = float(a3)
    return w


def turn_weight_undetermined(weights) -> bool:
    """The weights leave a3 undetermined: a fit in a ``fit-ioc`` weights.json says so (its uncertainty verdict on
    a3, ``ioc.uncertainty.verdict_category`` "not determined"), or a3 sits on a fit's lower bound
    (``A3_UNDETERMINED``: the preset walking-2021, 1e-6). The file is read once."""
    import json
    from pathlib import Path

    from cobot_analysis.models.ioc.uncertainty import verdict_category
    from cobot_analysis.models.presets import PRESETS

    spec, fits = weights, {}
    if weights is not None and str(weights) not in PRESETS and Path(str(weights)).is_file():
        try:
            doc = json.loads(Path(str(weights)).read_text())
        except ValueError:
            doc = None  # not JSON: load_weights below names the file
        if isinstance(doc, dict) and isinstance(doc.get("weights"), dict):
            spec, fits = doc["weights"], doc.get("fits") or {}
    verdicts = [f.get("uncertainty", {}).get("verdicts", {}).get("a3") for f in fits.values() if isinstance(f, dict)]
    if any(verdict_category(v) in ("not determined", "not determined at the search limit") for v in verdicts if isinstance(v, str)):
        return True
    return bool(_weights(spec)[3] <= A3_UNDETERMINED)


def continuation_error(trajectories, weights: np.ndarray, n0: int, fractions=CONTINUATIONS, fit: int = 5) -> np.ndarray:
    """Per trajectory and start ``k = round(f (N - 1))``, f in ``fractions``: the plan from the state
    estimated on the N0 samples up to k to the trajectory's goal, read at the measured pace, against the
    measured rest of the path, ``d = (1/(N - k)) sum_{i=k}^{N-1} ||c_i - x*_i||`` (NaN: no finite past
    or the plan failed). This is the IOC's path distance on paths that start in motion."""
    out = []
    for traj in trajectories:
        n = len(traj.poses)
        planner, filt = Planner(weights, traj.dt), quadratic_fit(min(fit, n0), traj.dt)
        for f in fractions:
            k = int(round(f * (n - 1)))
            past = traj.seen[k - n0 + 1: k + 1]
            if k < n0 - 1 or traj.goal is None or not np.isfinite(past[:, :2]).all():
                out.append(np.nan)
                continue
            p = plan_path(planner, plan_start(past, filt), traj.goal, n - 1 - k)
            out.append(np.nan if p is None else float(np.nanmean(np.hypot(*(traj.poses[k:, :2] - p[:, :2]).T))))
    return np.array(out)


def identify_turn_weight(trajectories, weights, n0: int, fractions=CONTINUATIONS, fit: int = 5) -> float:
    """a3 of the goal plans identified where the data determine it: on continuations started in motion.
    ``argmin over log10 a3 in the IOC's search box`` (``ioc.fit.LOG_BOUNDS``) of the mean
    ``continuation_error`` (Brent's bounded search, to 0.05 in log10 a3; the value in 3 significant
    digits), the other weights held; ``trajectories``: the study's mean paths with goals."""
    from scipy.optimize import minimize_scalar

    from cobot_analysis.models.ioc.fit import LOG_BOUNDS

    w0 = _weights(weights)

    def mean_error(log_a3: float) -> float:
        w = w0.copy()
        w[3] = 10.0 ** log_a3
        d = continuation_error(trajectories, w, n0, fractions, fit)
        return float(np.nanmean(d)) if np.isfinite(d).any() else np.inf

    res = minimize_scalar(mean_error, bounds=LOG_BOUNDS, method="bounded", options={"xatol": 0.05})
    if not np.isfinite(res.fun):
        raise InputError("the goal plans' turning weight a3 cannot be identified: no continuation of a mean path could be planned",
                         remedy="give weights whose a3 is determined (--weights), or mean paths with goals in the trajectories")
    return float(f"{10.0 ** res.x:.3g}")  # the search's tolerance (12 %) in 3 digits: a stable stage parameter


class GoalPredictor(Predictor):
    """Goal known: the plan from the state estimate at k to ``goal`` (module docstring)."""

    name = "goal"
    min_past = 3

    def __init__(self, n0: int, n_oc: int, dt: float = 1.0, *, goal=None, weights: str | None = "walking-2021",
                 fit: int = 5, n_intervals: int = N_INTERVALS, turn_weight: float | None = None):
        if goal is None:
            raise InputError("the goal-aware predictor needs a goal", remedy="pass --goal x,y,theta or use goal-inferred with --candidates")
        self.goal = check_goal(goal)
        super().__init__(n0, n_oc, dt)
        self.filter = quadratic_fit(min(int(fit), self.n0), self.dt)
        self.planner = Planner(_weights(weights, a3=turn_weight), self.dt, n_intervals)

    def predict(self, past: np.ndarray) -> np.ndarray | None:
        x0 = plan_start(past, self.filter)
        return plan_path(self.planner, x0, self.goal, self.horizon)


def plan_path(planner: Planner, x0: np.ndarray, goal, horizon: int) -> np.ndarray | None:
    """(horizon + 1, 3) predicted poses from x0 towards goal; x0's pose held when already at the goal."""
    if math.hypot(goal[0] - x0[0], goal[1] - x0[1]) < ARRIVED:
        return np.repeat(x0[None, :3], horizon + 1, axis=0)
    sol = planner.plan(x0, goal)
    return None if sol is None else planner.read(sol, horizon, math.hypot(x0[3], x0[4]))


class GoalInferencePredictor(Predictor):
    """Goal one of ``candidates`` (positions), inferred from the measured past (module docstring).

    After each window: ``posterior`` (M,) holds p(g | past); ``history`` lists (k, posterior) per window.
    """

    name = "goal-inferred"
    min_past = 3

    def __init__(self, n0: int, n_oc: int, dt: float = 1.0, *, candidates=None, weights: str | None = "walking-2021",
                 fit: int = 5, sigma: float = SIGMA, n_intervals: int = N_INTERVALS, goal=None, turn_weight: float | None = None):
        self.candidates = check_candidates(candidates)
        super().__init__(n0, n_oc, dt)
        self.sigma = float(sigma)
        self.filter = quadratic_fit(min(int(fit), self.n0), self.dt)
        w = _weights(weights, a3=turn_weight)
        # IPOPT with a CPU limit: every plan returns (a fatrop solve hung once here, models.oc.problem)
        self.planners = [Planner(w, self.dt, n_intervals, solver="ipopt", max_cpu_time=PLAN_CPU_LIMIT) for _ in self.candidates]
        self._length = max(self.horizon, self.n0)  # a plan long enough to cover a whole past window later

    def reset(self) -> None:
        super().reset()
        self._segment: tuple[int, np.ndarray] | None = None  # (j, (M, L + 1, 2) plans made at sample j)
        self._evidence = np.zeros(len(getattr(self, "candidates", ())))  # log-likelihoods of the finished segments
        self.posterior = None
        self.history: list[tuple[int, np.ndarray]] = []

    def on_skip(self) -> None:
        self._segment = None  # the finished segments' evidence stays

    def _loglik(self, past: np.ndarray, k: int) -> np.ndarray:
        """log p(samples j..k | g) = -d_g^2 / 2 sigma^2 of the current segment (0 where g's plan failed)."""
        j, plans = self._segment
        seen = past[len(past) - (k - j + 1):, :2]  # samples j..k
        ok = np.isfinite(plans[:, 0, 0])  # a failed plan is all NaN: no evidence (and no mean of nothing)
        d = np.full(len(plans), np.nan)
        d[ok] = np.nanmean(np.hypot(*(plans[ok, : k - j + 1] - seen[None]).transpose(2, 0, 1)), axis=1)
        return np.where(np.isfinite(d), -0.5 * (d / self.sigma) ** 2, 0.0)

    def predict(self, past: np.ndarray) -> np.ndarray | None:
        k = self.n_seen - 1
        x0 = plan_start(past, self.filter)
        finished = self._segment is not None and k - self._segment[0] + 1 >= self.n0  # a segment of N0 samples
        paths = None
        if self._segment is None or finished:  # a segment starts at k: the plan towards every candidate is its evidence
            paths = [self._plan(i, x0) for i in range(len(self.candidates))]
            if all(p is None for p in paths):
                return None
            if finished:
                self._evidence = self._evidence + self._loglik(past, k)
            self._segment = (k, np.stack([p[:, :2] if p is not None else np.full((self._length + 1, 2), np.nan) for p in paths]))
        posterior = self._posterior(past, k)
        # the prediction: the plan towards the most probable goal whose plan succeeds (inside a segment only the
        # plans tried in that order are solved: they are not evidence)
        for i in np.argsort(-posterior, kind="stable"):
            path = paths[i] if paths is not None else self._plan(i, x0)
            if path is not None:
                self.posterior = posterior
                self.history.append((k, posterior.copy()))
                return path[: self.horizon + 1]
        return None

    def _plan(self, i: int, x0: np.ndarray) -> np.ndarray | None:
        """The plan from x0 towards candidate i (heading: its bearing), ``_length`` samples long, or None."""
        g = self.candidates[i]
        return plan_path(self.planners[i], x0, (g[0], g[1], float("nan")), self._length)

    def _posterior(self, past: np.ndarray, k: int) -> np.ndarray:
        """p(g | past) from the finished segments' evidence and the current segment's (module docstring)."""
        logp = self._evidence + self._loglik(past, k)
        post = np.exp(logp - logp.max())
        return post / post.sum()


# ---- the studies' goals ---------------------------------------------------------------------------
def design_goal(study: str, meta: dict, end=None, end_heading: float = math.nan) -> tuple[float, float, float] | None:
    """The goal a trajectory walks to, from the study design (docs/methods.md sec. 1): the walking
    goal (0, 0, pi/2), unless the trajectory's last measured position ``end`` lies farther from it than
    ``comparison.DESIGN_GOAL_TOLERANCE`` or its study's ``end_heading`` (``comparison.end_heading`` over the
    study's trajectories: one walker's last heading is no evidence) is off pi/2 (``comparison.heading_off_design``):
    a frame of one's own; for the pair study's table, the goal position with the trial's end orientation
    (forward) or the start pose (return). None when the design gives none."""
    from cobot_analysis.design import GOAL_POSITIONS, PAIR_GOALS, WALKING_GOAL
    from cobot_analysis.models.comparison import DESIGN_GOAL_TOLERANCE, heading_off_design

    if study.startswith("walking"):
        far = end is not None and math.hypot(end[0] - WALKING_GOAL[0], end[1] - WALKING_GOAL[1]) > DESIGN_GOAL_TOLERANCE
        return None if far or heading_off_design(end_heading) else WALKING_GOAL
    stem = str(meta.get("condition") or "")
    goal = next((g for g in PAIR_GOALS if g.stem == stem), None)
    if goal is None:
        return None
    if meta.get("direction") == "return":
        return goal.start_pose
    end = meta.get("end_orientation")
    theta = float(end) if end is not None and np.isfinite(end) else float("nan")
    return (*GOAL_POSITIONS[stem.split("_")[1]], theta)


def study_candidates(study: str) -> np.ndarray:
    """Candidate goal positions of a study: the pair study's goal positions and its start (the
    return paths' goal); the walking study's single goal."""
    from cobot_analysis.design import GOAL_POSITIONS, WALKING_GOAL

    if study.startswith("walking"):
        return np.array([WALKING_GOAL[:2]])
    return np.array([(0.0, 0.0), *GOAL_POSITIONS.values()])


def parse_goal(text: str, option: str = "--goal") -> tuple[float, float, float]:
    """``"x,y[,theta]"`` -> a checked goal (``check_goal``)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise InputError(f"{option} {text!r} is not x,y[,theta]", remedy=f"write {option} as numbers, e.g. 0,0,1.5708") from None
    return check_goal(values, option)


def parse_candidates(text: str, option: str = "--candidates") -> tuple[tuple[float, float], ...]:
    """``"x,y;x,y;..."`` -> checked candidate positions (``check_candidates``)."""
    parts = [p for p in (q.strip() for q in text.split(";")) if p]
    return tuple(tuple(c) for c in check_candidates([parse_goal(p, option)[:2] for p in parts], option))
