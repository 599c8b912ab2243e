"""Kinematics from filtered marker positions (docs/methods.md sec. 2.4-2.7), vectorised over frames.

Marker arrays have shape ``(..., T, 3)`` (x, y, z in metres, laboratory frame, z vertical); NaN
marks a sample that is missing after gap filling (a long gap). Every function propagates NaN
instead of inventing values, except the rigid-body reconstruction of the pelvis centre
(``pelvis_com``), which is exact for a rigid pelvis and documented there.

- pelvis CoM (horizontal): ``c = (LASI + RASI + LPSI + RPSI) / 4``, keep (x, y); with one sacrum
  marker instead of the two PSIS: ``c = (LASI + RASI + 2 SACR) / 4`` (``sacrum_pelvis_com``)
- pelvis orientation: ``l = LASI - RASI`` (horizontal), forward normal ``n = (l_y, -l_x)``,
  ``theta = atan2(n_y, n_x) = atan2(-l_x, l_y)``, unwrapped over time
- local orientation: ``gamma = wrap(theta - atan2(v_y, v_x))``, ``v`` the CoM velocity
- table: centre ``(TAB2 + TAB3) / 2`` (diagonal midpoint), long axis ``u = TAB2 - TAB1``,
  ``theta_T = atan2(u_y, u_x)`` unwrapped; height = mean z of the visible corners
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from cobot_analysis.angles import wrap

FloatArray = npt.NDArray[np.float64]

#: default speed (m/s) below which the path tangent, hence gamma, is taken as ill-defined.
GAMMA_MIN_SPEED = 0.1


def unwrap_nan(angle: np.ndarray, axis: int = -1) -> np.ndarray:
    """``np.unwrap`` along ``axis`` that steps over NaN samples (NaN stay NaN).

    Each jump between consecutive *valid* samples is brought into (-pi, pi]; values after a NaN
    run continue from the last valid value.
    """
    a = np.moveaxis(np.asarray(angle, dtype=float), axis, -1)
    out = np.full_like(a, np.nan)
    flat_in = a.reshape(-1, a.shape[-1])
    flat_out = out.reshape(-1, a.shape[-1])
    for row_in, row_out in zip(flat_in, flat_out):  # rows = trajectories, never samples
        ok = ~np.isnan(row_in)
        if ok.any():
            row_out[ok] = np.unwrap(row_in[ok])
    return np.moveaxis(out, -1, axis)


# ---- pelvis ---------------------------------------------------------------------------------------
def pelvis_com(lasi: FloatArray, rasi: FloatArray, lpsi: FloatArray, rpsi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Horizontal pelvis centre ``c = (LASI + RASI + LPSI + RPSI) / 4`` -> ``(xy (T, 2), rigid (T,))``.

    Where exactly one of the four markers is missing (NaN), ``c`` is reconstructed rigidly from the
    three visible ones: with ``o`` their mean and ``R = [e1 e2 e3]`` the orthonormal frame
    ``e1 = (p_b - p_a)/|.|``, ``e2`` = the part of ``p_c - p_a`` orthogonal to ``e1``, normalised,
    ``e3 = e1 x e2``, the offset ``d = R^T (c - o)`` is constant for a rigid pelvis; it is averaged
    over the frames where all four markers are visible and ``c = o + R d`` elsewhere. This keeps
    the barycentre definition (no bias from dropping a marker, which would shift ``c`` by several
    cm). ``rigid`` is True at the reconstructed frames. With two or more markers missing, or no
    frame with all four, ``c`` is NaN there.
    """
    p = np.stack([np.asarray(m, dtype=float) for m in (lasi, rasi, lpsi, rpsi)], axis=-2)  # (T, 4, 3)
    visible = ~np.isnan(p).any(axis=-1)  # (T, 4)
    com = p.mean(axis=-2)  # NaN wherever a marker is missing
    rigid = np.zeros(visible.shape[:-1], dtype=bool)
    full = visible.all(axis=-1)
    if full.all() or not full.any():
        return com[..., :2], rigid
    for missing in range(4):  # the four possible missing markers, each vectorised over frames
        others = [k for k in range(4) if k != missing]
        target = ~visible[..., missing] & visible[..., others].all(axis=-1)
        if not target.any():
            continue
        o, frame = _frame3(p[..., others, :])
        d = np.einsum("tji,tj->ti", frame[full], com[full] - o[full]).mean(axis=0)  # R^T (c - o)
        com[target] = o[target] + np.einsum("tij,j->ti", frame[target], d)
        rigid[target] = True
    return com[..., :2], rigid


def sacrum_pelvis_com(lasi: FloatArray, rasi: FloatArray, sacr: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Horizontal pelvis centre from the two ASIS and one sacrum marker -> ``(xy (T, 2), rigid (T,))``.

    ``c = (LASI + RASI + 2 SACR) / 4``: the barycentre of the 4-marker pelvis with the sacrum marker
    standing for both PSIS (Plug-in-Gait places SACR at the PSIS midpoint, so ``c`` equals the
    4-marker barycentre there; docs/methods.md sec. 2). NaN where any of the three is missing: two
    markers do not fix the pelvis, so nothing is reconstructed (``rigid`` is all False).
    """
    c = (np.asarray(lasi, dtype=float) + np.asarray(rasi, dtype=float) + 2.0 * np.asarray(sacr, dtype=float)) / 4.0
    return c[..., :2], np.zeros(c.shape[:-1], dtype=bool)


def _frame3(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Origin (mean) and orthonormal frame (columns e1, e2, e3) of three points ``(T, 3, 3)``."""
    a, b, c = points[..., 0, :], points[..., 1, :], points[..., 2, :]
    e1 = b - a
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    w = c - a
    e2 = w - np.sum(w * e1, axis=-1, keepdims=True) * e1
    e2 /= np.linalg.norm(e2, axis=-1, keepdims=True)
    e3 = np.cross(e1, e2)
    return points.mean(axis=-2), np.stack([e1, e2, e3], axis=-1)


def pelvis_theta(lasi: FloatArray, rasi: FloatArray) -> FloatArray:
    """Global pelvis orientation ``theta = atan2(-l_x, l_y)``, ``l = LASI - RASI``, unwrapped over time.

    ``n = (l_y, -l_x)`` is the horizontal normal to RASI-LASI that points forward (``l`` points to
    the subject's left, so ``n`` = ``l`` turned by -90 deg). NaN where either marker is missing.
    """
    l = np.asarray(lasi, dtype=float) - np.asarray(rasi, dtype=float)
    return unwrap_nan(np.arctan2(-l[..., 0], l[..., 1]))


# ---- the vertical axis of the laboratory frame ----------------------------------------------------
#: the lab axes a frame's vertical may be (Vicon and Qualisys: z; OptiTrack Motive: y; a camera: -y)
UP_AXES = ("z", "y", "x", "-z", "-y", "-x")
#: the pelvis's up direction is within the pelvic tilt (about 10-20 deg) of the vertical: a lab axis within
#: 37 deg of it (cos 0.8) is the vertical one
UP_MIN_COS = 0.8


def levelling(axis: str) -> FloatArray:
    """The proper rotation ``R`` with ``R u = e_z`` for the lab axis ``axis`` (``u = +-e_k``): rows ``a``,
    ``u x a``, ``u`` with ``a = e_(k+1 mod 3)``; ``p' = R p`` puts the vertical on z (for ``"y"``: ``p' = (z, x, y)``)."""
    k = "xyz".index(axis[-1])
    u = np.eye(3)[k] * (-1.0 if axis.startswith("-") else 1.0)
    a = np.eye(3)[(k + 1) % 3]
    return np.vstack([a, np.cross(u, a), u])


def pelvis_up(lasi: FloatArray, rasi: FloatArray, back: FloatArray) -> FloatArray | None:
    """The pelvis's up direction in the lab frame: the median over frames of the unit vector
    ``f x l``, ``f = (LASI + RASI) / 2 - back`` (forward), ``l = LASI - RASI`` (left), as x forward, y left,
    z up; ``back`` the PSIS midpoint or the sacrum marker. It leans from the vertical by the pelvic tilt only,
    whatever the lab's axes, floor origin or the walker's heading. None when no frame has the three."""
    lasi, rasi, back = (np.asarray(m, dtype=float).reshape(-1, 3) for m in (lasi, rasi, back))
    up = np.cross((lasi + rasi) / 2 - back, lasi - rasi)
    up = up[np.isfinite(up).all(axis=1)]
    norm = np.linalg.norm(up, axis=1)
    up = up[norm > 0] / norm[norm > 0, None]
    if not len(up):
        return None
    m = np.median(up, axis=0)
    return m / np.linalg.norm(m) if np.linalg.norm(m) > 0 else None


def table_normal(tab1: FloatArray, tab2: FloatArray, tab3: FloatArray) -> FloatArray | None:
    """The normal of the table's top, ``(TAB2 - TAB1) x (TAB3 - TAB1)``, its median over frames (each frame's turned to
    agree with the first's), up to its sign (the corners' order fixes it, not the lab). None without a frame."""
    a, b, c = (np.asarray(m, dtype=float).reshape(-1, 3) for m in (tab1, tab2, tab3))
    n = np.cross(b - a, c - a)
    n = n[np.isfinite(n).all(axis=1)]
    norm = np.linalg.norm(n, axis=1)
    n = n[norm > 0] / norm[norm > 0, None]
    if not len(n):
        return None
    m = np.median(n * np.sign(n @ n[0])[:, None], axis=0)
    return m / np.linalg.norm(m) if np.linalg.norm(m) > 0 else None


def vertical_axis(up: FloatArray | None, min_cos: float = UP_MIN_COS) -> str | None:
    """The signed lab axis (``UP_AXES``) within ``arccos(min_cos)`` of the direction ``up``, or None."""
    if up is None:
        return None
    k = int(np.argmax(np.abs(up)))
    if abs(up[k]) < min_cos:
        return None
    return ("-" if up[k] < 0 else "") + "xyz"[k]


# ---- velocity and local orientation ---------------------------------------------------------------
def velocity(xy: np.ndarray, rate: float) -> np.ndarray:
    """CoM velocity ``v_i`` by central differences ``(c_{i+1} - c_{i-1}) rate / 2`` (one-sided at the ends)."""
    xy = np.asarray(xy, dtype=float)
    if xy.shape[-2] < 2:
        return np.zeros_like(xy)
    return np.gradient(xy, 1.0 / rate, axis=-2)


def gamma(theta: FloatArray, v: FloatArray, min_speed: float = GAMMA_MIN_SPEED) -> FloatArray:
    """Local orientation ``gamma = wrap(theta - atan2(v_y, v_x))`` in (-pi, pi].

    The tangent ``atan2(v_y, v_x)`` is ill-defined where the speed ``|v|`` is below
    ``min_speed`` (at rest: the ends of a trial, a stop): there gamma holds the last well-defined
    value, and before the first well-defined sample it takes the first well-defined value. So the
    start and end of a trial carry the gamma of the first / last moment the subject was moving.
    All NaN when the speed never reaches ``min_speed`` or theta is NaN.
    """
    theta = np.asarray(theta, dtype=float)
    v = np.asarray(v, dtype=float)
    speed = np.hypot(v[..., 0], v[..., 1])
    g = wrap(theta - np.arctan2(v[..., 1], v[..., 0]))
    defined = (speed >= min_speed) & ~np.isnan(g)
    return _hold(g, defined)


def _hold(values: np.ndarray, defined: np.ndarray) -> np.ndarray:
    """1-D: replace undefined samples by the last defined one (the first defined one before it)."""
    n = values.shape[-1]
    if not defined.any():
        return np.full(n, np.nan)
    idx = np.where(defined, np.arange(n), -1)
    idx = np.maximum.accumulate(idx)
    idx[idx < 0] = np.flatnonzero(defined)[0]
    return values[idx]


# ---- table ---------------------------------------------------------------------------------------
def table_pose(tab1: FloatArray, tab2: FloatArray, tab3: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Table centre and orientation from its corner markers -> ``(xy (T, 2), theta (T,))``.

    TAB1->TAB2 runs along a long side and TAB1->TAB3 along a short side, so TAB2 and TAB3 are
    opposite corners: centre ``c = (TAB2 + TAB3) / 2``; local x axis along the long side,
    ``theta_T = atan2(u_y, u_x)`` with ``u = TAB2 - TAB1``, unwrapped over time. NaN where a needed
    marker is missing.
    """
    t1, t2, t3 = (np.asarray(m, dtype=float) for m in (tab1, tab2, tab3))
    u = t2 - t1
    return ((t2 + t3) / 2.0)[..., :2], unwrap_nan(np.arctan2(u[..., 1], u[..., 0]))


def table_height(tab1: FloatArray, tab2: FloatArray, tab3: FloatArray) -> FloatArray:
    """Table-top height ``h = mean z`` of the visible corner markers (NaN only if all three are missing).

    Averaging the visible corners keeps ``h`` defined through a gap of one marker, so a gap does not
    split a carriage; a tilt while lifting moves ``h`` like the centre of the three corners.
    """
    z = np.stack([np.asarray(m, dtype=float)[..., 2] for m in (tab1, tab2, tab3)])
    with np.errstate(invalid="ignore"):
        ok = ~np.isnan(z)
        return np.where(ok.any(axis=0), np.nansum(z, axis=0) / np.maximum(ok.sum(axis=0), 1), np.nan)
