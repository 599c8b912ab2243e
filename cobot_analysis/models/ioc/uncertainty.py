"""Uncertainty and identifiability of fitted weights (docs/methods.md sec. 6.3).

Curvature at the fit: with y = log10 of the fitted weights and D(y) = (1/n) sum_i D_i(y) (each
target's lower level solved at the fit from the two cold guesses, the least cost kept, then at the
other points warm from that path only (one guess), so D_i follows one branch of lower-level solutions:
a start facing away from the goal has several local minima, and the best of several guesses would jump
between them inside the stencil (where a branch ends inside the stencil, a fold, the warm solve lands on
another minimum and the lack of fit below shows it); published convention: the duration rule at the fit (the fit's own
last run of it, not solved again), its horizon held at the other points, as the fit holds it), every target's D_i is evaluated on the central-
difference stencil of step ``h`` around the fit (1 + 2k + 2 k(k-1)/2 points for k weights), giving
per target a value D_i, a gradient g_i and a Hessian H_i, and their means D, g, H.

Verdicts, from the eigen-decomposition H = V diag(mu) V': a direction is *sloppy* when moving y by a
factor of 2 along it raises D by less than ``rel_tol`` D (0.5 mu (log10 2)^2 < rel_tol D). For weight
j, s_j = sum_{sloppy} V_ji^2:
- s_j < 0.1: "determined";
- else, in the flattest sloppy direction where the weight takes part (V_ji^2 >= 0.1), another weight k moving with the same sign
  and at least half the amplitude: "only its ratio to k is determined" (D changes little when both
  are scaled together);
- else "not determined by these data".
A weight taking part (V_ji^2 >= 0.1) in a direction of negative curvature beyond the sloppiness
(0.5 |mu| (log10 2)^2 >= rel_tol D: a fit stopped short of a minimum, e.g. by its evaluation budget) is "not
judged: the fit is not at a minimum of D" (counted as sloppy, such a direction would call the weight "not
determined").
A weight within 0.05 of a log10 search limit (a factor 1.12: ``fit.AT_LIMIT``, as the report's warning) carries "(at the
search limit ...)" beside its verdict.
A "determined" weight whose bootstrap interval (below) reaches a search limit is not determined after
all: resamples of the same data cannot exclude the limit (``interval_verdicts``).
No verdict at all ("not judged: D is not smooth at the fit") when a quadratic fitted by least squares
to D on the stencil (k >= 2: more points than coefficients) leaves more than ``ROUGH`` of D's rms change
unexplained: the lower level's paths then change regime within the stencil, and curvature means nothing;
the verdict then comes from the weight's profile likelihood when one is given (``profile.py``, "Which analysis
judges" below).

Bootstrap over the fitted units (targets): resample b draws n targets with replacement (counts c_i)
and refits the local quadratic model of its objective along the directions the full data determine
(the non-sloppy eigenvectors V_s of H; the sloppy ones held at the fit),
    y_b = y* + V_s z_b,  z_b = argmin_{y in [-7, 3]^k}  sum_i c_i (g_i' V_s z + 0.5 z' V_s' H_i V_s z),
95 % percentile intervals of 10^(y_b - y_full + y*), y_full the same refit of all targets once (a fit
stopped short of its optimum moves every resample by that step, which is no sampling spread); a weight that is not determined gets the search box as its interval. The refit is one quadratic
(Newton) step of each resample's own objective from the full fit, not a re-run of the fit: exact when
D_i is quadratic in y over the interval, and it needs no lower-level solve beyond the stencil; refitting along a sloppy direction would only return the resample noise of a
flat D (an exact gauge, e.g. the time scale, does not move at all). A determined weight whose refit the search box
pins (the weights on a limit leave it less than 10 % of its amplitude in the determined directions) in more than
(1 - level) / 2 of the resamples gets the box as its interval and "not determined by these data" with the reason
(``bootstrap``'s ``held``, ``interval_verdicts``). The stencil's evaluations are checkpointed (``resume``).

Which analysis judges (``disputed``, ``judged``; one rule for the bi-level and the single-level fit): the curvature
and the bootstrap's quadratic refits are the local (Wald) approximation of D; its profile likelihood (``profile.py``)
evaluates D itself along the weight, with the other weights re-fitted, and is the reference where the approximation
fails (Raue et al. 2009): where D is not smooth at the fit (every weight), for a weight the curvature does not judge
(the fit is not at a minimum of D along it), and for a weight the curvature determines but the bootstrap does not (the quadratic, measured within +-0.05 in log10, extrapolated to the search box in some
resamples). There the profile's verdict is the verdict, "determined" when the targets reject the weight on both sides;
a profile that could not judge (its refit failed) leaves the curvature's and the bootstrap's verdict. Elsewhere the
curvature judges, and the bootstrap overturns a "determined" (above). Each verdict names its analysis.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cobot_analysis.models.ioc.fit import LOG_BOUNDS, IOCSpec, fit_key, published_terms, search_limit_at, solve_target
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

FACTOR_2 = math.log10(2.0)
STEP = 0.05  # log10 units of the central differences
ROUGH = 0.1  # lack of fit of the quadratic model above which D is not smooth enough at the fit for a verdict
RESAMPLES = 200  # the default bootstrap count


@dataclass
class Curvature:
    """D and its derivatives in y = log10 of ``fitted`` at ``y``, per target (``Di``, ``gi``, ``Hi``) and
    their means (``D``, ``g``, ``H``)."""

    fitted: tuple[str, ...]
    y: np.ndarray
    Di: np.ndarray  # (n,)
    gi: np.ndarray  # (n, k)
    Hi: np.ndarray  # (n, k, k)
    failed: int  # lower-level solves that failed on the stencil (their D_i held at the centre value)
    lack_of_fit: float = 0.0  # rms residual of a quadratic fitted to D on the stencil / rms change of D (k >= 2)

    @property
    def D(self) -> float:
        return float(self.Di.mean())

    @property
    def g(self) -> np.ndarray:
        return self.gi.mean(axis=0)

    @property
    def H(self) -> np.ndarray:
        return self.Hi.mean(axis=0)


def stencil(k: int, h: float = STEP) -> list[np.ndarray]:
    """The central-difference points: 0, +-h e_i, then +-h (e_i + e_j) for i > j."""
    E = np.eye(k) * h
    pts = [np.zeros(k)] + [s * E[i] for i in range(k) for s in (1, -1)]
    pts += [s * (E[i] + E[j]) for i in range(k) for j in range(i) for s in (1, -1)]
    return pts


def curvature(spec: IOCSpec, targets: list[Target], weights: dict[str, float], *, h: float = STEP,
              checkpoint: Path | None = None, resume: bool = False, pool=None, chunks: int = 2,
              centre: list | None = None) -> Curvature:
    """Every target's D_i on the stencil around ``weights`` (module docstring); ``checkpoint``: a JSON
    file the evaluated stencil points are written to, one point at a time (``resume`` reuses them).
    ``pool``: an executor for the lower-level solves (chunks of targets; None: in-process): the centre
    first (its paths are the warm starts), then every other point at once, the same values as in-process.
    ``centre``: the fit's own lower-level solutions, one per target. Published convention: the duration rule's
    solutions at ``weights`` as the fit ran it last (``IOCResult.solutions``): the centre's D_i and the other points'
    seeds, not solved again. Continuous: the fit's paths (primal vectors), the warm candidate of the centre's solves
    beside the two cold guesses, the least cost kept, as the fit evaluates D: the stencil is then around the fit's own
    branch of lower-level solutions (without them, the cold guesses alone may land on another)."""
    from cobot_analysis.models.ioc.single_level import interleaved_chunks, run_chunks
    from cobot_analysis.parallel import InlineExecutor

    names = names_for(spec.model)
    w = np.array([weights[n] for n in names])
    idx = [names.index(n) for n in spec.fitted]
    k, n = len(idx), len(targets)
    key = hashlib.sha256(json.dumps([fit_key(spec, targets), list(map(float, w)), h]).encode()).hexdigest()[:16]
    done: list = []
    if resume and checkpoint is not None and checkpoint.is_file():
        data = json.loads(checkpoint.read_text())
        done = data["points"] if data.get("key") == key else []
    # the centre: every lower level as the fit evaluates it, from the fit's path (``centre``) and the two cold guesses
    # (published: the duration rule, or the fit's solutions of it given as ``centre``); its paths are the stencil's
    # warm starts
    published = spec.convention == "published"
    guesses: list = [None if published else ("rest", "line")] * n
    if centre is not None and not published:
        guesses = [(c, "rest", "line") if c is not None else g for c, g in zip(centre, guesses)]
        centre = None
    points = stencil(k, h)
    values = np.zeros((len(points), n))
    pool, parts = pool or InlineExecutor(), interleaved_chunks(n, chunks)

    def at(dy: np.ndarray) -> np.ndarray:
        wy = w.copy()
        wy[idx] = w[idx] * 10.0 ** dy
        return wy

    def save() -> None:
        if checkpoint is not None:
            checkpoint.parent.mkdir(parents=True, exist_ok=True)
            tmp = checkpoint.with_name(f".{checkpoint.name}.tmp")
            tmp.write_text(json.dumps({"key": key, "points": done}))
            os.replace(tmp, checkpoint)

    # logged points are reused; the centre is solved again (unless given) when points remain (its paths warm-start them)
    todo = [p for p in range(len(points)) if not (p < len(done) and (p > 0 or len(done) == len(points)))]
    for p in range(len(points)):
        if p not in todo:
            values[p] = done[p]
    if 0 in todo:
        centre = [_published_D(spec, t, s) for t, s in zip(targets, centre)] if centre is not None else \
            run_chunks(pool, stencil_chunk, parts, lambda q: (spec, at(points[0]), [(targets[i], guesses[i]) for i in q]), n)
        values[0] = [d for d, _ in centre]
        # off the centre, warm from the centre's path only: D_i along the branch of lower-level solutions the centre
        # is on (the cold guesses would let D_i jump to another local minimum inside the stencil)
        # (published: the centre's solution seeds the held horizon, as in the fit)
        guesses = [g if published else (g,) if g is not None else guesses[i] for i, (_, g) in enumerate(centre)]
        if not done:
            done.append(values[0].tolist())
        save()
    futures = {p: [(q, pool.submit(stencil_chunk, (spec, at(points[p]), [(targets[i], guesses[i]) for i in q]))) for q in parts]
               for p in todo if p > 0}
    for p, fs in futures.items():  # in stencil order: the checkpoint holds the points 0..p
        for q, f in fs:
            for i, (d, _) in zip(q, f.result()):
                values[p, i] = d
        if p >= len(done):
            done.append(values[p].tolist())
        save()
    bad = np.isnan(values)
    failed = int(bad.sum())
    values = np.where(bad, values[0][None, :], values)  # a failed solve: no information from that point
    values = np.where(np.isnan(values), 0.0, values)
    D0 = values[0]
    gi, Hi = np.zeros((n, k)), np.zeros((n, k, k))
    p = 1
    plus, minus = {}, {}
    for i in range(k):
        plus[i], minus[i] = values[p], values[p + 1]
        p += 2
        gi[:, i] = (plus[i] - minus[i]) / (2 * h)
        Hi[:, i, i] = (plus[i] - 2 * D0 + minus[i]) / h**2
    for i in range(k):
        for j in range(i):
            pp, mm = values[p], values[p + 1]
            p += 2
            Hi[:, i, j] = Hi[:, j, i] = (pp - plus[i] - plus[j] + 2 * D0 - minus[i] - minus[j] + mm) / (2 * h**2)
    return Curvature(tuple(spec.fitted), np.log10(w[idx]), D0, gi, Hi, failed, lack_of_fit(points, values.mean(axis=1)))


def stencil_chunk(task) -> list[tuple[float, object]]:
    """Worker task (top-level, picklable): task = (spec, w, [(target, guess), ...]); per target its D at the
    weights w (nan: the lower level failed) and the solution's warm start (the primal vector; published: the
    solution), or None."""
    spec, w, items = task
    out = []
    for t, g in items:
        d, sol = solve_target(spec, w, t, g)
        out.append((d["D"], (sol if spec.convention == "published" else sol.primal)) if d["success"] else (math.nan, None))
    return out


def _published_D(spec: IOCSpec, t: Target, sol) -> tuple[float, object]:
    """``stencil_chunk``'s (D, warm start) of a published solution already solved at the centre."""
    d = published_terms(spec, t, sol) if sol is not None else {"success": False}
    return (d["D"], sol) if d["success"] else (math.nan, None)


def lack_of_fit(points: list[np.ndarray], D: np.ndarray) -> float:
    """rms residual of the least-squares quadratic through D at the stencil points, over the rms change
    of D from the centre (0 for k = 1: the stencil then holds no more points than the quadratic)."""
    P = np.array(points)
    k = P.shape[1]
    A = np.column_stack([np.ones(len(P))] + [P[:, i] for i in range(k)] + [P[:, i] * P[:, j] for i in range(k) for j in range(i + 1)])
    r = D - A @ np.linalg.lstsq(A, D, rcond=None)[0]
    change = np.sqrt(np.mean((D - D[0]) ** 2))
    return float(np.sqrt(np.mean(r**2)) / change) if change > 0 else 0.0


def sloppy_directions(H: np.ndarray, D: float, rel_tol: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mu, V, sloppy): the eigen-decomposition of H and a mask of its sloppy directions (module docstring)."""
    mu, V = np.linalg.eigh((H + H.T) / 2)
    return mu, V, 0.5 * np.maximum(mu, 0.0) * FACTOR_2**2 < rel_tol * D


def determined(H: np.ndarray, D: float, rel_tol: float = 1e-3) -> np.ndarray:
    """Mask of the weights with less than 10 % of their weight in the sloppy directions."""
    _, V, sloppy = sloppy_directions(H, D, rel_tol)
    return (V[:, sloppy] ** 2).sum(axis=1) < 0.1


def verdicts(fitted, H: np.ndarray, D: float, weights: dict[str, float], rel_tol: float = 1e-3,
             lack: float = 0.0) -> dict[str, str]:
    """The plain verdict of each fitted weight from the curvature (module docstring); ``lack``: the stencil's
    lack of fit."""
    mu, V, mask = sloppy_directions(H, D, rel_tol)
    sloppy = list(np.flatnonzero(mask))
    ok = determined(H, D, rel_tol)
    # directions along which D is concave beyond the sloppiness: the fit is not at a minimum of D there
    falling = [i for i in range(len(mu)) if 0.5 * -mu[i] * FACTOR_2**2 >= rel_tol * D]
    out = {}
    for j, n in enumerate(fitted):
        if lack > ROUGH:
            verdict = f"not judged: D is not smooth at the fit (a quadratic leaves {100 * lack:.0f} % of its change over the stencil unexplained)"
        elif any(V[j, i] ** 2 >= 0.1 for i in falling):
            verdict = "not judged: the fit is not at a minimum of D (D is concave along a direction the weight takes part in)"
        elif ok[j]:
            verdict = "determined"
        else:
            i = min((i for i in sloppy if V[j, i] ** 2 >= 0.1), key=lambda i: mu[i], default=max(sloppy, key=lambda i: abs(V[j, i])))
            partners = [fitted[k] for k in range(len(fitted)) if k != j and V[k, i] * V[j, i] > 0 and abs(V[k, i]) >= 0.5 * abs(V[j, i])]
            verdict = f"only its ratio to {partners[0]} is determined" if partners else "not determined by these data"
        out[n] = verdict + _at_limit(weights[n])
    return out


def _at_limit(w: float) -> str:
    """" (at the search limit L)" for a weight within ``AT_LIMIT`` (0.05, a factor 1.12) of a log10 search limit, else ""."""
    b = search_limit_at(w)
    return "" if b is None else f" (at the search limit {10.0 ** b:g})"


def disputed(lack: float, curvature: dict[str, str], bootstrap: dict[str, str]) -> tuple[str, ...]:
    """The weights the curvature and the bootstrap cannot judge alike, whose profile likelihood judges them
    (module docstring, "Which analysis judges"): every weight when D is not smooth at the fit (``lack`` >
    ``ROUGH``), else those whose ``curvature`` verdict (``verdicts``) the ``bootstrap`` one (``interval_verdicts``)
    overturns (the search box holds their resampled refits, or their interval reaches a search limit), and those
    the curvature does not judge (the fit is not at a minimum of D along a direction they take part in).

        >>> from cobot_analysis.models.ioc.uncertainty import disputed
        >>> disputed(0.05, {"a2": "determined", "a3": "determined"},
        ...          {"a2": "not determined by these data (the search box holds its refit in 11 of 200 resamples: ...)",
        ...           "a3": "determined"})
        ('a2',)
    """
    if lack > ROUGH:
        return tuple(curvature)
    return tuple(n for n, v in curvature.items() if bootstrap[n] != v or verdict_category(v) == "not judged")


def judged(curvature: dict[str, str], bootstrap: dict[str, str], weights: dict[str, float], lack: float,
           profiled: dict[str, str] | None = None) -> tuple[dict[str, str], dict[str, str]]:
    """(verdict, the analysis that gave it) of each fitted weight, one rule for every fit method (module
    docstring, "Which analysis judges"; Raue et al. 2009): a weight's profile likelihood (``profiled``,
    ``profile.profiles``' verdicts), where one was computed and judged, gives its verdict ("profile"); a profile
    that could not judge (its refit failed) leaves the verdict to the curvature and the bootstrap when D is
    smooth at the fit; then the bootstrap's verdict where it overturns the curvature's ("bootstrap"), else the
    curvature's ("curvature"; "not judged" where D is not smooth). ``curvature``: ``verdicts``; ``bootstrap``:
    ``interval_verdicts`` of them; ``lack``: the stencil's lack of fit.

        >>> from cobot_analysis.models.ioc.uncertainty import judged
        >>> v, by = judged({"a2": "determined", "a3": "determined"},
        ...                {"a2": "not determined by these data (the search box holds its refit in 11 of 200 resamples)",
        ...                 "a3": "determined"}, {"a2": 7.8, "a3": 1.0}, 0.05,
        ...                {"a2": "determined (profile: the targets reject a2 below 4.7 and above 12)"})
        >>> v["a2"], by
        ('determined (profile: the targets reject a2 below 4.7 and above 12)', {'a2': 'profile', 'a3': 'curvature'})
    """
    profiled = profiled or {}
    out, by = {}, {}
    for n, v in curvature.items():
        p = profiled.get(n)
        if p is not None and (verdict_category(p) != "not judged" or lack > ROUGH):
            out[n], by[n] = p + _at_limit(weights[n]), "profile"
        elif bootstrap[n] != v:
            out[n], by[n] = bootstrap[n], "bootstrap"
        else:
            out[n], by[n] = v, "curvature"
    return out, by


def interval_verdicts(verdicts: dict[str, str], intervals: dict[str, tuple[float, float]],
                      held: dict[str, str] | None = None) -> dict[str, str]:
    """The verdicts with every "determined" weight whose refit the search box holds (``bootstrap``'s
    ``held``: why) or whose 95 % interval reaches a search limit (within 0.01 in log10) turned into "not
    determined by these data" (module docstring)."""
    out = dict(verdicts)
    for n, v in verdicts.items():
        lo, hi = (math.log10(max(x, 1e-300)) for x in intervals.get(n, (math.nan, math.nan)))
        edge = LOG_BOUNDS[0] if abs(lo - LOG_BOUNDS[0]) < 0.01 else LOG_BOUNDS[1] if abs(hi - LOG_BOUNDS[1]) < 0.01 else None
        if v.startswith("determined") and held and n in held:
            out[n] = f"not determined by these data ({held[n]})"
        elif v.startswith("determined") and edge is not None:
            out[n] = f"not determined by these data (its 95 % interval reaches the search limit {10.0 ** edge:g})"
    return out


def verdict_category(verdict: str) -> str:
    """The category of an identifiability verdict (``verdicts``, ``interval_verdicts``; docs/methods.md
    sec. 6.3), without its numbers: "determined", "ratio to <weight>", "not determined" or "not judged",
    with " at the search limit" appended when the verdict says so.

        >>> from cobot_analysis.models.ioc.uncertainty import verdict_category
        >>> verdict_category("only its ratio to a1 is determined (at the search limit 1e-07)")
        'ratio to a1 at the search limit'
    """
    head = verdict.split(" (at the search limit")[0]
    if head.startswith("only its ratio to "):
        category = "ratio to " + head[len("only its ratio to "):].split()[0]
    elif head.startswith("determined"):  # "determined (profile: ...)"
        category = "determined"
    elif head.startswith("not judged"):
        category = "not judged"
    elif head.startswith("not determined"):
        category = "not determined"
    else:
        category = head
    return category + (" at the search limit" if "(at the search limit" in verdict else "")


def quadratic_refit(c: Curvature, counts: np.ndarray, basis: np.ndarray | None = None) -> np.ndarray:
    """y minimising sum_i counts_i (g_i' dy + 0.5 dy' H_i dy) within the search box, dy = basis z
    (default: every direction) (module docstring)."""
    return _refit(c, counts, basis)[0]


def _refit(c: Curvature, counts: np.ndarray, basis: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """(``quadratic_refit``'s y, the unconstrained Newton step's y or None when the model has no minimum along
    the basis): the two differ where the search box holds the refit."""
    from scipy.optimize import LinearConstraint, minimize

    B = np.eye(len(c.y)) if basis is None else basis
    if B.shape[1] == 0:
        y = c.y.copy()
        return y, y
    g = counts @ c.gi / counts.sum() @ B
    H = B.T @ (np.einsum("i,ijk->jk", counts, c.Hi) / counts.sum()) @ B
    H = (H + H.T) / 2
    free = None
    try:  # the Newton step, when H is positive definite
        if np.all(np.linalg.eigvalsh(H) > 0):
            free = c.y + B @ -np.linalg.solve(H, g)
    except np.linalg.LinAlgError:
        pass
    if free is not None and np.all((free >= LOG_BOUNDS[0]) & (free <= LOG_BOUNDS[1])):
        return free, free
    box = LinearConstraint(B, LOG_BOUNDS[0] - c.y, LOG_BOUNDS[1] - c.y)
    r = minimize(lambda z: (g @ z + 0.5 * z @ H @ z, g + H @ z), np.zeros(B.shape[1]), jac=True,
                 method="SLSQP", constraints=[box], options={"ftol": 1e-12, "maxiter": 500})
    return c.y + B @ r.x, free


def bootstrap(c: Curvature, n_resamples: int = RESAMPLES, seed: int = 0, level: float = 0.95, rel_tol: float = 1e-3) -> dict:
    """Percentile intervals of the fitted weights over ``n_resamples`` resamples of the targets (module
    docstring): each resample refitted along the directions the full data determine (the sloppy ones
    held); a weight that is not determined gets the search box as its interval, and so does a determined
    weight whose refit the search box pins (the weights on a limit leave it less than 10 % of its amplitude
    in the determined directions) in more than (1 - level) / 2 of the resamples: its interval would be the
    box's, not the data's.
    Returns {"samples": (B, k) weights, "intervals": {name: (lo, hi)}, "sd_log10": {name: sd}, "on_box": resamples
    whose quadratic has no minimum inside the search box (refit on its edge), "held": {name: why} for the
    weights held by the box}."""
    rng = np.random.default_rng(seed)
    n = len(c.Di)
    _, V, sloppy = sloppy_directions(c.H, c.D, rel_tol)
    ok = determined(c.H, c.D, rel_tol) & (c.lack_of_fit <= ROUGH)
    B = V[:, ~sloppy & ok.any()]
    fits = [_refit(c, np.bincount(rng.integers(0, n, n), minlength=n).astype(float), B) for _ in range(n_resamples)]
    S = np.array([y for y, _ in fits]).reshape(-1, len(c.y))
    on_box = sum(free is None or y is not free for y, free in fits) if ok.any() else 0
    # per weight, the resamples whose refit the box pins: the weights on a limit there leave it less than 10 % of
    # its amplitude in the determined directions (S03: a2 on 1000, a4 moving only with it), and why
    lo, hi = LOG_BOUNDS
    held = {}
    pinned = np.zeros(S.shape, bool)
    for r, (y, free) in enumerate(fits):
        if free is not None and y is free:
            continue
        active = (np.abs(y - lo) < 1e-6) | (np.abs(y - hi) < 1e-6)
        _, sv, vt = np.linalg.svd(B[active], full_matrices=True) if active.any() else (None, np.zeros(0), np.eye(B.shape[1]))
        N = vt[int((sv > 1e-8).sum()):].T  # the determined directions that keep every active weight on its limit
        pinned[r] = ((B @ N) ** 2).sum(axis=1) < 0.1 * (B**2).sum(axis=1)
    for j, name in enumerate(c.fitted):
        rows = np.flatnonzero(pinned[:, j])
        if ok[j] and len(rows) > (1 - level) / 2 * len(S):
            why = [f"{c.fitted[i]} on its search limit {10.0 ** b:g} in {n_at}" for i in range(len(c.y)) for b in (lo, hi)
                   if (n_at := int((np.abs(S[rows, i] - b) < 1e-6).sum()))]
            none = sum(fits[r][1] is None for r in rows)
            why += [f"no minimum along the determined directions in {none}"] if none else []
            held[name] = f"the search box holds its refit in {len(rows)} of {len(S)} resamples: {', '.join(why)}"
    free = ok & np.array([name not in held for name in c.fitted])
    # centred on the fit: a fit stopped short of its optimum (budget, tolerance) moves every resample by the
    # same full-data step, which is not sampling spread
    S = np.clip(S - quadratic_refit(c, np.ones(n), B) + c.y, *LOG_BOUNDS)
    a = 100 * (1 - level) / 2
    W = 10.0 ** S
    box = (10.0 ** LOG_BOUNDS[0], 10.0 ** LOG_BOUNDS[1])
    return {"samples": W,
            "intervals": {name: (float(np.percentile(W[:, j], a)), float(np.percentile(W[:, j], 100 - a))) if free[j] else box
                          for j, name in enumerate(c.fitted)},
            "sd_log10": {name: float(S[:, j].std(ddof=1)) if free[j] and len(S) > 1 else math.inf for j, name in enumerate(c.fitted)},
            "on_box": on_box, "held": held}


def subjects_differ(estimates: dict[str, dict[str, float]], sd_log10: dict[str, dict[str, float]],
                    verdict: dict[str, dict[str, str]] | None = None, at_start: set[str] = frozenset()) -> list[dict]:
    """Whether the subjects' weights differ, weight by weight: Cochran's heterogeneity statistic on
    y_s = log10 w_s with the bootstrap standard deviations s_s,
        Q = sum_s (y_s - ybar)^2 / s_s^2,  ybar = sum_s y_s / s_s^2 / sum_s 1 / s_s^2,
    Q ~ chi2(S - 1) when every subject has the same weight; p-values Holm-adjusted over the weights.
    Subjects where the weight is not "determined" (``verdict``) or has no spread are left out of that
    weight's test, and so are the subjects in ``at_start``, whose fit ended at the start weights shared by
    every subject (their estimate is the start, not evidence that they agree). Returns one row per weight:
    weight, subjects, Q, df, p, p_holm, differ (p_holm < 0.05), at_start (the subjects left out for that)."""
    from scipy.stats import chi2

    names = sorted({n for e in estimates.values() for n in e})
    rows = []
    for n in names:
        ys, ss = [], []
        for s, e in estimates.items():
            sd = sd_log10.get(s, {}).get(n, math.nan)
            ok = verdict is None or verdict.get(s, {}).get(n, "").startswith("determined")
            if ok and s not in at_start and np.isfinite(sd) and sd > 0 and n in e:
                ys.append(math.log10(e[n]))
                ss.append(sd)
        row = {"weight": n, "subjects": len(ys), "Q": math.nan, "df": max(len(ys) - 1, 0), "p": math.nan,
               "at_start": sorted(at_start & set(estimates))}
        if len(ys) >= 2:
            y, wt = np.array(ys), 1.0 / np.array(ss) ** 2
            ybar = float((wt * y).sum() / wt.sum())
            q = float((wt * (y - ybar) ** 2).sum())
            row.update(Q=q, p=float(chi2.sf(q, len(ys) - 1)))
        rows.append(row)
    tested = sorted((r for r in rows if np.isfinite(r["p"])), key=lambda r: r["p"])
    m, running = len(tested), 0.0
    for i, r in enumerate(tested):  # Holm: p_(i) (m - i), kept monotone
        running = max(running, min(1.0, r["p"] * (m - i)))
        r["p_holm"] = running
    for r in rows:
        r.setdefault("p_holm", math.nan)
        r["differ"] = bool(r["p_holm"] < 0.05) if np.isfinite(r["p_holm"]) else None
    return rows
