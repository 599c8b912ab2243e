"""Pose streams (time, position, unit quaternion) and the quaternion maths they need.

Quaternions are stored scalar-last ``(qx, qy, qz, qw)`` as in ROS messages. Yaw is the first
angle of the ZYX (yaw-pitch-roll) decomposition, ``yaw = atan2(2 (qw qz + qx qy),
1 - 2 (qy^2 + qz^2))``, so a rotation ``Rz(a)`` applied on the left adds ``a`` to the yaw.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from cobot_analysis.schema import Column, TableSchema

POSES = TableSchema(
    name="localisation-poses",
    version=1,
    description="Pose streams read from a bag, one row per message (or per chained tf lookup).",
    columns={
        "run": Column("string", "", "run label (bag file stem unless given)"),
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


# ---- quaternions (scalar-last, arrays of shape (..., 4)), via scipy.spatial.transform ----------
def normalise(q):
    """Unit quaternions ``q / |q|`` (a zero quaternion gives NaN; scipy would raise)."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def yaw_of(q):
    """ZYX yaw ``atan2(2 (w z + x y), 1 - 2 (y^2 + z^2))`` (rad, wrapped)."""
    return Rotation.from_quat(q).as_euler("ZYX")[..., 0]


def from_yaw(yaw, pitch=0.0, roll=0.0):
    """Quaternion of ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    return Rotation.from_euler("ZYX", np.stack(np.broadcast_arrays(yaw, pitch, roll), axis=-1)).as_quat()


def multiply(a, b):
    """Hamilton product ``a b`` of unit quaternions."""
    return (Rotation.from_quat(a) * Rotation.from_quat(b)).as_quat()


def conjugate(q):
    """Inverse of unit quaternions."""
    return Rotation.from_quat(q).inv().as_quat()


def rotate(q, v):
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q``."""
    return Rotation.from_quat(q).apply(v)


def to_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions."""
    return Rotation.from_quat(q).as_matrix()


def from_matrix(m):
    """Unit quaternions of rotation matrices (..., 3, 3)."""
    return Rotation.from_matrix(m).as_quat()


def slerp(q0, q1, f):
    """Spherical linear interpolation ``q0 (q0^-1 q1)^f`` along the shorter arc, row-wise."""
    r0 = Rotation.from_quat(q0)
    step = (r0.inv() * Rotation.from_quat(q1)).as_rotvec()  # angle in [0, pi]: the shorter arc
    return (r0 * Rotation.from_rotvec(np.asarray(f, dtype=float)[..., None] * step)).as_quat()


def compose(p_a, q_a, p_b, q_b):
    """Pose product ``T_a T_b``: position ``p_a + R_a p_b``, orientation ``q_a q_b``."""
    r_a = Rotation.from_quat(q_a)
    return np.asarray(p_a) + r_a.apply(p_b), (r_a * Rotation.from_quat(q_b)).as_quat()


def invert(p, q):
    """Inverse pose: ``(-R^T p, q^-1)``."""
    r_inv = Rotation.from_quat(q).inv()
    return -r_inv.apply(p), r_inv.as_quat()
