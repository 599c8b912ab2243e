"""Profile likelihoods of the fitted weights (docs/methods.md sec. 6.3), where the curvature at the fit
cannot judge (D not locally quadratic: ``uncertainty.ROUGH``).

Profile of weight j: y_j = log10 w_j is held at a grid of values on each side of the fit (steps
``OFFSETS`` from it, then the search limit) and the other fitted weights are re-fitted there,
    PD_j(y_j) = min_{y_-j} D(y_j, y_-j),
by the single-level feasible-path fit (``single_level.fit_feasible_path``, no escape probes), started
from the previous grid point's weights and paths (a chain outward from the fit). At each point the
lower levels are first solved at the previous point's other weights warm from its paths and from the
two cold guesses, the least cost kept (the bi-level fit's rule): a path whose least-cost solution is
not the warm continuation has changed branch (a fold), and the profile reports it as a jump.
The D of a point is the fit's re-solved D (exact, not smoothed).

Threshold (Raue et al. 2009, Bioinformatics 25:1923): the likelihood-ratio bound of a pointwise 95 %
interval, -2 log LR(y_j) < chi2_1(0.95). D is the mean of the n targets' distances D_n >= 0; taken
as independent exponential losses of a common scale s (the distribution of largest entropy for a
positive loss of given mean), -log L = n log s + n D / s, and s profiled out (s = D),
    -2 log LR = 2 n log(PD_j / D_min) < chi2_1(0.95),  i.e.  PD_j < D_min exp(chi2_1(0.95) / (2 n)),
D_min the least D seen (the fit's, or a profile point's below it). Verdicts:
- D crosses the threshold on both sides: "determined", the interval between the crossings (linear
  interpolation in y_j between grid points: as coarse as the grid);
- D stays below it to a search limit on a side: "only its ratio to X is determined" when a re-fitted
  weight X moves with it at least half as much, with the same sign, over those points (the curvature
  verdict's rule, ``uncertainty.verdicts``), else "not determined by these data";
- a refit that fails ends that side: no verdict from it.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from cobot_analysis.models.ioc.fit import LOG_BOUNDS, IOCSpec, solve_target
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

OFFSETS = (0.1, 0.3, 1.0, 3.0)  # log10 steps from the fit on each side; then the search limit
LEVEL = 0.95


def threshold(D_min: float, n: int, level: float = LEVEL) -> float:
    """The profile's bound: D_min exp(chi2_1(level) / (2 n)) (module docstring)."""
    from scipy.stats import chi2

    return D_min * math.exp(chi2.ppf(level, 1) / (2 * n))


def grid(y0: float, side: int, offsets=OFFSETS) -> list[float]:
    """The profile's points on one side (+1 up, -1 down) of y0: y0 + side * offsets inside the search
    box, then the search limit (none when y0 is within 0.01 of it)."""
    limit = LOG_BOUNDS[1] if side > 0 else LOG_BOUNDS[0]
    if abs(limit - y0) < 0.01:
        return []
    return [y for y in (y0 + side * d for d in offsets) if side * (limit - y) > 0.01] + [limit]


def lower_levels(spec: IOCSpec, w: np.ndarray, targets: list[Target], paths: list) -> tuple[list, list, int]:
    """Every target's lower level at ``w``, warm from ``paths`` and from the two cold guesses, the least
    cost kept: (terms, primals, paths that changed branch: the least cost is not the warm continuation)."""
    terms, primals, switched = [], [], 0
    for t, z in zip(targets, paths):
        warm = solve_target(spec, w, t, (z,)) if z is not None else None
        cold = solve_target(spec, w, t, "rest")
        ok = [s for s in (warm, cold) if s is not None and s[0]["success"]]
        if not ok:
            return [], [], switched
        d, sol = min(ok, key=lambda s: s[1].cost)
        if warm is None or not warm[0]["success"] or (sol is not warm[1] and np.abs(sol.primal - warm[1].primal).max() > 1e-4):
            switched += 1
        terms.append(d)
        primals.append(sol.primal)
    return terms, primals, switched


def profile_chain(task) -> list[dict]:
    """Worker task (top-level, picklable): one side of one weight's profile, task = (spec, targets, w,
    name, ys, paths, stop): from weights ``w`` and the fit's ``paths``, each y of ``ys`` in turn (module
    docstring); stops after the first point whose D exceeds ``stop`` or whose refit fails. Per point:
    {"y", "D", "weights" (the re-fitted ones), "switched", "failed", "error"}."""
    from cobot_analysis.models.ioc.single_level import fit_feasible_path

    spec, targets, w, name, ys, paths, stop = task
    names = names_for(spec.model)
    j = names.index(name)
    others = tuple(n for n in spec.fitted if n != name)
    w, out = np.array(w, float), []
    for y in ys:
        w[j] = 10.0 ** y
        point = {"y": y, "D": math.nan, "weights": {}, "switched": 0, "failed": 0, "error": ""}
        out.append(point)
        terms, primals, point["switched"] = lower_levels(spec, w, targets, paths)
        if not terms:
            point["error"] = "a lower level failed"
            break
        D = float(np.mean([d["D"] for d in terms]))
        if others:
            try:
                r = fit_feasible_path(replace(spec, fitted=others, start_weights=tuple(map(float, w))), targets,
                                      start=primals, probe=False)
            except RuntimeError as e:  # a start path that is not a regular KKT point: no refit there
                point["error"] = str(e)
                break
            if r.objective <= D:
                D, primals = r.objective, r.primals
                w = np.array([r.weights[n] for n in names], float)
            point["failed"] = r.failed
        point["D"] = D
        point["weights"] = {n: float(w[names.index(n)]) for n in others}
        paths = primals
        if D > stop:
            break
    return out


def profiles(spec: IOCSpec, targets: list[Target], weights: dict[str, float], fitted=None, *, paths: list | None = None,
             pool=None, offsets=OFFSETS) -> dict:
    """The profiles of ``fitted`` (default: every fitted weight) at the fit ``weights`` (module docstring):
    the fit's lower levels first (warm from ``paths``, the fit's own, when given, and from the cold guesses),
    then one chain per weight and side on ``pool`` (an executor; None: in-process).
    Returns {"D": D at the fit, "n", "threshold", "D_min", "points": {name: [point, ...] in y order, the fit
    included}, "verdicts": {name: verdict}, "intervals": {name: (lo, hi)}}."""
    from cobot_analysis.models.presets import weights_vector
    from cobot_analysis.parallel import InlineExecutor

    pool, n = pool or InlineExecutor(), len(targets)
    w = np.asarray(weights_vector(weights, spec.model), float)
    terms, primals, _ = lower_levels(spec, w, targets, paths or [None] * n)
    if not terms:
        raise RuntimeError("profile: a lower level failed at the fitted weights")
    D0 = float(np.mean([d["D"] for d in terms]))
    stop = threshold(D0, n)
    fitted = tuple(fitted or spec.fitted)
    y0 = {name: math.log10(max(weights[name], 10.0 ** LOG_BOUNDS[0])) for name in spec.fitted}
    futures = {(name, side): pool.submit(profile_chain, (spec, targets, w, name, grid(y0[name], side, offsets), primals, stop))
               for name in fitted for side in (-1, 1)}
    chains = {key: f.result() for key, f in futures.items()}
    D_min = min([D0] + [p["D"] for c in chains.values() for p in c if np.isfinite(p["D"])])
    thr = threshold(D_min, n)
    out = {"D": D0, "n": n, "threshold": thr, "D_min": D_min, "points": {}, "verdicts": {}, "intervals": {}}
    for name in fitted:
        down, up = chains[(name, -1)], chains[(name, 1)]
        centre = {"y": y0[name], "D": D0, "weights": {k: weights[k] for k in spec.fitted if k != name}, "switched": 0,
                  "failed": 0, "error": ""}
        out["points"][name] = down[::-1] + [centre] + up
        out["verdicts"][name], out["intervals"][name] = verdict(name, y0, centre, down, up, thr, D_min)
    return out


def _side(y0: float, D0: float, chain: list[dict], thr: float, limit: float) -> tuple[str, float]:
    """One side of a profile, walked outward: ("rises", y where D crosses ``thr``), ("flat", the search
    limit), ("failed", y of the failed refit) or ("open", last y: the chain stopped short)."""
    prev_y, prev_D = y0, D0
    for p in chain:
        if not np.isfinite(p["D"]):
            return "failed", p["y"]
        if p["D"] > thr:
            f = (thr - prev_D) / (p["D"] - prev_D) if prev_D <= thr else 0.0
            return "rises", prev_y + f * (p["y"] - prev_y)
        prev_y, prev_D = p["y"], p["D"]
    return ("flat", limit) if abs(prev_y - limit) < 0.01 else ("open", prev_y)


def verdict(name: str, y0: dict[str, float], centre: dict, down: list[dict], up: list[dict], thr: float, D_min: float
            ) -> tuple[str, tuple[float, float]]:
    """The plain verdict of one weight from its profile: ``centre`` the fit, ``down`` and ``up`` the chains
    outward; and its interval (the search box unless determined) (module docstring)."""
    D0 = centre["D"]
    sides = {s: _side(y0[name], D0, chain, thr, LOG_BOUNDS[0 if s < 0 else 1]) for s, chain in ((-1, down), (1, up))}
    pts = down + up
    box = (10.0 ** LOG_BOUNDS[0], 10.0 ** LOG_BOUNDS[1])
    notes = []
    jumps = [p for p in pts if p.get("switched")]
    if jumps:
        notes.append("lower-level paths change branch (a fold) at " + ", ".join(f"{name} {10 ** p['y']:.3g} ({p['switched']})" for p in jumps))
    if D_min < D0:
        p = min((p for p in pts if np.isfinite(p["D"])), key=lambda p: p["D"])
        notes.append(f"D {p['D']:.4g} at {name} {10 ** p['y']:.3g}, below the fit's {D0:.4g}")
    failed = [(s, y) for s, (kind, y) in sides.items() if kind in ("failed", "open")]
    flat = [(s, y) for s, (kind, y) in sides.items() if kind == "flat"]
    tail = ("; " + "; ".join(notes)) if notes else ""
    if not failed and not flat:
        lo, hi = sides[-1][1], sides[1][1]
        return (f"determined (profile: D crosses its 95 % bound {thr:.4g} at {name} {10 ** lo:.3g} and {10 ** hi:.3g}{tail})",
                (10.0 ** lo, 10.0 ** hi))
    if not flat:
        s, y = failed[0]
        return f"not judged: the profile's refit failed at {name} {10 ** y:.3g}{tail}", box
    where = " and ".join(f"{10.0 ** y:g} {'below' if s < 0 else 'above'}" for s, y in flat)
    moved = [p for s, _ in flat for p in (down if s < 0 else up) if np.isfinite(p["D"])]
    dy = np.array([p["y"] - y0[name] for p in moved])
    partners = {}
    for other in centre["weights"]:
        dx = np.array([math.log10(max(p["weights"][other], 1e-300)) - y0[other] for p in moved])
        if len(dy) and dy @ dy > 0:
            partners[other] = float(dx @ dy / (dy @ dy))
    best = max(partners, key=partners.get, default=None)
    head = f"only its ratio to {best} is determined" if best is not None and partners[best] >= 0.5 else "not determined by these data"
    return f"{head} (profile: D stays below its 95 % bound {thr:.4g} to the search limit {where}{tail})", box
