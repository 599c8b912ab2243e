"""Uncertainty and identifiability of fitted weights (docs/methods.md sec. 6.4).

Identifiability at the optimum: the Hessian H of the fit's objective D (the lower level re-solved,
warm, at each point) with respect to y = log10 of the fitted weights, by central differences of
step ``h``; its eigen-decomposition H = V diag(mu) V'. A direction v is *sloppy* when moving y by a
factor of 2 along it raises D by less than ``rel_tol`` D (0.5 mu (log10 2)^2 < rel_tol D). Verdict per
weight j, from its weight in the sloppy directions s_j = sum_{sloppy} v_ij^2:

- s_j < 0.1: "determined";
- else, in the sloppy direction where |v_ij| is largest, another weight k moving with the same sign
  and at least half the amplitude: "only its ratio to k is determined" (D changes little when both
  are scaled together);
- else "not determined by these data".

A weight on a search limit (within 0.01 of a log10 bound) is flagged "at the search limit" beside the
verdict: the value there bounds the estimate; the curvature (the lower level is solved outside the
box too) says whether the data would have determined it.

Bootstrap: resample the fitted units (the targets) with replacement, refit with the single-level
method warm-started from the full fit (its weights and paths), percentile intervals.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from cobot_analysis.models.ioc.fit import LOG_BOUNDS, IOCSpec, solve_target
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

FACTOR_2 = math.log10(2.0)


def objective_at(spec: IOCSpec, targets: list[Target], w: np.ndarray, guesses: list) -> float:
    """D at weights w: the mean of the lower levels re-solved warm from ``guesses`` (the exact D)."""
    return float(np.mean([solve_target(spec, w, t, g)[0]["D"] for t, g in zip(targets, guesses)]))


def log_hessian(spec: IOCSpec, targets: list[Target], weights: dict[str, float], guesses: list,
                h: float = 0.05) -> tuple[float, np.ndarray]:
    """(D, H): D at ``weights`` and the central-difference Hessian of D in log10 of ``spec.fitted``."""
    names = names_for(spec.model)
    w = np.array([weights[n] for n in names])
    idx = [names.index(n) for n in spec.fitted]
    k = len(idx)

    def D(dy: np.ndarray) -> float:
        wy = w.copy()
        wy[idx] = w[idx] * 10.0 ** dy
        return objective_at(spec, targets, wy, guesses)

    d0 = D(np.zeros(k))
    H = np.zeros((k, k))
    E = np.eye(k) * h
    plus = [D(E[i]) for i in range(k)]
    minus = [D(-E[i]) for i in range(k)]
    for i in range(k):
        H[i, i] = (plus[i] - 2 * d0 + minus[i]) / h**2
        for j in range(i):
            H[i, j] = H[j, i] = (D(E[i] + E[j]) - plus[i] - plus[j] + 2 * d0 - minus[i] - minus[j] + D(-E[i] - E[j])) / (2 * h**2)
    return d0, H


def verdicts(fitted, H: np.ndarray, D: float, weights: dict[str, float], rel_tol: float = 1e-3) -> dict[str, str]:
    """The plain verdict of each fitted weight (module docstring)."""
    mu, V = np.linalg.eigh((H + H.T) / 2)
    sloppy = [i for i in range(len(mu)) if 0.5 * max(mu[i], 0.0) * FACTOR_2**2 < rel_tol * D]
    out = {}
    for j, n in enumerate(fitted):
        s = sum(V[j, i]**2 for i in sloppy)
        if s < 0.1:
            verdict = "determined"
        else:
            i = max(sloppy, key=lambda i: abs(V[j, i]))
            partners = [fitted[k] for k in range(len(fitted)) if k != j and V[k, i] * V[j, i] > 0 and abs(V[k, i]) >= 0.5 * abs(V[j, i])]
            verdict = f"only its ratio to {partners[0]} is determined" if partners else "not determined by these data"
        y = math.log10(max(weights[n], 1e-300))
        if abs(y - LOG_BOUNDS[0]) < 0.01 or abs(y - LOG_BOUNDS[1]) < 0.01:
            verdict += f" (at the search limit {10.0 ** (LOG_BOUNDS[0] if y < 0 else LOG_BOUNDS[1]):g})"
        out[n] = verdict
    return out


def bootstrap(spec: IOCSpec, targets: list[Target], weights: dict[str, float], primals: list, n_resamples: int = 200,
              seed: int = 0, level: float = 0.95, on_resample=None) -> dict:
    """Percentile intervals of the fitted weights over ``n_resamples`` resamples of the targets (with
    replacement), each fitted single-level from the full fit's weights and paths. Returns
    {"samples": (n_ok, k) array, "intervals": {name: (lo, hi)}, "failed": count}."""
    from cobot_analysis.models.ioc.single_level import fit_single_level

    names = names_for(spec.model)
    w_full = tuple(float(weights[n]) for n in names)
    rng = np.random.default_rng(seed)
    samples, failed = [], 0
    for b in range(n_resamples):
        pick = rng.integers(0, len(targets), len(targets))
        r = fit_single_level(replace(spec, start_weights=w_full), [targets[i] for i in pick],
                             start=[primals[i] for i in pick], verify=False)
        if r.success:
            samples.append([r.weights[n] for n in spec.fitted])
        else:
            failed += 1
        if on_resample:
            on_resample(b + 1, r.success)
    S = np.array(samples).reshape(-1, len(spec.fitted))
    a = 100 * (1 - level) / 2
    intervals = {n: (float(np.percentile(S[:, j], a)), float(np.percentile(S[:, j], 100 - a))) if len(S) else (math.nan, math.nan)
                 for j, n in enumerate(spec.fitted)}
    return {"samples": S, "intervals": intervals, "failed": failed}
