"""Text exports of marker trajectories: Vicon Nexus CSV ("Trajectories") and Qualisys TSV.

Vicon Nexus CSV export (the "Trajectories" section; other sections such as "Devices" are
skipped; a byte-order mark at the start of either export is ignored)::

    Trajectories
    200                                   <- rate (Hz)
    ,,Subj:LASI,,,Subj:RASI,,,            <- one label per marker, over its X, Y, Z columns
    Frame,Sub Frame,X,Y,Z,X,Y,Z
    ,,mm,mm,mm,mm,mm,mm                   <- units (without this row: refused unless --units states them)
    1,0,12.3,45.6,950.1,...               <- empty cells where the marker is occluded

Qualisys QTM TSV export (3D data)::

    NO_OF_FRAMES  1500
    FREQUENCY     200
    MARKER_NAMES  LASI  RASI ...
    Frame  Time  LASI X  LASI Y  LASI Z ...  <- header row (absent in old exports)
    1      0.000 ...                         <- occluded: empty, NaN/null, or 0 0 0 (QTM's filler)

QTM exports are in millimetres (the file does not state it). Frames must be strictly increasing
(so must Time in QTM files), and the file must end with an end of line (a truncated file would
end in a cut number); missing frame numbers are kept as occluded frames (up to as many as
the rows: a larger jump is a damaged frame number); no line may be longer than 1 MiB
(``MAX_LINE_BYTES``, checked before reading) and no data row wider than its header. Labels and
columns must line up (a damaged label row would give one marker's data another's name): Vicon
labels only above X columns followed by Y and Z; QTM MARKER_NAMES as many as NO_OF_MARKERS and
as the header row's "<label> X/Y/Z" columns, and no data beyond them. Both readers
return ``RawMarkers`` (labels, xyz [frames, markers, 3] in metres, rate, source units).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from cobot_analysis.errors import InputError
from cobot_analysis.io.c3d import REMEDY_UNITS, RawMarkers, occlude, to_metres_factor

_REEXPORT = "re-export the trial from the capture software"
#: bytes: longest line of an export read (a Vicon or QTM row of 1,000 markers is about 40 kB).
MAX_LINE_BYTES = 1 << 20
#: cells a data row may hold beyond its header (trailing separators).
EXTRA_CELLS = 4


def check_line_lengths(path: Path, limit: int = MAX_LINE_BYTES, chunk: int = 1 << 20) -> None:
    """Refuse a text export with a line longer than ``limit`` bytes before reading it (a 20 MB line
    took 66 s and then all the memory: a damaged or foreign file, not an export)."""
    run, line = 0, 1
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            parts = block.replace(b"\r", b"\n").split(b"\n")
            lengths = [run + len(parts[0])] + [len(x) for x in parts[1:]]
            longest = max(lengths[:-1], default=0) if len(parts) > 1 else 0
            if max(longest, lengths[-1]) > limit:
                k = next(i for i, n in enumerate(lengths) if n > limit)
                raise InputError(f"line {line + k} is longer than {limit // 1024} kB: not a marker export", path=path,
                                 remedy=_REEXPORT)
            line += len(parts) - 1
            run = lengths[-1]


def _check_width(rows: list[list[str]], header: int, path: Path, first_line: int) -> None:
    """Refuse a data row with more cells than its header allows (before a table of that width is allocated)."""
    wide = next((i for i, r in enumerate(rows) if len(r) > header + EXTRA_CELLS), None)
    if wide is not None:
        raise InputError(f"data row at line {first_line + wide} has {len(rows[wide])} cells, the header {header}", path=path,
                         remedy=_REEXPORT)


def sniff_text_format(head: str) -> str | None:
    """'vicon-csv' or 'qualisys-tsv' from the first lines of a text file, else None."""
    head = head.removeprefix("\ufeff")  # a byte-order mark (Excel, Windows editors) is not part of the first line
    lines = [ln.strip().strip(",").strip() for ln in head.splitlines() if ln.strip().strip(",")]
    if not lines:
        return None
    if lines[0].startswith(("NO_OF_FRAMES", "FILE_VERSION")):
        return "qualisys-tsv"
    if "Trajectories" in lines or lines[0] in ("Devices", "Model Outputs", "Joints", "Segments"):
        return "vicon-csv"
    return None


def _is_number(cell: str) -> bool:
    try:
        float(cell)
        return True
    except ValueError:
        return False


def _complete(text: str, path: Path) -> str:
    """The text of an export whose last line ends: a cut file would end in a cut number."""
    if text and not text.endswith(("\n", "\r")):
        raise InputError("truncated export: its last line is cut off (no end of line)", path=path, remedy=_REEXPORT)
    return text


def _numeric(rows: list[list[str]], path: Path, first_line: int) -> np.ndarray:
    """Rows of text cells -> float array; empty cells, 'NaN' and 'null' become NaN."""
    import pandas as pd

    width = max((len(r) for r in rows), default=0)
    text = "\n".join("\t".join(" ".join(c.split()) for c in r) + "\t" * (width - len(r)) for r in rows)  # no tab or newline inside a cell
    if not text:
        return np.empty((0, 0))
    try:
        df = pd.read_csv(io.StringIO(text), sep="\t", header=None, na_values=["null", "NaN", "nan"], skip_blank_lines=False,
                         quoting=3)  # csv.QUOTE_NONE: a quote is a character
    except (pd.errors.ParserError, ValueError) as exc:
        raise InputError(f"malformed data rows (from line {first_line}: {str(exc).splitlines()[-1][:80]})", path=path,
                         remedy=_REEXPORT) from exc
    for j, col in df.items():
        if not pd.api.types.is_numeric_dtype(col):
            bad = col[pd.to_numeric(col, errors="coerce").isna() & col.notna()].iloc[0]
            remedy = "export with '.' as the decimal separator" if "," in str(bad) else _REEXPORT
            raise InputError(f"non-numeric value {bad!r} in the data rows (from line {first_line})", path=path, remedy=remedy)
    return df.to_numpy(dtype=float)


def _frames_to_grid(frame_numbers: np.ndarray, values: np.ndarray, path: Path, what: str) -> np.ndarray:
    """Place rows at ``frame - first frame``; refuse non-increasing frame numbers (or times)."""
    if len(frame_numbers) == 0:
        raise InputError("empty trial (no data rows)", path=path, remedy="remove the trial from the protocol or re-export it")
    if np.isnan(frame_numbers).any():
        raise InputError(f"missing {what} values", path=path, remedy=_REEXPORT)
    step = np.diff(frame_numbers)
    if (step <= 0).any():
        i = int(np.argmax(step <= 0)) + 1
        kind = "duplicated" if step[i - 1] == 0 else "non-monotonic"
        raise InputError(f"{kind} {what} at data row {i + 1} ({frame_numbers[i - 1]:g} then {frame_numbers[i]:g})",
                         path=path, remedy="remove the repeated or out-of-order rows (or re-export the trial)")
    span = frame_numbers[-1] - frame_numbers[0] + 1
    if span > 2 * len(frame_numbers) + 100:  # more missing frames than rows: a damaged frame number, not gaps
        i = int(np.argmax(step))
        raise InputError(f"{what} jump from {frame_numbers[i]:g} to {frame_numbers[i + 1]:g} at data row {i + 2} "
                         f"({span:.0f} frames for {len(frame_numbers)} rows)", path=path, remedy=_REEXPORT)
    index = np.rint(frame_numbers - frame_numbers[0]).astype(int)
    grid = np.full((index[-1] + 1,) + values.shape[1:], np.nan)
    grid[index] = values
    return grid


def read_vicon_csv(path: str | os.PathLike, units: str | None = None) -> RawMarkers:
    """Read the "Trajectories" section of a Vicon Nexus CSV export (see module docstring)."""
    import csv

    path = Path(path)
    check_line_lengths(path)
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as fh:
        text = _complete(fh.read(), path)
    rows = list(csv.reader(io.StringIO(text, newline=""), quoting=csv.QUOTE_NONE))  # Nexus never quotes: a stray '"' is a character
    starts = [i for i, r in enumerate(rows) if r and r[0].strip() == "Trajectories"]
    if not starts:
        raise InputError("no 'Trajectories' section in this Vicon CSV export", path=path,
                         remedy="export the trajectories from Nexus (File > Export > CSV, Trajectories)")
    s = starts[0]
    if len(rows) < s + 5:
        raise InputError("truncated Vicon CSV export (header of the Trajectories section incomplete)", path=path, remedy=_REEXPORT)
    try:
        rate = float(rows[s + 1][0])
    except (ValueError, IndexError) as exc:
        raise InputError("no sampling rate on the line after 'Trajectories'", path=path, remedy=_REEXPORT) from exc
    names, axes, unit_row = rows[s + 2], rows[s + 3], rows[s + 4]
    if len(axes) < 2 or axes[0].strip() != "Frame":
        raise InputError("the Trajectories section has no 'Frame, Sub Frame, X, Y, Z' header", path=path, remedy=_REEXPORT)
    cols = [j for j, a in enumerate(axes) if a.strip() == "X"]
    labels = [names[j].strip() if j < len(names) else "" for j in cols]
    if not cols or any(not lab for lab in labels):
        raise InputError("marker labels missing above the X, Y, Z columns", path=path, remedy=_REEXPORT)
    stray = [names[j].strip() for j in range(len(names)) if names[j].strip() and j not in set(cols)]
    if stray or any([a.strip() for a in axes[j + 1:j + 3]] != ["Y", "Z"] for j in cols):
        raise InputError(f"labels and X, Y, Z columns do not line up{f' (label {stray[0]!r} above no X column)' if stray else ''}",
                         path=path, remedy=_REEXPORT)
    first_data = s + 5
    if unit_row and _is_number(unit_row[0]):  # the line after the axes is a data row: no units row
        if units is None:
            raise InputError("no units row in the Trajectories section (the line after 'Frame, Sub Frame, X, Y, Z' holds data)",
                             path=path, remedy="re-export with the units row, or state the units with --units mm (or m)")
        unit_row, first_data = [], s + 4
    stated = {unit_row[j].strip() for j in cols if j < len(unit_row) and unit_row[j].strip()}
    if len(stated) > 1:
        raise InputError(f"mixed length units {sorted(stated)}", path=path, remedy=REMEDY_UNITS)
    source_units = (units or (stated.pop() if stated else "mm")).lower()
    body = []
    for r in rows[first_data:]:
        if not any(c.strip() for c in r):
            break  # a blank line ends the section
        body.append(r)
    _check_width(body, len(axes), path, first_data + 1)
    data = _numeric(body, path, first_data + 1)
    if data.size == 0:
        raise InputError("empty trial (no data rows)", path=path, remedy="remove the trial from the protocol or re-export it")
    xyz_cols = np.array([[j, j + 1, j + 2] for j in cols])
    if xyz_cols.max() >= data.shape[1]:
        raise InputError("data rows shorter than the header", path=path, remedy=_REEXPORT)
    if axes[1].strip() == "Sub Frame" and np.nan_to_num(data[:, 1]).any():
        raise InputError("sub-frame rows in the Trajectories section", path=path, remedy="export trajectories at the camera rate")
    xyz = _frames_to_grid(data[:, 0], data[:, xyz_cols], path, "frame numbers") * to_metres_factor(source_units, path)
    return RawMarkers(labels, occlude(xyz), rate, source_units)


def read_qualisys_tsv(path: str | os.PathLike, units: str | None = None) -> RawMarkers:
    """Read a Qualisys QTM TSV 3D export (see module docstring); lengths in mm unless ``units``."""
    path = Path(path)
    check_line_lengths(path)
    with open(path, encoding="utf-8-sig", errors="replace") as fh:
        lines = _complete(fh.read(), path).splitlines()
    header: dict[str, list[str]] = {}
    i = 0
    while i < len(lines):
        cells = lines[i].split("\t")
        key = cells[0].strip()
        if not key or not key.replace("_", "").isupper() or key == "Frame":
            break
        header[key] = [c.strip() for c in cells[1:]]
        i += 1
    labels = [c for c in header.get("MARKER_NAMES", []) if c]
    if not labels:
        raise InputError("no MARKER_NAMES line in this Qualisys TSV export", path=path, remedy="export 3D data with marker names from QTM")
    stated = (header.get("NO_OF_MARKERS") or [""])[0]
    if stated and stated != str(len(labels)):
        raise InputError(f"NO_OF_MARKERS is {stated!r} but MARKER_NAMES lists {len(labels)} names", path=path, remedy=_REEXPORT)
    try:
        rate = float(header["FREQUENCY"][0])
    except (KeyError, IndexError, ValueError) as exc:
        raise InputError("no FREQUENCY line in this Qualisys TSV export", path=path, remedy=_REEXPORT) from exc
    columns: list[str] = []  # the "Frame  Time  LASI X ..." header row, when present
    if i < len(lines) and lines[i].split("\t")[0].strip() == "Frame":
        columns = [c.strip() for c in lines[i].split("\t")]
        i += 1
    rows = [ln.split("\t") for ln in lines[i:] if ln.strip()]
    _check_width(rows, len(columns) if columns else 2 + 3 * len(labels), path, i + 1)
    data = _numeric(rows, path, i + 1)
    if data.size == 0:
        raise InputError("empty trial (no data rows)", path=path, remedy="remove the trial from the protocol or re-export it")
    n = len(labels)
    if columns:
        lead = next((j for j, c in enumerate(columns) if c.endswith(" X")), len(columns))
        named = [c for c in columns[lead:] if c]
        if named != [f"{lab} {a}" for lab in labels for a in "XYZ"]:
            raise InputError("the column header row does not match MARKER_NAMES", path=path, remedy=_REEXPORT)
    else:  # no header row: Frame and Time columns present when the width says so
        lead = 2 if data.shape[1] == 3 * n + 2 else 0
        columns = ["Frame", "Time"] if lead == 2 else []
    extra = data[:, lead + 3 * n:]
    if data.shape[1] < lead + 3 * n or not np.isnan(extra).all():
        raise InputError(f"data rows have {data.shape[1] if extra.size == 0 else 'more'} columns, {lead + 3 * n} expected for "
                         f"{n} markers", path=path, remedy=_REEXPORT)
    xyz = data[:, lead:lead + 3 * n].reshape(len(data), n, 3)
    xyz[np.all(xyz == 0.0, axis=2)] = np.nan  # QTM writes 0 0 0 for an unlabelled/occluded marker
    if "Time" in columns[:lead]:
        _frames_to_grid(data[:, columns.index("Time")], data[:, :1], path, "Time values")
    frame = data[:, 0] if "Frame" in columns[:lead] else np.arange(len(data), dtype=float)
    source_units = (units or "mm").lower()
    xyz = _frames_to_grid(frame, xyz, path, "frame numbers") * to_metres_factor(source_units, path)
    return RawMarkers(labels, occlude(xyz), rate, source_units)
