"""Bi-level inverse optimal control (docs/methods.md sec. 6): fit the cost weights of an OC model to
measured (mean) trajectories.

Upper level: ``min_w (1/N_traj) sum_n D_n(w)`` over the log10 of the fitted weights, derivative-
free (Powell, as published, or Nelder-Mead), within bounds; one weight (``b0`` by default) is held
fixed because the lower-level optimum does not change when all weights are scaled together.
Lower level: the OC problem from the measured start pose to the measured end pose of each
trajectory with weights w, T free (``ocp.py``), resampled to the measured number of samples.
D_n = d_xy + 0.5 d_gamma (walker) or d_xy + 0.5 d_theta (table), with the distances of
``cobot_analysis.distances``; gamma of both paths from the path (``distances.gamma_from_path``).

Speed and reproducibility:
- every lower-level solve is warm-started from the solution at the best weights found so far
  (at first: the starting weights, best of a 'rest' and a 'line' initial guess) and, under the
  continuous convention, also solved from those two cold guesses, the least cost kept (the rule of
  ``generate``, so both find the same local minimum); the sequence of
  evaluations is deterministic, so the result is the same on a local pool and on a Dask cluster;
- the lower levels of one evaluation run in parallel (``cobot_analysis.parallel.executor``: local
  processes or ``--scheduler``), in chunks, on processes that keep their NLP built;
- after every upper-level iteration the log of evaluations and the current warm starts are
  written to a checkpoint; a resumed fit replays the optimiser against that log (no solve),
  restores the warm starts and continues where it stopped: the same result as an uninterrupted run;
- a lower level that does not converge (after a cold retry) counts as ``FAILED_D`` (a penalty)
  and is counted in the result, never silently averaged in.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from cobot_analysis.errors import InputError
from cobot_analysis.models.ioc.targets import PairTarget, Target
from cobot_analysis.models.presets import names_for

T_BOUNDS = (0.4, 2.5)  # free T within these multiples of T0: coupled model (coupled.CoupledOCP.solve), single level; the
# continuous walker rules keep their own, wider ones (conventions.OCRule.T_bounds)
FAILED_D = 10.0  # objective term of a lower level that did not converge (m-equivalent; >> any real D)
OPTIMIZERS = ("powell", "nelder-mead")
LOG_BOUNDS = (-7.0, 3.0)  # log10 of a fitted weight
AT_LIMIT = 0.05  # log10: a fitted weight within a factor 1.12 of a search limit is at that limit (a bound, not an estimate)



def search_limit_at(w: float) -> float | None:
    """The log10 search limit (``LOG_BOUNDS``) a fitted weight ``w`` is at (within ``AT_LIMIT``), else None."""
    y = math.log10(max(w, 1e-300))
    return next((b for b in LOG_BOUNDS if abs(y - b) < AT_LIMIT), None)

@dataclass(frozen=True)
class IOCSpec:
    """What the fit is (hashed into the checkpoint so a resume only continues the same fit)."""

    model: str = "improved"  # improved (walker, d_gamma) or table (d_theta)
    start_weights: tuple[float, ...] = ()  # the 11-vector a0..a6, b0..b3 the fit starts from
    fitted: tuple[str, ...] = ("a2", "a3", "a4")  # the continuous walker's default: all but held_weights("improved")
    optimizer: str = "powell"
    max_evaluations: int = 2000
    xtol: float = 1e-2  # log10 units
    ftol: float = 1e-5
    n_intervals: int = 50  # 50 vs 500 intervals: 2-12 mm apart (d_xy) on the published weights
    angle_weight: float = 0.5
    max_iter: int = 200  # lower-level iteration limit (a solve that hits it is retried cold, then failed)
    v_nominal: float = 1.0  # m/s: T0 = distance / v_nominal + 1 s, the free T is bounded to T_BOUNDS x T0
    convention: str = "continuous"  # docs/methods.md sec. 11 (published: the authors' discretisation, durations, distances)
    hold_duration: bool = True  # published: each target keeps the horizon the duration rule chose at the start weights

    @property
    def angle(self) -> str:
        return "theta" if self.model in ("table", "coupled") else "gamma"

    def weights(self, z: np.ndarray) -> np.ndarray:
        """Full 11-vector from the upper-level variables z = log10(fitted weights)."""
        w = np.array(self.start_weights, dtype=float)
        names = names_for(self.model)
        for name, zi in zip(self.fitted, z):
            w[names.index(name)] = 10.0 ** float(zi)
        return w

    def z0(self) -> np.ndarray:
        w = np.array(self.start_weights, dtype=float)
        names = names_for(self.model)
        # on the search box's limit when beyond it, above as below (scipy's bounded Powell would start outside, with a warning)
        return np.clip(np.log10(np.maximum([w[names.index(n)] for n in self.fitted], 10.0 ** LOG_BOUNDS[0])), *LOG_BOUNDS)


def held_weights(model: str, convention="continuous") -> tuple[str, ...]:
    """The weights a fit holds at their start value by default (docs/methods.md sec. 6, 11).

    Scaling every weight leaves the optimal path unchanged, so one weight fixes the scale. Under the
    continuous convention the goal at rest is a terminal constraint, and then:
    - b0..b3 weigh terms that are 0 on every feasible path: no path depends on them;
    - a0, the price of one second, fixes the scale;
    - a1 fixes the time scale: multiplying the acceleration weights by c^4 (a0 and the path terms
      held) makes the time-scaled path X(t / c) optimal, since the time and path terms of J grow as
      c and the acceleration terms as c^-3; the time-normalised paths D compares are the same, only
      the duration changes (c T). The data cannot tell these weights apart, so a1 stays at its start
      value during the search; the pace is fitted afterwards to measured durations (``pace.calibrate``).
    Under the published convention the goal is the terminal cost: b0 fixes the scale, and a0, a
    constant per node, moves no path on a held horizon. The walker's a5, a6 belong to the Mombaur
    model."""
    from cobot_analysis import conventions

    rule = conventions.get(convention).oc_rule(model)
    if rule.goal == "constraint":
        return ("a0", "a1", "b0", "b1", "b2", "b3") if model == "coupled" else ("a0", "a1", "a5", "a6", "b0", "b1", "b2", "b3")
    if model == "coupled":
        return ("a0", "b0")
    return ("a0", "a5", "a6", "b0") if rule.scheme == "euler" else ("a5", "a6", "b0")


# ---- lower level (runs on workers) -------------------------------------------------------------
def distances(t: Target, x, y, theta, convention="continuous", *, measured_resampled: tuple | None = None) -> dict[str, float]:
    """d_xy, d_theta, d_gamma of a path (x, y, theta) against target ``t`` under a convention
    (``distances.path_distances``; the target's recorded gamma when the convention takes it;
    ``measured_resampled``: t's (x, y) resampled by arc length once for many paths)."""
    from cobot_analysis import conventions
    from cobot_analysis.distances import path_distances

    comparison = conventions.get(convention).comparison
    gamma = t.gamma if comparison.measured_gamma == "data" else None
    return path_distances((t.x, t.y, t.theta), (x, y, theta), comparison, measured_gamma=gamma,
                          measured_resampled=measured_resampled)


def duration_terms(T: float, T0: float, bounds: tuple[float, float] = T_BOUNDS) -> dict:
    """T, T0 and whether T sits on a bound of ``bounds`` x T0 (relative 1e-3): -1 lower, +1 upper, 0 inside."""
    r = T / T0
    at = -1 if abs(r / bounds[0] - 1) < 1e-3 else (1 if abs(r / bounds[1] - 1) < 1e-3 else 0)
    return {"T": T, "T0": T0, "T_at_bound": at}


def published_duration_terms(sol, start, goal, dt: float) -> dict:
    """T, the authors' starting guess T0 = int(2/3 * 100 d) steps (as a duration), and whether T is on
    the upper bound of their search (the largest integer below 200 d steps: +1) (docs/methods.md sec. 11)."""
    from cobot_analysis.models.oc.duration import NODES_PER_METRE

    d = math.hypot(goal[0] - start[0], goal[1] - start[1])
    n = sol.U.shape[0]
    top = math.ceil(2 * d * NODES_PER_METRE) - 1
    return {"T": n * dt, "T0": int(d * NODES_PER_METRE * 2 / 3) * dt, "T_at_bound": 1 if n >= top else 0}


def _failed() -> dict:
    return {"D": FAILED_D, "d_xy": math.nan, "d_theta": math.nan, "d_gamma": math.nan, "T": math.nan, "T0": math.nan,
            "T_at_bound": 0, "success": False}


def solve_pair_target(spec: IOCSpec, w: np.ndarray, t: PairTarget, guess):
    """Coupled lower level: D = d_xy,1 + d_xy,2 + 0.5 (d_theta,1 + d_theta,2); the terms of each
    carrier are kept too (``d_xy_1``, ``d_theta_2``, ...; carrier 1 is Subject 2 on returns)."""
    from cobot_analysis.models.oc import resample
    from cobot_analysis.models.oc.coupled import initial_pair_duration, solve_pair
    from cobot_analysis.models.oc.problem import OCPSolution

    kw = {"n_intervals": spec.n_intervals, "max_iter": spec.max_iter, "v_nominal": spec.v_nominal}
    sol = solve_pair(t.start, t.goal, w, guess=guess, **kw)
    if not sol.success and not isinstance(guess, str):
        sol = solve_pair(t.start, t.goal, w, **kw)
    if not sol.success:
        return _failed(), sol
    d = {"d_xy": 0.0, "d_theta": 0.0, "d_gamma": 0.0}
    for i, c in enumerate(t.carriers):
        part = OCPSolution(sol.X[:, 6 * i:6 * i + 6], sol.U[:, 3 * i:3 * i + 3], sol.T, sol.cost, True, "", "", 0, sol.primal)
        r = resample(part, len(c.x))
        for k, v in distances(c, r["x"], r["y"], r["theta"]).items():
            d[k] += v
            d[f"{k}_{i + 1}"] = v
    d["D"] = d["d_xy"] + spec.angle_weight * d["d_theta"]
    d.update(duration_terms(sol.T, initial_pair_duration(t.start, t.goal, spec.v_nominal)))
    d["success"] = True
    return d, sol


def solve_target(spec: IOCSpec, w: np.ndarray, t: Target, guess):
    """Lower level for one target: (distances dict with D, T, T0, T_at_bound and success, solution).

    ``guess``: continuous convention, a primal vector (solved from it and from the two cold guesses, the
    least cost kept), a cold guess name (the two cold guesses) or a tuple of guesses (primal vectors or
    cold guess names: exactly those);
    published convention, the solution at other weights (seeds every horizon of the duration rule) or None."""
    from cobot_analysis.models.oc import resample, solve_model
    from cobot_analysis.models.oc.duration import initial_duration

    if spec.model == "coupled":
        return solve_pair_target(spec, w, t, guess)
    model = "table" if spec.model == "table" else "improved"
    if spec.convention == "published":
        from cobot_analysis.conventions import PUBLISHED

        seed = guess if hasattr(guess, "X") and spec.hold_duration else None
        if seed is not None:  # the held horizon, warm from the best weights' solution; the authors' DDP budget,
            # no IPOPT fallback on these long horizons (minutes per solve): a failed lower level counts FAILED_D
            sol = solve_model(model, t.start, t.goal, w, convention=PUBLISHED, max_iter=spec.max_iter, seed=seed,
                              horizon=seed.U.shape[0], fallback=False)
        else:  # the duration rule, as generate runs it
            sol = solve_model(model, t.start, t.goal, w, convention=PUBLISHED, warm=True)
        return published_terms(spec, t, sol), sol
    kw = {"n_intervals": spec.n_intervals, "duration": "free", "max_iter": spec.max_iter, "v_nominal": spec.v_nominal}
    # the warm start and generate's two cold guesses, the least cost kept: a start facing away from the goal
    # has several local minima (turn left or right), and a warm start alone follows the one it came from
    cold = ("rest", "line")
    guesses = guess if isinstance(guess, tuple) else cold if isinstance(guess, str) else (guess, *cold)
    sol = solve_model(model, t.start, t.goal, w, guess=guesses, **kw)
    if not sol.success:
        return _failed(), sol
    r = resample(sol, len(t.x))
    d = distances(t, r["x"], r["y"], r["theta"])
    d["D"] = d["d_xy"] + spec.angle_weight * d[f"d_{spec.angle}"]
    from cobot_analysis.conventions import CONTINUOUS

    d.update(duration_terms(sol.T, initial_duration(t.start, t.goal, spec.v_nominal), CONTINUOUS.oc_rule(model).T_bounds))
    d["length"] = float(np.hypot(np.diff(r["x"]), np.diff(r["y"])).sum())  # m: the time law is length / T
    d["success"] = True
    return d, sol


def published_terms(spec: IOCSpec, t: Target, sol) -> dict:
    """The published convention's distances of the lower-level solution ``sol`` to target ``t``, D and
    the duration terms, as ``solve_target`` returns them (failed: FAILED_D)."""
    from cobot_analysis.conventions import PUBLISHED

    if not sol.success:
        return _failed()
    d = distances(t, sol.X[:, 0], sol.X[:, 1], sol.X[:, 2], PUBLISHED)
    d["D"] = d["d_xy"] + spec.angle_weight * d[f"d_{spec.angle}"]
    d.update(published_duration_terms(sol, t.start, t.goal, PUBLISHED.oc_rule("table" if spec.model == "table" else "improved").dt))
    d["success"] = True
    return d


def _warm_start(spec: IOCSpec, sol):
    """What a later evaluation starts from: the primal vector (continuous) or the solution (published)."""
    return sol if spec.convention == "published" else sol.primal


def evaluate_chunk(task) -> list[tuple[dict, object]]:
    """Worker task: lower levels of a chunk of targets for one weight vector (top-level, picklable);
    returns (distances, warm start or None) per target."""
    spec, w, targets, guesses = task
    out = []
    for t, g in zip(targets, guesses):
        d, sol = solve_target(spec, w, t, g)
        out.append((d, _warm_start(spec, sol) if d["success"] else None))
    return out


def reference_chunk(task) -> list[tuple[dict, object]]:
    """Worker task: the reference solutions at the starting weights (best of two cold guesses;
    published: the authors' rule from rest)."""
    spec, w, targets = task
    out = []
    for t in targets:
        d, sol = solve_target(spec, w, t, None if spec.convention == "published" else ("rest", "line"))
        out.append((d, _warm_start(spec, sol) if sol.success else None))
    return out


def rule_check_chunk(task) -> list[tuple[dict, object]]:
    """Worker task (published convention): task = (spec, w, [(target, held solution at w or None), ...]); per target
    (distances, solution) of the duration rule at w as a check of the held solution's horizon, that solution its
    solve there (``oc.solve_model``'s ``start_horizon``: kept when the rule's criterion J/T is no lower one node either
    side, else the rule's search started there); without a held solution, the rule from the authors' T_guess."""
    from cobot_analysis.conventions import PUBLISHED
    from cobot_analysis.models.oc import solve_model

    spec, w, items = task
    rule = replace(spec, hold_duration=False)
    model = "table" if spec.model == "table" else "improved"
    out = []
    for t, s in items:
        if s is None:
            out.append(solve_target(rule, w, t, None))
            continue
        sol = solve_model(model, t.start, t.goal, w, convention=PUBLISHED, warm=True, seed=s, start_horizon=s.U.shape[0])
        out.append((published_terms(rule, t, sol), sol))
    return out


def longest_first(targets: list[Target]) -> list[list[int]]:
    """One pool task per target, the longest start-goal distance first: under the published convention the
    duration rule's horizon grows with it (up to 200 d steps), so the workers end together."""
    return [[i] for i in sorted(range(len(targets)), key=lambda i: -math.dist(targets[i].start[:2], targets[i].goal[:2]))]


# ---- upper level -------------------------------------------------------------------------------
@dataclass
class IOCResult:
    spec: IOCSpec
    weights: dict[str, float]
    objective: float
    start_objective: float
    evaluations: int
    iterations: int
    failed: int  # lower levels that did not converge at the fitted weights
    per_target: list[dict] = field(default_factory=list)
    message: str = ""
    held_objective: float | None = None  # published, held horizons: D the optimiser saw at the fitted weights
    horizons_changed: int | None = None  # targets whose horizon the duration rule moves at the fitted weights
    pace: dict | None = None  # continuous, measured durations given: the time-gauge calibration (models.ioc.pace)
    # the fit's own lower-level solutions, per target, the curvature's centre (uncertainty.curvature); not written.
    # Published, held horizons: the duration rule's solutions at the fitted weights (check ``success``); continuous: the
    # paths (primal vectors, None where none) of the best evaluation, the warm starts the fit ended with
    solutions: list | None = field(default=None, repr=False, compare=False)

    def to_json(self) -> dict:
        d = asdict(replace(self, solutions=None))
        del d["solutions"]
        d["spec"] = asdict(self.spec)
        return d


class Checkpoint:
    """Log of upper-level evaluations (JSON, atomic writes) keyed by the spec and the targets."""

    def __init__(self, path: Path | None, key: str):
        self.path, self.key = path, key
        self.log: list[dict] = []  # {"z": [...], "f": float, "terms": [...]}
        self.iterations = 0
        self.guesses: list | None = None  # warm starts (primal vectors) after the last logged evaluation

    def load(self) -> bool:
        if self.path is None or not self.path.is_file():
            return False
        try:
            data = json.loads(self.path.read_text())
        except ValueError:
            return False
        if data.get("key") != self.key:
            return False
        self.log, self.iterations = data["log"], data["iterations"]
        self.guesses = [np.array(g) if isinstance(g, list) else g for g in data["guesses"]]
        return True

    def save(self) -> None:
        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        # primal vectors (continuous) are kept; solutions (published) are not: a resume re-seeds from the reference
        guesses = [g.tolist() if isinstance(g, np.ndarray) else g if isinstance(g, str) else None for g in (self.guesses or [])]
        tmp.write_text(json.dumps({"key": self.key, "iterations": self.iterations, "log": self.log, "guesses": guesses}))
        os.replace(tmp, self.path)


CHECKPOINT_FORMAT = 2  # 2: the logged terms carry T, T0 and T_at_bound (older logs are not resumed)


def fit_key(spec: IOCSpec, targets: list[Target]) -> str:
    h = hashlib.sha256(json.dumps({**asdict(spec), "format": CHECKPOINT_FORMAT}, sort_keys=True).encode())
    for t in targets:
        h.update(t.trial.encode())
        for c in getattr(t, "carriers", (t,)):
            h.update(np.ascontiguousarray(np.c_[c.x, c.y, c.theta]).tobytes())
    return h.hexdigest()[:16]


class _Interrupted(Exception):
    pass


def fit(spec: IOCSpec, targets: list[Target], *, pool=None, chunks: int = 2, checkpoint: Path | None = None,
        resume: bool = False, on_evaluation: Callable[[int, float, float], None] | None = None,
        interrupt_after: int | None = None, measured_T=None) -> IOCResult:
    """Fit ``spec.fitted`` to ``targets``; ``pool`` is a concurrent.futures executor (None: in-process).

    ``measured_T``: the subjects' duration of each target (nan: none). Under the continuous convention
    (walker and table models) the start weights' time gauge is fitted to them first (the search then
    runs at the subjects' pace; ``spec.start_weights`` of the result are those), and the fitted weights'
    after the search (``pace.calibrate``: a1..a3 x c^4, the same D); the result holds the calibrated
    weights, their per-target terms and ``pace`` (with ``c_start``); without it the pace is the one the
    held a0, a1 give.

    ``interrupt_after``: stop (KeyboardInterrupt) after that many new evaluations (tests of resume).
    """
    from scipy.optimize import minimize

    from cobot_analysis.parallel import InlineExecutor

    if not targets:
        raise InputError("no trajectory with orientation to fit", remedy="check the input table (orientation missing everywhere?)")
    if spec.optimizer not in OPTIMIZERS:
        raise InputError(f"unknown optimizer {spec.optimizer!r}", remedy=f"use one of {', '.join(OPTIMIZERS)}")
    pool = pool or InlineExecutor()
    n_chunks = max(1, min(chunks, len(targets)))
    # published: one task per path, longest first (the held horizons differ by 8x); else interleaved chunks
    parts = longest_first(targets) if spec.convention == "published" else \
        [list(range(i, len(targets), n_chunks)) for i in range(n_chunks)]

    def run(tasks_fn, collect):
        futures = [pool.submit(tasks_fn, task) for task in collect]
        return [f.result() for f in futures]

    paced = measured_T is not None and spec.convention != "published" and spec.model in ("improved", "table")
    c_start = None
    if paced:  # the start weights' time gauge first (pace.py): the search runs at the subjects' pace, where the
        # cold guesses' duration T0 is near the optimum (far from it, they miss the least-cost local minimum)
        from cobot_analysis.models.ioc.pace import scale_time, time_gauge
        from cobot_analysis.models.presets import weights_vector

        w0 = spec.weights(spec.z0())
        first = run(reference_chunk, [(spec, w0, [targets[i] for i in p]) for p in parts])
        T = [np.nan] * len(targets)
        for p, res in zip(parts, first):
            for i, (d, _) in zip(p, res):
                T[i] = d["T"] if d["success"] else np.nan
        c_start = time_gauge(T, measured_T)
        if np.isfinite(c_start):
            w = scale_time(dict(zip(names_for(spec.model), map(float, spec.start_weights))), c_start)
            spec = replace(spec, start_weights=tuple(map(float, weights_vector(w, spec.model))))
    # reference solutions at the starting weights: the warm start of every later evaluation
    w0 = spec.weights(spec.z0())
    ref = run(reference_chunk, [(spec, w0, [targets[i] for i in p]) for p in parts])
    guesses: list = [None] * len(targets)
    start_terms: list = [None] * len(targets)
    z0 = tuple(float(v) for v in spec.z0())
    solved_at: list = [None] * len(targets)  # the z of each warm start's own solve (None: unknown)
    for p, res in zip(parts, ref):
        for i, (d, primal) in zip(p, res):
            guesses[i] = primal if primal is not None else ("rest" if spec.convention != "published" else None)
            start_terms[i], solved_at[i] = d, z0 if primal is not None else None
    start_objective = float(np.mean([d["D"] for d in start_terms]))

    ck = Checkpoint(checkpoint, fit_key(spec, targets))
    if resume and ck.load():  # the checkpoint's warm starts, the reference solutions where it holds none
        solved_at = [None if g is not None else a for g, a in zip(ck.guesses, solved_at)]
        guesses = [g if g is not None else r for g, r in zip(ck.guesses, guesses)]
    ck.guesses = guesses
    cache = {tuple(e["z"]): e for e in ck.log}
    # the starting point is the reference evaluation itself (not re-solved from its own warm start)
    cache.setdefault(z0, {"z": list(z0), "f": start_objective, "terms": start_terms})
    new = 0
    best = {"f": math.inf}

    def evaluate(z: np.ndarray) -> float:
        nonlocal new
        key = tuple(float(v) for v in z)
        if key in cache:
            e = cache[key]
        else:
            if interrupt_after is not None and new >= interrupt_after:
                raise _Interrupted
            w = spec.weights(z)
            res = run(evaluate_chunk, [(spec, w, [targets[i] for i in p], [guesses[i] for i in p]) for p in parts])
            terms: list = [None] * len(targets)
            primals: list = [None] * len(targets)
            for p, r in zip(parts, res):
                for i, (d, primal) in zip(p, r):
                    terms[i], primals[i] = d, primal
            e = {"z": list(key), "f": float(np.mean([d["D"] for d in terms])), "terms": terms}
            cache[key] = e
            ck.log.append(e)
            new += 1
            if e["f"] < best["f"]:  # warm starts follow the best weights
                for i, primal in enumerate(primals):
                    if primal is not None:
                        guesses[i], solved_at[i] = primal, key
        if e["f"] < best["f"]:
            best.update(e)
        if on_evaluation:
            on_evaluation(len(cache), e["f"], best["f"])
        return e["f"]

    iteration = 0

    def callback(*_args) -> None:
        nonlocal iteration
        iteration += 1
        if iteration > ck.iterations:
            ck.iterations = iteration
            ck.save()

    bounds = [LOG_BOUNDS] * len(spec.fitted)
    method = {"powell": "Powell", "nelder-mead": "Nelder-Mead"}[spec.optimizer]
    opts = {"maxfev": spec.max_evaluations, "xtol": spec.xtol, "ftol": spec.ftol} if method == "Powell" else \
        {"maxfev": spec.max_evaluations, "xatol": spec.xtol, "fatol": spec.ftol}
    try:
        res = minimize(evaluate, spec.z0(), method=method, bounds=bounds, callback=callback, options=opts)
    except _Interrupted:
        ck.save()
        raise KeyboardInterrupt("IOC interrupted (test hook); resume with the same checkpoint") from None
    ck.save()
    w_best = spec.weights(np.array(best["z"]))
    terms, objective, held, changed, solutions = best["terms"], float(best["f"]), None, None, None
    if spec.convention == "published" and spec.hold_duration:
        # the fit held each target's horizon: the duration rule runs again at the fitted weights, as a check of the held
        # horizon with the held solution there as its solve (``rule_check_chunk``; from T_guess where none is at hand)
        at_best = [g if a == tuple(best["z"]) else None for g, a in zip(guesses, solved_at)]
        rerun = run(rule_check_chunk, [(spec, w_best, [(targets[i], at_best[i]) for i in p]) for p in parts])
        new: list = [None] * len(targets)
        solutions = [None] * len(targets)
        for p, r in zip(parts, rerun):
            for i, (d, sol) in zip(p, r):
                new[i], solutions[i] = d, sol
        changed = sum(1 for a, b in zip(terms, new) if a["success"] and b["success"] and abs(a["T"] - b["T"]) > 1e-9)
        held, terms, objective = objective, new, float(np.mean([d["D"] for d in new]))
    if spec.convention != "published":
        solutions = [g if not isinstance(g, str) else None for g in guesses]
    weights, pace = dict(zip(names_for(spec.model), map(float, w_best))), None
    if paced:
        from cobot_analysis.models.ioc.pace import calibrate

        def solve(w: dict) -> list[dict]:
            res = run(evaluate_chunk, [(spec, weights_vector(w, spec.model), [targets[i] for i in p], [guesses[i] for i in p])
                                       for p in parts])
            out: list = [None] * len(targets)
            for p, r in zip(parts, res):
                for i, (d, _) in zip(p, r):
                    out[i] = d
            return out

        cal = calibrate(solve, weights, terms, measured_T)
        weights, terms, objective = cal.weights, cal.terms, cal.D_after
        pace = {k: v for k, v in asdict(cal).items() if k not in ("weights", "terms")} | {"c_start": c_start}
    return IOCResult(spec=spec, weights=weights, objective=objective,
                     start_objective=start_objective, evaluations=len(cache), iterations=iteration,
                     failed=sum(not d["success"] for d in terms), per_target=terms, message=str(res.message),
                     held_objective=held, horizons_changed=changed, pace=pace, solutions=solutions)
