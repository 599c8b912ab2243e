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

The bound (Raue et al. 2009, Bioinformatics 25:1923: a profile point is excluded from the 95 %
confidence set when the data reject it against the fit). D is a mean over the n targets of a distance,
not a log-likelihood, so the test is the one the targets give directly, the bootstrap's units: the
per-target rises delta_n = D_n(point) - D_n(fit) and their paired t statistic
    t = mean(delta) / (sd(delta) / sqrt(n)),
the point rejected when t > t_(n-1)(0.975) (the two-sided 95 % quantile, as chi2_1(0.95) = 1.96^2
in a likelihood ratio; comparing two fitted models by their per-observation loss differences is Vuong's
test, Econometrica 57:307, 1989), and the mean rise is at least ``REL_TOL`` D (the curvature verdict's
sloppiness: a rise below 0.1 % of D is flat there, and differences at the solvers' tolerance are not
evidence). Near a smooth optimum mean(delta) grows as dy^2 and sd(delta) as |dy|, so the crossing is
the sandwich (robust) standard error's interval; at a fold no smoothness is needed. The crossing is
interpolated linearly in y_j between grid points, on min(t / t_q, rise / (REL_TOL D)) = 1 (as coarse as
the grid), walking outward from the profile's least D (the fit, or a point lower by more than ``REL_TOL``, which
the test then takes as its reference: a fit stopped short of its minimum may itself be rejected). Verdicts:
- rejected on both sides: "determined", the interval between the crossings;
- no point rejected up to a search limit on a side: "only its ratio to X is determined" when a re-fitted
  weight X moves with it at least half as much, with the same sign, over those points (the curvature
  verdict's rule, ``uncertainty.verdicts``), else "not determined by these data";
- where the refit cannot start (a path that is not a regular KKT point of the restricted problem), D at the
  previous point's other weights stands for the point: an upper bound of the profile, so it can show that
  the point is not rejected, never that it is; a lower level that fails, or a rejected upper bound, ends
  that side without a verdict ("not judged");
- every point rejected against a lower D found on another weight's profile: "not judged" (the fit is not at a
  minimum of D).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from cobot_analysis.models.ioc.fit import LOG_BOUNDS, IOCSpec, solve_target
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

OFFSETS = (0.1, 0.3, 1.0, 3.0)  # log10 steps from the fit on each side; then the search limit
LEVEL = 0.95
REL_TOL = 1e-3  # a mean rise of D below this fraction of D is flat (``uncertainty.verdicts``' sloppiness)


def excess(Di: np.ndarray, D0i: np.ndarray, level: float = LEVEL) -> tuple[float, float, float]:
    """(t, t_q, min(t / t_q, rise / (REL_TOL D))) of a profile point's per-target D ``Di`` against the fit's ``D0i``
    (module docstring): the point is rejected when the last is above 1."""
    from scipy.stats import t as student

    d = np.asarray(Di, float) - np.asarray(D0i, float)
    n, rise = len(d), float(d.mean())
    sd = float(d.std(ddof=1)) if n > 1 else 0.0
    t = rise / (sd / math.sqrt(n)) if sd > 0 else (math.inf if rise > 0 else 0.0)
    tq = float(student.ppf(0.5 + level / 2, max(n - 1, 1)))
    flat = REL_TOL * float(np.mean(D0i))  # a fit at D = 0 (noise-free paths): any rise is above it
    return t, tq, min(t / tq, rise / flat if flat > 0 else (math.inf if rise > 0 else 0.0))


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
    name, ys, paths, D0i): from weights ``w`` and the fit's ``paths``, each y of ``ys`` in turn (module
    docstring); stops after the first point the targets reject against the fit's per-target D ``D0i``
    (``excess`` > 1) or where a lower level fails (``error``: why; also where the refit could not start). Per point: {"y", "D", "Di", "weights" (the re-fitted ones),
    "switched", "failed", "error"}."""
    from cobot_analysis.models.ioc.single_level import fit_feasible_path

    spec, targets, w, name, ys, paths, D0i = task
    names = names_for(spec.model)
    j = names.index(name)
    others = tuple(n for n in spec.fitted if n != name)
    w, out = np.array(w, float), []
    for y in ys:
        w[j] = 10.0 ** y
        point = {"y": y, "D": math.nan, "Di": [], "weights": {}, "switched": 0, "failed": 0, "error": ""}
        out.append(point)
        terms, primals, point["switched"] = lower_levels(spec, w, targets, paths)
        if not terms:
            point["error"] = "a lower level failed"
            break
        if others:
            try:
                r = fit_feasible_path(replace(spec, fitted=others, start_weights=tuple(map(float, w))), targets,
                                      start=primals, probe=False)
            except RuntimeError as e:  # a start path that is not a regular KKT point: no refit there, D at the previous
                # point's other weights is an upper bound of the profile (judged by ``_side``)
                point["error"] = str(e)
                r = None
            if r is not None and r.objective <= np.mean([d["D"] for d in terms]):
                terms, primals = r.per_target, r.primals
                w = np.array([r.weights[n] for n in names], float)
            point["failed"] = r.failed if r is not None else 0
        point["Di"] = [d["D"] for d in terms]
        point["D"] = float(np.mean(point["Di"]))
        point["weights"] = {n: float(w[names.index(n)]) for n in others}
        paths = primals
        if excess(point["Di"], D0i)[2] > 1:
            break
    return out


def profiles(spec: IOCSpec, targets: list[Target], weights: dict[str, float], fitted=None, *, paths: list | None = None,
             pool=None, offsets=OFFSETS) -> dict:
    """The profiles of ``fitted`` (default: every fitted weight) at the fit ``weights`` (module docstring):
    the fit's lower levels first (warm from ``paths``, the fit's own, when given, and from the cold guesses),
    then one chain per weight and side on ``pool`` (an executor; None: in-process).
    Returns {"D": D at the fit, "D_min": the least D seen, "n", "t_q", "points": {name: [point, ...] in y order,
    the fit included, each with its per-target "Di" and its "t" and "excess" against the least-D point}, "verdicts": {name: verdict},
    "intervals": {name: (lo, hi)}, "seconds": wall time}."""
    from cobot_analysis.models.presets import weights_vector
    from cobot_analysis.parallel import InlineExecutor

    t_start = time.perf_counter()
    pool, n = pool or InlineExecutor(), len(targets)
    w = np.asarray(weights_vector(weights, spec.model), float)
    terms, primals, _ = lower_levels(spec, w, targets, paths or [None] * n)
    if not terms:
        raise RuntimeError("profile: a lower level failed at the fitted weights")
    D0i = [d["D"] for d in terms]
    fitted = tuple(fitted or spec.fitted)
    y0 = {name: math.log10(max(weights[name], 10.0 ** LOG_BOUNDS[0])) for name in spec.fitted}
    futures = {(name, side): pool.submit(profile_chain, (spec, targets, w, name, grid(y0[name], side, offsets), primals, D0i))
               for name in fitted for side in (-1, 1)}
    chains = {key: f.result() for key, f in futures.items()}
    # the reference: the fit, or a profile point with a D lower by more than REL_TOL (the fit is then not the least D
    # along the profiles; a smaller difference is flat)
    D0 = float(np.mean(D0i))
    best = min([p for c in chains.values() for p in c if p["Di"]] + [{"D": D0, "Di": D0i}], key=lambda p: p["D"])
    best = best if best["D"] < (1 - REL_TOL) * D0 else {"D": D0, "Di": D0i}
    ref = list(best["Di"])
    for c in chains.values():
        for p in c:
            p["t"], _, p["excess"] = excess(p["Di"], ref) if p["Di"] else (math.nan, math.nan, math.nan)
    t0, t_q, e0 = excess(D0i, ref)
    out = {"D": D0, "D_min": best["D"], "n": n, "t_q": t_q, "points": {}, "verdicts": {}, "intervals": {}}
    for name in fitted:
        down, up = chains[(name, -1)], chains[(name, 1)]
        centre = {"y": y0[name], "D": D0, "Di": list(D0i), "weights": {k: weights[k] for k in spec.fitted if k != name},
                  "switched": 0, "failed": 0, "error": "", "t": t0, "excess": e0}
        out["points"][name] = down[::-1] + [centre] + up
        out["verdicts"][name], out["intervals"][name] = verdict(name, y0, centre, down, up, best["D"])
    out["seconds"] = time.perf_counter() - t_start
    return out


def _side(centre: dict, chain: list[dict], limit: float) -> tuple[str, float]:
    """One side of a profile, walked outward: ("rises", y where ``excess`` crosses 1), ("flat", the search
    limit), ("failed", y of the failed refit) or ("open", last y: the chain stopped short)."""
    prev_y, prev_e = centre["y"], max(centre["excess"], 0.0)
    for p in chain:
        if not np.isfinite(p["D"]) or (p["error"] and p["excess"] > 1):  # no D, or a rejected upper bound (no refit)
            return "failed", p["y"]
        if p["excess"] > 1:
            f = (1 - prev_e) / (p["excess"] - prev_e) if prev_e <= 1 and np.isfinite(p["excess"]) else 0.0
            return "rises", prev_y + f * (p["y"] - prev_y)
        prev_y, prev_e = p["y"], max(p["excess"], 0.0)
    return ("flat", limit) if abs(prev_y - limit) < 0.01 else ("open", prev_y)


def _tail(notes: list[str]) -> str:
    """The verdict's notes, "; "-joined after the verdict (none: "")."""
    return ("; " + "; ".join(notes)) if notes else ""


def verdict(name: str, y0: dict[str, float], centre: dict, down: list[dict], up: list[dict], D_min: float
            ) -> tuple[str, tuple[float, float]]:
    """The plain verdict of one weight from its profile: ``centre`` the fit, ``down`` and ``up`` the chains
    outward, each point with its ``excess``; and its interval (the search box unless determined) (module
    docstring). The sides are walked from the profile's least-D point ``D_min`` (the fit unless a point is lower by
    more than ``REL_TOL``)."""
    D0 = centre["D"]
    # walked outward from the profile's least-D point (the reference of ``excess``: the fit, or a point whose D is lower
    # by more than REL_TOL, and then the fit itself may be rejected)
    line = down[::-1] + [centre] + up
    i0 = len(down) if D_min >= D0 else min((i for i, p in enumerate(line) if np.isfinite(p["D"])), key=lambda i: line[i]["D"])
    sides = {s: _side(line[i0], chain, LOG_BOUNDS[0 if s < 0 else 1]) for s, chain in ((-1, line[:i0][::-1]), (1, line[i0 + 1:]))}
    pts = down + up
    box = (10.0 ** LOG_BOUNDS[0], 10.0 ** LOG_BOUNDS[1])
    notes = []
    jumps = [p for p in pts if p.get("switched")]
    if jumps:
        notes.append("lower-level paths change branch (a fold) at " + ", ".join(f"{name} {10 ** p['y']:.3g} ({p['switched']})" for p in jumps))
    lowest = [p for p in pts if p["D"] <= D_min < D0]
    if lowest:
        notes.append(f"D {lowest[0]['D']:.4g} at {name} {10 ** lowest[0]['y']:.3g}, below the fit's {D0:.4g}"
                     + (", which the targets reject" if centre["excess"] > 1 else ""))
    if line[i0]["excess"] > 1:  # the least D lies on another weight's profile, and the targets reject this whole line
        return (f"not judged: the fit is not at a minimum of D (the targets reject every point of the {name} profile "
                f"against D {D_min:.4g}, found on another weight's profile){_tail(notes)}", box)
    failed = [(s, y) for s, (kind, y) in sides.items() if kind in ("failed", "open")]
    flat = [(s, y) for s, (kind, y) in sides.items() if kind == "flat"]
    tail = _tail(notes)
    if not failed and not flat:
        lo, hi = sides[-1][1], sides[1][1]
        return (f"determined (profile: the targets reject {name} below {10 ** lo:.3g} and above {10 ** hi:.3g}{tail})",
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
    return f"{head} (profile: no value rejected by the targets up to the search limit {where}{tail})", box
