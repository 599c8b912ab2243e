"""Continuous dynamics of the walking-path models (docs/methods.md 5.1 and 5.3), as casadi expressions
(and the zero-control coast in numpy).

State X = (x, y, theta, v_forw, v_orth, omega), control U = (u1, u2, u3).

Holonomic walker (5.3):
    x' = cos(theta) v_forw - sin(theta) v_orth,   y' = sin(theta) v_forw + cos(theta) v_orth,
    theta' = omega,   v_forw' = u1,   v_orth' = u2,   omega' = u3.
Unicycle (5.1) as an OC model on the same state: x' = v cos(theta), y' = v sin(theta),
theta' = omega with v = v_forw; v_orth does not move the walker (it stays 0 at the optimum since
u2 is only penalised).

Discretisation (``step``), piecewise-constant controls, one of two schemes (docs/methods.md sec. 11):
- ``midpoint`` (continuous convention): velocities and heading integrated exactly, positions by the
  midpoint rule;
- ``euler`` (published convention, the authors' action models): explicit Euler,
  ``X_{k+1} = X_k + dt f(X_k, U_k)``.
"""

from __future__ import annotations

N_STATE = 6
N_CONTROL = 3
STATE_NAMES = ("x", "y", "theta", "v_forw", "v_orth", "omega")
CONTROL_NAMES = ("u1", "u2", "u3")
DYNAMICS = ("walker", "unicycle")
SCHEMES = ("midpoint", "euler")


def rhs(X, U, kind: str = "walker"):
    """``X' = f(X, U)`` for ``kind`` in ``DYNAMICS`` (casadi SX/MX/DM)."""
    import casadi as ca

    th, vf, vo, om = X[2], X[3], X[4], X[5]
    if kind == "walker":
        dx = ca.cos(th) * vf - ca.sin(th) * vo
        dy = ca.sin(th) * vf + ca.cos(th) * vo
    elif kind == "unicycle":
        dx = ca.cos(th) * vf
        dy = ca.sin(th) * vf
    else:
        raise ValueError(f"unknown dynamics {kind!r}; expected one of {DYNAMICS}")
    return ca.vertcat(dx, dy, om, U[0], U[1], U[2])


def step(X, U, dt, kind: str = "walker", scheme: str = "midpoint"):
    """One step of length ``dt`` with constant control ``U`` (casadi).

    ``midpoint``: exact in time for the velocities and the heading (polynomials in t), midpoint rule
    for the position:

        v(t + dt) = v + u dt,  theta(t + dt) = theta + omega dt + u3 dt^2 / 2,
        p(t + dt) = p + dt R(theta_m) v_m,  theta_m = theta + omega dt / 2 + u3 dt^2 / 8,  v_m = v + u dt / 2.

    Second order in dt for the position (error about dt^3 omega^2 |v| / 24 per step: < 1 mm over a
    100-interval walk), one sine/cosine pair per step instead of RK4's four.

    ``euler``: ``p + dt R(theta) v``, ``theta + omega dt``, ``v + u dt`` (first order).
    """
    import casadi as ca

    if scheme not in SCHEMES:
        raise ValueError(f"unknown scheme {scheme!r}; expected one of {SCHEMES}")
    th, vf, vo, om = X[2], X[3], X[4], X[5]
    if scheme == "euler":
        thm, vfm, vom, th_next = th, vf, vo, th + om * dt
    else:
        thm = th + om * dt / 2 + U[2] * dt**2 / 8
        vfm, vom, th_next = vf + U[0] * dt / 2, vo + U[1] * dt / 2, th + om * dt + U[2] * dt**2 / 2
    c, s = ca.cos(thm), ca.sin(thm)
    if kind == "walker":
        dx, dy = c * vfm - s * vom, s * vfm + c * vom
    elif kind == "unicycle":
        dx, dy = c * vfm, s * vfm
    else:
        raise ValueError(f"unknown dynamics {kind!r}; expected one of {DYNAMICS}")
    return ca.vertcat(X[0] + dt * dx, X[1] + dt * dy, th_next, vf + U[0] * dt, vo + U[1] * dt, om + U[2] * dt)


def coast(X, dt: float, n: int, kind: str = "walker", scheme: str = "midpoint"):
    """``n`` steps of ``step`` with zero control from the state ``X`` (numpy): (n + 1, 6) states.

    With U = 0 the velocities stay constant and ``step`` reduces to
    theta_{j+1} = theta_j + omega dt,  p_{j+1} = p_j + dt R(theta_m) v with theta_m = theta_j + omega dt / 2
    (midpoint) or theta_j (euler): the walker coasts along a circular arc (a straight line when omega = 0).
    """
    import numpy as np

    X = np.asarray(X, dtype=float)
    x, y, th, vf, vo, om = X[:6].tolist()  # Python floats: the same IEEE arithmetic, without numpy scalars' overhead
    if kind == "unicycle":
        vo = 0.0
    theta = th + om * dt * np.arange(n + 1)
    thm = theta[:-1] + (om * dt / 2 if scheme == "midpoint" else 0.0)
    c, s = np.cos(thm), np.sin(thm)
    step = np.empty((2, n))
    np.multiply(dt, c * vf - s * vo, out=step[0])
    np.multiply(dt, s * vf + c * vo, out=step[1])
    out = np.empty((n + 1, 6))
    out[0, :2] = x + 0.0, y + 0.0
    out[1:, :2] = np.cumsum(step, axis=1).T + (x, y)
    out[:, 2] = theta
    out[:, 3:] = X[3:6]
    return out


def world_velocity(theta, v_forw, v_orth, kind: str = "walker"):
    """Velocity of the walker in the world frame (numpy): ``(vx, vy)``."""
    import numpy as np

    if kind == "unicycle":
        v_orth = 0.0 * v_orth
    return (np.cos(theta) * v_forw - np.sin(theta) * v_orth, np.sin(theta) * v_forw + np.cos(theta) * v_orth)
