"""The single-level fit's smoothed distance D of one lower-level path to its measured path, with its
gradient and (projected) Hessian by the chain rule (docs/methods.md sec. 6.1).

The path z (nodes at s_k = k / N of the free duration T = exp(log T)) is resampled at the M measured
samples as ``oc.resample`` does (cubic Hermite in time):

    q = (x_s, y_s, theta_s) = H0 (x, y, theta) + H1 (T v_x, T v_y, T omega),
    v_x = cos(theta) v_f - sin(theta) v_o,   v_y = sin(theta) v_f + cos(theta) v_o,

(``hermite_matrices``: linear in the node values a = (x, y, theta, T v_x, T v_y, T omega)), and

    D = (1/M) sum_j phi(x_s,j - x_j, y_s,j - y_j) + w_angle d_angle,   phi(e) = sqrt(|e|^2 + eps^2) - eps,

d_angle = (1/(M-1)) sum_j sabs(wrap(gamma_j + theta_s,j - atan2(dy_j, dx_j))) (walker: gamma measured, the
heading of the model's sample steps dx_j = x_s,j+1 - x_s,j) or (1/M) sum_j sabs(wrap(theta_j - theta_s,j))
(table), sabs(a) = sqrt(a^2 + eps^2) - eps. Then

    grad_z D = A' H' grad_q D,   S' hess_z D S = (H A S)' hess_q D (H A S) + sum_i (H' grad_q D)_i S' hess_z a_i S,

A = da/dz (per node: 7 variables, the node's states and log T), hess_z a_i nonzero only for the products
T v_x, T v_y, T omega. Only the projection onto the few directions S the fit needs is formed (S = I gives
the full Hessian), in O(M m + N m^2) for m directions: no symbolic Hessian of the resampling.
"""

from __future__ import annotations

import numpy as np

SMOOTHING = 1e-4  # eps of the smoothed |.| (rad) and norm (m) in the NLP's D: < 1e-4 per sample


def hermite_matrices(n_intervals: int, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(H0, H1) with path samples = H0 @ node values + T * H1 @ node time derivatives: the cubic
    Hermite interpolant on nodes at s_k = k / N evaluated at s_j = j / (M - 1) (``oc.resample``)."""
    N, M = n_intervals, n_samples
    s = np.linspace(0.0, 1.0, M)
    k = np.minimum((s * N).astype(int), N - 1)
    h = 1.0 / N
    tau = s * N - k
    h00, h10 = 2 * tau**3 - 3 * tau**2 + 1, tau**3 - 2 * tau**2 + tau
    h01, h11 = -2 * tau**3 + 3 * tau**2, tau**3 - tau**2
    H0, H1 = np.zeros((M, N + 1)), np.zeros((M, N + 1))
    rows = np.arange(M)
    H0[rows, k], H0[rows, k + 1] = h00, h01
    H1[rows, k], H1[rows, k + 1] = h10 * h, h11 * h
    return H0, H1


def _outer(a: np.ndarray, c: np.ndarray, b: np.ndarray | None = None) -> np.ndarray:
    """sum_j c_j a_j b_j' over the rows of a and b (b = a when None)."""
    return a.T @ (c[:, None] * (a if b is None else b))


class ResampledDistance:
    """D(z; data) of one lower-level shape (module docstring), data = (x, y, theta, gamma) measured
    (M each, ``single_level.target_data``); ``angle`` "gamma" (walker) or "theta" (table)."""

    def __init__(self, ocp, n_samples: int, angle: str, angle_weight: float, eps: float = SMOOTHING):
        from cobot_analysis.models.dynamics import N_STATE

        self.H0, self.H1 = hermite_matrices(ocp.N, n_samples)
        self.node = np.asarray(ocp._xi[:, :N_STATE])  # (N+1, 6): x, y, theta, v_f, v_o, omega of each node
        self.iT = int(ocp._xi[0, N_STATE])  # log T
        self.M, self.angle, self.aw, self.eps = n_samples, angle, angle_weight, eps

    def __call__(self, z: np.ndarray, data: np.ndarray, S: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        """(D, grad_z D, S' hess_z D S) at the path z, S (n_vars x m) the directions."""
        H0, H1, M, eps, aw = self.H0, self.H1, self.M, self.eps, self.aw
        X, Y, TH, VF, VO, OM = (z[self.node[:, i]] for i in range(6))
        T = float(np.exp(z[self.iT]))
        c, s = np.cos(TH), np.sin(TH)
        U, V, W = T * (c * VF - s * VO), T * (s * VF + c * VO), T * OM
        xs, ys, ths = H0 @ X + H1 @ U, H0 @ Y + H1 @ V, H0 @ TH + H1 @ W
        mx, my, mth, mg = data[:M], data[M:2 * M], data[2 * M:3 * M], data[3 * M:]

        # D and its derivatives in q = (xs, ys, ths): gradient gx, gy, gth; Hessian as per-sample terms
        ex, ey = xs - mx, ys - my
        r = np.sqrt(ex**2 + ey**2 + eps**2)
        D = float(np.sum(r - eps)) / M
        gx, gy = ex / r / M, ey / r / M
        r3 = r**3 * M
        hxx, hyy, hxy = (ey**2 + eps**2) / r3, (ex**2 + eps**2) / r3, -ex * ey / r3
        if self.angle == "gamma":
            dx, dy = xs[1:] - xs[:-1], ys[1:] - ys[:-1]
            rr = np.sqrt(dx**2 + dy**2 + 1e-12)
            ch, sh = dx / rr, dy / rr
            a = mg[:-1] + ths[:-1]
            diff = np.arctan2(np.sin(a) * ch - np.cos(a) * sh, np.cos(a) * ch + np.sin(a) * sh)
            sd = np.sqrt(diff**2 + eps**2)
            k = aw / (M - 1)
            D += k * float(np.sum(sd - eps))
            s1, s2 = k * diff / sd, k * eps**2 / sd**3
            rho2 = dx**2 + dy**2
            px, py = dy / rho2, -dx / rho2  # d diff / d(dx, dy) (diff = a - atan2(dy, dx) wrapped)
            gth = np.append(s1, 0.0)
            gdx, gdy = s1 * px, s1 * py
            gx[1:] += gdx
            gx[:-1] -= gdx
            gy[1:] += gdy
            gy[:-1] -= gdy
            rho4 = rho2**2
            dxx, dyy, dxy = -2 * dx * dy / rho4, 2 * dx * dy / rho4, (dx**2 - dy**2) / rho4  # hess of diff in (dx, dy)
        else:
            a = np.arctan2(np.sin(mth - ths), np.cos(mth - ths))
            sa = np.sqrt(a**2 + eps**2)
            D += aw / M * float(np.sum(sa - eps))
            gth = -aw / M * a / sa
            hth = aw / M * eps**2 / sa**3

        # gradient in z: through a = (X, Y, TH, U, V, W)
        gX, gY, gTH = H0.T @ gx, H0.T @ gy, H0.T @ gth
        gU, gV, gW = H1.T @ gx, H1.T @ gy, H1.T @ gth
        nd = self.node
        gz = np.zeros(len(z))
        gz[nd[:, 0]] = gX
        gz[nd[:, 1]] = gY
        gz[nd[:, 2]] = gTH - V * gU + U * gV
        gz[nd[:, 3]] = T * (c * gU + s * gV)
        gz[nd[:, 4]] = T * (-s * gU + c * gV)
        gz[nd[:, 5]] = T * gW
        gz[self.iT] = float(U @ gU + V @ gV + W @ gW)

        # the directions S through a and q
        sX, sY, sTH, sVF, sVO, sOM = (S[nd[:, i]] for i in range(6))
        sT = S[self.iT]
        Tc, Ts = (T * c)[:, None], (T * s)[:, None]
        sU = U[:, None] * sT - V[:, None] * sTH + Tc * sVF - Ts * sVO
        sV = V[:, None] * sT + U[:, None] * sTH + Ts * sVF + Tc * sVO
        sW = W[:, None] * sT + T * sOM
        qx, qy, qth = H0 @ sX + H1 @ sU, H0 @ sY + H1 @ sV, H0 @ sTH + H1 @ sW
        cross = _outer(qx, hxy, qy)
        Hq = _outer(qx, hxx) + _outer(qy, hyy) + cross + cross.T
        if self.angle == "gamma":
            ddx, ddy = qx[1:] - qx[:-1], qy[1:] - qy[:-1]
            e = qth[:-1] + px[:, None] * ddx + py[:, None] * ddy
            cross = _outer(ddx, s1 * dxy, ddy)
            Hq += _outer(e, s2) + _outer(ddx, s1 * dxx) + _outer(ddy, s1 * dyy) + cross + cross.T
        else:
            Hq += _outer(qth, hth)
        # sum_i (H' grad_q D)_i hess a_i: U = T v_x, V = T v_y, W = T omega in (log T, theta, v_f, v_o, omega)
        c_TT = float(U @ gU + V @ gV + W @ gW)
        c_Tth, c_thth = -V * gU + U * gV, -(U * gU + V * gV)
        c_Tvf, c_Tvo = T * (c * gU + s * gV), T * (-s * gU + c * gV)
        c_thvf, c_thvo = T * (-s * gU + c * gV), -T * (c * gU + s * gV)
        mixed = np.outer(sT, c_Tth @ sTH + c_Tvf @ sVF + c_Tvo @ sVO + (T * gW) @ sOM) \
            + sTH.T @ (c_thvf[:, None] * sVF + c_thvo[:, None] * sVO)
        Hq += c_TT * np.outer(sT, sT) + _outer(sTH, c_thth) + mixed + mixed.T
        return D, gz, Hq
