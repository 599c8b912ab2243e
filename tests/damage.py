"""Ways to damage an input file, shared by the tests and ``benchmarks/fuzz_inputs.py``.

Each helper reads ``src`` and writes the damaged copy to ``dst`` (``src`` itself when ``dst`` is
None), so a raw test file can be spoilt in place or copied. Offsets into the data section of a
C3D file come from its header (``c3d_data_offset``); text exports are damaged as bytes. A new
format (e.g. bags) only needs its own ``*_data_offset`` to get the same treatment.
"""

from __future__ import annotations

import random
import struct
from pathlib import Path

import numpy as np

C3D_BLOCK = 512


def _out(src: Path, dst: Path | None) -> Path:
    return Path(src) if dst is None else Path(dst)


def truncate(src, keep: int, dst=None) -> Path:
    """Keep the first ``keep`` bytes (negative: drop the last ``-keep`` bytes)."""
    data = Path(src).read_bytes()
    out = _out(src, dst)
    out.write_bytes(data[:keep])
    return out


def overwrite(src, offset: int, payload: bytes, dst=None) -> Path:
    """Replace ``len(payload)`` bytes at ``offset`` (negative: from the end)."""
    data = bytearray(Path(src).read_bytes())
    start = offset if offset >= 0 else len(data) + offset
    data[start:start + len(payload)] = payload
    out = _out(src, dst)
    out.write_bytes(bytes(data))
    return out


def mutate(src, seed: int, n: int = 1, start: int = 0, stop: int | None = None, dst=None) -> tuple[Path, list[int]]:
    """Set ``n`` random bytes in ``[start, stop)`` to random values (reproducible with ``seed``).

    Returns the damaged file and the offsets changed (a byte may be set to its own value).
    """
    data = bytearray(Path(src).read_bytes())
    rng = random.Random(seed)
    stop = len(data) if stop is None else min(stop, len(data))
    offsets = sorted(rng.randrange(start, stop) for _ in range(n)) if stop > start else []
    for i in offsets:
        data[i] = rng.randrange(256)
    out = _out(src, dst)
    out.write_bytes(bytes(data))
    return out, offsets


def _bytes(src) -> bytes:
    return src if isinstance(src, (bytes, bytearray)) else Path(src).read_bytes()


def c3d_data_offset(src) -> int:
    """Byte offset of the data section of a C3D file or its bytes (header word 9: its 512-byte block, from 1)."""
    data = _bytes(src)
    param = (data[0] - 1) * C3D_BLOCK
    order = ">" if len(data) > param + 3 and data[param + 3] == 86 else "<"  # processor type 86: MIPS (big-endian)
    block, = struct.unpack(order + "H", data[16:18])
    return (block - 1) * C3D_BLOCK


def c3d_layout(src) -> dict[str, int | bool]:
    """Header facts of a C3D file or its bytes (Intel or DEC byte order): points, analog words per frame, frames,
    float data."""
    data = _bytes(src)
    points, analogs, first, last = struct.unpack("<4H", data[2:10])
    proc = data[(data[0] - 1) * C3D_BLOCK + 3]
    is_float = bool(data[{84: 15, 85: 13, 86: 12}.get(proc, 15)] & 0x80)  # sign bit of the header's scale factor
    return {"points": points, "analogs": analogs, "frames": last - first + 1, "float": is_float}


def c3d_value_offset(src, frame: int, point: int, axis: int) -> int:
    """Byte offset of one coordinate (``axis`` 0..2) of ``point`` at ``frame`` in the data section of a
    C3D file (4-byte floats or 2-byte integers, points then analog words in each frame)."""
    lay = c3d_layout(src)
    size = 4 if lay["float"] else 2
    return c3d_data_offset(src) + (frame * (4 * lay["points"] + lay["analogs"]) + point * 4 + axis) * size


def c3d_set_float(src, frame: int, point: int, axis: int, value: float, dst=None) -> Path:
    """Write ``value`` (float32, Intel byte order) as one coordinate of a point in a float C3D."""
    return overwrite(src, c3d_value_offset(src, frame, point, axis), struct.pack("<f", value), dst)


def c3d_mutate_data(src, seed: int, n: int = 1, dst=None) -> tuple[Path, list[int]]:
    """``mutate`` restricted to the data section of a C3D file."""
    return mutate(src, seed, n, start=c3d_data_offset(src), dst=dst)


def scale_values(values: np.ndarray, factor: float, rows: slice | np.ndarray | None = None) -> np.ndarray:
    """A copy of ``values`` with ``rows`` (all by default) multiplied by ``factor``."""
    out = np.array(values, dtype=float, copy=True)
    out[slice(None) if rows is None else rows] *= factor
    return out


def c3d_parameter_records(src) -> list[dict]:
    """The records of a C3D parameter section: name, group id (negative for a group), offset of the
    record, and the offsets of its structural bytes (name length, group id, next-record pointer,
    type, dimensions, description length), for damage aimed at the structure rather than the values."""
    data = _bytes(src)
    start = (data[0] - 1) * C3D_BLOCK
    section = data[start:start + data[start + 2] * C3D_BLOCK]
    out, pos = [], 4
    while pos + 4 <= len(section):
        nchar, gid = struct.unpack("bb", section[pos:pos + 2])
        if nchar == 0:
            break
        name_end = pos + 2 + abs(nchar)
        offset, = struct.unpack("<h", section[name_end:name_end + 2])
        body = name_end + 2
        places = [pos, pos + 1, name_end, name_end + 1]
        if gid < 0:
            places.append(body)
        elif body + 2 <= len(section):
            dtype, ndims = struct.unpack("bB", section[body:body + 2])
            dims = section[body + 2:body + 2 + ndims]
            places += [body, body + 1, *range(body + 2, body + 2 + len(dims)), body + 2 + ndims + abs(dtype) * int(np.prod(list(dims)))]
        out.append({"name": section[pos + 2:name_end].decode("latin-1"), "gid": gid, "offset": start + pos,
                    "structure": [start + p for p in places if start + p < len(data)]})
        if offset <= 0:
            break
        pos = name_end + offset
    return out
