"""C3D marker files: header and parameter checks, then the point data read with numpy (ezc3d
for the files outside what that reader handles).

ezc3d reads a truncated C3D silently (fewer frames), and a corrupt parameter section made it
segfault or hang in our tests, so the file is checked here first (C3D User Guide):
- header: byte 1 is the key 0x50; byte 0 is the 512-byte block number of the parameter section;
  words 2-5 give the number of points, analog values per frame and the first and last frame;
  words 7-8 the scale factor (negative = float data); word 9 the data start block. The file must
  hold ``frames x (points x 4 + analogs) x (4 bytes if float else 2)`` bytes from the data start,
  and not whole frames more beyond one 512-byte block of padding (a damaged frame range or point
  count would otherwise drop data silently).
- parameter section: every group/parameter record is walked; pointers, data and descriptions
  must stay inside their record, character parameters have dimensions (ezc3d crashed on a
  character scalar), a description is at most 127 characters (ezc3d reads its length
  as a signed byte and hung or crashed on longer ones), no parameter is given twice in a group,
  POINT:SCALE and POINT:RATE hold a value, POINT:USED must equal the header's point count,
  ANALOG:SCALE and ANALOG:OFFSET must hold a value per analog channel (ezc3d crashed or hung
  without them), ROTATION:RATIO and ROTATION:USED are not negative (ezc3d crashed). Names may
  hold any bytes, as ezc3d reads them (Vicon Nexus writes names with spaces, e.g.
  PROCESSING:Marker Diameter), except in the POINT and ANALOG groups, which must be named in
  upper case without padding (``_check_names``: ezc3d looks them up by exact name and crashed).
- consistency (``_check_consistency``): the header's analog values per frame equal ANALOG:USED x
  ANALOG:RATE / POINT:RATE, its frame range POINT:FRAMES (a negative one read as the unsigned
  16-bit count it is), its data start POINT:DATA_START and its scale's sign POINT:SCALE's (else
  the data would be read with a wrong stride); POINT:RATE is read as the file declares it (ezc3d
  replaces 0 by the header's rate and fails on NaN): a NaN is refused here, 0 and negative rates
  by ``plausibility.trial_rate``.
The byte order follows the processor type stored in the parameter section (84 Intel, 85 DEC,
86 MIPS big-endian).

Point data: ``_numpy_points`` reads them from the bytes when the file is of the common kind
(Intel, one POINT:SCALE, a parameter section laid out record after record...), giving exactly
what ezc3d gives (tests/test_c3d_reader.py); ezc3d reads the others (``_ezc3d_points``).
Missing points: NaN where the point's residual is negative (how Vicon and ezc3d mark an occluded
marker); any NaN coordinate makes the whole sample occluded (a NaN stored with a valid residual
is counted in the notes). Labels are text as ezc3d decodes them; bytes that are not UTF-8 become
U+FFFD.
"""

from __future__ import annotations

import math
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
    notes: tuple[str, ...] = ()  # what the reader left out, for the import report


#: POINT groups that list model outputs stored as points (BTK's point types), with their unit
#: parameter; a file's POINT:TYPE_GROUPS (Vicon: ANGLES, ANGLE, POWERS, POWER, ...) adds its own.
OUTPUT_GROUPS = {"ANGLES": "ANGLE_UNITS", "FORCES": "FORCE_UNITS", "MOMENTS": "MOMENT_UNITS", "POWERS": "POWER_UNITS",
                 "SCALARS": "SCALAR_UNITS", "REACTIONS": "REACTION_UNITS"}


def is_c3d(head: bytes) -> bool:
    """True if the first bytes look like a C3D header (parameter block >= 2, key byte 0x50)."""
    return len(head) >= 2 and head[1] == C3D_KEY and head[0] >= 2


def to_metres_factor(units: str, path: str | os.PathLike) -> float:
    """Scale factor from a length unit name ('mm', 'cm', 'm', any case) to metres."""
    key = units.strip().lower()
    if key not in _TO_METRES:
        raise InputError(f"unknown length unit {units!r}", path=path, remedy=REMEDY_UNITS)
    return _TO_METRES[key]


def check_c3d_header(path: str | os.PathLike) -> dict[str, int | bool | float | None]:
    """Validate the header of a C3D file without ezc3d; return its point and frame counts, its
    declared POINT:RATE (``rate``, None when not an IEEE float) and the header's frame rate
    (``header_rate``).

    Raises ``InputError`` for a file that is not C3D, is truncated, or has an inconsistent header.
    """
    return _check(Path(path))[0]


class _Layout(NamedTuple):
    """What the checks read of a C3D file, for ``_numpy_points``."""

    head: bytes  # the 512-byte header
    section: bytes  # the parameter section
    records: list  # parameter records (``_walk_parameters``)
    proc: int  # processor type (84 Intel, 85 DEC, 86 MIPS)
    n_points: int
    n_analog: int  # analog values per frame (header word 3)
    first: int  # header words 4-5 as stored
    last: int
    data_start: int  # 512-byte block of the data section, from 1
    params: dict  # (GROUP, NAME) -> (number of values, first value)


def _check(path: Path) -> tuple[dict[str, int | bool | float | None], _Layout]:
    """``check_c3d_header``, also returning what was read (``_Layout``)."""
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
    if size <= (data_start - 1) * BLOCK and frame_bytes:
        raise InputError(f"empty trial (the C3D file holds no frames: it ends where its data section starts, although "
                         f"its header announces {n_frames})", path=path, remedy="remove the trial from the protocol or re-export it")
    if last < 65535 and size < expected:  # 16-bit frame counts overflow on long trials
        raise InputError(f"truncated C3D file ({size} bytes, the header announces {expected})", path=path,
                         remedy="re-export the trial from the capture software")
    if last < 65535 and size - expected > BLOCK and size - expected >= frame_bytes > 0:  # writers pad up to a block
        raise InputError(f"corrupt C3D header: the file holds {size - expected} bytes ({(size - expected) // frame_bytes} frames' "
                         f"worth) beyond the {n_frames} frames its header announces (frames {first}-{last})", path=path,
                         remedy="re-export the trial from the capture software")
    with open(path, "rb") as fh:
        fh.seek(param_start)
        section = fh.read(pblock[2] * BLOCK)
    records: list = []
    params = _walk_parameters(section, order, path, ieee=proc != 85, records=records)
    _check_names(records, path)
    used = params.get(("POINT", "USED"), (1, None))[1]
    if used is not None and used != n_points:
        raise InputError(f"corrupt C3D file (header announces {n_points} points, POINT:USED {used})", path=path,
                         remedy="re-export the trial from the capture software")
    for name in ("SCALE", "RATE"):
        if params.get(("POINT", name), (1, None))[0] < 1:
            raise InputError(f"corrupt C3D parameter section (POINT:{name} holds no value)", path=path,
                             remedy="re-export the trial from the capture software")
    _check_consistency(params, n_points, n_analog, first, last, data_start, is_float, path)
    for name in ("RATIO", "USED"):  # rotations per frame, rotation channels: ezc3d crashed (bad_alloc, segfault) on negatives
        count = params.get(("ROTATION", name), (0, None))[1]
        if count is not None and count < 0:
            raise InputError(f"corrupt C3D parameter section (ROTATION:{name} is {count:g})", path=path,
                             remedy="re-export the trial from the capture software")
    channels = params.get(("ANALOG", "USED"), (1, None))[1]
    for name in ("SCALE", "OFFSET") if n_analog and channels and channels > 0 else ():  # ezc3d crashed without them
        count = params.get(("ANALOG", name), (0, None))[0]
        if count < channels:
            raise InputError(f"corrupt C3D parameter section (ANALOG:{name} holds {count} values for {channels} analog channels)",
                             path=path, remedy="re-export the trial from the capture software")
    header_rate = struct.unpack(order + "f", head[20:24])[0] if proc != 85 else None
    rate = params.get(("POINT", "RATE"), (1, None))[1]
    if rate is not None and np.isnan(rate):  # ezc3d fails on it (vector::_M_default_append): nothing to read
        raise InputError(f"invalid sampling rate: POINT:RATE is NaN (the header says {header_rate:g} Hz)", path=path,
                         remedy="re-export the trial from the capture software")
    info = {"points": n_points, "frames": n_frames, "float": is_float, "rate": rate, "header_rate": header_rate}
    return info, _Layout(head, section, records, proc, n_points, n_analog, first, last, data_start, params)


def _check_consistency(params: dict, n_points: int, n_analog: int, first: int, last: int, data_start: int, is_float: bool,
                       path: Path) -> None:
    """The header words against the parameter section (C3D User Guide): the analog values per frame
    are ANALOG:USED x (ANALOG:RATE / POINT:RATE), the frame count is POINT:FRAMES, the data start
    block is POINT:DATA_START and the data are floats when POINT:SCALE is negative. A mismatch
    means one of the two is damaged: the data would be read with a wrong stride (positions of one
    marker read as another's, y = 0 everywhere), so the file is refused here, before the
    plausibility checks could blame the units."""
    def value(group: str, name: str):
        return params.get((group, name), (0, None))[1]

    def refuse(what: str) -> InputError:
        return InputError(f"inconsistent C3D file: {what}", path=path, remedy="re-export the trial from the capture software")

    channels = value("ANALOG", "USED")
    if n_analog and not channels:
        raise refuse(f"the header announces {n_analog} analog values per frame but ANALOG:USED is {channels or 0} (or absent): "
                     f"the marker data would be read with a wrong stride")
    if channels and channels > 0 and n_analog % channels:
        raise refuse(f"the header announces {n_analog} analog values per frame, not a multiple of ANALOG:USED {channels}")
    point_rate, analog_rate = value("POINT", "RATE"), value("ANALOG", "RATE")
    if channels and channels > 0 and n_analog and point_rate and analog_rate and point_rate > 0 and analog_rate > 0:
        per_frame = analog_rate / point_rate
        if abs(n_analog / channels - per_frame) > 1e-3 * per_frame:
            raise refuse(f"the header announces {n_analog} analog values per frame for {channels} channels "
                         f"({n_analog // channels} samples per frame), ANALOG:RATE / POINT:RATE is {analog_rate:g} / {point_rate:g}")
    frames = value("POINT", "FRAMES")
    if frames is not None and frames < 0 and frames == int(frames):  # a 16-bit count > 32767 read as signed
        frames += 65536
    if frames is not None and last < 65535 and 0 < frames < 65535 and frames != last - first + 1:  # larger counts overflow
        raise refuse(f"the header announces frames {first}-{last} ({last - first + 1}), POINT:FRAMES {frames:g}")
    start = value("POINT", "DATA_START")
    if start is not None and start > 0 and start != data_start:
        raise refuse(f"the header's data start block is {data_start}, POINT:DATA_START {start:g}")
    scale = value("POINT", "SCALE")
    if scale is not None and scale != 0 and n_points and (scale < 0) != is_float:
        raise refuse(f"the header's scale factor says {'float' if is_float else 'integer'} data, POINT:SCALE {scale:g} "
                     f"says {'float' if scale < 0 else 'integer'}")


def _check_names(records: list, path: Path) -> None:
    """The POINT and ANALOG groups and their parameters are named as the C3D User Guide writes them
    (upper case, no padding): ezc3d looks them up by exact name, so a parameter named ``scale``
    (checked here as SCALE) is absent for it, and it crashed on such files (ANALOG:scale, offset)."""
    groups = {-gid: name for gid, name, *_ in records if gid < 0}
    for gid, name, *_ in records:
        group = groups.get(-gid if gid < 0 else gid, b"")
        if group.decode("latin-1").strip().upper() in ("POINT", "ANALOG") and not _canonical(name):
            what = "group" if gid < 0 else f"parameter of group {group.decode('latin-1').strip().upper()}"
            raise InputError(f"corrupt C3D parameter section ({what} named {name.decode('latin-1')!r}, not in upper case "
                             f"without padding as the C3D standard writes it)", path=path,
                             remedy="re-export the trial from the capture software")


def _walk_parameters(section: bytes, order: str, path: Path, ieee: bool = True,
                     records: list | None = None) -> dict[tuple[str, str], tuple[int, float | None]]:
    """Walk the parameter records (C3D User Guide, "The parameter section") and check that each
    one lies inside the section, so that ezc3d never follows a corrupt pointer. Returns, keyed
    (GROUP, NAME), the number of values of each parameter and its first value when it is a number
    (16-bit integer, or a float when ``ieee``: DEC floats are another format). ``records`` (when
    given) receives each record as ``(group id, raw name, type, dimensions, data offset, end,
    next)``: ``end`` is where its description ends, ``next`` where its pointer leads (0: last)."""
    def corrupt(what: str) -> InputError:
        return InputError(f"corrupt C3D parameter section ({what})", path=path, remedy="re-export the trial from the capture software")

    groups: dict[int, str] = {}
    found: list[tuple[int, str, int, int | None]] = []  # group id, name, number of values, integer scalar
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
        name = section[pos + 2:name_end].decode("latin-1")  # any bytes, as ezc3d reads them (Vicon: "Marker Diameter")
        offset, = struct.unpack(order + "h", section[name_end:name_end + 2])
        body = name_end + 2
        nxt = name_end + offset
        if offset != 0 and not body < nxt <= end:
            raise corrupt("bad record pointer")
        limit = nxt if offset != 0 else end
        if gid < 0:
            groups[-gid] = name.upper()
            desc = body
        else:
            if body + 2 > limit:
                raise corrupt("truncated parameter record")
            dtype, ndims = struct.unpack("bB", section[body:body + 2])
            if dtype not in (-1, 1, 2, 4) or ndims > 7 or body + 2 + ndims > limit or (dtype == -1 and ndims == 0):
                raise corrupt(f"bad parameter type of {name.strip()!r}")  # ezc3d crashed on a character scalar
            dims = section[body + 2:body + 2 + ndims]
            count = math.prod(dims) if ndims else 1
            data = body + 2 + ndims
            desc = data + abs(dtype) * count
            scalar = None
            if count >= 1 and dtype == 2 and data + 2 <= limit:
                scalar = struct.unpack(order + "h", section[data:data + 2])[0]
            elif count >= 1 and dtype == 4 and ieee and data + 4 <= limit:
                scalar = struct.unpack(order + "f", section[data:data + 4])[0]
            found.append((gid, name.strip().upper(), count, scalar))
        if desc >= limit:
            raise corrupt("parameter data past its record")
        if section[desc] > 127:  # ezc3d reads the length as a signed byte: it hung or crashed on these
            raise corrupt(f"description length {section[desc]} of {name.strip()!r} out of range")
        if desc + 1 + section[desc] > limit:
            raise corrupt(f"description of {name.strip()!r} past its record")
        if records is not None:
            records.append((gid, section[pos + 2:name_end], None if gid < 0 else dtype, None if gid < 0 else bytes(dims),
                            None if gid < 0 else data, desc + 1 + section[desc], nxt if offset != 0 else 0))
        if offset == 0:
            break
        pos = nxt
    keys = [(g, n) for g, n, _, _ in found]
    if len(set(keys)) < len(keys):  # ezc3d crashed when a parameter moved into a group that has one of its name
        g, n = next(k for k in keys if keys.count(k) > 1)
        raise corrupt(f"parameter {groups.get(g, '?')}:{n} given twice")
    return {(groups.get(g, "?"), n): (count, v) for g, n, count, v in found}


def _canonical(name: bytes) -> bool:
    """A record name as ezc3d and our checks both key it: no NUL, no padding, upper case."""
    text = name.decode("latin-1")
    return b"\0" not in name and text == text.strip().upper()


def _decode_value(section: bytes, dtype: int, dims: bytes, at: int):
    """A parameter's value in the form the ezc3d Python reader gives it (Intel byte order): a list
    of strings for characters (one per column of the first dimension, NUL bytes dropped, trailing
    spaces removed, UTF-8 with undecodable bytes kept as surrogates), else an array of the
    dimensions in column-major order (bytes and 16-bit integers signed, floats widened)."""
    shape = tuple(dims) or (1,)
    count = math.prod(shape)
    if dtype == -1:
        width = shape[0]
        if len(dims) == 1:
            items = [section[at:at + width]] if width else []
        else:
            items = [section[at + k * width:at + (k + 1) * width] for k in range(math.prod(shape[1:]))]
        return [b.replace(b"\0", b"").rstrip(b" ").decode("utf-8", "surrogateescape") for b in items]
    kind = {1: "<i1", 2: "<i2", 4: "<f4"}[dtype]
    values = np.frombuffer(section, dtype=kind, count=count, offset=at)
    return (values.astype(float) if dtype == 4 else values.astype(int)).reshape(shape, order="F")


def _numpy_points(path: Path, lay: _Layout) -> tuple[dict, np.ndarray] | None:
    """The POINT parameters (as ``ezc3d`` gives them) and the positions ``[frames, points, 3]`` in
    the file's unit, NaN where the residual is negative, read with numpy; None when the file is
    outside what this reader handles (ezc3d then reads it).

    Data section (C3D User Guide): frame after frame, each point as x, y, z and a fourth value (a
    camera-mask part and a residual part), then the frame's analog values. Float data (POINT:SCALE
    < 0): x, y, z float32; the point is invalid (x, y, z = NaN) when its fourth 4-byte value, read
    as a float32, is negative: what the installed ezc3d (1.7.2) does, measured on random words in
    tests/test_c3d_reader.py (its later sources read a camera word and a signed residual word;
    the two differ only on damaged words, and the test pins the installed behaviour). Integer
    data: x, y, z int16 x SCALE, then a camera-mask byte and a signed residual byte; a negative
    residual byte marks an invalid point.

    Handled: Intel processor type, one POINT:SCALE, fewer than 65535 frames, first frame >= 1, a
    parameter section that ezc3d reads record after record without a gap, canonical POINT and
    ANALOG names, the analog values per frame ezc3d derives from ANALOG:USED x int(ANALOG:RATE /
    POINT:RATE) equal to the header's, the parameters ezc3d needs for the analog data of the
    types it reads them as, and a TRIAL group when MANUFACTURER:COMPANY names Vicon (ezc3d fails
    without it). Everything else (DEC and MIPS files among them) goes to ezc3d, the
    reference this reader is tested against (tests/test_c3d_reader.py)."""
    if lay.proc != 84 or not lay.n_points or lay.first == 0 or lay.last >= 65535 or lay.section[0] != 1:
        return None
    groups: dict[int, bytes] = {}
    for gid, name, _, _, _, end, nxt in lay.records:
        if nxt and end != nxt:  # ezc3d reads the next record where this one ends ("Bad c3d formatting")
            return None
        if gid < 0:
            if -gid in groups or name in groups.values():
                return None
            groups[-gid] = name
    if any(gid >= 0 and gid not in groups for gid, *_ in lay.records):  # ezc3d fails on group 0, fills in unnamed ones
        return None
    canonical = {name.decode("latin-1").strip().upper(): gid for gid, name in groups.items()}
    if "SHADOW" in canonical or canonical.get("POINT") is None:
        return None
    wanted = {g: canonical[g] for g in ("POINT", "ANALOG", "ROTATION") if g in canonical}
    if any(not _canonical(groups[gid]) for gid in wanted.values()):
        return None
    found: dict[str, dict] = {g: {} for g in ("POINT", "ANALOG", "ROTATION")}
    by_gid = {gid: found[g] for g, gid in wanted.items()}
    for gid, name, dtype, dims, at, _, _ in lay.records:
        if gid in by_gid:
            if not _canonical(name):
                return None
            by_gid[gid][name.decode("latin-1")] = {"type": dtype, "value": _decode_value(lay.section, dtype, dims, at)}
    point, analog, rotation = found["POINT"], found["ANALOG"], found["ROTATION"]
    # ezc3d looks up the TRIAL group (and fails without it) when MANUFACTURER:COMPANY names Vicon
    exact = {name: gid for gid, name in groups.items()}
    for gid, name, dtype, dims, at, _, _ in lay.records:
        if gid == exact.get(b"MANUFACTURER") and name == b"COMPANY":
            company = _decode_value(lay.section, dtype, dims, at) if dtype == -1 else None
            if company is None or any("Vicon" in c for c in company):
                if b"TRIAL" not in exact:
                    return None
        if gid == exact.get(b"TRIAL") and name in (b"ACTUAL_START_FIELD", b"ACTUAL_END_FIELD") and dtype != 2:
            return None

    def number(group: dict, name: str, dtype: int):
        """The first value of a parameter of type ``dtype``; None when absent; False when of another type or empty."""
        if name not in group:
            return None
        p = group[name]
        return p["value"].ravel()[0] if p["type"] == dtype and p["value"].size else False

    used, scale, rate = number(point, "USED", 2), number(point, "SCALE", 4), number(point, "RATE", 4)
    head_scale, = struct.unpack("<f", lay.head[12:16])
    if used != lay.n_points or scale is None or scale is False or point["SCALE"]["value"].size != 1 or "SCALE2" in point:
        return None
    if not (np.isfinite(scale) and np.isfinite(head_scale) and scale != 0 and head_scale != 0 and (scale < 0) == (head_scale < 0)):
        return None
    if number(point, "DATA_START", 2) != lay.data_start or rate is None or rate is False or not np.isfinite(rate):
        return None
    n_frames = lay.last - lay.first + 1
    frames = number(point, "FRAMES", 2)
    if frames is False or frames not in (None, 0, n_frames):  # ezc3d takes a differing POINT:FRAMES as the frame count
        return None
    if any(k not in point or point[k]["type"] != -1 for k in ("LABELS", "UNITS")):
        return None
    channels = number(analog, "USED", 2)
    if channels is False or (channels or 0) < 0:
        return None
    channels = channels or 0
    analog_rate = number(analog, "RATE", 4)
    if analog_rate is False or (analog_rate is not None and not (np.isfinite(analog_rate) and 0 <= analog_rate < 1e4 * rate)):
        return None  # ezc3d makes int(ANALOG:RATE / POINT:RATE) subframes per frame, even without channels
    if lay.n_analog or channels:
        if analog_rate is None or not rate >= 1:
            return None
        if int(analog_rate / rate) * channels != lay.n_analog:  # ezc3d's stride (updateHeader)
            return None
        for name, dtype in (("SCALE", 4), ("OFFSET", 2)):
            p = analog.get(name)
            if p is None or p["type"] != dtype or p["value"].size < channels:
                return None
        if number(analog, "GEN_SCALE", 4) is False:
            return None
    if "ROTATION" in wanted:  # ezc3d reads rotations (none here) and fails without these
        if number(rotation, "USED", 2) != 0 or number(rotation, "DATA_START", 2) in (None, False) or \
                (number(rotation, "RATIO", 2) in (None, False) and number(rotation, "RATE", 4) in (None, False)):
            return None
    is_float = scale < 0
    size = 4 if is_float else 2
    width = (4 * lay.n_points + lay.n_analog) * size  # bytes per frame
    raw = np.fromfile(path, dtype=np.uint8, count=n_frames * width, offset=(lay.data_start - 1) * BLOCK)
    if raw.size != n_frames * width:
        return None
    frames = raw.reshape(n_frames, width)[:, :16 * lay.n_points if is_float else 8 * lay.n_points]
    if is_float:
        values = frames.view("<f4").reshape(n_frames, lay.n_points, 4)
        with np.errstate(invalid="ignore"):  # signalling NaNs become quiet NaNs, as in ezc3d
            xyz = values[..., :3].astype(float)
        invalid = values[..., 3] < 0  # the fourth value as a float32 (a NaN or -0.0 is not negative)
    else:
        values = frames.view("<i2").reshape(n_frames, lay.n_points, 4)
        xyz = values[..., :3].astype(float) * float(scale)
        invalid = frames.view("<i1").reshape(n_frames, lay.n_points, 8)[..., 7] < 0
    xyz[invalid] = np.nan
    return point, xyz


def _values(group: dict, name: str) -> list:
    """The values of a parameter as a list (empty when absent or not a list of values)."""
    value = group.get(name, {}).get("value") if isinstance(group.get(name), dict) else None
    try:
        return [v for v in np.asarray(value).ravel()] if value is not None else []
    except (TypeError, ValueError):
        return []


def _text(value) -> str:
    """A C3D string as clean text: ezc3d keeps bytes that are not UTF-8 as surrogates; they become U+FFFD."""
    return str(value).encode("utf-8", "surrogateescape").decode("utf-8", "replace").strip()


def occlude(xyz: np.ndarray) -> np.ndarray:
    """A sample with any NaN coordinate is occluded as a whole (in place; returns ``xyz``)."""
    xyz[np.isnan(xyz).any(axis=2)] = np.nan
    return xyz


def model_outputs(point: dict) -> dict[str, str]:
    """Labels of the POINT channels that are model outputs, not markers -> their group and unit.

    Plug-in-Gait and other models store joint angles (deg), moments (N.mm), powers (W), forces (N)
    and scalars as POINT channels, listed by label in POINT:ANGLES, MOMENTS, POWERS, FORCES,
    SCALARS (and REACTIONS), each with its unit in POINT:<TYPE>_UNITS; POINT:TYPE_GROUPS names
    further groups and their unit key in pairs (group, type).
    """
    groups = dict(OUTPUT_GROUPS)
    pairs = [_text(v).upper() for v in _values(point, "TYPE_GROUPS")]
    for group, kind in zip(pairs[0::2], pairs[1::2]):
        groups.setdefault(group, f"{kind}_UNITS")
    out: dict[str, str] = {}
    for group, unit_key in groups.items():
        units = [_text(u) for u in _values(point, unit_key)]
        for label in _values(point, group):
            label = _text(label)
            if label:
                out.setdefault(label, f"{group.lower()}{' (' + units[0] + ')' if units and units[0] else ''}")
    return out


def _ezc3d_points(path: Path) -> tuple[dict, np.ndarray, float]:
    """The POINT parameters, the positions ``[frames, points, 3]`` in the file's unit (NaN where the
    residual is negative) and the header's frame rate, read by ezc3d."""
    import ezc3d

    try:
        c3d = ezc3d.c3d(str(path), extract_forceplat_data=False)
        point = c3d["parameters"]["POINT"]
        points = c3d["data"]["points"]  # (4, markers, frames)
        residuals = c3d["data"]["meta_points"]["residuals"]
        header_rate = float(c3d["header"]["points"]["frame_rate"])
    except Exception as exc:  # ezc3d raises OSError/RuntimeError/KeyError on bad files
        raise InputError(f"unreadable C3D file ({type(exc).__name__}: {exc})", path=path,
                         remedy="re-export the trial from the capture software") from exc
    if points.shape[2] == 0:
        raise InputError("empty trial (the C3D file holds no frames)", path=path,
                         remedy="remove the trial from the protocol or re-export it")
    positions = points[:3].transpose(2, 1, 0)
    if residuals.size:
        positions[np.transpose(residuals[0] < 0)] = np.nan
    return point, positions, header_rate


def read_c3d(path: str | os.PathLike, units: str | None = None, numpy: bool = True) -> RawMarkers:
    """Read the markers of a C3D file: ``(labels, xyz [frames, markers, 3] in m, rate, units, notes)``.

    ``units`` overrides the file's ``POINT:UNITS`` (default when the file states none: mm, the
    Vicon default). Model outputs stored as points (``model_outputs``) are left out and counted in
    ``notes``: they are angles, moments, powers or forces, not positions. After the checks
    (``check_c3d_header``) the point data are read with numpy (``_numpy_points``) when the file is
    within what that reader handles, else by ezc3d (``numpy=False``: always ezc3d, the reference).
    """
    path = Path(path)
    head, layout = _check(path)
    fast = _numpy_points(path, layout) if numpy else None
    if fast is not None:
        point, positions = fast
        header_rate = head["header_rate"]
    else:
        point, positions, header_rate = _ezc3d_points(path)
    labels = [_text(s) for s in _values(point, "LABELS")]
    # Long label lists continue in LABELS2, LABELS3, ... (C3D convention for > 255 labels).
    for k in range(2, 100):
        if f"LABELS{k}" not in point:
            break
        labels += [_text(s) for s in _values(point, f"LABELS{k}")]
    n_points = positions.shape[1]
    labels = labels[:n_points] + [f"*{i}" for i in range(len(labels), n_points)]  # unlabelled: Vicon's "*N"
    stated = _text((_values(point, "UNITS") or [""])[0])
    source_units = (units or stated or "mm").lower()
    factor = to_metres_factor(source_units, path)
    outputs = model_outputs(point)
    keep = [j for j, lab in enumerate(labels) if lab not in outputs]
    notes = ()
    if len(keep) < len(labels):
        kinds = sorted({outputs[labels[j]] for j in range(len(labels)) if labels[j] in outputs})
        notes = (f"{path.name}: {len(labels) - len(keep)} model outputs stored as POINT channels left out "
                 f"(not markers: {', '.join(kinds)})",)
    xyz = (positions if len(keep) == n_points else positions[:, keep]) * factor  # [frames, markers, 3]
    nan = np.isnan(xyz)
    occluded = nan.any(axis=2)
    partial = occluded & ~nan.all(axis=2)
    if partial.any():
        notes += (f"{path.name}: {int(partial.sum())} samples with a NaN coordinate counted as occluded",)
    xyz[occluded] = np.nan  # a sample with any NaN coordinate is occluded as a whole (``occlude``)
    # POINT:RATE as the file declares it (ezc3d replaces a zero one by the header's rate silently).
    rate = head["rate"] if head["rate"] is not None else float((_values(point, "RATE") or [header_rate])[0])
    if head["header_rate"] is not None and rate != head["header_rate"] and rate > 0 and head["header_rate"] > 0:
        notes += (f"{path.name}: POINT:RATE {rate:g} Hz differs from the header's frame rate {head['header_rate']:g} Hz; "
                  f"using POINT:RATE",)
    return RawMarkers([labels[j] for j in keep], xyz, rate, source_units, notes)
