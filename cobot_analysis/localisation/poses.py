"""Pose streams (time, position, unit quaternion) and the quaternion maths they need.

Quaternions are stored scalar-last ``(qx, qy, qz, qw)`` as in ROS messages. Yaw is the first
angle of the ZYX (yaw-pitch-roll) decomposition, ``yaw = atan2(2 (qw qz + qx qy),
1 - 2 (qy^2 + qz^2))``, so a rotation ``Rz(a)`` applied on the left adds ``a`` to the yaw.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.schema import Column, TableSchema

POSES = TableSchema(
    name="localisation-poses",
    version=1,
    description="Pose streams read from a bag, one row per message (or per chained tf lookup).",
    columns={
        "run": Column("string", "", "run label (bag file stem unless given; STEM for the pieces STEM_N of a split recording read as one)"),
        "source": Column("string", "", "'truth' (motion capture) or 'icp' (on-board localisation)"),
        "t": Column("float", "s", "stamp (header stamp, or bag record time with --time record), ROS epoch seconds"),
        "x": Column("float", "m", "position in the frame of the stream, levelled to z-up when it is not (see localisation up_truth / up_icp)"),
        "y": Column("float", "m", "position in the frame of the stream, levelled likewise"),
        "z": Column("float", "m", "position in the frame of the stream (vertical)"),
        "qx": Column("float", "-", "orientation quaternion, x"),
        "qy": Column("float", "-", "orientation quaternion, y"),
        "qz": Column("float", "-", "orientation quaternion, z"),
        "qw": Column("float", "-", "orientation quaternion, w (scalar)"),
        "yaw": Column("float", "rad", "ZYX yaw from the quaternion, unwrapped along the stream"),
    },
)


@dataclass
class PoseStream:
    """A time-ordered pose stream: ``t`` (n,), ``xyz`` (n, 3), ``quat`` (n, 4) scalar-last."""

    t: np.ndarray
    xyz: np.ndarray
    quat: np.ndarray
    name: str = ""
    frame_id: str = ""
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    @cached_property
    def yaw(self) -> np.ndarray:
        """Yaw unwrapped along the stream (rad); computed once (a stream's arrays are not changed in place)."""
        return np.unwrap(yaw_of(self.quat))

    def select(self, mask) -> "PoseStream":
        return PoseStream(self.t[mask], self.xyz[mask], self.quat[mask], self.name, self.frame_id, dict(self.meta))

    def to_frame(self, run: str, source: str) -> pd.DataFrame:
        return pd.DataFrame({
            "run": run, "source": source, "t": self.t,
            "x": self.xyz[:, 0], "y": self.xyz[:, 1], "z": self.xyz[:, 2],
            "qx": self.quat[:, 0], "qy": self.quat[:, 1], "qz": self.quat[:, 2], "qw": self.quat[:, 3],
            "yaw": self.yaw,
        }, copy=False)  # views of the stream's arrays (no consolidated copy)


# ---- quaternions (scalar-last, arrays of shape (..., 4)), in numpy -----------------------------
# The Hamilton conventions of scipy.spatial.transform.Rotation (inputs normalised, no sign
# canonicalisation), written out: importing scipy.spatial costs a localisation run 0.2-0.3 s.
def row_norm(v, keepdims: bool = False):
    """Euclidean norm along the last axis, ``sqrt((v_0^2 + v_1^2) + ...)``: ``np.linalg.norm(v, axis=-1)`` (the
    same sum, component by component) without its generic path, 2x faster on the 100,000 poses of a run."""
    sq = np.square(v)
    total = sq[..., 0].copy()
    for k in range(1, sq.shape[-1]):
        total += sq[..., k]
    total = np.sqrt(total, out=total)
    return total[..., None] if keepdims else total


def normalise(q):
    """Unit quaternions ``q / |q|`` (a zero quaternion gives NaN; scipy would raise)."""
    q = np.asarray(q, dtype=float)
    return q / row_norm(q, keepdims=True)


def yaw_of(q):
    """ZYX yaw ``atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))`` (rad, wrapped)."""
    x, y, z, w = np.moveaxis(normalise(q), -1, 0)
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def from_yaw(yaw, pitch=0.0, roll=0.0):
    """Quaternion of ``Rz(yaw) Ry(pitch) Rx(roll)``: ``q_z(yaw) q_y(pitch) q_x(roll)``."""
    yaw, pitch, roll = np.broadcast_arrays(*(np.asarray(a, dtype=float) / 2 for a in (yaw, pitch, roll)))
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    return np.stack([sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy], axis=-1)


def _product(a, b):
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def multiply(a, b):
    """Hamilton product ``a b`` of unit quaternions."""
    return _product(normalise(a), normalise(b))


def conjugate(q):
    """Inverse of unit quaternions: ``(-x, -y, -z, w)``."""
    return normalise(q) * np.array([-1.0, -1.0, -1.0, 1.0])


def rotate(q, v):
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q``: ``v + 2 w (u x v) + 2 u x (u x v)``."""
    q = normalise(q)
    u, w = q[..., :3], q[..., 3:]
    c = np.cross(u, np.asarray(v, dtype=float))
    return v + 2 * w * c + 2 * np.cross(u, c)


def to_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions."""
    x, y, z, w = np.moveaxis(normalise(q), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def from_matrix(m):
    """Unit quaternions of rotation matrices (..., 3, 3), from the largest of the trace and the
    diagonal (numerically stable; the sign scipy gives)."""
    m = np.asarray(m, dtype=float)
    flat = m.reshape(-1, 3, 3)
    diag = np.diagonal(flat, axis1=1, axis2=2)
    decision = np.column_stack([diag, diag.sum(axis=1)])
    choice = decision.argmax(axis=1)
    q = np.empty((len(flat), 4))
    rows = np.flatnonzero(choice != 3)
    i = choice[rows]
    j, k = (i + 1) % 3, (i + 2) % 3
    q[rows, i] = 1 - decision[rows, 3] + 2 * flat[rows, i, i]
    q[rows, j] = flat[rows, j, i] + flat[rows, i, j]
    q[rows, k] = flat[rows, k, i] + flat[rows, i, k]
    q[rows, 3] = flat[rows, k, j] - flat[rows, j, k]
    rows = np.flatnonzero(choice == 3)
    q[rows, 0] = flat[rows, 2, 1] - flat[rows, 1, 2]
    q[rows, 1] = flat[rows, 0, 2] - flat[rows, 2, 0]
    q[rows, 2] = flat[rows, 1, 0] - flat[rows, 0, 1]
    q[rows, 3] = 1 + decision[rows, 3]
    return normalise(q).reshape(m.shape[:-2] + (4,))


def slerp(q0, q1, f):
    """Spherical linear interpolation ``q0 (q0^-1 q1)^f`` along the shorter arc, row-wise."""
    q0 = normalise(q0)
    d = _product(conjugate(q0), normalise(q1))
    d = np.where(d[..., 3:] < 0, -d, d)  # the shorter arc: angle in [0, pi]
    s = np.linalg.norm(d[..., :3], axis=-1, keepdims=True)
    angle = 2 * np.arctan2(s, d[..., 3:])
    half = np.asarray(f, dtype=float)[..., None] * angle / 2
    axis = np.divide(d[..., :3], s, out=np.zeros_like(d[..., :3]), where=s > 0)
    return _product(q0, np.concatenate([axis * np.sin(half), np.cos(half)], axis=-1))


def compose(p_a, q_a, p_b, q_b):
    """Pose product ``T_a T_b``: position ``p_a + R_a p_b``, orientation ``q_a q_b``."""
    return np.asarray(p_a) + rotate(q_a, p_b), multiply(q_a, q_b)


def invert(p, q):
    """Inverse pose: ``(-R^T p, q^-1)``."""
    q_inv = conjugate(q)
    return -rotate(q_inv, p), q_inv
