"""The vertical axis of a pose stream, and the levelled (z-up) frame the comparison works in.

Travelled distance, drift, stops and yaw are planar quantities: they need the horizontal plane of
the motion. ROS frames are z-up (REP 103), but a motion-capture or camera frame need not be
(camera optical frames have y down, Motive's default is y up). ``--up`` gives the vertical axis of
each stream (``x``, ``y``, ``z``, ``-x``, ``-y``, ``-z``; one value for both or ``TRUTH,ICP``), or
``auto`` detects it:

- the positions of a robot walking or driving on a floor spread along the two horizontal axes and
  hardly along the vertical one: the axis of smallest spread (sd) is the vertical one when that
  spread is below ``RATIO`` times the next smallest; the sign cannot be told from the motion (+ is
  taken; it only flips the sign of yaw and of the offsets about it, not the errors);
- when no axis stands out (e.g. a straight walk) z is assumed, with a warning if z is not the axis
  of smallest spread.

Levelling (docs/methods.md sec. 9): a proper rotation ``R`` with ``R u = e_z`` (rows ``a``,
``u x a``, ``u`` for ``u = +-e_k`` and ``a = e_(k+1 mod 3)``; for a camera frame, ``up = -y``,
this is x forward, y left, z up) maps positions ``p' = R p`` and orientations ``R_q' = R R_q R^T``
(the body frame is taken to follow the convention of the world frame, as in a camera's optical
frame), so a rotation about ``u`` becomes a rotation about z and keeps its meaning as yaw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cobot_analysis.kinematics import UP_AXES, levelling
from cobot_analysis.localisation.poses import PoseStream, conjugate, from_matrix, multiply

RATIO = 0.2  # the vertical spread must be below this fraction of the next smallest one


@dataclass(frozen=True)
class Vertical:
    """The vertical axis of a stream (``"z"``, ``"-y"``, ...) and how it was found."""

    axis: str
    how: str  # "given", "detected", "assumed"
    spread: tuple[float, float, float]  # sd of x, y, z (m)

    @property
    def rotation(self) -> np.ndarray:
        """``R`` with ``R u = e_z`` (module doc; ``kinematics.levelling``)."""
        return levelling(self.axis)

    def describe(self) -> str:
        return f"{self.axis} ({self.how})"


def parse(text: str) -> tuple[str | None, str | None]:
    """``--up`` -> (truth axis, ICP axis); None = detect. Raises ValueError on a bad value."""
    parts = [p.strip().lower() for p in text.split(",")]
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or any(p not in (*UP_AXES, "auto") for p in parts):
        raise ValueError(text)
    return tuple(None if p == "auto" else p for p in parts)  # type: ignore[return-value]


def find(stream: PoseStream, axis: str | None = None) -> Vertical:
    """The vertical axis of ``stream``: ``axis`` if given, else detected (module doc)."""
    sd = tuple(float(v) for v in np.std(stream.xyz, axis=0)) if len(stream) > 1 else (0.0, 0.0, 0.0)
    if axis is not None:
        return Vertical(axis, "given", sd)
    order = np.argsort(sd)
    if sd[order[0]] < RATIO * sd[order[1]]:
        return Vertical("xyz"[order[0]], "detected", sd)
    return Vertical("z", "assumed", sd)


def level(stream: PoseStream, vertical: Vertical) -> PoseStream:
    """``stream`` in the frame levelled to ``vertical`` (unchanged when it is z)."""
    if vertical.axis == "z":
        return stream
    r = vertical.rotation
    rot = from_matrix(r)
    quat = multiply(multiply(rot, stream.quat), conjugate(rot))
    return PoseStream(stream.t, stream.xyz @ r.T, quat, stream.name, stream.frame_id, {**stream.meta, "up": vertical.axis})


def warning(name: str, vertical: Vertical) -> str | None:
    """The warning a run needs about the vertical axis of its stream ``name`` (None when z is sure)."""
    sd = ", ".join(f"{a} {v:.3g}" for a, v in zip("xyz", vertical.spread))
    if vertical.how == "detected" and vertical.axis != "z":
        return (f"the {name} frame is not z-up: its vertical axis is {vertical.axis} (detected from the spread of the "
                f"positions, sd {sd} m); distance, drift, stops and yaw are computed in the plane normal to it "
                "(pass --up to set the axis and its sign)")
    if vertical.how == "assumed" and np.argmin(vertical.spread) != 2:
        return (f"cannot tell the vertical axis of the {name} frame from the motion (sd {sd} m); z assumed: "
                "pass --up if the frame is not z-up")
    if vertical.how == "given" and vertical.axis != "z":
        return f"the {name} frame is taken as {vertical.axis}-up (--up); the comparison works in the frame levelled to it"
    return None
