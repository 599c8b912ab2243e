"""Raw marker import: protocol -> tidy long markers (``markers.parquet``) + the trials table (``trials.parquet``).

Each trial file named by the protocol is read by content (C3D header, Vicon CSV "Trajectories"
section or Qualisys TSV header, whatever its name), converted to metres, and its labels are
resolved to (entity, canonical marker) with ``Protocol.resolve_label`` after the marker map
(protocol ``marker_map``, then ``--marker-map FILE``, then ``--map LAB=CANON``; a map key may be
the whole label as the file lists it, ``Daphnee:ASISr``, or the label without its prefix; a label
the file gives twice is addressed by its occurrence, ``sacrum#2``). In a
single-person study a label prefix the protocol does not declare as an entity (Vicon writes the
subject's name: ``Alice:LASI``) is ignored. Only the markers the pipeline uses are kept
(``KEPT_SUBJECT_MARKERS`` per person, ``TABLE_MARKERS`` for the table) unless ``keep_all`` is
set; model outputs stored as C3D points (angles, moments, powers, forces) are never markers.

Pelvis: LASI RASI LPSI RPSI, or LASI RASI SACR when the PSIS are absent or never visible
(``protocol.pelvis_definition``); the markers used are stored per trial (``pelvis_markers`` in
trials.parquet and in the metadata of markers.parquet) and counted in ``import/results.md``.

Checks (each an ``InputError`` naming the file and the remedy): unreadable or truncated file,
empty trial, two labels mapped to one pelvis or table marker, missing pelvis markers of a person
(walker / subject1 / subject2) or table corners (TAB1..TAB3), a required marker never visible,
a sampling rate outside 1 Hz-10 kHz, an invalid declared rate (0, negative, NaN: refused unless the protocol says
``invalid_rate: protocol``; ``plausibility.trial_rate``), a trial file outside the protocol's folder (unless
``allow_outside``), implausible positions (``plausibility.check_positions``:
infinite, outside the lab, jumps, single-sample spikes), and an implausible length scale. Scale check: the median inter-ASIS distance |LASI - RASI| of adults is
0.15-0.40 m (for a table-only recording, |TAB1 - TAB2| is 0.5-2.5 m); a value 1000 times too
large or too small means mm and m were confused. Table corners labelled against the convention the table pose needs
(``check_table_corners``: TAB1 -> TAB2 a long side, TAB1 -> TAB3 a short side) are refused. Pelvis heights are not used: labs differ in
their vertical axis and floor origin, distances do not.

A trial whose file is identical to an earlier trial's (``repeated``: one path listed twice, or a copy) is refused:
one recording would count as two.

Vertical axis (``--up``, ``lab_vertical``): the pipeline's frame is z-up. A lab whose vertical is another axis
(OptiTrack Motive: y) is found from the pelvis itself, whose up direction (forward x left, ``kinematics.pelvis_up``)
leans from the vertical by the pelvic tilt only, and each such trial is rotated to z up (``kinematics.levelling``:
for y up, (x, y, z) -> (z, x, y)); ``--up AXIS`` gives it. Once turned, every pelvis must point up: one pointing
down has its left and right markers swapped, one pointing sideways contradicts the axis given. The axis of each trial is in
the markers file's metadata (``vertical``) and in ``import/results.md``. Every trial is checked before the stage
keeps anything (the markers are written trial by trial into the stage's temporary directory,
``stream_import``, which a refused run discards), and all refused trials are named in one error (or
skipped and listed with ``--skip-bad``).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis import refusals
from cobot_analysis.errors import InputError
from cobot_analysis.io.c3d import RawMarkers, is_c3d, read_c3d
from cobot_analysis.io.plausibility import FAR_REMEDY, LAB_EXTENT, MAX_SPEED, MAX_SPIKE, check_positions, trial_rate
from cobot_analysis.io.protocol import (ENTITIES, KEPT_SUBJECT_MARKERS, PELVIS_DEFINITIONS, PELVIS_MARKERS, SACRUM, TABLE_MARKERS,
                                        Protocol, load_protocol, pelvis_definition, read_yaml)
from cobot_analysis.io.text_exports import read_qualisys_tsv, read_vicon_csv, sniff_text_format
from cobot_analysis.kinematics import UP_AXES, levelling, pelvis_up, table_normal, vertical_axis
from cobot_analysis.refusals import Refused
from cobot_analysis.schema import TRIAL_COLUMNS, TRIALS

READERS = {"c3d": read_c3d, "vicon-csv": read_vicon_csv, "qualisys-tsv": read_qualisys_tsv}
UNITS = ("auto", "mm", "m")
#: where each format declares its sampling rate, for messages.
RATE_SOURCES = {"c3d": "POINT:RATE", "vicon-csv": "the rate line after 'Trajectories'", "qualisys-tsv": "FREQUENCY"}
ASIS_RANGE = (0.15, 0.40)  # m, median |LASI - RASI| of adults
TABLE_SIDE_RANGE = (0.5, 2.5)  # m, |TAB1 - TAB2| (a long side of the table)
TRIALS_PER_TASK = 8  # trials sent to a pool worker at once (stream_import)
MAP_REMEDY = "map the lab's labels with --map LAB=CANON (repeatable), --marker-map FILE.yaml or marker_map in the protocol"
#: the pelvis markers' names in other marker sets (Qualisys sports, CAST / Visual3D, OpenSim, pyomeca), compared
#: without case, '_', '.', '-' and spaces: never mapped on their own (a guess would be a silent error), only
#: suggested as the exact --map options of a refusal
PELVIS_SYNONYMS = {
    "LASI": ("L_IAS", "LIAS", "LASIS", "L_ASIS", "ASISl", "ASIS_L", "LeftASIS"),
    "RASI": ("R_IAS", "RIAS", "RASIS", "R_ASIS", "ASISr", "ASIS_R", "RightASIS"),
    "LPSI": ("L_IPS", "LIPS", "LPSIS", "L_PSIS", "PSISl", "PSIS_L", "LeftPSIS"),
    "RPSI": ("R_IPS", "RIPS", "RPSIS", "R_PSIS", "PSISr", "PSIS_R", "RightPSIS"),
    "SACR": ("SACRUM", "S_SACR", "MPSIS", "PSIS_mid"),
}


def suggested_map(labels: list[str], missing: set[str]) -> list[str]:
    """``--map LABEL=CANON`` for each ``missing`` pelvis marker one of whose ``PELVIS_SYNONYMS`` is in ``labels``, as the
    file names it (per label prefix, i.e. per person; none where a prefix has two candidates), e.g.
    ``['--map L_IAS=LASI', ...]``."""
    def key(name: str) -> str:
        return "".join(ch for ch in name.lower() if ch.isalnum())

    out = []
    for canon in sorted(missing):
        names = {key(s) for s in PELVIS_SYNONYMS.get(canon, ())}
        found: dict[str, list[str]] = {}
        for lab in labels:
            prefix, _, name = lab.rpartition(":")
            if key(name) in names:
                found.setdefault(prefix, []).append(lab)
        out += [f"--map {labs[0]}={canon}" for _, labs in sorted(found.items()) if len(labs) == 1]
    return out


def detect_format(path: str | os.PathLike) -> str:
    """'c3d', 'vicon-csv' or 'qualisys-tsv' from the file's content (not its name)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise InputError(f"cannot read the file ({exc.strerror or type(exc).__name__})", path=path,
                         remedy="check that it exists and is readable") from exc
    if not head:
        raise InputError("empty file", path=path, remedy="re-export the trial from the capture software")
    if is_c3d(head):
        return "c3d"
    if path.suffix.lower() == ".c3d":
        raise InputError("not a C3D file although named .c3d (no C3D header)", path=path,
                         remedy="re-export the trial as C3D, or give the file the name of its real format")
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError("UTF-16 text (a UTF-16 byte-order mark): the exports are read as UTF-8", path=path,
                         remedy="save the file as UTF-8 (or re-export it from the capture software)")
    fmt = sniff_text_format(head.decode("utf-8-sig", errors="replace"))
    if fmt is None:
        raise InputError("unrecognised marker file: not C3D, a Vicon Nexus CSV export or a Qualisys TSV export", path=path,
                         remedy="export the trial as C3D, Vicon CSV (Trajectories) or QTM TSV")
    return fmt


def read_markers(path: str | os.PathLike, units: str = "auto") -> tuple[str, RawMarkers]:
    """Read any supported marker file: ``(source_format, RawMarkers)``; ``units`` 'auto' trusts the file."""
    fmt = detect_format(path)
    return fmt, READERS[fmt](path, units=None if units == "auto" else units)


@dataclass(frozen=True)
class TrialTask:
    """What a worker needs to import one trial (picklable)."""

    trial: str
    path: Path
    pair_study: bool
    units: str
    entities: dict[str, str]
    marker_map: dict[str, str]
    keep_all: bool
    protocol_rate: float | None = None
    lab_extent: float = LAB_EXTENT
    max_speed: float = MAX_SPEED
    max_spike: float = MAX_SPIKE
    invalid_rate: str = "refuse"
    sha256: str | None = None  # the raw file's SHA-256 when the caller has it (the stage's input hashes): not hashed again
    up: str = "auto"  # the lab's vertical axis (``kinematics.UP_AXES``) or auto (``lab_vertical``)


@dataclass
class ImportedTrial:
    trial: str
    entities: list[str]
    markers: list[str]
    xyz: np.ndarray  # [frames, markers, 3] in m
    rate: float
    source_units: str
    source_format: str
    sha256: str
    notes: list[str] = field(default_factory=list)
    pelvis: dict[str, tuple[str, ...]] = field(default_factory=dict)  # person -> pelvis markers used
    vertical: str = "z"  # the file's vertical axis, rotated to z (``lab_vertical``)
    vertical_how: str = "assumed"  # given (--up), detected (from the pelvis) or assumed


def _is_person(entity: str) -> bool:
    return entity in ENTITIES and entity != "table"


def _resolve(resolver: Protocol, label: str, task: TrialTask) -> tuple[str, str]:
    """Raw label -> (entity, canonical marker). The marker map is looked up with the whole label
    first (``Daphnee:ASISr``, as the file lists it), then without its prefix. Single-person
    recordings: a label prefix the protocol does not declare is the subject's name (Vicon writes
    ``Alice:LASI``), so the marker belongs to the walker."""
    entity, marker = resolver.resolve_label(label)
    prefix = label.rpartition(":")[0]
    if prefix and not task.pair_study and prefix not in task.entities and prefix.lower() not in ENTITIES:
        entity = "table" if marker in TABLE_MARKERS else "walker"
    return entity, marker


def occurrence_keys(labels: list[str], marker_map: dict[str, str]) -> list[str]:
    """The labels as the marker map addresses them: a label the file gives more than once is
    ``LABEL#k`` (its k-th occurrence, from 1) where the map has that key, else the label itself."""
    counts: dict[str, int] = {}
    keys = []
    for lab in labels:
        counts[lab] = counts.get(lab, 0) + 1
        key = f"{lab}#{counts[lab]}"
        keys.append(key if key in marker_map and labels.count(lab) > 1 else lab)
    return keys


def _required(entity: str) -> set[str]:
    return set(TABLE_MARKERS) if entity == "table" else {m for d in PELVIS_DEFINITIONS for m in d}


def _scale_check(path: Path, units: str, pairs: list[tuple[np.ndarray, np.ndarray]], bounds: tuple[float, float], what: str) -> None:
    """Refuse a length scale 1000x off (mm read as m, or m read as mm)."""
    dist = np.concatenate([np.linalg.norm(a - b, axis=1) for a, b in pairs])
    dist = dist[np.isfinite(dist)]
    if dist.size == 0:  # never both visible: nothing to judge
        return
    dist = float(np.median(dist))
    lo, hi = bounds
    if lo <= dist <= hi:
        return
    if lo <= dist / 1000 <= hi:
        raise InputError(f"marker distances look like millimetres labelled as metres (median {what} {dist:.4g} m; "
                         f"expected {lo}-{hi} m)", path=path, remedy="pass --units mm")
    if lo <= dist * 1000 <= hi:
        raise InputError(f"marker distances look like metres labelled as mm (median {what} {dist:.4g} m; "
                         f"expected {lo}-{hi} m)", path=path, remedy="pass --units m")
    raise InputError(f"implausible length scale (median {what} {dist:.4g} m, expected {lo}-{hi} m; file units {units})",
                     path=path, remedy=f"check the units (--units mm|m) and the marker labels; {MAP_REMEDY}")


@lru_cache(maxsize=1)
def _no_rows() -> pd.DataFrame:
    """An empty table, made once: the label resolver of a trial reads only the protocol's entities and map."""
    return pd.DataFrame()


def import_trial(task: TrialTask) -> ImportedTrial:
    """Read one trial file, resolve its labels and check it (see module docstring)."""
    from cobot_analysis.provenance import file_sha256

    path = task.path
    fmt, raw = read_markers(path, task.units)
    if raw.xyz.shape[0] == 0:
        raise InputError("empty trial (no frames)", path=path, remedy="remove the trial from the protocol or re-export it")
    rate, rate_notes = trial_rate(raw.rate, RATE_SOURCES[fmt], task.protocol_rate, task.invalid_rate, path)
    notes = list(raw.notes) + rate_notes
    none = _no_rows()
    resolver = Protocol(path=path, study="", trials=none, subjects=none, pairs=none, entities=task.entities, marker_map=task.marker_map)
    resolved = [_resolve(resolver, key, task) for key in occurrence_keys(raw.labels, task.marker_map)]
    keep, seen = [], {}
    for j, (entity, marker) in enumerate(resolved):
        known = (entity == "table" and marker in TABLE_MARKERS) or (_is_person(entity) and marker in KEPT_SUBJECT_MARKERS)
        if not (known or task.keep_all):
            continue
        if (entity, marker) in seen:
            if marker in _required(entity) and raw.labels[seen[entity, marker]] == raw.labels[j]:
                lab, first = raw.labels[j], seen[entity, marker]
                raise InputError(f"label {lab!r} is given twice (points {first + 1} and {j + 1} of the file), both {entity} {marker}",
                                 path=path, remedy=f"name one occurrence by its number in the marker map, e.g. --map '{lab}#2={lab}_2' "
                                                   f"to use the first as {marker} (or --map '{lab}#1={lab}_1' the second)")
            if marker in _required(entity):
                raise InputError(f"labels {raw.labels[seen[entity, marker]]!r} and {raw.labels[j]!r} both map to {entity} {marker}",
                                 path=path, remedy=f"fix the marker map; {MAP_REMEDY}")
            k = 2  # a duplicated label the pipeline does not use (e.g. two RKNE): kept under a numbered name
            while (entity, f"{marker}#{k}") in seen:
                k += 1
            notes.append(f"{path.name}: duplicated label {raw.labels[j]!r} kept as {marker}#{k}")
            resolved[j] = (entity, marker := f"{marker}#{k}")
        seen[entity, marker] = j
        keep.append(j)

    expected = {e for e, _ in resolved if e in ENTITIES}
    if task.pair_study:
        expected |= {"subject1", "subject2", "table"}
    if not expected & {"walker", "subject1", "subject2"} and "table" not in expected:
        expected.add("walker")
    visible = {key for key, j in seen.items() if not np.isnan(raw.xyz[:, j, 0]).all()}
    missing, pelvis = [], {}
    for e in sorted(expected):
        present = {m for ee, m in seen if ee == e}
        if e == "table":
            missing += [f"table:{m}" for m in TABLE_MARKERS if m not in present]
            continue
        use = pelvis_definition({m for ee, m in visible if ee == e}) or pelvis_definition(present)
        if use is None:  # LPSI and RPSI, or SACR: name the markers of the 4-marker pelvis, and the alternative
            alternative = f" (or {e}:{SACRUM} instead of {e}:LPSI and {e}:RPSI)" if SACRUM not in present else ""
            missing.append(", ".join(f"{e}:{m}" for m in PELVIS_MARKERS if m not in present) + alternative)
        pelvis[e] = use
    if missing:
        found = ", ".join(raw.labels[:20]) + (" ..." if len(raw.labels) > 20 else "")
        absent = {m for e in expected if e != "table" for m in (*PELVIS_MARKERS, SACRUM) if (e, m) not in seen}
        hint = suggested_map(raw.labels, absent)
        raise InputError(f"required markers missing: {', '.join(missing)} (labels found: {found})", path=path,
                         remedy=f"the labels look like another marker set's pelvis: {' '.join(hint)} (or the same in --marker-map "
                                f"FILE.yaml or the protocol's marker_map)" if hint else MAP_REMEDY)

    keep.sort(key=lambda j: resolved[j])  # canonical order: entity, then marker
    xyz = raw.xyz[:, keep, :]
    ents = [resolved[j][0] for j in keep]
    marks = [resolved[j][1] for j in keep]
    never = np.isnan(xyz[:, :, 0]).all(axis=0)
    for k in np.flatnonzero(never):
        needed = marks[k] in (TABLE_MARKERS if ents[k] == "table" else pelvis.get(ents[k], ()))
        if needed:
            raise InputError(f"marker {marks[k]} of {ents[k]} is never visible (all {len(xyz)} samples missing)", path=path,
                             remedy="check the labelling of the trial in the capture software, or leave the trial out of the protocol")
        notes.append(f"{path.name}: marker {marks[k]} of {ents[k]} is never visible")

    col = {(e, m): k for k, (e, m) in enumerate(zip(ents, marks))}
    persons = sorted(e for e in expected if _is_person(e))
    if persons:
        pairs = [(xyz[:, col[e, "LASI"]], xyz[:, col[e, "RASI"]]) for e in persons]
        _scale_check(path, raw.units, pairs, ASIS_RANGE, "inter-ASIS distance |LASI - RASI|")
    else:
        _scale_check(path, raw.units, [(xyz[:, col["table", "TAB1"]], xyz[:, col["table", "TAB2"]])], TABLE_SIDE_RANGE,
                     "table side |TAB1 - TAB2|")
    if all(("table", m) in col for m in TABLE_MARKERS):
        check_table_corners(path, *(xyz[:, col["table", m]] for m in TABLE_MARKERS))
    check_positions(xyz, [raw.labels[j] for j in keep], float(rate), path, lab_extent=task.lab_extent, max_speed=task.max_speed,
                    max_spike=task.max_spike)
    vertical, how = lab_vertical(task.up, xyz, col, pelvis, path)
    if vertical != "z":
        xyz = xyz @ levelling(vertical).T
    return ImportedTrial(task.trial, ents, marks, xyz, float(rate), raw.units, fmt, task.sha256 or file_sha256(path), notes, pelvis,
                         vertical, how)


def check_table_corners(path: Path, tab1: np.ndarray, tab2: np.ndarray, tab3: np.ndarray) -> None:
    """Refuse table corners labelled against the convention the table pose needs (docs/protocol.md): TAB1 -> TAB2
    along a long side and TAB1 -> TAB3 along a short side, so TAB2 and TAB3 are opposite corners (the centre is their
    midpoint, the orientation TAB2 - TAB1). Over the frames where the three are seen: the angle at TAB1 within 15
    degrees of a right angle (else TAB1 is not the corner between the two), and the median |TAB1 - TAB2| at least
    0.95 |TAB1 - TAB3| (a square table passes either way). Otherwise the centre would be a side's midpoint and the
    orientation a quarter turn off, without a word."""
    a, b = tab2 - tab1, tab3 - tab1
    seen = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    if not seen.any():
        return
    a, b = a[seen], b[seen]
    la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        angle = float(np.degrees(np.nanmedian(np.arccos(np.clip(np.sum(a * b, axis=1) / (la * lb), -1, 1)))))
    long, short = float(np.median(la)), float(np.median(lb))
    convention = "TAB1 -> TAB2 along a long side, TAB1 -> TAB3 along a short side (docs/protocol.md)"
    if abs(angle - 90.0) > 15.0:
        raise InputError(f"table corners: the angle at TAB1 between TAB2 and TAB3 is {angle:.0f} degrees, not a right angle: "
                         "TAB1 is not the corner between TAB2 and TAB3", path=path,
                         remedy=f"relabel the corners with the marker map (--map LABEL=TAB1 ..., as the file names them): {convention}")
    if long < 0.95 * short:
        raise InputError(f"table corners: TAB1 -> TAB2 ({long:.2f} m) is shorter than TAB1 -> TAB3 ({short:.2f} m): TAB2 must "
                         "be along a long side", path=path,
                         remedy=f"swap TAB2 and TAB3 with the marker map (--map TAB2=TAB3 --map TAB3=TAB2): {convention}")


def lab_vertical(up: str, xyz: np.ndarray, col: dict[tuple[str, str], int], pelvis: dict[str, tuple[str, ...]],
                 path: Path) -> tuple[str, str]:
    """(the vertical axis of a trial's lab frame, how it was found), and the pelvis and table checked against it.

    ``up`` when given ("given"); ``auto``: the lab axis along the up direction of its persons' pelvis
    (``kinematics.pelvis_up``, ``vertical_axis``: within 37 degrees), the most persons' (ties: z, then a positive axis),
    "detected"; else z "assumed" (no pelvis or no axis near it; -z is no lab frame but a pelvis whose left and right
    markers are swapped). Then, in the frame turned to z up, every person's pelvis must point up: ``InputError`` when
    one points down (LASI and RASI swapped) or sideways (another vertical axis than the one given or found); a table
    alone (no pelvis) must have its top horizontal (``kinematics.table_normal`` within 37 degrees of z), else the lab's
    vertical is another axis, which a table cannot tell the sign of: given with --up."""
    from collections import Counter

    ups = {}
    for e, markers in pelvis.items():
        back = [xyz[:, col[e, m]] for m in markers[2:]]  # LPSI and RPSI, or SACR
        if (u := pelvis_up(xyz[:, col[e, "LASI"]], xyz[:, col[e, "RASI"]], sum(back) / len(back))) is not None:
            ups[e] = u
    found = Counter(a for u in ups.values() if (a := vertical_axis(u)) is not None)
    if up != "auto":
        axis, how = up, "given"
    elif found and (axis := max(found, key=lambda a: (found[a], a == "z", not a.startswith("-")))) != "-z":
        how = "detected"
    else:
        axis, how = "z", "assumed"
    R = levelling(axis)
    for e, u in sorted(ups.items()):
        turned = vertical_axis(R @ u)
        if turned == "-z":
            raise InputError(f"the pelvis of {e} points down (its up direction, forward x left, is {vertical_axis(u)} in the "
                             f"file, whose vertical is {axis} ({how})): LASI and RASI look swapped", path=path,
                             remedy="fix the labels in the capture software, or swap them with the marker map (e.g. --map "
                                    "LASI=RASI --map RASI=LASI, as the file names them); --up -z if the lab's vertical points down")
        if turned not in (None, "z"):
            raise InputError(f"the pelvis of {e} has its up direction along {vertical_axis(u)} of the file's frame, not along its "
                             f"vertical {axis} ({how})", path=path,
                             remedy="give the lab's vertical axis with --up (auto finds it from the pelvis), or check the pelvis labels")
    if not pelvis and all(("table", m) in col for m in TABLE_MARKERS):
        n = table_normal(*(xyz[:, col["table", m]] for m in TABLE_MARKERS))
        if n is not None and (turned := vertical_axis(R @ n)) is not None and turned.lstrip("-") != "z":
            k = vertical_axis(n).lstrip("-")
            raise InputError(f"the table's top is not horizontal in a frame whose vertical is {axis} ({how}): its normal is "
                             f"along {k} of the file's frame", path=path,
                             remedy=f"give the lab's vertical axis, --up {k} or --up -{k} (a table alone cannot tell its sign)")
    return axis, how


def repeated(trial: ImportedTrial, first: dict[str, str], files: dict[str, Path]) -> Refused | None:
    """``trial`` refused when its file is byte for byte the file of an earlier trial (the same SHA-256: one path listed
    twice, or a copy): one recording counted as two trials would weigh twice in every mean and test. ``first``: the
    SHA-256 -> trial of the trials kept so far (updated); ``files``: trial -> raw file."""
    earlier = first.setdefault(trial.sha256, trial.trial)
    if earlier == trial.trial:
        return None
    path = files[trial.trial]
    return Refused.of(trial.trial, path, InputError(
        f"the same recording as trial {earlier!r} (the files are identical, SHA-256 {trial.sha256[:12]}...)", path=path,
        remedy="give each trial its own recording: remove the repeated row from the protocol's trials, or point it at its file"))


def import_or_refuse(task: TrialTask) -> ImportedTrial | Refused:
    """``import_trial``, with bad input returned as ``Refused`` so that one run names every bad file."""
    try:
        return import_trial(task)
    except InputError as exc:
        return Refused.of(task.trial, task.path, exc)


def trial_rows(t: ImportedTrial):
    """One trial's rows of the markers table as Arrow (``schema.MARKERS``; ``long_table`` order and types,
    built from the arrays without pandas): what ``stream_import`` writes as the trial's row group."""
    import pyarrow as pa

    n_frames, n_markers, _ = t.xyz.shape
    frames = np.arange(n_frames)

    def labels(values: list[str]) -> Any:  # dictionary<int32, string>, one entry per marker, repeated per frame
        names = sorted(set(values))
        codes = np.repeat(np.array([names.index(v) for v in values], dtype=np.int32), n_frames)
        return pa.DictionaryArray.from_arrays(codes, pa.array(names, pa.string()))

    x, y, z = (np.ascontiguousarray(t.xyz[:, :, k].T).ravel() for k in range(3))
    arrays = [pa.DictionaryArray.from_arrays(np.zeros(n_frames * n_markers, np.int32), pa.array([t.trial], pa.string())),
              np.tile(frames, n_markers), np.tile(frames / t.rate, n_markers), labels(t.entities), labels(t.markers),
              *(pa.array(v, from_pandas=True) for v in (x, y, z)), np.isnan(x)]  # NaN (occluded) stored as null
    return pa.Table.from_arrays(arrays, schema=_markers_schema())


@lru_cache(maxsize=1)
def _markers_schema():
    """The Arrow schema of the markers table as ``schema.to_arrow`` gives it for ``long_table``'s frame."""
    from cobot_analysis.schema import MARKERS, to_arrow

    one = ImportedTrial("t", ["walker"], ["LASI"], np.zeros((1, 1, 3)), 1.0, "m", "c3d", "")
    return to_arrow(long_table([one]), MARKERS).schema


def refusal_error(refused: list[Refused], n_trials: int, where: str | os.PathLike, stage: str) -> InputError:
    """One ``InputError`` naming every refused trial of a stage (``refusals.error``)."""
    return refusals.error(refused, n_trials, stage)


def long_table(trials: list[ImportedTrial]) -> pd.DataFrame:
    """Tidy long markers table (schema.MARKERS), rows ordered by trial, entity, marker, frame.

    Every column is allocated once and filled trial by trial with vectorised numpy (no copy by
    concatenation); labels are categorical.
    """
    entity_cats = sorted({e for t in trials for e in t.entities})
    marker_cats = sorted({m for t in trials for m in t.markers})
    e_index = {e: i for i, e in enumerate(entity_cats)}
    m_index = {m: i for i, m in enumerate(marker_cats)}
    n_rows = sum(t.xyz.shape[0] * t.xyz.shape[1] for t in trials)
    trial_code = np.empty(n_rows, dtype=np.int32)
    entity_code = np.empty(n_rows, dtype=np.int32)
    marker_code = np.empty(n_rows, dtype=np.int32)
    frame = np.empty(n_rows, dtype=np.int64)
    floats = np.empty((4, n_rows))  # time, x, y, z: one block, no copy when the DataFrame is built
    start = 0
    for i, t in enumerate(trials):
        n_frames, n_markers, _ = t.xyz.shape
        rows = slice(start, start + n_frames * n_markers)
        trial_code[rows] = i
        entity_code[rows] = np.repeat(np.array([e_index[e] for e in t.entities], dtype=np.int32), n_frames)
        marker_code[rows] = np.repeat(np.array([m_index[m] for m in t.markers], dtype=np.int32), n_frames)
        frame[rows].reshape(n_markers, n_frames)[:] = np.arange(n_frames)
        floats[0, rows].reshape(n_markers, n_frames)[:] = np.arange(n_frames) / t.rate
        for k in range(3):
            floats[1 + k, rows].reshape(n_markers, n_frames)[:] = t.xyz[:, :, k].T
        start = rows.stop
    df = pd.DataFrame(floats.T, columns=["time", "x", "y", "z"], copy=False)
    df.insert(0, "trial", pd.Categorical.from_codes(trial_code, [t.trial for t in trials]))
    df.insert(1, "frame", frame)
    df.insert(3, "entity", pd.Categorical.from_codes(entity_code, entity_cats))
    df.insert(4, "marker", pd.Categorical.from_codes(marker_code, marker_cats))
    df["occluded"] = np.isnan(floats[1])
    return df


def trial_metadata(protocol: Protocol) -> pd.DataFrame:
    """The protocol's trials with the study's metadata columns (``schema.TRIAL_COLUMNS``, their types):
    the first columns of ``trials_table``, known before any file is read."""
    df = protocol.trials.copy()
    df["trial"] = df["trial"].astype(str)
    df.insert(0, "study", protocol.study)
    df["kind"] = "trial"
    df["n_trials"] = 1
    for name, col in TRIAL_COLUMNS.items():
        if name not in df.columns:
            df[name] = None
        df[name] = df[name].astype({"string": "string", "int": "Int64", "float": "float64"}[col.dtype])
    return df


def trials_table(protocol: Protocol, trials: list[ImportedTrial], files: dict[str, Path]) -> pd.DataFrame:
    """One row per imported recording (schema.TRIALS): protocol metadata + how it was read (``files``: each
    trial's resolved file, ``TrialTask.path``)."""
    df = trial_metadata(protocol)
    by_id = {t.trial: t for t in trials}
    df["file"] = [str(files[t]) for t in df["trial"]]
    df["sha256"] = [by_id[t].sha256 for t in df["trial"]]
    df["source_format"] = [by_id[t].source_format for t in df["trial"]]
    df["source_units"] = [by_id[t].source_units for t in df["trial"]]
    df["rate"] = [by_id[t].rate for t in df["trial"]]
    df["n_frames"] = [by_id[t].xyz.shape[0] for t in df["trial"]]
    df["pelvis_markers"] = [_pelvis_text(by_id[t].pelvis) for t in df["trial"]]
    return df[list(TRIALS.columns) + [c for c in df.columns if c not in TRIALS.columns]]


def load_marker_map(path: str | os.PathLike) -> dict[str, str]:
    """A marker map YAML file: ``LAB: CANON`` lines, or the same under a ``marker_map:`` key (a label
    given twice is refused)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("marker map file not found", path=path, remedy="pass an existing YAML file to --marker-map")
    doc = read_yaml(path, "marker map", "write one 'LAB: CANON' line per label")
    doc = doc.get("marker_map", doc) if isinstance(doc, dict) else doc
    if not isinstance(doc, dict) or not all(isinstance(v, str) for v in doc.values()):
        raise InputError("a marker map must map lab labels to canonical labels", path=path, remedy="write one 'LAB: CANON' line per label")
    return {str(k): v for k, v in doc.items()}


def parse_map_options(items: list[str]) -> dict[str, str]:
    """``["L_ASIS=LASI", ...]`` -> ``{"L_ASIS": "LASI"}``; a label given two different targets is refused
    (one label is one marker; a single sacrum marker is a pelvis definition of its own)."""
    out: dict[str, str] = {}
    for item in items:
        lab, sep, canon = item.partition("=")
        lab, canon = lab.strip(), canon.strip()
        if not sep or not lab or not canon:
            raise InputError(f"--map {item!r} is not LAB=CANON", remedy="write e.g. --map L_ASIS=LASI")
        if out.get(lab, canon) != canon:
            hint = (f"LASI RASI plus one sacrum marker is a pelvis: map it once, --map {lab}={SACRUM}"
                    if {out[lab], canon} <= {"LPSI", "RPSI", SACRUM} else "give each label one canonical marker")
            raise InputError(f"--map gives label {lab!r} two markers ({lab}={out[lab]} and {lab}={canon}); a label is one marker",
                             remedy=hint)
        out[lab] = canon
    return out


def _pelvis_text(pelvis: dict[str, tuple[str, ...]]) -> str:
    """'LASI,RASI,SACR' (one person) or 'subject1=LASI,RASI,LPSI,RPSI;subject2=...'."""
    if list(pelvis) == ["walker"]:
        return ",".join(pelvis["walker"])
    return ";".join(f"{e}={','.join(m)}" for e, m in sorted(pelvis.items()))


@dataclass
class ImportPlan:
    """A protocol's import, before any file is read: the trials' tasks, the stage's input files (protocol,
    marker map, trial tables, raw files) and parameters (recorded in the manifest)."""

    protocol: Protocol
    tasks: list[TrialTask]
    inputs: list[Path]
    params: dict[str, Any]
    limits: dict[str, float]


def plan_import(protocol_path: str | os.PathLike, *, units: str = "auto", marker_map: dict[str, str] | None = None,
                marker_map_file: str | os.PathLike | None = None, keep_all: bool = False, skip_bad: bool = True,
                lab_extent: float = LAB_EXTENT, max_speed: float = MAX_SPEED, max_spike: float = MAX_SPIKE,
                up: str = "auto") -> ImportPlan:
    """Read the protocol (and marker map) and list what importing it means; bad options and a bad protocol
    raise ``InputError`` here, before any raw file is read."""
    if units not in UNITS:
        raise InputError(f"unknown --units {units!r}", remedy=f"use one of {', '.join(UNITS)}")
    if up not in ("auto", *UP_AXES):
        raise InputError(f"unknown --up {up!r}: the lab's vertical axis", remedy=f"use one of auto, {', '.join(UP_AXES)} (e.g. --up y for OptiTrack Motive)")
    if lab_extent > LAB_EXTENT:  # the trajectory tables' limit (schema.POSITION): every later stage would refuse them
        raise InputError(f"--lab-extent {lab_extent:g} m is beyond the {LAB_EXTENT:g} m of the lab origin that every later "
                         "stage accepts", remedy=f"give --lab-extent at most {LAB_EXTENT:g}, {FAR_REMEDY}")
    protocol = load_protocol(protocol_path)
    mapping = dict(protocol.marker_map)
    inputs: list[Path] = [protocol.path]
    if marker_map_file is not None:
        mapping.update(load_marker_map(marker_map_file))
        inputs.append(Path(marker_map_file))
    mapping.update(marker_map or {})
    tables = protocol_tables(protocol.path)
    inputs += tables
    files = [protocol.file_path(f) for f in protocol.trials["file"]]  # resolved
    pair_study = "pair" in protocol.trials.columns and protocol.trials["pair"].notna().any()
    tasks = [TrialTask(str(trial), f, bool(pair_study), units, dict(protocol.entities), mapping, keep_all, protocol.rate,
                       lab_extent, max_speed, max_spike, protocol.invalid_rate, up=up) for trial, f in zip(protocol.trials["trial"], files)]
    limits = {"lab_extent": lab_extent, "max_speed": max_speed, "max_spike": max_spike}
    root = protocol.path.parent.resolve()  # allow_outside: the files outside(protocol.path.parent, f)
    outside_files = [str(f) for f in [*(Path(t).resolve() for t in tables), *files] if not f.is_relative_to(root)]
    params = {"protocol": str(protocol.path.resolve()), "units": units, "marker_map": mapping, "keep_all_markers": keep_all,
              "entities": protocol.entities,
              "skip_bad": skip_bad, "allow_outside": protocol.allow_outside, "outside_files": outside_files, "up": up, **limits}
    return ImportPlan(protocol, tasks, inputs + [Path(f) for f in files], params, limits)


def imported_tables(plan: ImportPlan, imported: list[ImportedTrial], refused: list[Refused]) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, Any]]:
    """(markers long table, trials table, the markers file's metadata) of the trials imported."""
    trials, meta = imported_summary(plan, imported, refused)
    return long_table(imported), trials, meta


def imported_summary(plan: ImportPlan, imported: list[ImportedTrial], refused: list[Refused]) -> tuple[pd.DataFrame, dict[str, Any]]:
    """(trials table, the markers file's metadata) of the trials imported (their samples not needed)."""
    protocol = plan.protocol
    kept = protocol.trials[protocol.trials["trial"].astype(str).isin({t.trial for t in imported})]
    trials = trials_table(Protocol(protocol.path, protocol.study, kept, rate=protocol.rate), imported,
                          {t.trial: t.path for t in plan.tasks})
    rates = {t.trial: t.rate for t in imported}
    unique_rates = sorted(set(rates.values()))
    meta = {"study": protocol.study, "rate": unique_rates[0] if len(unique_rates) == 1 else None, "rates": rates,
            "source_units": {t.trial: t.source_units for t in imported},
            "source_format": {t.trial: t.source_format for t in imported},
            "pelvis_markers": {t.trial: {e: list(m) for e, m in t.pelvis.items()} for t in imported},
            "vertical": {t.trial: f"{t.vertical} ({t.vertical_how})" for t in imported},
            "skipped": {r.trial: r.reason for r in refused}, **plan.limits}
    return trials, meta


@dataclass
class Streamed:
    """What ``stream_import`` wrote: the trials imported (samples dropped), the refused ones, the
    counts of marker samples written and occluded, what the worker returned besides each imported
    trial's rows (``also``, in protocol order: e.g. its preprocessing), and the trials table and the
    file's metadata (``imported_summary``; None when no trial was imported)."""

    imported: list[ImportedTrial]
    refused: list[Refused]
    n_samples: int = 0
    n_occluded: int = 0
    also: list[Any] = field(default_factory=list)
    trials: pd.DataFrame | None = None
    meta: dict[str, Any] | None = None


def stream_import(plan: ImportPlan, markers_path: Path, *, jobs: int | None = None, scheduler: str | None = None,
                  worker: Callable[[Any], Any] = import_or_refuse, items: list[Any] | None = None) -> Streamed:
    """Import every trial of ``plan`` and write its markers to ``markers_path`` as they come: each worker
    reads and checks its trial (``import_or_refuse``), the parent turns it into the trial's rows
    (``trial_rows``: 0.35 ms, less than pickling the rows in the worker and unpickling them here, 1 ms)
    and appends them as one Parquet row group per trial, in protocol order, keeping only the per-trial
    summaries, so memory does not grow with the number of trials. The file's metadata (rates, units,
    pelvis markers, refusals: ``imported_summary``) is added when every trial is done; the caller refuses
    the run (and discards the file) when trials were refused without ``skip_bad``.

    ``worker`` / ``items`` (one per task of the plan, in its order): another task function returning
    ``Refused`` or ``(trial, anything)``, the second kept in ``Streamed.also`` (the import and preprocess
    in one pass: ``preprocess.stage.import_and_process``)."""
    import base64
    import json

    import pyarrow.parquet as pq

    from cobot_analysis.parallel import default_jobs, imap_tasks
    from cobot_analysis.schema import METADATA_KEY, MARKERS

    todo = plan.tasks if items is None else items
    # a few trials per pool task (the pool's cost per task paid once per chunk), at least 8 chunks per worker
    chunk = max(1, min(TRIALS_PER_TASK, len(todo) // (8 * (jobs or default_jobs()))))
    out = Streamed([], [])
    writer = None
    done = False
    first: dict[str, str] = {}
    files = {t.trial: t.path for t in plan.tasks}
    try:
        for r in imap_tasks(worker, todo, jobs=jobs, scheduler=scheduler, description="import", chunk=chunk):
            if not isinstance(r, Refused):
                r = repeated(r[0] if isinstance(r, tuple) else r, first, files) or r
            if isinstance(r, Refused):
                out.refused.append(r)
                continue
            trial, *also = r if isinstance(r, tuple) else (r,)
            out.also += also
            rows = trial_rows(trial)
            trial.xyz = np.empty((len(trial.xyz), 0, 3))  # its frames only: the samples are in the file
            if writer is None:  # the table's metadata (METADATA_KEY) is added at the end, when it is known
                schema = rows.schema.with_metadata({k: v for k, v in rows.schema.metadata.items() if k != METADATA_KEY})
                # LZ4 (not the pipeline's zstd): as small for these coordinates (+9 %), half the CPU to write
                # and read; statistics of the labels and frames only (the trial's say which row group is whose);
                # the coordinates byte-stream-split, not dictionary-encoded (1.0 instead of 1.5 ms per trial to
                # write, 0.43 instead of 0.56 to read, +8 % size); page checksums, as schema.write_table
                writer = pq.ParquetWriter(markers_path, schema, compression="lz4", write_page_checksum=True,
                                          use_dictionary=["trial", "entity", "marker", "frame", "occluded"],
                                          column_encoding={c: "BYTE_STREAM_SPLIT" for c in ("x", "y", "z")},
                                          write_statistics=["trial", "entity", "marker", "frame"])
            writer.write_table(rows, row_group_size=max(len(rows), 1))
            out.imported.append(trial)
            out.n_samples += len(rows)
            out.n_occluded += sum(c.true_count for c in rows.column("occluded").chunks)
        if writer is not None:
            out.trials, out.meta = imported_summary(plan, out.imported, out.refused)
            text = json.dumps({**MARKERS.metadata(), **out.meta}, default=str).encode()
            # in the footer's key-value metadata and in the Arrow schema stored there (what pyarrow reads)
            final = writer.schema.with_metadata({**writer.schema.metadata, METADATA_KEY: text})
            writer.add_key_value_metadata({METADATA_KEY: text, b"ARROW:schema": base64.b64encode(final.serialize().to_pybytes())})
        done = True
    finally:
        if writer is not None:
            writer.close()
        if not done:  # an error or an interrupt: no partial file
            Path(markers_path).unlink(missing_ok=True)
    return out


def protocol_tables(protocol_path: Path, keys: tuple[str, ...] = ("trials", "subjects", "pairs")) -> list[Path]:
    """The CSV files the protocol's sections ``keys`` point to (those given inline have none), for input hashes."""
    import yaml

    doc = yaml.safe_load(Path(protocol_path).read_text()) or {}
    return [Path(protocol_path).parent / doc[k] for k in keys if isinstance(doc.get(k), str)]
