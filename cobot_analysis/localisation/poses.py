"""Pose streams (time, position, unit quaternion) and the quaternion maths they need.

Quaternions are stored scalar-last ``(qx, qy, qz, qw)`` as in ROS messages. Yaw is the first
angle of the ZYX (yaw-pitch-roll) decomposition, ``yaw = atan2(2 (qw qz + qx qy),
1 - 2 (qy^2 + qz^2))``, so a rotation ``Rz(a)`` applied on the left adds ``a`` to the yaw.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from cobot_analysis.schema import Column, TableSchema

POSES = TableSchema(
    name="localisation-poses",
    version=1,
    description="Pose streams read from a bag, one row per message (or per chained tf lookup).",
    columns={
        "run": Column("string", "", "run label (bag file stem unless given)"),
        "source": Column("string", "", "'truth' (motion capture) or 'icp' (on-board localisation)"),
        "t": Column("float", "s", "stamp (header stamp, or bag record time with --time record), ROS epoch seconds"),
        "x": Column("float", "m", "position in the frame of the stream"),
        "y": Column("float", "m", "position in the frame of the stream"),
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

    @property
    def yaw(self) -> np.ndarray:
        """Yaw unwrapped along the stream (rad)."""
        return np.unwrap(yaw_of(self.quat))

    def select(self, mask) -> "PoseStream":
        return PoseStream(self.t[mask], self.xyz[mask], self.quat[mask], self.name, self.frame_id, dict(self.meta))

    def to_frame(self, run: str, source: str) -> pd.DataFrame:
        return pd.DataFrame({
            "run": run, "source": source, "t": self.t,
            "x": self.xyz[:, 0], "y": self.xyz[:, 1], "z": self.xyz[:, 2],
            "qx": self.quat[:, 0], "qy": self.quat[:, 1], "qz": self.quat[:, 2], "qw": self.quat[:, 3],
            "yaw": self.yaw,
        })


# ---- quaternions (scalar-last, arrays of shape (..., 4)) -------------------------------------
def normalise(q):
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def yaw_of(q):
    """ZYX yaw ``atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))`` (rad, wrapped)."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def from_yaw(yaw, pitch=0.0, roll=0.0):
    """Quaternion of ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    cy, sy = np.cos(np.asarray(yaw) / 2), np.sin(np.asarray(yaw) / 2)
    cp, sp = np.cos(np.asarray(pitch) / 2), np.sin(np.asarray(pitch) / 2)
    cr, sr = np.cos(np.asarray(roll) / 2), np.sin(np.asarray(roll) / 2)
    q = np.stack(np.broadcast_arrays(sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                                     cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy), axis=-1)
    return q


def multiply(a, b):
    """Hamilton product ``a b``."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def conjugate(q):
    q = np.asarray(q, dtype=float)
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def rotate(q, v):
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q``: ``v + 2 w (u x v) + 2 u x (u x v)``."""
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    u, w = q[..., :3], q[..., 3:4]
    uv = np.cross(u, v)
    return v + 2.0 * w * uv + 2.0 * np.cross(u, uv)


def to_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def from_matrix(m):
    """Unit quaternion of one rotation matrix (Shepperd's method)."""
    m = np.asarray(m, dtype=float)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
    return normalise(np.array(q))


def slerp(q0, q1, f):
    """Spherical linear interpolation ``q0 (q0^-1 q1)^f`` along the shorter arc, row-wise."""
    q0, q1 = normalise(q0), normalise(q1)
    f = np.asarray(f, dtype=float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(theta)
    small = sin < 1e-9
    w0 = np.where(small, 1.0 - f, np.sin((1.0 - f) * theta) / np.where(small, 1.0, sin))
    w1 = np.where(small, f, np.sin(f * theta) / np.where(small, 1.0, sin))
    return normalise(w0 * q0 + w1 * q1)


def compose(p_a, q_a, p_b, q_b):
    """Pose product ``T_a T_b``: position ``p_a + R_a p_b``, orientation ``q_a q_b``."""
    return np.asarray(p_a) + rotate(q_a, p_b), normalise(multiply(q_a, q_b))


def invert(p, q):
    """Inverse pose: ``(-R^T p, q^*)``."""
    qc = conjugate(q)
    return -rotate(qc, p), qc
