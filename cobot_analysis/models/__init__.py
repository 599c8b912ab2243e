"""Walking-path models (docs/methods.md sec. 5): one API for all of them.

    from cobot_analysis.models import generate
    df = generate("improved", start=(-1.5, -3.4, 0.0), goal=(0.0, 0.0, math.pi / 2), weights="walking-2021")

``generate`` returns the columns of measured trajectories (x, y, theta, gamma, vx, vy, time, phase,
...) plus the model's velocities and controls, so generated and measured paths go through the
same metrics, figures and reports. Models: ``unicycle``, ``clothoid``, ``mombaur``, ``improved``
and ``table`` (the improved model with the table preset); ``coupled`` lives in ``coupled.py``.

OC models are solved on a grid of ``n_intervals`` (default 100) and resampled to ``n_samples``
with cubic Hermite interpolation of the positions (the node velocities are the derivatives) and of
theta (omega): the difference to a 500-interval solve is measured in tests/test_models.py.

Every path says whether it reached its goal (``goal_check``: end position within ``GOAL_TOLERANCE``
[0] m and heading within [1] rad; columns ``end_position_error``, ``end_heading_error``,
``goal_reached``), the time law it implies (``mean_speed`` = path length / T, m/s) and how its heading turns
(``heading_turns``). Under the
continuous convention the goal at rest is a constraint (docs/methods.md sec. 5.5, 11): a path that
misses it is never ``converged``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.errors import InputError
from cobot_analysis.models.oc import OC_MODELS, resample, solve_model
from cobot_analysis.models.presets import DEFAULT_PRESET, PRESETS, load_weights, weights_vector

MODELS = ("unicycle", "clothoid", "mombaur", "improved", "table")
GOAL_TOLERANCE = (0.01, 0.05)  # m, rad: a path ends at its goal (docs/methods.md sec. 5.5)
GOAL_EXTENT = 10.0  # m: |x|, |y| of a start or goal in the studies' frames, the goal predictor's bound too
# (imported by models.prediction.goal; their paths lie within 6 m of the origin)

__all__ = ["GOAL_EXTENT", "GOAL_TOLERANCE", "MODELS", "OC_MODELS", "PRESETS", "generate", "check_endpoints", "goal_check", "heading_turns", "mean_speed",
           "refuse_unreached", "spins", "spin_status"]


def goal_check(x, y, theta, goal) -> dict[str, float | bool]:
    """End position error |p_N - p_f| (m), end heading error |wrap(theta_N - theta_f)| (rad) and
    whether both are within ``GOAL_TOLERANCE``."""
    from cobot_analysis.angles import angle_diff

    ep = math.hypot(float(x[-1]) - goal[0], float(y[-1]) - goal[1])
    eh = abs(float(angle_diff(float(theta[-1]), goal[2])))
    ok = bool(np.isfinite(ep) and np.isfinite(eh) and ep <= GOAL_TOLERANCE[0] and eh <= GOAL_TOLERANCE[1])
    return {"end_position_error": ep, "end_heading_error": eh, "goal_reached": ok}


def heading_turns(theta) -> dict[str, float]:
    """How a path's heading turns (rad, theta unwrapped): ``net`` = theta_N - theta_0, ``shortest`` = wrap(net), the
    shortest turn between the same two headings, and ``excess`` = sum |theta_{i+1} - theta_i| - |net|, the turning
    beyond the net turn (a turn and back, a loop: a full turn adds 2 pi).

        >>> from cobot_analysis.models import heading_turns
        >>> h = heading_turns([0.0, 3.0, 6.0])   # turning the long way to a heading 0.28 rad to the right
        >>> round(h["net"], 2), round(h["shortest"], 2), h["excess"]
        (6.0, -0.28, 0.0)
    """
    from cobot_analysis.angles import wrap

    theta = np.asarray(theta, float)
    net = float(theta[-1] - theta[0])
    return {"net": net, "shortest": float(wrap(net)), "excess": float(np.abs(np.diff(theta)).sum()) - abs(net)}


def spins(theta) -> bool:
    """The heading turns more than a full turn beyond its net turn, ``sum |dtheta| - |theta_N - theta_0| > 2 pi``
    (theta unwrapped; ``heading_turns``' excess): no walker's path; a loop adds a full turn."""
    return heading_turns(theta)["excess"] > 2 * math.pi


def spin_status(theta, omega=None) -> str:
    """'' or, for a path that ``spins``, what its ``status`` says: the turning beyond the net turn and the largest
    |omega| (rad/s), with no '|' (a cell of results.md's tables). Such a path can be a converged solution at its
    goal: the weights leave the turning rate's changes almost free (a3 near zero, docs/methods.md sec. 5.5)."""
    if not spins(theta):
        return ""
    rate = "" if omega is None else f", its turning rate up to {np.nanmax(np.abs(np.asarray(omega, float))):.3g} rad/s"
    return f"spins: its heading turns {heading_turns(theta)['excess']:.1f} rad beyond its net turn{rate} (no walker's path)"


def mean_speed(x, y, T: float) -> float:
    """Path length over duration, sum |p_{i+1} - p_i| / T (m/s): the time law a path implies."""
    length = float(np.hypot(np.diff(np.asarray(x, float)), np.diff(np.asarray(y, float))).sum())
    return length / T if T > 0 else math.nan


def check_endpoints(start, goal, *, path=None, min_distance: float = 0.01, options=("--start", "--goal"),
                    outside: str | None = None) -> None:
    """Refuse NaN poses, a start or goal outside the lab (|x|, |y| <= ``GOAL_EXTENT``, the bound of the goal
    predictor's goals) and a start equal to the goal (nothing to plan); ``options`` name the two poses in the message,
    ``outside`` is the remedy of a pose outside the lab (default: give the option in metres)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if start.shape[-1] < 3 or goal.shape[-1] < 3:
        raise InputError("start and goal must be poses (x, y, theta)", path=path, remedy="give three numbers each")
    for option, pose in zip(options, (start, goal)):
        if not np.all(np.isfinite(pose[:3])):
            raise InputError(f"{option} ({', '.join(f'{v:g}' for v in pose[:3])}) has a NaN or infinite value", path=path,
                             remedy=f"give {option} as three finite numbers (m, m, rad); a study's mean gives its first and "
                                    "last samples")
    for option, pose in zip(options, (start, goal)):
        if max(abs(pose[0]), abs(pose[1])) > GOAL_EXTENT:
            raise InputError(f"{option} ({pose[0]:g}, {pose[1]:g}) lies outside the lab (|x|, |y| <= {GOAL_EXTENT:g} m)",
                             path=path, remedy=outside or f"give {option} in metres in the study's frame, within "
                                                          f"{GOAL_EXTENT:g} m of its origin (not millimetres)")
    if math.hypot(goal[0] - start[0], goal[1] - start[1]) < min_distance:
        raise InputError(f"start equals goal (closer than {min_distance * 100:.0f} cm)", path=path,
                         remedy="give a goal at least 1 cm away from the start")


def refuse_unreached(df: pd.DataFrame, *, option: str = "--goal", max_iter_option: str = "--max-iter") -> None:
    """An ``InputError`` naming ``option`` when a path asked for on its own (``generate`` with one start
    and goal) did not converge or reach its goal: the output would hold no usable path."""
    bad = df.groupby("trial", sort=False).tail(1)
    bad = bad[~bad["converged"].astype(bool)]
    if len(bad):
        r = bad.iloc[0]
        raise InputError(f"the {r.model} model does not reach {option} from the start: {r.status}",
                         remedy=f"check {option} (metres, lab frame, heading on the branch meant) or raise {max_iter_option}")


def _frame(arrays: dict[str, np.ndarray], *, model: str, weights_label: str, entity: str, trial: str,
           condition: str, study: str, cost: float, convention: str, goal, converged: bool = True,
           status: str = "") -> pd.DataFrame:
    from cobot_analysis.distances import gamma_from_path

    n = len(arrays["x"])
    T = float(arrays["time"][-1])
    df = pd.DataFrame({
        "study": study, "trial": trial, "kind": "model", "n_trials": 1, "condition": condition,
        "entity": entity, "sample": np.arange(n), "phase": 100.0 * np.arange(n) / (n - 1), **arrays,
    })
    df["gamma"] = gamma_from_path(df["x"].to_numpy(), df["y"].to_numpy(), df["theta"].to_numpy())
    df["travel_time"] = T
    df["travelled_distance"] = math.hypot(df["x"].iloc[-1] - df["x"].iloc[0], df["y"].iloc[-1] - df["y"].iloc[0])
    df["quality"] = "ok"
    df["model"] = model
    df["weights"] = weights_label
    df["cost"] = cost
    reached = goal_check(arrays["x"], arrays["y"], arrays["theta"], goal)
    for k, v in reached.items():
        df[k] = v
    df["mean_speed"] = mean_speed(arrays["x"], arrays["y"], T)
    # continuous convention: the goal is a constraint, a path that misses it did not converge
    df["converged"] = bool(converged and (reached["goal_reached"] or convention != "continuous"))
    if not status:
        status = (spin_status(arrays["theta"], arrays.get("omega")) or "ok") if reached["goal_reached"] else (
            f"ends {reached['end_position_error']:.3f} m and {reached['end_heading_error']:.3f} rad from its goal"
            + (" (terminal cost, published convention)" if convention == "published" else ""))
    df["status"] = status
    df["convention"] = convention
    return df


def generate(model: str, start: Sequence[float], goal: Sequence[float], weights=None, n_samples: int = 500, *,
             convention=None, n_intervals: int = 100, duration: str | None = None, v_nominal: float = 1.0,
             solver: str = "fatrop", guesses=("rest", "line"), trial: str | None = None, condition: str = "",
             study: str = "model", entity: str | None = None, max_iter: int = 500,
             on_failure: str = "raise") -> pd.DataFrame:
    """A trajectory of ``model`` from ``start`` to ``goal`` (poses (x, y, theta), goal heading on the
    branch wanted) with the columns of measured trajectories; see the module docstring.

    ``weights``: preset name, fitted-weights file, mapping, or None (the model's default preset).
    ``convention`` (docs/methods.md sec. 11), by default the one the weights were made under, as on the
    command line (``presets.weights_convention``; ``continuous`` when unknown or when that convention has
    no rule for the model): ``continuous``, the OC solution resampled to
    ``n_samples`` in time; ``published``, the solution's nodes (one per step of the authors' node
    step; ``n_samples`` is ignored for OC models). When the OC problem does not converge: raises
    ``SolverError`` (``on_failure="raise"``) or returns the solver's last iterate with
    ``converged`` false and the reason in ``status`` (``"flag"``; never a silent result). A duration on a
    bound of its search (``conventions.OCRule.T_bounds`` x T0) is said in ``status`` too: the time law is
    then the bound's, not the weights'. The goal columns are described in the module docstring.
    """
    from cobot_analysis import conventions
    from cobot_analysis.models.oc import node_arrays

    if model not in MODELS:
        raise InputError(f"unknown model {model!r}", remedy=f"use one of {', '.join(MODELS)}")
    if convention is None:
        from cobot_analysis.models.presets import weights_convention

        convention = weights_convention(weights) if model != "clothoid" else None
        if convention is None or model not in conventions.get(convention).oc:
            convention = "continuous"
    conv = conventions.get(convention)
    if model != "clothoid":
        conv.oc_rule(model)
    check_endpoints(start, goal)
    entity = entity or ("table" if model == "table" else "walker")
    trial = trial or f"{model}"
    if model == "clothoid":
        from cobot_analysis.models.clothoid import clothoid_path

        s, x, y, theta = clothoid_path(start, goal, n_samples)
        T = s[-1] / v_nominal
        zeros = np.zeros(n_samples)
        arrays = {"time": s / v_nominal, "x": x, "y": y, "theta": theta, "v_forw": np.full(n_samples, v_nominal),
                  "v_orth": zeros, "omega": np.gradient(theta, s / v_nominal) if T > 0 else zeros,
                  "vx": v_nominal * np.cos(theta), "vy": v_nominal * np.sin(theta), "u1": zeros, "u2": zeros, "u3": zeros}
        return _frame(arrays, model=model, weights_label="", entity=entity, trial=trial, condition=condition,
                      study=study, cost=float("nan"), convention=conv.name, goal=goal)
    label = weights if isinstance(weights, str) else (DEFAULT_PRESET[model] if weights is None else "custom")
    w = weights_vector(load_weights(weights if weights is not None else DEFAULT_PRESET[model], "improved"))
    sol = solve_model(model, start, goal, w, convention=conv, n_intervals=n_intervals, duration=duration,
                      v_nominal=v_nominal, solver=solver, guess=guesses, max_iter=max_iter, warm=True)
    what = f"{model} model from {tuple(np.round(start, 3))} to {tuple(np.round(goal, 3))}"
    if on_failure == "raise" or not np.all(np.isfinite(sol.X)):
        sol.check(what)
    kind = "unicycle" if model == "unicycle" else "walker"
    if conv.name == "published":
        arrays = node_arrays(sol, kind)
    else:
        from cobot_analysis.models.oc.duration import initial_duration

        T0 = initial_duration(start, goal, v_nominal)
        how = duration or conv.oc_rule(model).duration  # free: the rule's bounds; search: duration.search_duration's
        lo, hi = conv.oc_rule(model).T_bounds if how == "free" else (0.4, 2.0)
        at_bound = how in ("free", "search") and min(abs(sol.T / T0 / b - 1) for b in (lo, hi)) < 1e-3
        if at_bound:
            from cobot_analysis.console import warn

            warn(f"{trial}: the optimal duration lies at a bound of the search interval (T = {sol.T:.2f} s = "
                 f"{sol.T / T0:.2f} x T0): the weights favour a duration outside [{lo:g}, {hi:g}] x T0")
        arrays = resample(sol, n_samples, kind)
    status = "" if sol.success else f"solver did not converge ({sol.solver}: {sol.status}, {sol.iterations} iterations)"
    if conv.name != "published" and sol.success and at_bound:  # a time law the bound chose, not the weights
        status = f"duration on a bound of its search ({sol.T / T0:.2f} x T0)"
    return _frame(arrays, model=model, weights_label=str(label), entity=entity, trial=trial, condition=condition,
                  study=study, cost=sol.cost, convention=conv.name, goal=goal, converged=sol.success, status=status)
