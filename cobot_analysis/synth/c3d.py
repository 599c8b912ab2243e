"""Writing synthetic recordings as C3D files with ezc3d, the way Vicon exports them.

Points in millimetres (``POINT:UNITS = mm``), float storage, ``POINT:RATE`` in Hz. An occluded
sample is NaN with residual -1 (the C3D convention for an invalid point, which ezc3d and Vicon
use; readers then return NaN). ezc3d writes no date or time, so the same data give byte-identical
files.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np


def write_c3d(path: str | os.PathLike, labels: Sequence[str], xyz: np.ndarray, rate: float,
              missing: np.ndarray | None = None) -> None:
    """Write markers ``xyz`` (frames, markers, 3) in metres to ``path`` (C3D, mm).

    ``missing`` (frames, markers) marks occluded samples (written as NaN, residual -1); NaN in
    ``xyz`` count as missing too.
    """
    import ezc3d

    xyz = np.asarray(xyz, dtype=float)
    n_frames, n_markers, _ = xyz.shape
    gone = np.isnan(xyz).any(axis=-1)
    if missing is not None:
        gone |= missing
    points = np.ones((4, n_markers, n_frames))
    points[:3] = np.transpose(xyz * 1000.0, (2, 1, 0))
    points[:3, gone.T] = np.nan
    residuals = np.where(gone.T, -1.0, 0.0)[None]
    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [float(rate)]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(labels)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    c3d["data"]["points"] = points
    c3d["data"]["meta_points"] = {"residuals": residuals,
                                  "camera_masks": np.zeros((7, n_markers, n_frames), dtype=bool)}
    c3d.write(str(path))
