"""Continuous dynamics of the walking-path models (METHODS.md 5.1 and 5.3), as casadi expressions.

State X = (x, y, theta, v_forw, v_orth, omega), control U = (u1, u2, u3).

Holonomic walker (5.3):
    x' = cos(theta) v_forw - sin(theta) v_orth,   y' = sin(theta) v_forw + cos(theta) v_orth,
    theta' = omega,   v_forw' = u1,   v_orth' = u2,   omega' = u3.
Unicycle (5.1) as an OC model on the same state: x' = v cos(theta), y' = v sin(theta),
theta' = omega with v = v_forw; v_orth does not move the walker (it stays 0 at the optimum since
u2 is only penalised).

Discretisation: one classic Runge-Kutta-4 step per interval, piecewise-constant controls.
"""

from __future__ import annotations

N_STATE = 6
N_CONTROL = 3
STATE_NAMES = ("x", "y", "theta", "v_forw", "v_orth", "omega")
CONTROL_NAMES = ("u1", "u2", "u3")
DYNAMICS = ("walker", "unicycle")


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


def rk4_step(X, U, dt, kind: str = "walker"):
    """One RK4 step of length ``dt`` with constant control ``U``."""
    k1 = rhs(X, U, kind)
    k2 = rhs(X + dt / 2 * k1, U, kind)
    k3 = rhs(X + dt / 2 * k2, U, kind)
    k4 = rhs(X + dt * k3, U, kind)
    return X + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def world_velocity(theta, v_forw, v_orth, kind: str = "walker"):
    """Velocity of the walker in the world frame (numpy): ``(vx, vy)``."""
    import numpy as np

    if kind == "unicycle":
        v_orth = 0.0 * v_orth
    return (np.cos(theta) * v_forw - np.sin(theta) * v_orth, np.sin(theta) * v_forw + np.cos(theta) * v_orth)
