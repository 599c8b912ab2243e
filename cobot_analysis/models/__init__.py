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
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd

from cobot_analysis.errors import InputError
from cobot_analysis.models.oc import OC_MODELS, resample, solve_model
from cobot_analysis.models.presets import DEFAULT_PRESET, PRESETS, load_weights, weights_vector

MODELS = ("unicycle", "clothoid", "mombaur", "improved", "table")

__all__ = ["MODELS", "OC_MODELS", "PRESETS", "generate", "check_endpoints"]


def check_endpoints(start, goal, *, path=None, min_distance: float = 0.01) -> None:
    """Refuse NaN poses and a start equal to the goal (nothing to plan)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if start.shape[-1] < 3 or goal.shape[-1] < 3:
        raise InputError("start and goal must be poses (x, y, theta)", path=path, remedy="give three numbers each")
    if not (np.all(np.isfinite(start[:3])) and np.all(np.isfinite(goal[:3]))):
        raise InputError("start or goal pose has NaN", path=path, remedy="check the trajectory's first and last samples")
    if math.hypot(goal[0] - start[0], goal[1] - start[1]) < min_distance:
        raise InputError(f"start equals goal (closer than {min_distance * 100:.0f} cm)", path=path,
                         remedy="give a goal at least 1 cm away from the start")


def _frame(arrays: dict[str, np.ndarray], *, model: str, weights_label: str, entity: str, trial: str,
           condition: str, study: str, cost: float, convention: str) -> pd.DataFrame:
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
    df["converged"] = True
    df["convention"] = convention
    return df


def generate(model: str, start: Sequence[float], goal: Sequence[float], weights=None, n_samples: int = 500, *,
             convention=None, n_intervals: int = 100, duration: str | None = None, v_nominal: float = 1.0,
             solver: str = "fatrop", guesses=("rest", "line"), trial: str | None = None, condition: str = "",
             study: str = "model", entity: str | None = None, max_iter: int = 500) -> pd.DataFrame:
    """A trajectory of ``model`` from ``start`` to ``goal`` (poses (x, y, theta), goal heading on the
    branch wanted) with the columns of measured trajectories; see the module docstring.

    ``weights``: preset name, fitted-weights file, mapping, or None (the model's default preset).
    ``convention`` (docs/methods.md sec. 11), by default the one the weights were made under, as on the
    command line (``presets.weights_convention``; ``continuous`` when unknown or when that convention has
    no rule for the model): ``continuous``, the OC solution resampled to
    ``n_samples`` in time; ``published``, the solution's nodes (one per step of the authors' node
    step; ``n_samples`` is ignored for OC models). Raises ``SolverError`` when the OC problem does
    not converge (never a silent result).
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
                      study=study, cost=float("nan"), convention=conv.name)
    label = weights if isinstance(weights, str) else (DEFAULT_PRESET[model] if weights is None else "custom")
    w = weights_vector(load_weights(weights if weights is not None else DEFAULT_PRESET[model], "improved"))
    sol = solve_model(model, start, goal, w, convention=conv, n_intervals=n_intervals, duration=duration,
                      v_nominal=v_nominal, solver=solver, guess=guesses, max_iter=max_iter, warm=True)
    sol.check(f"{model} model from {tuple(np.round(start, 3))} to {tuple(np.round(goal, 3))}")
    kind = "unicycle" if model == "unicycle" else "walker"
    if conv.name == "published":
        arrays = node_arrays(sol, kind)
    else:
        from cobot_analysis.models.oc.duration import initial_duration

        T0 = initial_duration(start, goal, v_nominal)
        if min(abs(sol.T / T0 - b) for b in (0.4, 2.0, 2.5)) < 1e-3:
            from cobot_analysis.console import warn

            warn(f"{trial}: the optimal duration lies at a bound of the search interval (T = {sol.T:.2f} s = "
                 f"{sol.T / T0:.2f} x T0): the weights favour a duration outside [0.4, 2.5] x T0")
        arrays = resample(sol, n_samples, kind)
    return _frame(arrays, model=model, weights_label=str(label), entity=entity, trial=trial, condition=condition,
                  study=study, cost=sol.cost, convention=conv.name)
