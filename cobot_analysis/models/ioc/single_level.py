"""Single-level inverse optimal control (docs/methods.md sec. 6.2), after Becanovic, Jovanovic and
Bonnet (IEEE-RAS Humanoids 2024): the lower level is replaced by its first-order optimality
conditions, and one NLP is solved over the fitted weights w and, for every target n, the lower
level's primal vector z_n (states, controls, log T) and the multipliers lambda_n of its equality
constraints g_n:

    min_{w, z, lambda}  (1/N_traj) sum_n D_n(z_n)
    s.t.  grad_z L_n(z_n, lambda_n; w) = 0,   g_n(z_n) = 0,   L_n = J_n(z_n; w) + lambda_n' g_n(z_n),
          w_i in [1e-7, 1e3] (the bi-level search box), the held weights fixed (b0 fixes the scale).

J_n and g_n are the lower level's own NLP (``oc.problem.WalkerOCP``, the one the bi-level fit
solves), evaluated symbolically; casadi differentiates it, so a change of the OC problem (a cost term,
a terminal constraint) carries over. The KKT conditions are linear in w and lambda.

D_n = d_xy + 0.5 d_gamma (walker) or d_xy + 0.5 d_theta (table) of the path resampled to the measured
samples as ``oc.resample`` does (cubic Hermite in time; the nodes sit at fixed fractions of T, so the
resampling is linear in the nodes and in T times the node velocities), with |a| and the Euclidean
norm smoothed to sqrt(a^2 + eps^2) - eps so that D is twice differentiable; its gradient and Hessian by
the chain rule through the resampling (``resampled_distance``), not symbolically.

Solved by a feasible path (``fit_feasible_path``, docs/methods.md sec. 6.1): a trust-region step in
log10 w with the exact gradient and Hessian of D along the manifold of KKT points, then each path's
KKT system restored by Newton's method (LAPACK's band LU of its KKT matrix), so the constraints hold at
every step; the steps end on a grid of log10 w (``GRID``), so the route does not follow the round-off of the
linear algebra. The D reported is never the smoothed one: the lower level is re-solved at the fitted
weights as the bi-level fit solves it, and D computed exactly.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from cobot_analysis.errors import InputError
from cobot_analysis.models.ioc.buffered import BufferedCall
from cobot_analysis.models.ioc.fit import LOG_BOUNDS, IOCSpec
from cobot_analysis.models.ioc.resampled_distance import SMOOTHING, ResampledDistance
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

METHODS = ("bilevel", "single-level")
MAX_FOLDED = 0.5  # a step that ends the branches of more of the paths than this fraction is rejected unsolved
MAX_STEPS = 40  # the feasible-path fit's own budget of trust-region steps per round
PROBE_DISTANCES = (1.5, 3.0)  # log10 units: the escape probes' distances from a converged point (``escape_probes``)
# log10 units: every step and probe ends on this grid of log10 w (a factor 1 + 2.3e-6 in w: far below what D determines),
# so that round-off in the linear algebra (the LU's order of operations, another BLAS) does not change the fit's steps
GRID = 1e-6


@dataclass
class SingleLevelResult:
    spec: IOCSpec
    weights: dict[str, float]
    objective: float  # exact D of the lower level re-solved at the fitted weights (mean over targets)
    nlp_objective: float  # the smoothed D at the NLP's solution
    start_objective: float  # exact D at the starting weights
    iterations: int
    status: str
    success: bool
    seconds: float  # build + start + solve + verification
    failed: int  # re-solved lower levels that did not converge
    at_duration_bound: int
    kkt_residual: float  # max |KKT| at the NLP's solution
    per_target: list[dict] = field(default_factory=list)
    timing: dict = field(default_factory=dict)  # seconds: start (lower levels, multipliers), steps (with the re-solves)
    pace: dict | None = None  # measured durations given: the time-gauge calibration (models.ioc.pace), as the bi-level fit's
    probes: int = 0  # re-solved D at escape probes (``escape_probes``)
    primals: list = field(default_factory=list, repr=False)  # the single-level paths (warm starts)

    def to_json(self) -> dict:
        d = asdict(self)
        d["spec"] = asdict(self.spec)
        d.pop("primals")
        return d


# ---- the lower level's NLP, symbolically ---------------------------------------------------------
def lower_level(spec: IOCSpec):
    """The lower level's ``WalkerOCP`` (the shape ``solve_model`` builds for a free duration, with the
    convention's goal rule: under the continuous convention the goal pose at rest is a constraint)."""
    from cobot_analysis import conventions
    from cobot_analysis.models.oc.problem import OCPShape, get_ocp

    rule = conventions.get(spec.convention).oc_rule(spec.model)
    return get_ocp(OCPShape(spec.n_intervals, "walker", free_time=True, max_iter=spec.max_iter, goal=rule.goal))


def weight_slots(ocp) -> np.ndarray:
    """Indices of the 11 weights in the OC problem's parameter vector (found, not assumed)."""
    probe = np.arange(11) + 1000.5
    p = ocp.parameters((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), probe, 2.0)
    return np.array([int(np.flatnonzero(p == v)[0]) for v in probe])


def kkt_functions(ocp):
    """casadi functions of one target: ``kkt(z, lam, w, p) = [grad_z L; g]`` and
    ``grads(z, w, p) = (grad_z J, jac_z g)`` (for the least-squares multipliers), L = J + lam' g,
    from the lower level's own NLP function ``nlp(z, p) -> (J, g)``."""
    import casadi as ca

    nlp = ocp._sx_nlp()
    z, lam = ca.SX.sym("z", ocp.n_vars), ca.SX.sym("lam", ocp.n_cons)
    w, p = ca.SX.sym("w", 11), ca.SX.sym("p", ocp.n_params)
    slots = weight_slots(ocp)
    pe = ca.SX(p)
    for i, s in enumerate(slots):
        pe[int(s)] = w[i]
    out = nlp(x=z, p=pe)
    J, g = out["f"], out["g"]
    grad_L = ca.gradient(J + ca.dot(lam, g), z)
    kkt = ca.Function("kkt", [z, lam, w, p], [ca.vertcat(grad_L, g)])
    grads = ca.Function("grads", [z, w, p], [ca.gradient(J, z), ca.jacobian(g, z)])
    return kkt, grads


def target_data(t: Target) -> np.ndarray:
    """(x, y, theta, gamma) of a target, gamma from the measured path (continuous convention)."""
    from cobot_analysis.distances import gamma_from_path

    return np.concatenate([t.x, t.y, t.theta, gamma_from_path(t.x, t.y, t.theta)])


def multipliers(grads, z, w, p, i_T: int) -> tuple[np.ndarray, float]:
    """(lambda, nu) = argmin |grad J + jac_g' lambda + nu e_T| (least squares) at a lower-level path
    z; nu: the multiplier of the duration bounds on log T (index ``i_T``)."""
    gJ, Jg = grads(z, w, p)
    A = np.column_stack([Jg.full().T, np.eye(len(z))[:, i_T]])
    sol = np.linalg.lstsq(A, -gJ.full().ravel(), rcond=None)[0]
    return sol[:-1], float(sol[-1])


# ---- the fit -------------------------------------------------------------------------------------
def check_spec(spec: IOCSpec, n_targets: int) -> None:
    """The bad inputs of a fit (one line each): unknown weights, fewer paths than fitted weights, a
    convention or model the single-level fit does not cover."""
    names = names_for(spec.model)
    bad = [n for n in spec.fitted if n not in names]
    if bad or not spec.fitted:
        raise InputError(f"--fit names {bad or '(none)'} are not weights of the model ({', '.join(names)})", remedy="e.g. --fit a1,a2,a4")
    if n_targets < len(spec.fitted):
        raise InputError(f"{n_targets} paths cannot determine {len(spec.fitted)} weights",
                         remedy="fit fewer weights (--fit) or add paths")
    if spec.model not in ("improved", "table") or spec.convention not in ("continuous", "published"):
        raise InputError(f"the single-level fit covers the improved and table models, not {spec.model!r} / {spec.convention!r}",
                         remedy="use --method bilevel for this fit")
    if spec.convention == "published" and not spec.hold_duration:  # no first-order condition for an integer horizon
        raise InputError("the single-level fit under the published convention holds each path's horizon (docs/methods.md sec. 6.1)",
                         remedy="use --method bilevel to search with the duration rule at every evaluation")


def newton_functions(ocp, fitted: list[int]):
    """casadi functions of one target, v = (z, lambda), w the 11 weights, p the parameters:
    ``newton(v, w, p) -> (F, K, F_w)``: the KKT residual F = [grad_z L; g] (``kkt_functions``), its
    Jacobian K in v (the lower level's KKT matrix, sparse) and dF/dw of the ``fitted`` weights;
    ``second(v, w, p, mu) -> hess_(v, w_fitted) (mu' F)`` (sparse; the third derivatives of J and g
    that the exact Hessian of D along the KKT manifold needs)."""
    import casadi as ca

    nlp = ocp._sx_nlp()
    v, mu = ca.SX.sym("v", ocp.n_vars + ocp.n_cons), ca.SX.sym("mu", ocp.n_vars + ocp.n_cons)
    z, lam = v[:ocp.n_vars], v[ocp.n_vars:]
    w, p = ca.SX.sym("w", 11), ca.SX.sym("p", ocp.n_params)
    wf = ca.vertcat(*[w[i] for i in fitted])
    pe = ca.SX(p)
    for i, s in enumerate(weight_slots(ocp)):
        pe[int(s)] = w[i]
    out = nlp(x=z, p=pe)
    F = ca.vertcat(ca.gradient(out["f"] + ca.dot(lam, out["g"]), z), out["g"])
    newton = ca.Function("newton", [v, w, p], [F, ca.jacobian(F, v), ca.densify(ca.jacobian(F, wf))])
    second = ca.Function("second", [v, w, p, mu], [ca.hessian(ca.dot(mu, F), ca.vertcat(v, wf))[0]])
    return newton, second


@functools.lru_cache(maxsize=4)
def branch_calls(spec: IOCSpec, fitted: tuple[int, ...], n_samples: int, eps: float = SMOOTHING) -> tuple:
    """The casadi functions a ``_Branch`` calls, built once per lower-level shape, fitted set and
    number of samples and reused by later fits (per-subject fits, repeated benchmarks)."""
    ocp = lower_level(spec)
    newton, second = newton_functions(ocp, list(fitted))
    return BufferedCall(newton), BufferedCall(second), ResampledDistance(ocp, n_samples, spec.angle, spec.angle_weight, eps)


class _Permutation:
    """A reverse Cuthill-McKee permutation of the KKT matrix K (variables and multipliers of each
    stage brought together: a band of half widths kl, ku ~ 2 stages) and the map that puts K's stored
    values (K's sparsity is fixed: computed once per ``BufferedCall``) straight into LAPACK's band
    storage of K[order][:, order] (``band``): row kl + ku + i - j of column j holds K[order][i, j]."""

    def __init__(self, K):
        from scipy.sparse import csc_matrix
        from scipy.sparse.csgraph import reverse_cuthill_mckee

        n = K.shape[0]
        pattern = csc_matrix((np.arange(1.0, K.nnz + 1.0), K.indices, K.indptr), shape=K.shape)
        self.order = np.asarray(reverse_cuthill_mckee((pattern + pattern.T).tocsr(), symmetric_mode=True))
        P = pattern[self.order][:, self.order].tocsc()
        rows, cols = P.indices, np.repeat(np.arange(n), np.diff(P.indptr))
        self.kl, self.ku = int(np.max(rows - cols, initial=0)), int(np.max(cols - rows, initial=0))
        self.source = P.data.astype(int) - 1
        self.flat = (self.kl + self.ku + rows - cols) * n + cols  # flat index in the (2 kl + ku + 1, n) band array

    def band(self, K) -> np.ndarray:
        """K permuted, in LAPACK's band storage for ``dgbtrf`` (kl extra rows for its fill)."""
        ab = np.zeros((2 * self.kl + self.ku + 1, K.shape[0]))
        ab.flat[self.flat] = K.data[self.source]
        return ab


def _permutation(newton: BufferedCall) -> _Permutation:
    """The ``_Permutation`` of the KKT matrix output of ``newton`` (kept on it)."""
    if not hasattr(newton, "permutation"):
        newton.permutation = _Permutation(newton.out[1])
    return newton.permutation


class _Factor:
    """LU of K permuted symmetrically (``_Permutation``) by LAPACK's band LU with partial pivoting
    (``dgbtrf``), solving K x = b and K' x = b (``dgbtrs``). RuntimeError when K is singular."""

    def __init__(self, K, perm: _Permutation):
        from scipy.linalg.lapack import dgbtrf

        self.order, self.kl, self.ku = perm.order, perm.kl, perm.ku
        self.lu, self.pivots, info = dgbtrf(perm.band(K), perm.kl, perm.ku, overwrite_ab=True)
        if info != 0:
            raise RuntimeError(f"singular KKT matrix (dgbtrf info {info})")

    def solve(self, b, trans: bool = False):
        from scipy.linalg.lapack import dgbtrs

        b = np.asarray(b, float)
        x = np.empty_like(b)
        x[self.order], info = dgbtrs(self.lu, self.kl, self.ku, b[self.order], self.pivots, trans=int(trans))
        return x


class _Branch:
    """One target's lower-level KKT point v = (z, lambda) at weights w, followed by Newton's method
    on F(v; w) = 0 (``newton_functions``), with the sensitivity S = dv/dw_fitted, the smoothed D and
    the derivatives of D along the branch."""

    def __init__(self, calls, p, data, nz: int):
        self.newton, self.second, self.distance = calls
        self.perm = _permutation(self.newton)
        self.p, self.data, self.nz = p, data, nz
        self.v = self.S = None

    def correct(self, v, w, tol: float, max_newton: int = 10) -> bool:
        """Newton's method from v at weights w until max |F| <= tol, then S, D, grad D and the exact
        Hessian of D(w) along the branch there. False (state unchanged) when it does not converge or
        K is singular (a fold of the branch)."""
        v, last = np.array(v, float), math.inf
        for _ in range(max_newton):
            F, K, Fw = self.newton(v, w, self.p)
            res = float(np.max(np.abs(F)))
            if not res < last:  # diverging (or nan): not this branch's neighbourhood
                return False
            last = res
            try:
                lu = _Factor(K, self.perm)
            except RuntimeError:
                return False
            if res <= tol:
                break
            v = v - lu.solve(F)
        else:
            return False
        nz = self.nz
        S = -lu.solve(Fw.reshape(len(v), -1))  # K S + F_w = 0 (one fitted weight: F_w comes as a vector)
        D, gz, SHS = self.distance(v[:nz], self.data, S[:nz])
        gv = np.concatenate([gz, np.zeros(len(v) - nz)])
        mu = lu.solve(gv, trans=True)  # adjoint: K' mu = grad_v D
        T = np.vstack([S, np.eye(S.shape[1])])
        Q = self.second(v, w, self.p, mu)[0]
        self.v, self.S, self.residual, self.D = v, S, res, D
        self.g = S[:nz].T @ gz  # dD/dw_fitted
        # d2D/dw2 = S' hess D S + grad D' d2v/dw2, K d2v/dw2 = -T' hess(F) T (F is linear in w)
        self.H = SHS - T.T @ (Q @ T)
        return True


def correct_chunk(task) -> list:
    """Worker task (top-level, picklable): Newton corrections of a chunk of branches at weights w,
    task = (shape, fitted, n_samples, eps, tol, w, [(p, data, v), ...]); per branch its state
    {v, S, D, g, H, residual} (``_Branch``) or None when Newton's method fails."""
    shape, fitted, M, eps, tol, w, items = task
    calls, nz = branch_calls(shape, fitted, M, eps), lower_level(shape).n_vars
    out = []
    for p, data, v in items:
        b = _Branch(calls, p, data, nz)
        out.append({k: getattr(b, k) for k in ("v", "S", "D", "g", "H", "residual")} if b.correct(v, w, tol) else None)
    return out


def fold_chunk(task) -> list:
    """Worker task: the branches of a chunk of paths that ended at weights w (a fold), each path's lower level
    re-solved there as the bi-level fit solves it (warm from the predicted path and from the two cold
    guesses, the least cost kept) and corrected (``correct_chunk``); task = (spec, shape, fitted, n_samples,
    eps, tol, w, [(target, p, data, v), ...]); per path the branch state or None."""
    from cobot_analysis.models.ioc.fit import solve_target

    spec, shape, fitted, M, eps, tol, w, items = task
    nl = lower_level(shape).n_cons
    out = []
    for t, p, data, v in items:
        d, sol = solve_target(spec, w, t, v[:len(v) - nl])
        out.append(correct_chunk((shape, fitted, M, eps, tol, w, [(p, data, np.concatenate([sol.primal, np.zeros(nl)]))]))[0]
                   if d["success"] else None)
    return out


def probe_chunk(task) -> list:
    """Worker task: the lower levels of a chunk of paths at an escape probe's weights w, each solved once, warm
    from its path at the converged point (``escape_probes``), D as ``fit.solve_target`` computes it;
    task = (spec, w, [(target, primal), ...]); per path (D, primal), or (inf, None) when the solve fails."""
    from cobot_analysis.models.ioc.fit import distances
    from cobot_analysis.models.oc import resample, solve_model

    spec, w, items = task
    model = "table" if spec.model == "table" else "improved"
    out = []
    for t, z in items:
        sol = solve_model(model, t.start, t.goal, w, n_intervals=spec.n_intervals, duration="free", max_iter=spec.max_iter,
                          v_nominal=spec.v_nominal, guess=z)
        if not sol.success:
            out.append((math.inf, None))
            continue
        r = resample(sol, len(t.x))
        d = distances(t, r["x"], r["y"], r["theta"])
        out.append((d["d_xy"] + spec.angle_weight * d[f"d_{spec.angle}"], sol.primal))
    return out


def trust_region_step(g: np.ndarray, H: np.ndarray, radius: float) -> np.ndarray:
    """argmin_s g's + s'Hs/2 over |s| <= radius: s = -(H + mu I)^-1 g with the least mu >= 0 making
    H + mu I positive definite and |s| <= radius (bisection on mu; Moré and Sorensen's condition)."""
    eig, V = np.linalg.eigh(H)
    lo = max(0.0, -eig[0]) * (1 + 1e-9) + 1e-15
    step = lambda m: -np.linalg.solve(H + m * np.eye(len(g)), g)  # noqa: E731
    if eig[0] > 0 and np.linalg.norm(step(0.0)) <= radius:
        return step(0.0)
    hi = lo + np.linalg.norm(g) / radius + abs(eig[-1])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.linalg.norm(step(mid)) > radius else (lo, mid)
    s = step(hi)
    if eig[0] < 0 and np.linalg.norm(s) < radius:  # the hard case (g orthogonal to the negative curvature)
        v = V[:, 0] * (-1.0 if g @ V[:, 0] > 0 else 1.0)
        b = s @ v
        s = s + (-b + math.sqrt(b * b + radius**2 - s @ s)) * v
    return s


def free_weights(g: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The weights a step may move from y (log10 w): all but those on a search limit (``LOG_BOUNDS``) that D
    pushes outward (the gradient g)."""
    lo, hi = LOG_BOUNDS
    return ~(((y <= lo + 1e-9) & (g > 0)) | ((y >= hi - 1e-9) & (g < 0)))


def on_grid(y: np.ndarray) -> np.ndarray:
    """y (log10 w) rounded to the nearest point of the ``GRID`` within the search box ``LOG_BOUNDS``."""
    return np.clip(np.round(np.asarray(y, float) / GRID) * GRID, *LOG_BOUNDS)


def box_step(g: np.ndarray, H: np.ndarray, y: np.ndarray, radius: float) -> np.ndarray:
    """The model's step from y (log10 w) within |s| <= radius and the search box ``LOG_BOUNDS``: a weight on
    a search limit that D pushes outward (the gradient g) is held (``free_weights``), the others take
    ``trust_region_step``; the step ends on the ``GRID`` (``on_grid``, projected onto the box)."""
    free = free_weights(g, y)
    s = np.zeros_like(y)
    if free.any():
        s[free] = trust_region_step(g[free], H[np.ix_(free, free)], radius)
    return on_grid(y + s) - y


def shrunk_radius(step, s: np.ndarray, radius: float, xtol: float) -> float:
    """The trust radius after the rejected step s = step(radius): radius / 4, and / 4 again while
    step(radius) is still s (a model step inside the radius, the Newton step, or one held by the search
    box): from the same point the same step is rejected again, so it is not tried again. Stops below
    ``xtol``, where the fit stops."""
    radius /= 4
    while radius >= xtol and np.array_equal(step(radius), s):
        radius /= 4
    return radius


def escape_probes(y: np.ndarray, H: np.ndarray, distances=PROBE_DISTANCES) -> list[np.ndarray]:
    """Points y + d u (log10 weights, clipped to the search box) around a converged point y, in the plane
    of the two eigenvectors v1, v2 of the model Hessian H with the least curvature (the directions the
    data determine least, where D is flat enough to hide another basin behind a low ridge): u along
    +-v1, +-v2 and the four diagonals (one direction when one weight is fitted), d in ``distances``.
    Duplicates (a clip onto a search limit) and y itself are left out."""
    lam, V = np.linalg.eigh(0.5 * (H + H.T))
    flat = V[:, np.argsort(lam)[:2]]
    dirs = [flat[:, 0]] if flat.shape[1] == 1 else [np.cos(a) * flat[:, 0] + np.sin(a) * flat[:, 1]
                                                      for a in np.arange(8) * np.pi / 4]
    out: list[np.ndarray] = []
    for d in distances:
        for u in (dirs if len(dirs) > 1 else [dirs[0], -dirs[0]]):
            q = on_grid(y + d * u)
            if np.abs(q - y).max() > 1e-6 and all(np.abs(q - o).max() > 1e-6 for o in out):
                out.append(q)
    return out


def screen(m: int, bound: float, D_now, solve, batches: int = 6) -> dict:
    """The points 0..m-1 (weight vectors) whose D, the mean of the n paths' D_i (each >= 0) at that point, is
    below ``bound``: {index: (D, {path: primal})}. ``solve([(point, paths), ...])`` -> per pair
    {path: (D_i, primal or None when the lower level failed)} (solved side by side). The paths are solved in
    batches, those with the largest D at the current point (``D_now``) first, and a point is dropped as soon
    as the sum of its paths' D exceeds n bound (its mean cannot end below) or a lower level fails: the same
    points as solving every path at every point."""
    n = len(D_now)
    split = np.array_split(np.argsort(-np.asarray(D_now), kind="stable"), min(batches, n))
    alive = {j: [0.0, {}, 0] for j in range(m)}  # partial sum of D, primals, batches solved

    def advance(js: list) -> None:
        for j, got in zip(js, solve([(j, split[alive[j][2]]) for j in js])):
            batch, alive[j][2] = split[alive[j][2]], alive[j][2] + 1
            for i in batch:
                alive[j][0] += got[i][0]
                alive[j][1][i] = got[i][1]
            if not (alive[j][0] < n * bound and all(alive[j][1][i] is not None for i in batch)):
                del alive[j]

    while rest := [j for j, a in alive.items() if a[2] < len(split)]:
        advance(rest)
    return {j: (a[0] / n, a[1]) for j, a in alive.items()}


def interleaved_chunks(n: int, chunks: int) -> list[list[int]]:
    """Path indices 0..n-1 dealt round-robin into at most ``chunks`` tasks (long and short paths mixed)."""
    k = max(1, min(chunks, n))
    return [list(range(i, n, k)) for i in range(k)]


def run_chunks(pool, fn, parts: list[list[int]], make_task, n: int) -> list:
    """``fn(make_task(part))`` for every part on ``pool``, the results put back in path order."""
    futures = [pool.submit(fn, make_task(p)) for p in parts]
    out: list = [None] * n
    for p, f in zip(parts, futures):
        for i, r in zip(p, f.result()):
            out[i] = r
    return out


def fit_feasible_path(spec: IOCSpec, targets: list[Target], *, start: list | None = None, eps: float = SMOOTHING,
                      radius: float = 0.3, max_steps: int = MAX_STEPS, tol: float = 1e-8, xtol: float = 1e-3,
                      restarts: int = 2, probe: bool = True, measured_T=None, pool=None,
                      chunks: int = 2) -> SingleLevelResult:
    """The single-level NLP (module docstring) solved by a feasible-path trust-region SQP in
    y = log10 of the fitted weights (docs/methods.md sec. 6.1): every iterate keeps each target's
    KKT conditions F_n(z_n, lambda_n; w) = 0 (Newton's method on the lower level's KKT matrix K_n,
    started from the linear predictor v_n + S_n dw, S_n = -K_n^-1 dF_n/dw), so the NLP's
    constraints never leave their manifold. On it D(y) = (1/N) sum_n D_n(z_n(w)) (smoothed D) has
    the gradient (1/N) sum_n S_n' grad D_n and the exact Hessian (1/N) sum_n (S_n' hess D_n S_n
    - T_n' hess_(v,w)(mu_n' F_n) T_n), T_n = [S_n; I], K_n' mu_n = grad_v D_n (the adjoint; F is
    linear in w), both carried to y by dw/dy = w ln 10; the step minimises that quadratic model
    within |dy| <= radius (``trust_region_step``) and the search box (a weight on a search limit that
    D pushes outward is held for the step), and is accepted when D on the
    corrected paths falls by at least 10 % of the predicted decrease (radius x2 up to 1, or /4 and again
    while the model's step stays the one rejected: ``shrunk_radius``; a step with no predicted decrease,
    projected onto the box, is rejected without correcting the paths; a path whose correction fails, a
    fold of its branch, goes on from its lower level re-solved at the step's weights; the step is rejected
    only if that fails too).
    Stops when an accepted step is below ``xtol`` (log10), the radius falls below it, or after
    ``max_steps`` steps. Start: the lower level solved at the start weights (``start``: given paths).
    The D reported is the one of the lower level re-solved at the fitted weights, as the bi-level fit
    solves it (warm from the branch's path and from the two cold guesses, the least cost kept). When
    that re-solve lands on other paths (a lower-cost local minimum of some lower levels), the steps
    start again on those; when it does not and ``probe``, D is re-solved at the ``escape_probes`` (each
    lower level once, warm from its path: ``probe_chunk``) and the steps start again from the lowest if it
    is below (``restarts`` new rounds at most); the round
    with the least re-solved D is kept, or the start (its weights, paths and D: the result's ``success``
    False) when no round ends below the start's D. ``measured_T``: the subjects' duration per target (nan: none),
    as the bi-level fit takes them (``fit.fit``): the start weights are carried to their time gauge
    first, the fitted weights calibrated to it after (``pace.calibrate``; the result's ``pace``).
    ``pool``: an executor for the lower-level solves and the Newton corrections (chunks of
    targets; None: in-process), as the bi-level fit's."""
    from dataclasses import replace

    from cobot_analysis.conventions import CONTINUOUS
    from cobot_analysis.models.dynamics import N_STATE
    from cobot_analysis.models.ioc.pace import calibrate, scale_time, time_gauge
    from cobot_analysis.models.oc.duration import initial_duration
    from cobot_analysis.models.presets import weights_vector

    t0 = time.perf_counter()
    check_spec(spec, len(targets))
    if spec.convention != "continuous":
        raise ValueError("fit_feasible_path is the continuous convention's; published: single_level_published.fit_held_horizons")
    names = names_for(spec.model)
    w = np.array(spec.start_weights, float)
    fi = [names.index(n) for n in spec.fitted]
    w[fi] = np.clip(w[fi], 10.0 ** LOG_BOUNDS[0], 10.0 ** LOG_BOUNDS[1])
    from cobot_analysis.models.ioc.fit import evaluate_chunk, reference_chunk
    from cobot_analysis.parallel import InlineExecutor

    ocp = lower_level(spec)
    M = len(targets[0].x)
    if any(len(t.x) != M for t in targets):
        raise InputError("the targets have different numbers of samples", remedy="fit means or resampled trials (average)")
    shape = IOCSpec(model=spec.model, n_intervals=spec.n_intervals, max_iter=spec.max_iter, convention=spec.convention,
                    angle_weight=spec.angle_weight)  # what the functions depend on: the cache key
    T0 = [initial_duration(t.start, t.goal, spec.v_nominal) for t in targets]
    nz, nl, n = ocp.n_vars, ocp.n_cons, len(targets)
    P = [ocp.parameters(t.start, t.goal, w, T) for t, T in zip(targets, T0)]
    data = [target_data(t) for t in targets]
    pool = pool or InlineExecutor()
    parts = interleaved_chunks(n, chunks)  # the Newton corrections (about 3 ms per path) in chunks
    # the lower-level solves (cold guesses, an IPOPT fallback: 5 to 300 ms per path) one task per path: the pool
    # balances them (0.1 s less wall than in chunks on the walking means with --jobs 2)
    single = interleaved_chunks(n, n)

    def correct(w, V, jump: bool = False) -> list | None:
        """Every branch corrected at w from the vectors V (None if one fails). ``jump``: a branch whose
        Newton correction fails (a fold: its path ends there) goes on from its lower level re-solved at w
        (``fold_chunk``), unless the branches of more than ``MAX_FOLDED`` of the paths end there (a step too
        long for the predictor: None without re-solving them)."""
        out = run_chunks(pool, correct_chunk, parts,
                         lambda p: (shape, tuple(fi), M, eps, tol, w, [(P[i], data[i], V[i]) for i in p]), n)
        lost = [i for i, r in enumerate(out) if r is None]
        if lost and jump and len(lost) <= MAX_FOLDED * n:
            k = max(1, min(chunks, len(lost)))
            futures = [(lost[j::k], pool.submit(fold_chunk, (spec, shape, tuple(fi), M, eps, tol, w,
                                                             [(targets[i], P[i], data[i], V[i]) for i in lost[j::k]])))
                       for j in range(k)]
            for part, f in futures:
                for i, r in zip(part, f.result()):
                    out[i] = r
        return None if any(r is None for r in out) else out

    start_terms, c_start = [], None
    if start is None:
        ref = run_chunks(pool, reference_chunk, single, lambda p: (spec, w, [targets[i] for i in p]), n)
        if measured_T is not None:  # the start weights' time gauge first, as the bi-level fit (``fit.fit``): the
            # lower levels' cold guesses (duration T0) then start near the optimal durations and find the least-cost
            # local minima that they miss far from them (D itself is invariant to the gauge)
            c_start = time_gauge([d["T"] if d["success"] else math.nan for d, _ in ref], measured_T)
            if np.isfinite(c_start):
                w = weights_vector(scale_time(dict(zip(names, map(float, w))), c_start), spec.model)
                spec = replace(spec, start_weights=tuple(map(float, w)))
                ref = run_chunks(pool, reference_chunk, single, lambda p: (spec, w, [targets[i] for i in p]), n)
        start_terms = [d for d, _ in ref]
        start = [primal for _, primal in ref]
        if any(z is None for z in start):
            raise RuntimeError("single-level: a lower level did not converge at the start weights")
    branches = correct(w, [np.concatenate([z, np.zeros(nl)]) for z in start])  # F is linear in lambda: Newton finds it
    if branches is None:
        raise RuntimeError("single-level: a lower-level solution at the start weights is not a regular KKT point")
    start_objective = float(np.mean([d["D"] for d in start_terms])) if start_terms else math.nan
    at_start = (start_objective, w.copy(), branches, list(start), start_terms) if start_terms else None
    timing = {"start": time.perf_counter() - t0}  # seconds; "steps" below includes "probes" (the escape probes' solves)

    def model(w, branches):
        """Gradient and Hessian of D in y = log10 w_fitted (w = 10^y: dw/dy = w ln 10)."""
        c = w[fi] * math.log(10.0)
        gw = np.mean([b["g"] for b in branches], axis=0)
        Hw = np.mean([b["H"] for b in branches], axis=0)
        return gw * c, 0.5 * (Hw + Hw.T) * np.outer(c, c) + np.diag(gw * c * math.log(10.0))

    def sqp(w, branches, radius):
        """Trust-region steps from (w, branches) (docstring): (w, branches, steps, accepted, Newton failures)."""
        D, y = float(np.mean([b["D"] for b in branches])), np.log10(w[fi])
        steps = accepted = fails = 0
        while steps < max_steps and radius >= xtol:
            g, H = model(w, branches)
            s = box_step(g, H, y, radius)
            pred = -(g @ s + 0.5 * s @ H @ s)
            steps += 1
            new, D_new = None, math.inf
            if pred > 0:  # else rejected whatever the corrected paths give (a step projected onto the box): not corrected
                w_new = w.copy()
                w_new[fi] = 10.0 ** (y + s)
                new = correct(w_new, [b["v"] + b["S"] @ (w_new[fi] - w[fi]) for b in branches], jump=True)  # predictor, corrector
                D_new = float(np.mean([b["D"] for b in new])) if new is not None else math.inf
                fails += new is None
            if new is not None and D - D_new >= 0.1 * pred:
                accepted += 1
                if D - D_new >= 0.75 * pred and np.linalg.norm(s) >= 0.99 * radius:
                    radius = min(2 * radius, 1.0)
                w, y, D, branches = w_new, y + s, D_new, new
                if np.linalg.norm(s) < xtol:
                    break
            else:
                radius = shrunk_radius(lambda r: box_step(g, H, y, r), s, radius, xtol)
        return w, branches, steps, accepted, fails

    def resolve(ws: list, Zs: list) -> list:
        """The lower levels re-solved at each weight vector of ``ws`` as the bi-level fit solves them (warm from
        ``Zs`` and from the two cold guesses, the least cost kept): per vector, (D, terms, primals)."""
        futures = [[pool.submit(evaluate_chunk, (spec, wk, [targets[i] for i in p], [Zs[i] for i in p])) for p in single]
                   for wk in ws]
        out = []
        for fs in futures:
            res = [None] * n
            for p, f in zip(single, fs):
                for i, r in zip(p, f.result()):
                    res[i] = r
            out.append((float(np.mean([d["D"] for d, _ in res])), [d for d, _ in res], [z for _, z in res]))
        return out

    def solve_at(pairs: list) -> list:
        """(D, primal) of the given paths at each (weight vector, paths) pair, each lower level warm from the
        round's path (``probe_chunk``), in chunks on the pool."""
        subs = []
        for j, batch in pairs:
            k = max(1, min(chunks, len(batch)))
            subs.append([(part, pool.submit(probe_chunk, (spec, ws[j], [(targets[i], Zs[i]) for i in part])))
                         for part in (batch[r::k] for r in range(k))])
        out = []
        for fs in subs:
            got = {}
            for part, f in fs:
                got.update(zip(part, f.result()))
            out.append(got)
        return out

    best, steps, accepted, fails, rounds, probes = None, 0, 0, 0, 0, 0
    for k in range(1 + restarts):
        rounds += 1
        w, branches, n_steps, n_acc, n_fail = sqp(w, branches, radius)
        steps, accepted, fails = steps + n_steps, accepted + n_acc, fails + n_fail
        Zs = [b["v"][:nz].copy() for b in branches]
        objective, terms, solved = resolve([w], Zs)[0]
        if best is not None and not objective < best[0]:
            break
        best = (objective, w.copy(), branches, Zs, terms)
        if k == restarts:
            break
        switched = [z_new is not None and np.abs(z_new - z).max() > 1e-4 for z_new, z in zip(solved, Zs)]
        if any(switched):  # the re-solve found lower-cost paths (another local minimum of some lower levels)
            w_next, V = w, [np.concatenate([z_new, np.zeros(nl)]) if sw else b["v"]
                            for z_new, sw, b in zip(solved, switched, branches)]
        elif probe:  # a shallow local minimum of D? re-solved D along the flat directions (``escape_probes``)
            y = np.log10(w[fi])
            points = escape_probes(y, model(w, branches)[1])
            probes += len(points)
            ws = []
            for q in points:
                ws.append(w.copy())
                ws[-1][fi] = 10.0 ** q
            t_probe = time.perf_counter()
            found = screen(len(ws), objective, [d["D"] for d in terms], solve_at)
            timing["probes"] = timing.get("probes", 0.0) + time.perf_counter() - t_probe
            if not found:
                break
            j = min(found, key=lambda j: found[j][0])
            w_next, V = ws[j], [np.concatenate([found[j][1][i], np.zeros(nl)]) for i in range(n)]
        else:
            break
        # start again on those paths
        restart = correct(w_next, V)
        if restart is None:
            break
        w, branches = w_next, restart
    kept_start = at_start is not None and not best[0] < at_start[0]
    if kept_start:  # no round ended below the start: the steps followed branches that stopped being the least-cost
        best = at_start  # lower levels without a fold; the fit never reports weights that fit worse than its start
    objective, w, branches, Zs, terms = best
    nlp_objective = float(np.mean([b["D"] for b in branches]))
    timing["steps"] = time.perf_counter() - t0 - timing["start"]
    weights, pace = dict(zip(names, map(float, w))), None
    if measured_T is not None:  # the fitted weights' time gauge (``pace.calibrate``), as the bi-level fit reports it
        cal = calibrate(lambda wd: resolve([np.asarray(weights_vector(wd, spec.model), float)], Zs)[0][1], weights, terms,
                        measured_T)
        weights, terms, objective = cal.weights, cal.terms, cal.D_after
        pace = {k: v for k, v in asdict(cal).items() if k not in ("weights", "terms")} | {"c_start": c_start}
    rule = CONTINUOUS.oc_rule("table" if spec.model == "table" else "improved")
    logT = np.array([z[ocp._xi[0, N_STATE]] for z in Zs])
    at_bound = int(np.sum((np.abs(logT - np.log(rule.T_bounds[0] * np.array(T0))) < 1e-3)
                          | (np.abs(logT - np.log(rule.T_bounds[1] * np.array(T0))) < 1e-3)))
    return SingleLevelResult(spec=spec, weights=weights, objective=objective, nlp_objective=nlp_objective,
                             start_objective=start_objective, iterations=steps,
                             status=f"feasible-path SQP: {accepted} of {steps} steps accepted in {rounds} round(s)"
                                    f"{f', {fails} Newton corrections failed' if fails else ''}"
                                    f"{f', {probes} escape probes' if probes else ''}"
                                    f"{'; no round ended below the start, whose weights are kept' if kept_start else ''}",
                             success=accepted > 0 and not kept_start, seconds=time.perf_counter() - t0,
                             failed=sum(not d["success"] for d in terms), at_duration_bound=at_bound,
                             kkt_residual=float(max(b["residual"] for b in branches)), per_target=terms, timing=timing,
                             primals=Zs, pace=pace, probes=probes)


def fit_task(task) -> SingleLevelResult:
    """Worker task (top-level, picklable): one whole fit in that process, task = (spec, targets, keyword
    arguments of ``fit_feasible_path``, no pool): several fits (per subject) then run side by side on the
    pool, one per worker, instead of one after another with each step's lower levels spread over the
    workers and waited for (the same result: each path's computation does not depend on where it runs)."""
    spec, targets, kwargs = task
    return fit_feasible_path(spec, targets, **kwargs)


def cross_check(spec: IOCSpec, targets: list[Target], result: SingleLevelResult, weights: dict[str, float], *, pool=None,
                chunks: int = 2) -> float:
    """D at another fit's ``weights`` (the bi-level fit's) with each lower level re-solved as that fit solves it
    (the two cold guesses) and, as a further candidate, warm from the single-level fit's path, the least cost
    kept: both fits' D then come from the same candidate paths. The paths are carried to the weights' time
    gauge by scaling the weights instead (a1..a3 x c^4 with c^4 = a1 of the paths / a1 of ``weights``, which
    moves no time-normalised path, ``pace.scale_time``)."""
    from cobot_analysis.models.ioc.fit import evaluate_chunk
    from cobot_analysis.models.ioc.pace import scale_time
    from cobot_analysis.models.presets import weights_vector
    from cobot_analysis.parallel import InlineExecutor

    a1 = result.weights["a1"] / (result.pace["c"] ** 4 if result.pace else 1.0)  # a1 of the fit's paths
    w = weights_vector(scale_time(weights, (a1 / weights["a1"]) ** 0.25), spec.model)
    pool, n = pool or InlineExecutor(), len(targets)
    out = run_chunks(pool, evaluate_chunk, interleaved_chunks(n, chunks),
                     lambda p: (spec, w, [targets[i] for i in p], [result.primals[i] for i in p]), n)
    return float(np.mean([d["D"] for d, _ in out]))


def check_method(method: str, bootstrap: int = 0) -> None:
    """The fit's method name and bootstrap count (bad input: one line, before anything is written)."""
    if method not in METHODS:
        raise InputError(f"unknown --method {method!r}", remedy=f"use one of {', '.join(METHODS)}")
    if bootstrap == 1 or bootstrap < 0:
        raise InputError(f"--bootstrap {bootstrap}: a bootstrap needs at least 2 resamples", remedy="use --bootstrap 200 (or 0 for none)")


def as_ioc_result(r: SingleLevelResult):
    """The single-level result in the bi-level fit's result type (``fit.IOCResult``: what the stage
    writes): no upper-level evaluations, the NLP solver's iterations and status."""
    from cobot_analysis.console import warn
    from cobot_analysis.models.ioc.fit import IOCResult

    if not r.success or not r.objective < r.start_objective:
        warn(f"single-level IOC: {r.status}, D {r.objective:.4f} re-solved at the fitted weights against "
             f"{r.start_objective:.4f} at the start: not a fit to report (use --method bilevel)")
    return IOCResult(spec=r.spec, weights=r.weights, objective=r.objective, start_objective=r.start_objective, evaluations=0,
                     iterations=r.iterations, failed=r.failed, per_target=r.per_target, pace=r.pace,
                     message=f"single-level: {r.status} (smoothed D {r.nlp_objective:.4f}, {r.seconds:.1f} s)")

