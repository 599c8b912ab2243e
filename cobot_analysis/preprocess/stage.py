"""The preprocess stage: raw markers -> time-normalised trajectories (docs/methods.md sec. 2).

Order of operations, per recording:

1. checks (``_check``): the pelvis of each subject (LASI RASI LPSI RPSI, or LASI RASI SACR when
   the PSIS are absent or never seen: ``io.protocol.pelvis_definition``), TAB1-3 of the table,
   positions as plausible as the import required (``io.plausibility``, with the import's limits
   stored in markers.parquet), heights in metres; gap report of these markers -> ``gaps.parquet``;
2. short gaps (<= ``max_gap``, interior) filled by cubic spline and flagged (``gaps.py``);
3. zero-phase Butterworth low-pass of each continuous segment (``filtering.py``);
4. kinematics (``cobot_analysis.kinematics``): pelvis CoM (4 markers: rigid-body reconstruction
   when one is missing; sacrum pelvis: ``sacrum_pelvis_com``), theta, velocity; table centre,
   orientation, height;
5. segmentation (``segmentation.py``): pair recordings by table height into forward and return
   carriages (each of the 3 entities cut at the table's onset/offset; trial ids
   ``<recording>_forward`` / ``<recording>_return``; the return is scenario 3 and its
   ``end_orientation`` is the measured table orientation at its offset), walking trials by CoM
   speed. With ``keep_approach``, each subject's walk to the table (speed segmentation before the
   first lift) is kept as ``<recording>_approach`` (direction "approach", subjects only). A walking
   recording where nobody walks (a static recording) is refused as such, and so is a pair recording that
   contradicts the protocol (``pairs.py``: the number of carriages, a return that does not go back to the
   start, an end orientation off the table's, Subject 1 at the other end of the table than in the study's
   other recordings);
6. per trajectory: gamma (``kinematics.gamma``, ends held below ``gamma_min_speed``), quality
   flags, time normalisation to N samples (``normalisation.py``) -> ``trajectories.parquet``, with
   the pelvis markers used (``pelvis_markers``, e.g. 'LASI,RASI,SACR'; empty for the table).

Every recording is processed before anything is written: by default (``skip_bad``) the refused
ones are left out and listed (``cobot_analysis.refusals``: console, results.md, manifest), without it
they are named together in one error.

Orientation with a long pelvis-marker gap: by default (``orientation_markers="pelvis"``) a long
gap on any of the 4 pelvis markers makes the trajectory's orientation missing, as in the walking
study, where orientation is only reported when the whole pelvis is seen; with ``"asis"`` theta is
kept whenever LASI and RASI are seen (theta only needs them, docs/methods.md sec. 2.5). Position is
always kept: the CoM is rebuilt rigidly from the 3 visible pelvis markers (exact for a rigid
pelvis, where dropping a marker from the mean would shift the CoM by about 5 cm).

Quality flags (``quality`` column, ';'-separated, 'ok' when none):
``short_gaps_filled`` (spline-filled frames inside the trajectory), ``long_gap`` (an unfilled gap
of one of the entity's markers inside the trajectory), ``com_rigid_fill`` (pelvis centre
reconstructed from 3 markers somewhere), ``orientation_missing`` (a long gap on a pelvis marker --
or on TAB1/TAB2 for the table -- somewhere in the trajectory: theta and gamma are NaN for the whole
trajectory, position is kept, docs/methods.md sec. 2.2), ``position_missing`` (some samples of
x, y are NaN: two or more pelvis markers missing at once), ``gamma_undefined`` (the speed never
reaches ``gamma_min_speed``), ``truncated`` (the walk or carriage runs off the start or end of the
recording, or of the visible data, while moving: ``segmentation.cut_off``; its travel time and
distance cover only the recorded part), ``later_walks`` (a walking recording holds more walks after the
first, separated by a rest of at least ``min_rest``, e.g. back to the start: the first is the trial, the
later ones are left out), ``end_orientation_measured`` (a forward carriage without an ``end_orientation`` in the
trials table: its configuration's orientation nearer the table's at its end, ``pairs.end_orientation``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from cobot_analysis import kinematics as kin
from cobot_analysis.angles import wrap
from cobot_analysis.errors import InputError
from cobot_analysis.io.markers import Refused, refusal_error
from cobot_analysis.io.plausibility import LAB_EXTENT, MAX_SPEED, MAX_SPIKE, check_positions
from cobot_analysis.io.protocol import PELVIS_MARKERS, SACRUM, TABLE_MARKERS, pelvis_definition, pelvis_requirement
from cobot_analysis.preprocess import filtering, gaps, normalisation, pairs, segmentation
from cobot_analysis.schema import MARKERS, TRIAL_COLUMNS, TRIALS, VERIFY, not_the_table, read_table, table_metadata

SUBJECT_ENTITIES = ("walker", "subject1", "subject2")
USED_MARKERS = PELVIS_MARKERS + (SACRUM,) + TABLE_MARKERS
#: trial metadata columns copied from trials.parquet to every trajectory.
META_COLUMNS = tuple(c for c in TRIAL_COLUMNS if c not in ("kind", "n_trials", "direction"))
NUMERIC = ("sample", "phase", "time", "record_time", "x", "y", "theta", "gamma", "vx", "vy",
           "travel_time", "travelled_distance")


@dataclass(frozen=True)
class Params:
    """Parameters of the preprocess stage (recorded in the manifest)."""

    max_gap: float = gaps.MAX_GAP  # s
    cutoff: float = filtering.CUTOFF  # Hz
    order: int = filtering.ORDER
    order_convention: str = filtering.DEFAULT_CONVENTION
    n_samples: int = normalisation.N_SAMPLES
    lift_threshold: float = segmentation.LIFT_THRESHOLD  # m
    floor_window: float = segmentation.FLOOR_WINDOW  # s
    speed_threshold: float = segmentation.SPEED_THRESHOLD  # m/s
    rest_speed: float = segmentation.REST_SPEED  # m/s
    min_duration: float = segmentation.MIN_DURATION  # s
    min_set_down: float = segmentation.MIN_SET_DOWN  # s: a shorter set-down joins two lifts (a re-grip)
    min_rest: float = segmentation.MIN_REST  # s
    gamma_min_speed: float = kin.GAMMA_MIN_SPEED  # m/s
    keep_approach: bool = False
    orientation_markers: str = "pelvis"  # "pelvis": theta needs all the pelvis markers used; "asis": LASI and RASI
    skip_bad: bool = True  # skip (and list) the refused recordings (cobot_analysis.refusals); False: refuse the run

    def __post_init__(self) -> None:
        """Bounded before any work: durations, rates and thresholds finite and >= 0, the cut-off > 0 (``inf`` overflowed
        in ``round(max_gap * rate)``), at least 2 samples and an order >= 1."""
        for name in ("max_gap", "cutoff", "lift_threshold", "floor_window", "speed_threshold", "rest_speed", "min_duration",
                     "min_set_down", "min_rest", "gamma_min_speed"):
            value = getattr(self, name)
            positive = name == "cutoff"  # a low-pass filter at 0 Hz has no pass band
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0 \
                    or (positive and value == 0):
                raise InputError(f"{option_name(name)} {value!r} is not a finite number {'> 0' if positive else '>= 0'}",
                                 remedy=f"give {option_name(name)} a finite value (default {getattr(Params, name):g})")
        for name, low in (("n_samples", 2), ("order", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise InputError(f"{option_name(name)} {value!r} is not an integer >= {low}",
                                 remedy=f"give {option_name(name)} an integer (default {getattr(Params, name)})")

    def memory_bytes(self, n_trajectories: int) -> int:
        """Estimated peak memory of the trajectories table: ``n_samples x trajectories x`` its columns
        (8 bytes each) ``x 3`` (the per-trajectory frames, their concatenation and the Parquet writer)."""
        return int(self.n_samples) * n_trajectories * (len(NUMERIC) + len(META_COLUMNS) + 8) * 8 * 3


def option_name(field_name: str) -> str:
    """The command-line option of a ``Params`` field (``n_samples`` -> ``--samples``)."""
    return "--samples" if field_name == "n_samples" else "--" + field_name.replace("_", "-")


def available_memory() -> int | None:
    """Bytes of memory the machine can still give (``MemAvailable`` of /proc/meminfo), None when unknown."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        import os

        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(p: Params, trials_path: Path) -> None:
    """Refuse, before any work, a ``--samples`` whose trajectories table would not fit in memory:
    ``Params.memory_bytes`` for the largest number of trajectories the recordings can give (one per
    walking recording; pair recordings: 3 entities x 2 carriages, + 2 approaches with
    ``keep_approach``) against the memory available."""
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(trials_path, columns=None)
    except Exception:  # noqa: BLE001 - unreadable: load_recordings names the problem
        return
    pair = "pair" in table.column_names and table.column("pair").null_count < len(table)
    check_memory_for(p, len(table), pair, trials_path)


def check_memory_for(p: Params, n_recordings: int, pair: bool, path: Path) -> None:
    """``check_memory`` for ``n_recordings`` recordings (``pair``: of a pair study) listed in ``path``."""
    n_traj = n_recordings * ((8 if p.keep_approach else 6) if pair else 1)
    need, have = p.memory_bytes(n_traj), available_memory()
    if have is not None and need > have:
        raise InputError(f"--samples {p.n_samples} would need about {need / 1e9:.3g} GB for {n_traj} trajectories "
                         f"({have / 1e9:.3g} GB of memory available)", path=path,
                         remedy=f"use fewer samples per trajectory (default {Params.n_samples})")


@dataclass
class Recording:
    """One recording's markers as dense arrays ``(T, 3)`` (NaN = missing) and its trials row; ``row_groups``:
    the row groups of the markers file that hold its rows, when they are read by the worker that
    processes it (``load_markers``) rather than up front."""

    trial: str
    rate: float
    meta: dict[str, Any]
    markers: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    source: str = ""  # the raw file (else the markers file), for error messages
    limits: dict[str, float] = field(default_factory=dict)  # plausibility limits of the import (lab_extent, max_speed, max_spike)
    row_groups: tuple[int, ...] | None = None


# ---- reading --------------------------------------------------------------------------------------
def load_recordings(markers_path: Path, trials_path: Path, *, lazy: bool = False) -> list[Recording]:
    """Read the markers the stage uses and the trials table; one ``Recording`` per trial.

    Only the pelvis and table-corner rows are kept (``_read_marker_rows``), so memory stays at
    about 4 markers x frames x trials. Raises ``InputError`` for foreign or broken files,
    trials without marker rows, and marker rows of unknown trials.

    ``lazy``: when every row group of the markers file holds one trial (its Parquet statistics say
    so, as ``import`` writes it), only the trials' row groups are listed here (``Recording.row_groups``)
    and each recording's markers are read by ``load_markers`` where it is processed: memory no
    longer grows with the number of trials. Other files are read up front.
    """

    trials = read_table(trials_path, TRIALS)
    if not markers_path.is_file():
        raise InputError("file not found", path=markers_path, remedy="run `cobot-analysis import` first or pass --markers")
    try:
        meta = table_metadata(markers_path)
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise InputError(f"not a readable Parquet file ({type(exc).__name__})", path=markers_path,
                         remedy="re-run `cobot-analysis import`") from exc
    if meta.get("table") != MARKERS.name:
        raise not_the_table(markers_path, MARKERS.name, meta.get("table"), "pass the markers.parquet written by `cobot-analysis import`")
    index = _trial_row_groups(markers_path) if lazy else None
    if index is None:
        try:
            names, tcode, slots, slot, frame, xyz = _read_marker_rows(markers_path)
        except InputError:
            raise
        except Exception as exc:  # pyarrow raises several types for corrupt files or missing columns
            raise InputError(f"cannot read the marker columns ({type(exc).__name__}: {exc})", path=markers_path,
                             remedy="re-run `cobot-analysis import`") from exc
        present = {names[i] for i in np.unique(tcode)}
    else:
        present = set(index)
    limits = {"lab_extent": float(meta.get("lab_extent") or LAB_EXTENT), "max_speed": float(meta.get("max_speed") or MAX_SPEED),
              "max_spike": float(meta.get("max_spike") or MAX_SPIKE)}
    known = set(trials["trial"].astype(str))
    stray = sorted(present - known)
    if stray:
        raise InputError(f"marker rows of trials {stray[:3]} that {trials_path.name} does not list", path=markers_path,
                         remedy="pass the trials.parquet written with these markers (same import)")
    if index is None:
        if np.any(np.diff(tcode) < 0):
            order = np.argsort(tcode, kind="stable")
            tcode, slot, frame, xyz = tcode[order], slot[order], frame[order], xyz[order]
        bounds = np.searchsorted(tcode, np.arange(len(names) + 1))
        where = {name: i for i, name in enumerate(names)}
    recordings = []
    rows = trials.copy(deep=False)
    rows.attrs = {}  # iterrows deep-copies the table's metadata (every trial's rate, units...) into each row
    for _, row in rows.iterrows():
        trial = str(row["trial"])
        rate = float(row["rate"]) if pd.notna(row.get("rate")) else float("nan")
        if not rate > 0:
            raise InputError(f"trial {trial} has no valid sampling rate ({row.get('rate')})", path=trials_path,
                             remedy="re-run `cobot-analysis import` (the rate comes from the raw file or the protocol)")
        rec = Recording(trial, rate, {c: row.get(c) for c in TRIAL_COLUMNS}, source=str(row.get("file") if isinstance(row.get("file"), str) and row.get("file") else markers_path),
                        limits=limits)
        if index is not None:
            rec.row_groups = tuple(index.get(trial, ()))
            if not rec.row_groups:
                _no_samples(trial, markers_path)
        else:
            i = where.get(trial)
            a, b = (bounds[i], bounds[i + 1]) if i is not None else (0, 0)
            _fill(rec, slots, slot[a:b], frame[a:b], xyz[a:b], markers_path)
        recordings.append(rec)
    return recordings


def _no_samples(trial: str, markers_path: Path) -> None:
    raise InputError(f"trial {trial} has no pelvis or table marker samples (empty trial)", path=markers_path,
                     remedy="check the raw file and its labels, or remove the trial from the protocol")


def _fill(rec: Recording, slots: list, slot: np.ndarray, frame: np.ndarray, xyz: np.ndarray, markers_path: Path) -> None:
    """``rec.markers``: one dense ``(frames, 3)`` array per marker from its rows (frame numbers from 0)."""
    if len(frame) == 0:
        _no_samples(rec.trial, markers_path)
    if frame.min() < 0:
        raise InputError(f"trial {rec.trial} has negative frame numbers", path=markers_path, remedy="re-run `cobot-analysis import`")
    n = int(frame.max()) + 1
    present, inverse = np.unique(slot, return_inverse=True)
    dense = np.full((len(present), n, 3), np.nan)
    dense[inverse, frame] = xyz
    for k, code in enumerate(present):
        rec.markers[slots[code]] = dense[k]


def _trial_row_groups(markers_path: Path) -> dict[str, list[int]] | None:
    """``{trial: [row groups]}`` when the statistics of the ``trial`` column say that every row group
    of the file holds the rows of one trial; None otherwise (or when unknown)."""
    import pyarrow.parquet as pq

    try:
        md = pq.ParquetFile(markers_path).metadata
        j = md.schema.to_arrow_schema().get_field_index("trial")
        index: dict[str, list[int]] = {}
        for i in range(md.num_row_groups):
            stats = md.row_group(i).column(j).statistics
            if stats is None or not stats.has_min_max or stats.min != stats.max or stats.null_count:
                return None
            index.setdefault(str(stats.min), []).append(i)
        return index
    except Exception:  # noqa: BLE001 - unreadable here: the up-front reading names the problem
        return None


def load_markers(rec: Recording, markers_path: Path, pf=None) -> Recording:
    """Fill ``rec.markers`` from its row groups of the markers file (``Recording.row_groups``), checking
    that they hold its rows only; ``pf``: the file already open (``pq.ParquetFile``)."""
    if rec.row_groups is None:
        return rec
    try:
        names, tcode, slots, slot, frame, xyz = _read_marker_rows(markers_path, rec.row_groups, pf)
    except InputError:
        raise
    except Exception as exc:  # pyarrow raises several types for corrupt files or missing columns
        raise InputError(f"cannot read the marker columns ({type(exc).__name__}: {exc})", path=markers_path,
                         remedy="re-run `cobot-analysis import`") from exc
    other = {names[i] for i in np.unique(tcode)} - {rec.trial}
    if other:
        raise InputError(f"marker rows of trials {sorted(other)[:3]} in the row groups of trial {rec.trial} "
                         "(the file's statistics disagree with its rows)", path=markers_path, remedy="re-run `cobot-analysis import`")
    _fill(rec, slots, slot, frame, xyz, markers_path)
    return rec


def _codes(column) -> tuple[np.ndarray, list]:
    """Dictionary indices (-1 for null) and dictionary values of a string column."""
    import pyarrow as pa

    arr = column.combine_chunks() if hasattr(column, "combine_chunks") else column
    if not pa.types.is_dictionary(arr.type):
        arr = arr.dictionary_encode()
    return arr.indices.fill_null(-1).to_numpy(zero_copy_only=False), arr.dictionary.to_pylist()


def _read_marker_rows(path: Path, row_groups: tuple[int, ...] | None = None, pf=None):
    """The pelvis / table-corner rows of a markers file (of ``row_groups``, default all), row group by
    row group, as numpy arrays.

    Strings stay dictionary-encoded (never materialised): returns ``(trial names, trial code per
    row, slot keys [(entity, marker)], slot code per row, frame, xyz with NaN where occluded)``.
    """
    import pyarrow.parquet as pq

    cols = ["trial", "frame", "entity", "marker", "x", "y", "z", "occluded"]
    pf = pf or pq.ParquetFile(path, read_dictionary=["trial", "entity", "marker"], **VERIFY)
    names = set(pf.schema_arrow.names)  # (schema_arrow is rebuilt at each access)
    missing = [c for c in cols if c not in names]
    if missing:
        raise InputError(f"markers table lacks columns {missing}", path=path, remedy="re-run `cobot-analysis import`")
    trial_ids: dict[str, int] = {}
    slot_ids: dict[tuple[str, str], int] = {}
    parts = []
    for i in range(pf.num_row_groups) if row_groups is None else row_groups:
        # one thread: Arrow's thread pool cost more than it saved on a row group (0.6 ms of CPU, 4.7 ms of wall
        # time per trial instead of 0.55 ms with 2 workers on 2 shared cores)
        rg = pf.read_row_group(i, columns=cols, use_threads=False)
        m_idx, m_dict = _codes(rg.column("marker"))
        keep_local = np.array([m in USED_MARKERS for m in m_dict] + [False])  # index -1 (null) -> False
        keep = keep_local[m_idx]
        if not keep.any():
            continue
        e_idx, e_dict = _codes(rg.column("entity"))
        t_idx, t_dict = _codes(rg.column("trial"))
        t_map = np.array([trial_ids.setdefault(str(t), len(trial_ids)) for t in t_dict] + [-1], dtype=np.int64)
        pair = e_idx[keep].astype(np.int64) * (len(m_dict) + 1) + m_idx[keep]
        lut = np.full((len(e_dict) + 1) * (len(m_dict) + 1), -1, dtype=np.int64)  # local pair -> global slot
        for u in np.flatnonzero(np.bincount(pair, minlength=len(lut))):
            lut[u] = slot_ids.setdefault((str(e_dict[u // (len(m_dict) + 1)]), str(m_dict[u % (len(m_dict) + 1)])),
                                         len(slot_ids))
        xyz = np.empty((int(keep.sum()), 3))
        for j, c in enumerate(("x", "y", "z")):
            xyz[:, j] = rg.column(c).to_numpy()[keep]
        occluded = rg.column("occluded").fill_null(False).to_numpy(zero_copy_only=False)[keep]
        xyz[occluded] = np.nan
        parts.append((t_map[t_idx[keep]], lut[pair], rg.column("frame").to_numpy()[keep], xyz))
    if not parts:
        return list(trial_ids), np.empty(0, np.int64), list(slot_ids), np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, 3))
    tcode, slot, frame, xyz = (np.concatenate([p[k] for p in parts]) for k in range(4))
    return list(trial_ids), tcode, list(slot_ids), slot, frame, xyz


# ---- one recording --------------------------------------------------------------------------------
def _pelvis(rec: Recording, entity: str) -> tuple[str, ...]:
    """The pelvis markers of a subject (``protocol.pelvis_definition`` of the markers seen at least once)."""
    present = {m for e, m in rec.markers if e == entity}
    seen = {m for m in present if not np.isnan(rec.markers[(entity, m)]).all()}
    use = pelvis_definition(seen)
    if use is not None:
        return use
    use = pelvis_definition(present)
    if use is None:
        missing = [m for m in PELVIS_MARKERS if m not in present]
        raise InputError(f"trial {rec.trial}: {entity} lacks markers {missing}"
                         + (f" (or {SACRUM} instead of LPSI and RPSI)" if SACRUM not in present else ""), path=rec.source,
                         remedy="map them with the protocol's marker_map (--map LAB=CANON) and re-import")
    m = next(m for m in use if m not in seen)
    raise InputError(f"trial {rec.trial}: marker {m} of {entity} is NaN in every frame", path=rec.source,
                     remedy="fix its label in the raw file or remove the trial from the protocol")


def _check(rec: Recording) -> tuple[list[str], bool, dict[str, tuple[str, ...]]]:
    """Entities of the recording (subjects, then table) and the markers used per entity (pelvis
    definition of each subject, TAB1-3 of the table), after the bad-input checks."""
    entities = sorted({e for e, _ in rec.markers}, key=lambda e: (e == "table", e))
    subjects = [e for e in entities if e in SUBJECT_ENTITIES]
    has_table = "table" in entities
    if not subjects:
        raise InputError(f"trial {rec.trial} has no pelvis markers (found entities {entities})", path=rec.source,
                         remedy=f"map the pelvis labels to {pelvis_requirement()} with the protocol's marker_map and re-import")
    if all(np.isnan(xyz).all() for xyz in rec.markers.values()):
        raise InputError(f"trial {rec.trial}: every pelvis and table marker sample is NaN (no data)", path=rec.source,
                         remedy="check the raw file, or remove the trial from the protocol")
    used: dict[str, tuple[str, ...]] = {}
    for e in entities:
        if e != "table":
            used[e] = _pelvis(rec, e)
            continue
        missing = [m for m in TABLE_MARKERS if (e, m) not in rec.markers]
        if missing:
            raise InputError(f"trial {rec.trial}: {e} lacks markers {missing}", path=rec.source,
                             remedy="map them with the protocol's marker_map (--map LAB=CANON) and re-import")
        for m in TABLE_MARKERS:
            if np.isnan(rec.markers[(e, m)]).all():
                raise InputError(f"trial {rec.trial}: marker {m} of {e} is NaN in every frame", path=rec.source,
                                 remedy="fix its label in the raw file or remove the trial from the protocol")
        used[e] = TABLE_MARKERS
    keys = [(e, m) for e in entities for m in used[e]]
    zmed = float(np.nanmedian(np.concatenate([rec.markers[k][:, 2] for k in keys])))
    if not 0.2 < zmed < 3.0:
        hint = "millimetres" if zmed > 200 else "a wrong unit or a vertical axis other than z"
        raise InputError(f"trial {rec.trial}: median marker height {zmed:.4g} m looks like {hint}", path=rec.source,
                         remedy="re-import with the right --units and --up (markers.parquet must be in metres, z up)")
    check_positions(np.stack([rec.markers[k] for k in keys], axis=1), [f"{e}:{m}" for e, m in keys], rec.rate, rec.source,
                    what=f"trial {rec.trial}: ", **rec.limits)
    return entities, has_table, used


def _flags(*pairs: tuple[str, bool]) -> str:
    on = [name for name, cond in pairs if cond]
    return ";".join(on) if on else "ok"


def process_recording(rec: Recording, p: Params) -> dict[str, Any]:
    """Gaps, filter, kinematics, segmentation and normalisation of one recording.

    Returns ``{"gaps": [GAPS row tuples], "trajectories": [(metadata dict, numeric array
    (N, len(NUMERIC)))]}``.
    """
    entities, has_table, used = _check(rec)
    rate = rec.rate
    # 1-2. gaps: report and fill the short ones
    gap_rows: list[tuple] = []
    filled: dict[tuple[str, str], np.ndarray] = {}
    fill_mask: dict[tuple[str, str], np.ndarray] = {}
    for e in entities:
        for m in used[e]:
            xyz, mask, starts, lengths, done = gaps.fill_gaps(rec.markers[(e, m)], rate, p.max_gap)
            filled[(e, m)], fill_mask[(e, m)] = xyz, mask
            gap_rows += [(rec.trial, e, m, int(s), int(k), k / rate, bool(d)) for s, k, d in zip(starts, lengths, done)]
    # 3. filter all markers of the recording in one go (segments split at the remaining NaN)
    keys = list(filled)
    sos = filtering.butter_sos(p.cutoff, rate, p.order, p.order_convention)
    smooth = filtering.lowpass(np.stack([filled[k] for k in keys], axis=1), sos)
    mk = {k: smooth[:, i] for i, k in enumerate(keys)}
    n_frames = smooth.shape[0]
    # 4. kinematics per entity, on the whole recording
    kinem: dict[str, dict[str, np.ndarray]] = {}
    for e in entities:
        if e == "table":
            xy, theta = kin.table_pose(mk[(e, "TAB1")], mk[(e, "TAB2")], mk[(e, "TAB3")])
            rigid = np.zeros(n_frames, dtype=bool)
            theta_needs = ("TAB1", "TAB2")
        elif used[e] == PELVIS_MARKERS:
            xy, rigid = kin.pelvis_com(*(mk[(e, m)] for m in PELVIS_MARKERS))
        else:
            xy, rigid = kin.sacrum_pelvis_com(*(mk[(e, m)] for m in used[e]))
        if e != "table":
            theta = kin.pelvis_theta(mk[(e, "LASI")], mk[(e, "RASI")])
            theta_needs = used[e] if p.orientation_markers == "pelvis" else ("LASI", "RASI")
        markers = used[e]
        kinem[e] = {
            "xy": xy, "theta": theta, "v": kin.velocity(xy, rate), "rigid": rigid,
            "filled": np.any([fill_mask[(e, m)] for m in markers], axis=0),
            "gap": np.any([np.isnan(filled[(e, m)]).any(axis=1) for m in markers], axis=0),
            "theta_gap": np.any([np.isnan(filled[(e, m)]).any(axis=1) for m in theta_needs], axis=0),
        }
    # 5. segmentation -> (label, onset, offset, entities, cut off by the recording's edges)
    segs = _segments(rec, p, entities, has_table, mk, kinem)
    # 6. trajectories
    out = []
    for label, on, off, ents, cut, later in segs:
        base = {c: rec.meta.get(c) for c in META_COLUMNS}
        base.update(kind="trial", n_trials=1, direction=label)
        base["trial"] = f"{rec.trial}_{label}" if label else rec.trial
        measured = False  # a forward carriage's end orientation taken from the table (none in the trials table)
        if label == "return":
            base["scenario"] = 3  # the return is scenario 3 by design (docs/methods.md sec. 1.2)
            th = kinem["table"]["theta"][off] if "table" in kinem else np.nan
            base["end_orientation"] = float(wrap(th))  # measured: the table's orientation at the offset
        elif label == "forward":
            base["end_orientation"], measured = pairs.end_orientation(rec.trial, rec.source, rec.meta, kinem["table"]["theta"][off])
        for e in ents:
            meta, numeric = _trajectory(base, e, kinem[e], on, off, rate, p, cut, later, measured)
            meta["pelvis_markers"] = None if e == "table" else ",".join(used[e])
            out.append((meta, numeric))
    result: dict[str, Any] = {"gaps": gap_rows, "trajectories": out}
    if {"subject1", "subject2", "table"} <= set(entities):  # the end each subject holds, checked across recordings
        carried = np.concatenate([np.arange(on, off + 1) for label, on, off, *_ in segs if label != "approach"])
        k = {e: kinem[e]["xy"][carried] for e in ("subject1", "subject2")}
        result["subject1_end"] = (rec.trial, rec.source, pairs.subject1_end(k["subject1"], k["subject2"],
                                                                            kinem["table"]["theta"][carried]))
    return result


def process_or_refuse(rec: Recording, p: Params) -> dict[str, Any] | Refused:
    """``process_recording``, with bad input returned as ``Refused`` so that one run names every bad trial."""
    try:
        return process_recording(rec, p)
    except InputError as exc:
        return Refused.of(rec.trial, rec.source, exc)


def _segments(rec: Recording, p: Params, entities: list[str], has_table: bool, mk: dict, kinem: dict) -> list[tuple]:
    """``[(direction label or None, onset frame, offset frame, entities, cut, later), ...]`` of one recording;
    ``cut``: the trajectory runs off the start or end of the recording or of its visible data
    (``segmentation.cut_off``); ``later``: walks of the recording after this one, left out (a walking trial's)."""
    subjects = [e for e in entities if e != "table"]
    rate = rec.rate
    if not has_table:
        speed = np.hypot(*kinem[subjects[0]]["v"].T)
        found = segmentation.walks(speed, rate, p.speed_threshold, p.min_duration, p.rest_speed, p.min_rest)
        if not found:
            xy = kinem[subjects[0]]["xy"]
            with np.errstate(invalid="ignore"):
                spread = float(np.nanmax(np.hypot(*(xy - np.nanmedian(xy, axis=0)).T))) if np.isfinite(xy).any() else float("nan")
                top = float(np.nanmax(speed)) if np.isfinite(speed).any() else float("nan")
            raise InputError(f"trial {rec.trial}: nobody walks (static recording?): the pelvis CoM stays within {spread:.3f} m "
                             f"over {len(speed) / rate:.3g} s, top speed {top:.2f} m/s; a walk is above {p.speed_threshold:g} m/s "
                             f"for {p.min_duration:g} s", path=rec.source,
                             remedy="leave it out of the protocol; for a slow walk lower --speed-threshold / --min-duration")
        # the first walk is the trial's (later ones: e.g. back to the start, flagged later_walks)
        return [(None, *found[0], subjects, segmentation.cut_off(speed, *found[0]), len(found) - 1)]
    pairs.check_labels(rec.trial, rec.source, rec.meta)
    height = kin.table_height(*(mk[("table", m)] for m in TABLE_MARKERS))
    found, h0 = segmentation.carriages(height, rate, p.lift_threshold, p.floor_window, p.min_duration, p.min_set_down)
    direction = rec.meta.get("direction")
    labels = [str(direction)] if isinstance(direction, str) and direction else ["forward", "return"]
    pairs.check_floor(rec.trial, rec.source, height, h0, rate, p.floor_window, p.min_duration)
    pairs.check_count(rec.trial, rec.source, found, labels, h0, rate, p.lift_threshold, p.min_duration,
                      p.min_set_down)
    if labels == ["forward", "return"]:
        pairs.check_return(rec.trial, rec.source, found, kinem["table"]["xy"], rate)
    segs = [(lab, a, b, entities, segmentation.cut_off(height, a, b), 0) for lab, (a, b) in zip(labels, found)]
    if p.keep_approach:  # each subject's walk to the table: speed segmentation before the first lift
        on = found[0][0]
        approach = []
        for e in subjects:
            speed = np.hypot(*kinem[e]["v"][: on + 1].T)
            bounds = segmentation.walking_bounds(speed, rate, p.speed_threshold, p.min_duration, p.rest_speed)
            if bounds is not None:  # it ends where the carriage starts: only a cut-off start counts
                approach.append(("approach", bounds[0], bounds[1], [e], segmentation.cut_off(speed, bounds[0], bounds[1], end=False), 0))
        segs = approach + segs
    return segs


def _trajectory(base: dict[str, Any], entity: str, k: dict[str, np.ndarray], on: int, off: int, rate: float,
                p: Params, cut: bool = False, later: int = 0, end_measured: bool = False) -> tuple[dict[str, Any], np.ndarray]:
    sl = slice(on, off + 1)
    xy, v, theta = k["xy"][sl], k["v"][sl], k["theta"][sl]
    orientation_missing = bool(k["theta_gap"][sl].any() or np.isnan(theta).any())
    if orientation_missing:
        theta = np.full_like(theta, np.nan)
        g = theta
    else:
        g = kin.unwrap_nan(kin.gamma(theta, v, p.gamma_min_speed))
    n = p.n_samples
    res = normalisation.normalise(np.column_stack([xy, theta, g, v]), 0, off - on, n)
    travel_time = (off - on) / rate
    ph = normalisation.phase(n)
    t = ph * travel_time / 100.0
    x, y = res[:, 0], res[:, 1]
    numeric = np.column_stack([
        np.arange(n), ph, t, on / rate + t, x, y, res[:, 2], wrap(res[:, 3]), res[:, 4], res[:, 5],
        np.full(n, travel_time), np.full(n, np.hypot(x[-1] - x[0], y[-1] - y[0])),
    ])
    quality = _flags(
        ("short_gaps_filled", bool(k["filled"][sl].any())),
        ("long_gap", bool(k["gap"][sl].any())),
        ("com_rigid_fill", bool(k["rigid"][sl].any())),
        ("orientation_missing", orientation_missing),
        ("position_missing", bool(np.isnan(xy).any())),
        ("gamma_undefined", not orientation_missing and bool(np.isnan(g).all())),
        ("truncated", cut),
        ("later_walks", later > 0),
        ("end_orientation_measured", end_measured),
    )
    return {**base, "entity": entity, "quality": quality}, numeric


def _process_chunk(item: tuple[Path, list[Recording], Params]) -> list[dict[str, Any] | Refused]:
    """Read (``load_markers``, the file opened once) and process recordings; each one's markers are
    dropped once it is done."""
    import pyarrow.parquet as pq

    markers_path, recs, p = item
    pf = None
    out = []
    for r in recs:
        if r.row_groups is not None and pf is None:
            pf = pq.ParquetFile(markers_path, read_dictionary=["trial", "entity", "marker"], **VERIFY)
        out.append(process_or_refuse(load_markers(r, markers_path, pf), p))
        r.markers = {}
    return out


# ---- assembling -----------------------------------------------------------------------------------
def assemble(results: list[dict[str, Any]], n_samples: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Concatenate per-recording results into the trajectories and gaps tables."""
    trajs = [t for r in results for t in r["trajectories"]]
    numeric = np.concatenate([a for _, a in trajs]) if trajs else np.empty((0, len(NUMERIC)))
    meta = pd.DataFrame([m for m, _ in trajs], columns=[*TRIAL_COLUMNS, "entity", "pelvis_markers", "quality"])
    for c in ("scenario", "repetition", "n_trials"):
        meta[c] = pd.to_numeric(meta[c], errors="coerce").astype("Int64")
    meta["end_orientation"] = pd.to_numeric(meta["end_orientation"], errors="coerce").astype(float)
    for c in meta.columns:  # labels: str or None (never NaN, never numbers)
        if c in ("entity", "pelvis_markers", "quality") or TRIAL_COLUMNS[c].dtype == "string":
            meta[c] = [v if isinstance(v, str) else None if v is None or pd.isna(v) else str(v) for v in meta[c]]
    df = meta.iloc[np.repeat(np.arange(len(meta)), n_samples)].reset_index(drop=True)
    for j, c in enumerate(NUMERIC):
        df[c] = numeric[:, j]
    df["sample"] = df["sample"].astype(np.int64)
    df = df[[*TRIAL_COLUMNS, "entity", *NUMERIC, "quality", "pelvis_markers"]]
    gap_df = pd.DataFrame([g for r in results for g in r["gaps"]],
                          columns=["trial", "entity", "marker", "start_frame", "n_frames", "duration", "filled"])
    gap_df = gap_df.astype({"start_frame": np.int64, "n_frames": np.int64, "duration": float, "filled": bool})
    return df, gap_df


def process(markers_path: Path, trials_path: Path, p: Params, *, jobs: int | None = None,
            scheduler: str | None = None) -> tuple[pd.DataFrame, pd.DataFrame, int, list[Refused]]:
    """Preprocess every recording of an import: (trajectories, gaps, recordings processed, refused ones).

    Bad filter parameters and a ``--samples`` too large for the memory (``check_memory``) are refused
    before any long work; refused recordings raise one ``InputError`` naming them all unless
    ``p.skip_bad`` (and some recording is good)."""
    from cobot_analysis.parallel import chunked, default_jobs, map_tasks

    check_memory(p, trials_path)
    # local workers read their trials' row groups themselves; a Dask cluster's workers get the arrays
    # (they may not see this file system)
    recordings = load_recordings(markers_path, trials_path, lazy=scheduler is None)
    import scipy.interpolate  # noqa: F401 - imported once here, inherited by forked workers

    for r in recordings:  # bad parameters are reported before any long work
        _check_filter(r, p, trials_path)
    n_jobs = 1 if scheduler is None and (jobs or default_jobs()) <= 1 else (jobs or default_jobs())
    size = max(1, min(25, len(recordings) // (4 * n_jobs) or 1))
    chunks = [(markers_path, list(c), p) for c in chunked(recordings, size)]
    del recordings
    done = [r for chunk in map_tasks(_process_chunk, chunks, jobs=n_jobs, scheduler=scheduler,
                                     description="preprocess") for r in chunk]
    return finish(done, p, markers_path)


def _check_filter(rec: Recording, p: Params, trials_path: Path) -> None:
    """Refuse filter parameters that do not fit the recording's rate (``filtering.butter_sos``)."""
    try:
        filtering.butter_sos(p.cutoff, rec.rate, p.order, p.order_convention)
    except ValueError as exc:
        raise InputError(f"trial {rec.trial}: {exc}", path=trials_path,
                         remedy="change --cutoff / --order / --order-convention") from exc


def finish(done: list[dict[str, Any] | Refused], p: Params, markers_path: Path) -> tuple[pd.DataFrame, pd.DataFrame, int, list[Refused]]:
    """``process``'s result from every recording's (``process_or_refuse``, in the trials table's order):
    refused ones named together in one ``InputError`` unless ``p.skip_bad`` (and some recording is good)."""
    refused = [r for r in done if isinstance(r, Refused)]
    results = [r for r in done if not isinstance(r, Refused)]
    swapped = pairs.swapped_subjects([r["subject1_end"] for r in results if "subject1_end" in r])
    if swapped:  # Subject 1 at the other end of the table than in the other recordings
        names = {r.trial for r in swapped}
        results = [r for r in results if r.get("subject1_end", ("",))[0] not in names]
        refused += swapped
    if refused and (not p.skip_bad or not results):
        raise refusal_error(refused, len(done), markers_path, "preprocess")
    traj, gap_df = assemble(results, p.n_samples)
    return traj, gap_df, len(results), refused


# ---- import and preprocess in one pass ------------------------------------------------------------
def recording_of(trial: Any, meta: dict[str, Any], source: str, limits: dict[str, float]) -> Recording:
    """The ``Recording`` that ``load_recordings`` + ``load_markers`` read back from the import's files, made
    from the imported trial itself (``io.markers.ImportedTrial``): its pelvis and table-corner markers, a
    sample whose x is missing missing in full (the markers table's ``occluded``)."""
    rec = Recording(trial.trial, float(trial.rate), meta, source=source, limits=limits)
    for k, key in sorted(((k, (e, m)) for k, (e, m) in enumerate(zip(trial.entities, trial.markers)) if m in USED_MARKERS),
                         key=lambda item: item[1]):
        xyz = np.array(trial.xyz[:, k, :], dtype=float)
        xyz[np.isnan(xyz[:, 0])] = np.nan
        rec.markers[key] = xyz
    return rec


@dataclass(frozen=True)
class OnePass:
    """A trial's task for ``import_and_process``: its import task, the preprocess parameters, its row of
    the trials table's metadata columns, and the plausibility limits of the import."""

    task: Any  # io.markers.TrialTask
    params: Params
    meta: dict[str, Any]
    limits: dict[str, float]


def import_and_process(item: OnePass) -> Refused | tuple[Any, dict[str, Any] | Refused | None]:
    """Import one trial (``io.markers.import_or_refuse``: every check) and preprocess it where it was read:
    ``(trial, its preprocessing)``, the same as ``process_or_refuse`` of what the ``preprocess`` stage
    reads back from the import's files; None when the filter does not fit the trial's rate (the caller
    refuses the run as ``process`` does: ``_check_filter``)."""
    from cobot_analysis.io.markers import import_or_refuse

    t = import_or_refuse(item.task)
    if isinstance(t, Refused):
        return t
    rec = recording_of(t, item.meta, str(item.task.path), item.limits)
    p = item.params
    try:
        filtering.butter_sos(p.cutoff, rec.rate, p.order, p.order_convention)
    except ValueError:
        return t, None
    return t, process_or_refuse(rec, p)


def finish_one_pass(imported: list[Any], done: list[dict[str, Any] | Refused | None], p: Params, markers_path: Path,
                    trials_path: Path) -> tuple[pd.DataFrame, pd.DataFrame, int, list[Refused]]:
    """``process``'s result from ``import_and_process``'s (``done``, one per trial ``imported``, in order),
    with the same refusals: filter parameters that do not fit a trial's rate, then the refused recordings."""
    for t, d in zip(imported, done):
        if d is None:
            _check_filter(Recording(t.trial, float(t.rate), {}), p, trials_path)
    return finish(list(done), p, markers_path)


def one_pass_items(plan: Any, p: Params) -> list[OnePass]:
    """``import_and_process``'s tasks of an import plan (``io.markers.ImportPlan``): each with its row of
    the trials table's metadata, as ``load_recordings`` gives it (``Recording.meta``)."""
    import scipy.interpolate  # noqa: F401 - imported once here (0.8 s of CPU), inherited by forked workers
    import scipy.signal  # noqa: F401

    from cobot_analysis.io.markers import trial_metadata

    rows = trial_metadata(plan.protocol)
    rows.attrs = {}
    limits = {"lab_extent": float(plan.limits.get("lab_extent") or LAB_EXTENT),
              "max_speed": float(plan.limits.get("max_speed") or MAX_SPEED),
              "max_spike": float(plan.limits.get("max_spike") or MAX_SPIKE)}
    meta = [{c: row.get(c) for c in TRIAL_COLUMNS} for _, row in rows.iterrows()]
    return [OnePass(task, p, m, limits) for task, m in zip(plan.tasks, meta)]
