"""ICP pose against motion capture: time base, delay, structural offset, errors, drift
(docs/methods.md sec. 9, steps 1-4).

Notation: ``s_i`` the ICP stamps, ``P(t)`` the motion-capture (truth) pose, ``Q_i`` the ICP pose,
``d`` the delay (the ICP pose at ``s_i`` describes the robot at ``s_i - d``).

1. Time base: the truth is interpolated at ``s_i - d`` (positions linearly, orientation by
   quaternion slerp; yaw unwrapped), only where its bracketing samples are at most ``max_gap``
   apart (default ``default_max_gap``: twice the median sample spacing of the truth, at least
   0.05 s, so that one missing sample is bridged at any rate). ``association="nearest"`` instead
   takes the truth sample nearest to ``s_i - d`` within ``max_diff`` (the nearest-stamp matching
   of evo). Too few associated poses is an error that names its cause (no common time span, or
   truth gaps longer than ``max_gap``, or no truth sample within ``max_diff``); a comparison that
   leaves out many ICP poses, or any in a truth dropout, carries a ``coverage`` warning (``_coverage``).
2. Delay: ``d* = argmin_d J(d)``, ``J(d) = sum_i sum_a w_a (r_ia(d) - mean_i r_ia(d))^2`` with
   ``r_i(d) = Q_i - P(s_i - d)`` on the axes (x, y, z, yaw) - i.e. the difference that remains
   after the mean offset is removed. A grid scan every 20 ms (or the motion-capture period if
   longer) over the search window finds the basin (far narrower than the gait period, so the
   scan cannot miss it); a golden-section search between the grid neighbours of the best grid
   point refines it to 1e-6 s. ICP poses whose window ``[s - hi, s - lo]`` meets a truth gap
   longer than ``max_gap`` are left out of ``J`` (a dropout's interpolated line biases it). With a rigid alignment (se3, yaw) the position residual is taken
   after that alignment at each ``d`` instead of after the mean. Standard error (sandwich, Gauss-Newton):
   ``var d = sum_ia w_a^2 sigma_a^2 g_ia^2 / (sum_ia w_a g_ia^2)^2``, ``g_i = dP/dt (s_i - d)``
   centred, ``sigma_a`` the residual sd of axis a (serially uncorrelated noise assumed). A minimum
   on the first or last grid point of the window is no minimum of ``J``: ``at_edge`` is set, the
   standard error is NaN, and the run carries a warning to widen the window. The delay is told only
   by changes of the truth's velocity (the mean removes a constant shift): when the same estimate
   with the velocity differenced over +-0.5 s (``motion_sd``: free of the motion capture's noise, which
   over +-0.05 s passes for motion when the robot stands still) exceeds ``UNDETERMINED``,
   ``determined`` is False and ``compare`` refuses to estimate it. With the mean offset, frames
   rotated about the vertical (``_rotated_note``) are said: they bias the delay (and, rotated far, make it
   undetermined: the refusal then names the rigid alignment).
3. Structural offset: ``o = mean_i (Q_i - P(s_i - d))`` per axis (circular mean for yaw) and
   ``Q_i - o`` (docs/methods.md), or a rigid alignment of the ICP positions onto the truth: Umeyama
   SE(3) (``"se3"``) or a rotation about z plus a translation (``"yaw"``, 4 DoF).
4. Errors: ``e_i = Q'_i - P(s_i - d)`` per axis; mean +- sd of ``|e|``, RMSE, max; the 3-D
   position error ``||e_xyz||`` (RMSE, mean, max as evo's APE on the translation part); drift:
   least-squares line ``||e_xy|| = a + b s`` against the travelled distance ``s`` (planar path
   length of the truth smoothed by a centred moving average), b in m per m; NaN, said, when the compared
   poses span less than ``MIN_TRAVEL`` of it (standing still: a slope over the noise). Jumps (``_jumps``: steps
   of ``e`` between consecutive poses of at least ``JUMP`` and ``JUMP_FACTOR`` times the median step,
   a relocalisation) are counted and warned about; with jumps, an estimated delay is estimated again
   with the mean of each stretch between them removed from the residuals (``segments``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from cobot_analysis.angles import angle_diff, circular_mean, wrap
from cobot_analysis.errors import InputError
from cobot_analysis.localisation.poses import PoseStream, from_matrix, from_yaw, multiply, normalise, slerp, yaw_of

AXES = ("x", "y", "z", "yaw")
UNDETERMINED = 0.1  # s: a delay whose standard error from the truth's smoothed velocity exceeds this is not estimated


@dataclass
class Delay:
    value: float  # s
    sd: float  # s
    method: str
    grid: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))  # (delay, J) of the scan
    n: int = 0
    window: tuple[float, float] = (float("nan"), float("nan"))
    at_edge: bool = False  # the minimum of the scan is on an end of the window
    motion_sd: float = 0.0  # s: the standard error with the truth velocity over +-0.5 s (module doc, step 2)

    @property
    def determined(self) -> bool:
        """The truth's velocity changes enough to tell delays apart."""
        return self.motion_sd <= UNDETERMINED

    def edge_warning(self) -> str | None:
        """Advice when the estimate is on an end of its search window (module doc, step 2)."""
        if not self.at_edge:
            return None
        lo, hi = self.window
        width = hi - lo
        upper = self.value > (lo + hi) / 2
        wider = f"{lo:g},{hi + width:g}" if upper else f"{lo - width:g},{hi:g}"
        return (f"the delay estimate {self.value:.3f} s is at the {'upper' if upper else 'lower'} end of its search window "
                f"{lo:g}..{hi:g} s, so it is not a minimum of the cost: widen the window (e.g. --delay-window {wider}) and "
                "check that the estimate moves inside it; if it follows the edge, the two streams do not match "
                "(check --truth, --icp and --time) or give the delay with --delay")


@dataclass
class Alignment:
    """How the ICP poses were brought onto the truth: ``p' = R p + t``, ``yaw' = yaw + dyaw``."""

    method: str  # mean, se3, yaw, none
    rotation: np.ndarray  # 3x3
    translation: np.ndarray  # 3
    offset: np.ndarray  # reported structural offset (x, y, z, yaw) = ICP minus truth

    def apply(self, xyz, quat):
        if self.method == "mean":
            return xyz - self.offset[:3], normalise(multiply(from_yaw(-self.offset[3]), quat))
        q_r = from_matrix(self.rotation)
        return (self.rotation @ np.asarray(xyz).T).T + self.translation, normalise(multiply(q_r, quat))

    def to_icp_frame(self, xyz, yaw):
        """Inverse map of truth positions and yaw into the ICP (map) frame."""
        if self.method == "mean":
            return np.asarray(xyz) + self.offset[:3], np.asarray(yaw) + self.offset[3]
        r_yaw = np.arctan2(self.rotation[1, 0], self.rotation[0, 0])
        return (self.rotation.T @ (np.asarray(xyz) - self.translation).T).T, np.asarray(yaw) - r_yaw


@dataclass
class Comparison:
    delay: Delay
    alignment: Alignment
    samples: pd.DataFrame  # one row per associated ICP sample
    summary: dict
    notes: list[str] = field(default_factory=list)  # warnings: ICP poses left out (``_coverage``), jumps (``_jumps``)


# ---- 1. time base -----------------------------------------------------------------------------
def interpolate(stream: PoseStream, t, max_gap: float = np.inf):
    """Pose of ``stream`` at times ``t``: (xyz, quat, valid). Linear / slerp between the bracketing
    samples; ``valid`` is False outside the stream or across a gap longer than ``max_gap``."""
    t = np.asarray(t, dtype=float)
    n = len(stream)
    i = np.clip(np.searchsorted(stream.t, t, side="left"), 1, n - 1)
    t0, t1 = stream.t[i - 1], stream.t[i]
    dt = t1 - t0
    f = np.clip((t - t0) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)
    xyz = stream.xyz[i - 1] + f[:, None] * (stream.xyz[i] - stream.xyz[i - 1])
    quat = slerp(stream.quat[i - 1], stream.quat[i], f)
    valid = (t >= stream.t[0]) & (t <= stream.t[-1]) & (dt <= max_gap)
    return xyz, quat, valid


def nearest(stream: PoseStream, t, max_diff: float):
    """The sample of ``stream`` nearest to each ``t`` (ties to the earlier one): (index, valid)."""
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(stream.t, t, side="right"), 1, len(stream) - 1)
    j = np.where(np.abs(stream.t[i] - t) < np.abs(t - stream.t[i - 1]), i, i - 1)
    valid = np.abs(stream.t[j] - t) <= max_diff
    return j, valid


def _channels(stream: PoseStream) -> np.ndarray:
    return np.column_stack([stream.xyz, stream.yaw])


# ---- 2. delay ---------------------------------------------------------------------------------
def estimate_delay(truth: PoseStream, icp: PoseStream, window: tuple[float, float] = (0.0, 1.5),
                   weights=(1.0, 1.0, 1.0, 1.0), min_samples: int = 20, grid_step: float = 0.02,
                   rigid: str | None = None, max_gap: float = np.inf, segments: np.ndarray | None = None) -> Delay:
    """Delay of ``icp`` behind ``truth`` (s) minimising ``J(d)`` over ``window`` (module docstring).

    ``rigid="se3"`` or ``"yaw"``: the position residual is taken after the rigid alignment of the
    ICP positions onto the truth at each ``d`` (for frames that differ by a rotation). ICP poses
    whose window ``[s - hi, s - lo]`` meets a truth gap longer than ``max_gap`` are left out (the
    straight line interpolated across a dropout is no truth, and it biases the delay). ``segments``: a
    label per ICP pose (the stretches between relocalisation jumps), whose offsets are removed one by one."""
    lo, hi = window
    w = np.asarray(weights, dtype=float)
    keep = (icp.t - hi >= truth.t[0]) & (icp.t - lo <= truth.t[-1]) & ~_meets_gap(truth.t, icp.t - hi, icp.t - lo, max_gap)
    s = icp.t[keep]
    if len(s) < min_samples:
        return Delay(float("nan"), float("nan"), "not enough overlap", n=len(s), window=(lo, hi))
    q = _channels(icp)[keep]
    label = np.zeros(len(s), int) if segments is None else np.unique(segments[keep], return_inverse=True)[1]
    size = np.bincount(label)
    ref = _channels(truth)
    tref = truth.t

    # Each truth interval as one row (channels at its start, slopes, start time): one gather per evaluation.
    segments = np.column_stack([ref[:-1], np.diff(ref, axis=0) / np.diff(tref)[:, None], tref[:-1]])

    def truth_at(tq):
        """Linear interpolation of the 4 truth channels at ``tq`` (inside the truth span)."""
        seg = segments.take(np.clip(np.searchsorted(tref, tq, side="right"), 1, len(tref) - 1) - 1, axis=0)
        return seg[:, :4] + (tq - seg[:, 8])[:, None] * seg[:, 4:8]

    def residuals(d):
        p = truth_at(s - d)
        r = q - p
        if rigid:
            rot, t = (umeyama if rigid == "se3" else yaw_alignment)(q[:, :3], p[:, :3])
            r[:, :3] = q[:, :3] @ rot.T + t - p[:, :3]
        for k in range(3):  # the mean of each stretch between jumps (of the whole run without jumps)
            r[:, k] -= (np.bincount(label, r[:, k]) / size)[label]
        yaw = wrap(r[:, 3])  # finite (both streams are), so its circular mean needs no NaN handling
        r[:, 3] = wrap(yaw - np.arctan2(np.bincount(label, np.sin(yaw)), np.bincount(label, np.cos(yaw)))[label])
        return r

    def cost(d):
        r = residuals(d)
        return float(np.sum(w * r * r))

    step = max(float(np.median(np.diff(tref))), grid_step)
    grid = np.arange(lo, hi + step / 2, step)
    costs = np.array([cost(d) for d in grid])
    k = int(np.argmin(costs))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    d = golden_section(cost, a, b, 1e-6)
    r = residuals(d)
    sigma2 = r.var(axis=0, ddof=1)

    def standard_error(h):
        """The sandwich estimate with the truth velocity as centred differences over +-h seconds (at the ICP
        poses whose +-h lies inside the truth span: a difference cut short at an end is no velocity)."""
        tq = s - d
        inside = (tq - h >= tref[0]) & (tq + h <= tref[-1])
        g = (truth_at(tq[inside] + h) - truth_at(tq[inside] - h)) / (2 * h)
        g -= g.mean(axis=0) if len(g) else 0.0
        denom = np.sum(w * g * g)
        return float(np.sqrt(np.sum(w * w * sigma2 * g * g)) / denom) if denom > 0 else float("inf")

    sd = standard_error(0.05)
    at_edge = k in (0, len(grid) - 1)
    method = "least squares: grid scan + golden section" + (" (minimum at the window edge)" if at_edge else "")
    return Delay(d, float("nan") if at_edge else sd, method, np.column_stack([grid, costs]), int(len(s)), (lo, hi), at_edge,
                 standard_error(0.5))


def _meets_gap(t: np.ndarray, u: np.ndarray, v: np.ndarray, max_gap: float) -> np.ndarray:
    """Whether each interval ``[u, v]`` overlaps a sample interval of ``t`` longer than ``max_gap``."""
    if len(t) < 2:
        return np.zeros(len(u), bool)
    long = np.concatenate([[0], np.cumsum(np.diff(t) > max_gap)])  # long intervals before each sample
    first = np.clip(np.searchsorted(t, u, side="right") - 1, 0, len(t) - 2)  # interval k is [t_k, t_k+1]
    last = np.clip(np.searchsorted(t, v, side="left") - 1, 0, len(t) - 2)
    return long[last + 1] - long[first] > 0


def golden_section(f, a: float, b: float, tol: float) -> float:
    """Minimum of a unimodal ``f`` on ``[a, b]``: the bracket shrinks by ``1/phi`` per step."""
    invphi = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = b - invphi * (b - a), a + invphi * (b - a)
    fc, fd = f(c), f(d)
    while b - a > tol:
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - invphi * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + invphi * (b - a)
            fd = f(d)
    return float((a + b) / 2.0)


# ---- 3. alignment -----------------------------------------------------------------------------
def umeyama(src, dst):
    """Rigid ``R, t`` minimising ``sum ||dst_i - (R src_i + t)||^2`` (Umeyama 1991, no scale):
    ``Sigma = (1/n) sum (dst_i - mu_d)(src_i - mu_s)^T = U D V^T``, ``R = U S V^T`` with
    ``S = diag(1, 1, det(U) det(V))``, ``t = mu_d - R mu_s``."""
    src, dst = np.asarray(src, dtype=float), np.asarray(dst, dtype=float)
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    sigma = (dst - mu_d).T @ (src - mu_s) / len(src)
    u, _, vt = np.linalg.svd(sigma)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1.0
    r = u @ s @ vt
    return r, mu_d - r @ mu_s


def yaw_alignment(src, dst):
    """Rotation about z and translation (4 DoF) minimising the same sum:
    ``phi = atan2(sum (x_s y_d - y_s x_d), sum (x_s x_d + y_s y_d))`` on centred coordinates."""
    src, dst = np.asarray(src, dtype=float), np.asarray(dst, dtype=float)
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    phi = np.arctan2(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    c, s_ = np.cos(phi), np.sin(phi)
    r = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
    return r, mu_d - r @ mu_s


def align(method: str, truth_xyz, truth_yaw, icp_xyz, icp_yaw) -> Alignment:
    diff = np.column_stack([icp_xyz - truth_xyz, angle_diff(icp_yaw, truth_yaw)])
    if method == "mean":
        off = np.concatenate([diff[:, :3].mean(axis=0), [float(circular_mean(diff[:, 3]))]])
        return Alignment("mean", np.eye(3), -off[:3], off)
    if method == "none":
        return Alignment("none", np.eye(3), np.zeros(3), np.zeros(4))
    r, t = umeyama(icp_xyz, truth_xyz) if method == "se3" else yaw_alignment(icp_xyz, truth_xyz)
    # Reported offset: the transform from the truth frame to the ICP frame, as x, y, z, yaw.
    inv_t = -r.T @ t
    return Alignment(method, r, t, np.concatenate([inv_t, [-np.arctan2(r[1, 0], r[0, 0])]]))


ROTATED = 1.5  # a rotation about the vertical that divides the RMS position residual of the mean offset by more is said


def _rotated_note(truth_xyz, icp_xyz) -> str | None:
    """With the mean offset, the warning a run needs when the ICP frame looks rotated about the vertical against the
    truth's: a rotation about z plus a translation (``yaw_alignment``) leaves an RMS position residual ``ROTATED``
    times smaller than the mean offset does. The mean cannot remove a rotation, and it biases the delay too (0.02 rad:
    0.507 s for 0.55, RMSE 23 mm for 8.5); but the mean offset is the published method, and a localisation that
    drifts in heading looks alike, so the run goes on, saying so."""
    rot, t = yaw_alignment(icp_xyz, truth_xyz)
    fit = np.sqrt(np.mean(np.sum((icp_xyz @ rot.T + t - truth_xyz) ** 2, axis=1)))
    d = icp_xyz - truth_xyz
    mean = np.sqrt(np.mean(np.sum((d - d.mean(axis=0)) ** 2, axis=1)))
    if not mean > ROTATED * fit:
        return None
    return (f"the ICP frame looks rotated about the vertical against the motion capture's by about "
            f"{-np.arctan2(rot[1, 0], rot[0, 0]):.3g} rad (fitted to the positions, a rotation leaves an RMS residual of "
            f"{1000 * fit:.3g} mm where the mean offset leaves {1000 * mean:.3g} mm): the mean offset cannot remove it, "
            "and the delay and errors include it; --alignment yaw (a rotation about the vertical and a translation) "
            "or se3 removes it")


ROTATION_SE = 0.02  # rad: a rigid alignment whose rotation has a larger standard error is fitted to the noise


def _check_rotation(method: str, truth_xyz, r, path) -> None:
    """Refuse a rigid alignment (``se3``, ``yaw``) whose rotation the positions do not fix: its standard
    error ``sigma / (spread sqrt(n))`` (``sigma`` the sd per axis of the residuals ``r`` left by the fit,
    ``spread`` the sd of the truth positions along the direction the rotation needs: the second principal
    one for se3, the first horizontal one for yaw) above ``ROTATION_SE``."""
    n = len(truth_xyz)
    sigma = float(np.sqrt(np.mean(r.var(axis=0))))
    cols = slice(0, 3) if method == "se3" else slice(0, 2)
    sd = np.linalg.svd(truth_xyz[:, cols] - truth_xyz[:, cols].mean(axis=0), compute_uv=False) / np.sqrt(n)
    spread = sd[1] if method == "se3" else sd[0]
    se = sigma / (spread * np.sqrt(n)) if spread > 0 else np.inf
    if se <= ROTATION_SE:
        return
    still = sd[0] * np.sqrt(n) * ROTATION_SE < sigma  # no direction fixes a rotation
    where = ("hardly spread in the horizontal plane" if method == "yaw" else "hardly spread in any direction" if still
             else "spread along one direction only")
    raise InputError(f"--alignment {method} is ill-posed on this run: the motion-capture positions {where} "
                     f"(sd {', '.join(f'{1000 * v:.3g}' for v in sd)} mm against a residual sd of {1000 * sigma:.3g} mm), so the "
                     f"rotation would be fitted to the noise (standard error {se:.2g} rad)", path=path,
                     remedy="use --alignment mean" + (" or yaw (the line fixes the rotation about the vertical)"
                                                      if method == "se3" and not still else ""))


# ---- 4. errors and drift ------------------------------------------------------------------------
def travelled_distance(truth: PoseStream, window: float = 2.0) -> np.ndarray:
    """Cumulative planar path length of the truth smoothed by a centred moving average over
    ``window`` seconds (about two steps: removes the lateral gait sway and the measurement noise
    that would otherwise add to the length), m."""
    xy = truth.xyz[:, :2]
    k = int(round(window / float(np.median(np.diff(truth.t))))) // 2 if len(xy) > 1 else 0
    if k >= 1 and len(xy) > 2 * k + 1:
        # Odd reflection at both ends keeps a linear trend through the edges.
        pad = np.vstack([2 * xy[0] - xy[k:0:-1], xy, 2 * xy[-1] - xy[-2:-k - 2:-1]])
        c = np.cumsum(np.vstack([np.zeros((1, 2)), pad]), axis=0)
        xy = (c[2 * k + 1:] - c[:-2 * k - 1]) / (2 * k + 1)  # centred mean of 2k + 1 samples
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


MIN_TRAVEL = 1.0  # m: the shortest path of the compared poses over which a drift per metre is fitted


def _short_path(distance: np.ndarray) -> str | None:
    """The warning when the compared poses span less than ``MIN_TRAVEL`` of travelled distance (a robot standing
    still: the drift would be a slope over the marker noise's path, e.g. 0.14 +- 0.14 m/m over 5 mm)."""
    if np.ptp(distance) >= MIN_TRAVEL:
        return None
    return (f"the compared poses span {1000 * np.ptp(distance):.3g} mm of travelled distance, less than {MIN_TRAVEL:g} m: "
            "no drift per metre (NaN; a robot standing still, or a short run)")


def summarise(err: np.ndarray, distance: np.ndarray) -> dict:
    """Per-axis and 3-D error statistics of ``err`` (n, 4: x, y, z, yaw signed), and drift (NaN over a path
    shorter than ``MIN_TRAVEL``)."""
    out: dict = {"n": int(len(err))}
    for a, name in enumerate(AXES):
        e = np.abs(err[:, a])
        out[f"err_{name}_mean"] = float(e.mean())
        out[f"err_{name}_sd"] = float(e.std(ddof=1)) if len(e) > 1 else float("nan")
        out[f"err_{name}_rmse"] = float(np.sqrt(np.mean(err[:, a] ** 2)))
        out[f"err_{name}_max"] = float(e.max())
    norm = np.linalg.norm(err[:, :3], axis=1)
    out.update({"ape_rmse": float(np.sqrt(np.mean(norm**2))), "ape_mean": float(norm.mean()),
                "ape_median": float(np.median(norm)), "ape_std": float(norm.std()), "ape_max": float(norm.max()),
                "ape_min": float(norm.min())})
    exy = np.hypot(err[:, 0], err[:, 1])
    if len(err) > 2 and _short_path(distance) is None:
        coef, cov = np.polyfit(distance, exy, 1, cov=True)
        out["drift"] = float(coef[0])
        out["drift_sd"] = float(np.sqrt(cov[0, 0]))
        out["drift_intercept"] = float(coef[1])
    else:
        out["drift"] = out["drift_sd"] = out["drift_intercept"] = float("nan")
    return out


def default_max_gap(truth: PoseStream) -> float:
    """Longest truth gap interpolated across by default: twice the median sample spacing, >= 0.05 s."""
    return max(0.05, 2.0 * float(np.median(np.diff(truth.t)))) if len(truth) > 1 else 0.05


def _spans(truth: PoseStream, icp: PoseStream, delay: float | None) -> str:
    shift = f" - delay {delay:.3f} s" if delay else ""
    return (f"motion capture {truth.t[0]:.3f}..{truth.t[-1]:.3f} s, ICP{shift} "
            f"{icp.t[0] - (delay or 0.0):.3f}..{icp.t[-1] - (delay or 0.0):.3f} s")


DROPPED_REMEDY = "the poses left after those were too few: check the topics with `cobot-analysis bag-info` and the recording"


def _dropped(*streams: PoseStream) -> str:
    """'; on reading, ...' the streams' notes of poses dropped as damaged (``bags``), or '': when too few samples are
    left, the likely cause, said in the one line instead of only in the warning before it."""
    notes = [n for s in streams for n in s.meta.get("notes", []) if " dropped: " in n]
    return f"; on reading, {'; '.join(notes)}" if notes else ""


def _too_few(truth: PoseStream, icp: PoseStream, tq, valid, d: Delay, association: str, max_gap: float, max_diff: float,
             min_samples: int, path) -> InputError:
    """The error for too few associated poses, naming its cause (module doc, step 1)."""
    inside = (tq >= truth.t[0]) & (tq <= truth.t[-1])
    n, n_in = int(valid.sum()), int(inside.sum())
    spacing = np.diff(truth.t)
    sp = f"median {np.median(spacing):.3g} s, longest gap {spacing.max():.3g} s" if len(spacing) else "a single sample"
    given = d.method == "given"
    if n_in < min_samples:
        return InputError(f"too few overlapping samples: {n_in} ICP poses fall inside the motion-capture time span "
                          f"(need {min_samples}; {_spans(truth, icp, d.value)}{_dropped(truth, icp)})", path=path,
                          remedy=DROPPED_REMEDY if _dropped(truth, icp) else
                          "check that both topics cover the same time (bag-info), the --time option (header stamps "
                          "or record time)" + (" and --delay" if given else ""))
    if association == "nearest":
        return InputError(f"too few associated samples: {n} of the {n_in} ICP poses inside the motion capture have a truth "
                          f"sample within --max-diff {max_diff:g} s (truth sample spacing: {sp}; need {min_samples})",
                          path=path, remedy=f"raise --max-diff (half the truth spacing, {np.median(spacing) / 2:.3g} s, "
                                            "or more) or use --association interpolate")
    return InputError(f"too few associated samples: {n_in - n} of the {n_in} ICP poses inside the motion capture fall in "
                      f"truth gaps longer than --max-gap {max_gap:g} s (truth sample spacing: {sp}; need {min_samples})",
                      path=path, remedy=f"raise --max-gap (e.g. --max-gap {2 * np.median(spacing):.3g}) if interpolating "
                                        "across such gaps is acceptable")


DROPOUT = 1.0  # s: a truth gap this long that leaves ICP poses out is a dropout the run must mention
COVERED = 0.9  # fraction of the ICP poses below which the compared samples are said to leave much out


def _coverage(truth: PoseStream, icp: PoseStream, tq, valid, max_gap: float, max_diff: float, association: str) -> str | None:
    """The warning when the compared ICP poses leave out more than ``1 - COVERED`` of them, or any in a truth
    gap of ``DROPOUT`` s or more: how many, why (outside the truth's span, in its gaps) and the longest gap."""
    inside = (tq >= truth.t[0]) & (tq <= truth.t[-1])
    n, total, lost = int(valid.sum()), len(icp), int((inside & ~valid).sum())
    spacing = np.diff(truth.t)
    k = int(np.argmax(spacing)) if len(spacing) else 0
    longest = float(spacing[k]) if len(spacing) else 0.0
    if n >= COVERED * total and not (lost and longest >= DROPOUT):
        return None
    rule = f"--max-gap {max_gap:g} s" if association == "interpolate" else f"no sample within --max-diff {max_diff:g} s"
    gap = (f", the longest a gap of {longest:.3g} s from {truth.t[k] - truth.t[0]:.1f} s into the motion capture"
           if lost and longest > max_gap else "")
    return (f"{n} of {total} ICP poses compared: {total - int(inside.sum())} fall outside the motion-capture span "
            f"(after the delay), {lost} in its gaps ({rule}{gap}); the errors, the drift and the delay describe the "
            "compared poses only")


def _icp_gaps(icp: PoseStream) -> str | None:
    """The warning when the ICP stream falls silent (localisation lost, its node stalled) for ``DROPOUT`` s or
    more and 5 times its median sample spacing: the errors cannot cover that time."""
    spacing = np.diff(icp.t)
    if not len(spacing):
        return None
    limit = max(DROPOUT, 5.0 * float(np.median(spacing)))
    k = int(np.argmax(spacing))
    n = int(np.sum(spacing >= limit))
    if not n:
        return None
    return (f"the ICP stream has {n} gap{'s' if n > 1 else ''} of {limit:.2g} s or more (the longest {spacing[k]:.2g} s from "
            f"{icp.t[k] - icp.t[0]:.1f} s into it): no pose was published there, so the errors do not cover that time")


def compare(truth: PoseStream, icp: PoseStream, *, delay: float | None = None, window=(0.0, 1.5),
            weights=(1.0, 1.0, 1.0, 1.0), alignment: str = "mean", association: str = "interpolate",
            max_gap: float | None = None, max_diff: float = 0.01, distance_window: float = 2.0,
            min_samples: int = 20, path=None) -> Comparison:
    """Steps 1-4 of docs/methods.md sec. 9 on one run (``delay`` given or estimated; ``max_gap``
    None: ``default_max_gap``)."""
    max_gap = default_max_gap(truth) if max_gap is None else float(max_gap)
    segments = None
    while True:  # twice when the ICP jumps: the delay is then estimated between the jumps
        cmp = _compare_once(truth, icp, delay, window, weights, alignment, association, max_gap, max_diff, distance_window,
                            min_samples, path, segments)
        steps = _jumps(cmp.samples[[f"err_{a}" for a in AXES]].to_numpy())
        if delay is not None or segments is not None or not steps.any():
            break
        segments = np.searchsorted(cmp.samples["t"].to_numpy()[1:][steps], icp.t, side="right")
    cmp.summary["jumps"] = int(steps.sum())
    if steps.any():
        cmp.notes.append(_jump_note(icp, cmp.samples, steps, delay is None))
    return cmp


JUMP = (0.1, 0.1)  # m, rad: the smallest step of the ICP-minus-truth difference between consecutive poses taken as a jump
JUMP_FACTOR = 10.0  # ... and it must be this many times the median step (the noise)


def _jumps(err: np.ndarray) -> np.ndarray:
    """Steps ``k -> k + 1`` of the ICP-minus-truth difference ``err`` (n, 4: x, y, z, yaw; consecutive compared
    poses) that are jumps: a position step of at least ``JUMP[0]`` and ``JUMP_FACTOR`` times the median step,
    or a yaw step likewise."""
    if len(err) < 3:
        return np.zeros(max(len(err) - 1, 0), bool)
    dp = np.linalg.norm(np.diff(err[:, :3], axis=0), axis=1)
    dy = np.abs(wrap(np.diff(err[:, 3])))
    return ((dp >= max(JUMP[0], JUMP_FACTOR * np.median(dp))) | (dy >= max(JUMP[1], JUMP_FACTOR * np.median(dy))))


def _jump_note(icp: PoseStream, samples: pd.DataFrame, steps: np.ndarray, estimated: bool) -> str:
    """The warning for the ICP's jumps: how many, when (s into the ICP stream) and how large."""
    err = samples[[f"err_{a}" for a in AXES]].to_numpy()
    k = np.flatnonzero(steps)
    sizes = np.linalg.norm(err[k + 1, :3] - err[k, :3], axis=1), np.abs(wrap(err[k + 1, 3] - err[k, 3]))
    t = samples["t"].to_numpy()[k + 1] - icp.t[0]
    where = ", ".join(f"{a:.1f} s ({b:.2g} m, {c:.2g} rad)" for a, b, c in list(zip(t, *sizes))[:5]) + (", ..." if len(k) > 5 else "")
    return (f"{len(k)} jump{'s' if len(k) > 1 else ''} of the ICP against the motion capture (a relocalisation: its "
            f"difference to the truth steps by at least {JUMP[0]:g} m or {JUMP[1]:g} rad between consecutive poses) at "
            f"{where} into the ICP stream; the errors include {'them' if len(k) > 1 else 'it'}"
            + (", the delay is estimated with the offset of each stretch between jumps removed" if estimated else ""))


def _compare_once(truth: PoseStream, icp: PoseStream, delay, window, weights, alignment: str, association: str,
                  max_gap: float, max_diff: float, distance_window: float, min_samples: int, path,
                  segments: np.ndarray | None) -> Comparison:
    """``compare`` with the delay's stretches between jumps given (``segments``, a label per ICP pose)."""
    if delay is None:
        dl = estimate_delay(truth, icp, window, weights, min_samples, rigid=alignment if alignment in ("se3", "yaw") else None,
                            max_gap=max_gap, segments=segments)
        span = (icp.t - window[1] >= truth.t[0]) & (icp.t - window[0] <= truth.t[-1])
        if not np.isfinite(dl.value) and span.sum() >= min_samples:  # enough poses, but next to truth gaps
            near_gap = _meets_gap(truth.t, icp.t - window[1], icp.t - window[0], max_gap)
            raise _too_few(truth, icp, icp.t - window[0], span & ~near_gap, dl, "interpolate", max_gap, max_diff, min_samples, path)
        if not np.isfinite(dl.value):
            raise InputError(f"too few overlapping samples to estimate the delay ({dl.n} ICP poses inside the motion-capture "
                             f"span for a search window of {window[0]:g}..{window[1]:g} s, need {min_samples}; "
                             f"{_spans(truth, icp, None)}{_dropped(truth, icp)})", path=path,
                             remedy=DROPPED_REMEDY if _dropped(truth, icp) else
                             "check that both topics cover the same time (bag-info) and the --time option (header "
                             "stamps or record time); a delay outside the window needs a wider --delay-window")
    else:
        dl = Delay(float(delay), 0.0, "given")
    tq = icp.t - dl.value
    if association == "nearest":
        j, valid = nearest(truth, tq, max_diff)
        t_xyz, t_quat = truth.xyz[j], truth.quat[j]
        valid &= (tq >= truth.t[0] - max_diff) & (tq <= truth.t[-1] + max_diff)
    else:
        t_xyz, t_quat, valid = interpolate(truth, tq, max_gap)
    n = int(valid.sum())
    if n < min_samples:
        raise _too_few(truth, icp, tq, valid, dl, association, max_gap, max_diff, min_samples, path)
    t_xyz, t_quat = t_xyz[valid], t_quat[valid]
    i_xyz, i_quat = icp.xyz[valid], icp.quat[valid]
    t_yaw = np.unwrap(yaw_of(t_quat))
    i_yaw = np.unwrap(yaw_of(i_quat))
    al = align(alignment, t_xyz, t_yaw, i_xyz, i_yaw)
    c_xyz, c_quat = al.apply(i_xyz, i_quat)
    rotated = _rotated_note(t_xyz, i_xyz) if alignment == "mean" else None
    if alignment in ("se3", "yaw"):  # first: the remedy of the delay's error below must work
        _check_rotation(alignment, t_xyz, c_xyz - t_xyz, path)
    if not dl.determined:
        left = 1000 * float(np.sqrt(np.mean(np.sum((c_xyz - t_xyz) ** 2, axis=1))))
        raise InputError("the delay cannot be estimated from this run: the motion capture hardly changes its velocity against "
                         f"the {left:.3g} mm left between the streams (standard error {dl.motion_sd:.2g} s; a robot standing "
                         "still or moving straight at a constant speed, or streams that do not match), so every delay in "
                         f"the window fits alike (the scan's minimum, {dl.value:.3f} s, is noise)", path=path,
                         remedy=(f"{rotated[0].upper()}{rotated[1:]}" if rotated else
                                 "give it with --delay (standing still, any value gives the same errors, e.g. --delay 0); "
                                 "if the robot moved, check --truth and --icp"))
    c_yaw = np.unwrap(yaw_of(c_quat))
    err = np.column_stack([c_xyz - t_xyz, angle_diff(c_yaw, t_yaw)])
    travelled = travelled_distance(truth, distance_window)
    dist = np.interp(tq[valid], truth.t, travelled)
    summary = summarise(err, dist)
    summary.update({"delay": dl.value, "delay_sd": dl.sd, "delay_method": dl.method, "delay_at_edge": dl.at_edge,
                    "alignment": al.method, "association": association, "max_gap": max_gap, "distance": float(travelled[-1]),
                    **{f"offset_{a}": float(v) for a, v in zip(AXES, al.offset)},
                    "duration": float(truth.t[-1] - truth.t[0]), "n_truth": int(len(truth)), "n_icp": int(len(icp))})
    samples = pd.DataFrame({
        "t": icp.t[valid], "t_truth": tq[valid], "distance": dist,
        **{f"truth_{a}": v for a, v in zip(AXES, (*t_xyz.T, t_yaw))},
        **{f"icp_{a}": v for a, v in zip(AXES, (*i_xyz.T, i_yaw))},
        **{f"aligned_{a}": v for a, v in zip(AXES, (*c_xyz.T, c_yaw))},
        **{f"err_{a}": err[:, k] for k, a in enumerate(AXES)},
        "err_xyz": np.linalg.norm(err[:, :3], axis=1),
    })
    notes = [rotated, _coverage(truth, icp, tq, valid, max_gap, max_diff, association), _icp_gaps(icp), _short_path(dist)]
    return Comparison(dl, al, samples, summary, [n for n in notes if n])

