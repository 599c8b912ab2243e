"""C3D marker files: header check, then ezc3d.

ezc3d reads a truncated C3D silently (fewer frames), and a corrupt parameter section made it
segfault or hang in our tests, so the file is checked here first (C3D User Guide):
- header: byte 1 is the key 0x50; byte 0 is the 512-byte block number of the parameter section;
  words 2-5 give the number of points, analog values per frame and the first and last frame;
  words 7-8 the scale factor (negative = float data); word 9 the data start block. The file must
  hold ``frames x (points x 4 + analogs) x (4 bytes if float else 2)`` bytes from the data start.
- parameter section: every group/parameter record is walked; names must be text, pointers and
  data must stay inside the section, and POINT:USED must equal the header's point count.
The byte order follows the processor type stored in the parameter section (84 Intel, 85 DEC,
86 MIPS big-endian).

Missing points: ezc3d returns NaN where the residual word is negative (how Vicon and ezc3d mark
an occluded marker); any NaN coordinate makes the whole sample occluded.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import NamedTuple

import numpy as np

from cobot_analysis.errors import InputError

C3D_KEY = 0x50
BLOCK = 512
_PROCESSORS = {84: "<", 85: "<", 86: ">"}  # Intel, DEC (little-endian integers), MIPS
_TO_METRES = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
REMEDY_UNITS = "pass --units mm or --units m to state the unit of the raw file"


class RawMarkers(NamedTuple):
    """Marker positions of one recording as read from its file."""

    labels: list[str]
    xyz: np.ndarray  # [frames, markers, 3], metres, NaN where occluded
    rate: float  # Hz
    units: str  # length unit of the raw file ("mm" or "m")


def is_c3d(head: bytes) -> bool:
    """True if the first bytes look like a C3D header (parameter block >= 2, key byte 0x50)."""
    return len(head) >= 2 and head[1] == C3D_KEY and head[0] >= 2


def to_metres_factor(units: str, path: str | os.PathLike) -> float:
    """Scale factor from a length unit name ('mm', 'cm', 'm', any case) to metres."""
    key = units.strip().lower()
    if key not in _TO_METRES:
        raise InputError(f"unknown length unit {units!r}", path=path, remedy=REMEDY_UNITS)
    return _TO_METRES[key]


def check_c3d_header(path: str | os.PathLike) -> dict[str, int | bool]:
    """Validate the header of a C3D file without ezc3d; return its point and frame counts.

    Raises ``InputError`` for a file that is not C3D, is truncated, or has an inconsistent header.
    """
    path = Path(path)
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(BLOCK)
        if len(head) < BLOCK or not is_c3d(head):
            raise InputError("not a C3D file (no C3D header: byte 2 must be 0x50)", path=path,
                             remedy="check the file is a C3D export, or name it after its real format")
        param_start = (head[0] - 1) * BLOCK
        if size < param_start + BLOCK:
            raise InputError("truncated C3D file (parameter section missing)", path=path,
                             remedy="re-export the trial from the capture software")
        fh.seek(param_start)
        pblock = fh.read(4)
    order = _PROCESSORS.get(pblock[3])
    if order is None:
        raise InputError(f"corrupt C3D parameter section (processor type {pblock[3]})", path=path,
                         remedy="re-export the trial from the capture software")
    proc = pblock[3]
    n_points, n_analog, first, last = struct.unpack(order + "4H", head[2:10])
    data_start, = struct.unpack(order + "H", head[16:18])
    if data_start < head[0] + pblock[2] or last < first - 1:
        raise InputError("corrupt C3D header (data block or frame range inconsistent)", path=path,
                         remedy="re-export the trial from the capture software")
    if last == first - 1:
        raise InputError("empty trial (the C3D file holds no frames)", path=path,
                         remedy="remove the trial from the protocol or re-export it")
    n_frames = last - first + 1
    # Float data when the scale factor (words 7-8) is negative: read its sign bit only (DEC
    # floats are not IEEE but keep the sign in bit 15 of their first word).
    is_float = bool(head[{84: 15, 85: 13, 86: 12}[proc]] & 0x80)
    frame_bytes = (4 * n_points + n_analog) * (4 if is_float else 2)
    expected = (data_start - 1) * BLOCK + n_frames * frame_bytes
    if last < 65535 and size < expected:  # 16-bit frame counts overflow on long trials
        raise InputError(f"truncated C3D file ({size} bytes, the header announces {expected})", path=path,
                         remedy="re-export the trial from the capture software")
    with open(path, "rb") as fh:
        fh.seek(param_start)
        section = fh.read(pblock[2] * BLOCK)
    params = _walk_parameters(section, order, path)
    used = params.get(("POINT", "USED"))
    if used is not None and used != n_points:
        raise InputError(f"corrupt C3D file (header announces {n_points} points, POINT:USED {used})", path=path,
                         remedy="re-export the trial from the capture software")
    return {"points": n_points, "frames": n_frames, "float": is_float}


def _walk_parameters(section: bytes, order: str, path: Path) -> dict[tuple[str, str], int]:
    """Walk the parameter records (C3D User Guide, "The parameter section") and check that each
    one lies inside the section, so that ezc3d never follows a corrupt pointer. Returns the
    integer scalars found, keyed (GROUP, NAME)."""
    def corrupt(what: str) -> InputError:
        return InputError(f"corrupt C3D parameter section ({what})", path=path, remedy="re-export the trial from the capture software")

    groups: dict[int, str] = {}
    scalars: list[tuple[int, str, int]] = []
    pos, end = 4, len(section)
    for _ in range(100_000):
        if pos + 2 > end:
            raise corrupt("runs past its end")
        nchar, gid = struct.unpack("bb", section[pos:pos + 2])
        if nchar == 0:
            break
        nchar = abs(nchar)
        name_end = pos + 2 + nchar
        if name_end + 2 > end:
            raise corrupt("record past its end")
        name = section[pos + 2:name_end]
        if not all(32 < c < 127 for c in name):
            raise corrupt("non-text parameter name")
        offset, = struct.unpack(order + "h", section[name_end:name_end + 2])
        body = name_end + 2
        nxt = name_end + offset
        if offset != 0 and not body < nxt <= end:
            raise corrupt("bad record pointer")
        limit = nxt if offset != 0 else end
        if gid < 0:
            groups[-gid] = name.decode().upper()
            size = 1 + (section[body] if body < end else 0)
        else:
            if body + 2 > limit:
                raise corrupt("truncated parameter record")
            dtype, ndims = struct.unpack("bB", section[body:body + 2])
            if dtype not in (-1, 1, 2, 4) or ndims > 7 or body + 2 + ndims > limit:
                raise corrupt(f"bad parameter type of {name.decode()}")
            dims = section[body + 2:body + 2 + ndims]
            count = int(np.prod(list(dims))) if ndims else 1
            data = body + 2 + ndims
            size = 2 + ndims + abs(dtype) * count + 1
            if ndims == 0 and dtype == 2 and data + 2 <= limit:
                scalars.append((gid, name.decode().upper(), struct.unpack(order + "h", section[data:data + 2])[0]))
        if body + size > limit:
            raise corrupt("parameter data past its record")
        if offset == 0:
            break
        pos = nxt
    return {(groups.get(g, "?"), n): v for g, n, v in scalars}


def read_c3d(path: str | os.PathLike, units: str | None = None) -> RawMarkers:
    """Read the markers of a C3D file: ``(labels, xyz [frames, markers, 3] in m, rate, units)``.

    ``units`` overrides the file's ``POINT:UNITS`` (default when the file states none: mm, the
    Vicon default).
    """
    import ezc3d

    path = Path(path)
    check_c3d_header(path)
    try:
        c3d = ezc3d.c3d(str(path), extract_forceplat_data=False)
    except Exception as exc:  # ezc3d raises OSError/RuntimeError on bad files
        raise InputError(f"unreadable C3D file ({exc})", path=path, remedy="re-export the trial from the capture software") from exc
    point = c3d["parameters"]["POINT"]
    labels = [str(s).strip() for s in point["LABELS"]["value"]]
    # Long label lists continue in LABELS2, LABELS3, ... (C3D convention for > 255 labels).
    for k in range(2, 100):
        more = point.get(f"LABELS{k}")
        if more is None:
            break
        labels += [str(s).strip() for s in more["value"]]
    points = c3d["data"]["points"]  # (4, markers, frames)
    labels = labels[: points.shape[1]] + [f"*{i}" for i in range(len(labels), points.shape[1])]  # unlabelled: Vicon's "*N"
    stated = (point.get("UNITS", {}).get("value") or [""])[0].strip()
    source_units = (units or stated or "mm").lower()
    factor = to_metres_factor(source_units, path)
    xyz = points[:3].transpose(2, 1, 0) * factor  # [frames, markers, 3], one copy
    residuals = c3d["data"]["meta_points"]["residuals"]
    if residuals.size:
        xyz[np.transpose(residuals[0] < 0)] = np.nan
    rate = float(point["RATE"]["value"][0]) if len(point["RATE"]["value"]) else float(c3d["header"]["points"]["frame_rate"])
    return RawMarkers(labels, xyz, rate, source_units)
