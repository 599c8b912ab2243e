"""The protocol file: which raw file is which trial, of whom, in which condition.

A protocol is a YAML file::

    study: synthetic-walking
    rate: 200                  # Hz, optional (the raw file's own rate wins when it is valid)
    invalid_rate: protocol     # optional: use ``rate`` where a file declares an invalid rate (default: refuse)
    entities:                  # label prefix in the raw files ("S1:LASI") -> entity
      S1: subject1
      S2: subject2
      Table: table
    marker_map:                # optional: lab label -> canonical label (ISB names, TAB1..TAB3)
      L_ASIS: LASI
    subjects: subjects.csv     # or an inline list of mappings: id, sex, weight (kg), height (m)
    pairs: pairs.csv           # pair study: id, subject1, subject2
    trials: trials.csv         # or an inline list; columns below

Trials columns: ``trial`` (unique id), ``file`` (relative to the protocol file, inside its folder
unless ``allow_outside: true``: ``..``, absolute paths and symbolic links that lead out of it are
refused by default), and the trial
metadata of ``schema.TRIAL_COLUMNS`` that apply (subject or pair, condition, direction, scenario,
configuration, end_orientation, repetition). CSV paths are relative to the protocol file.

Any other key is an error that names the valid ones (``PROTOCOL_KEYS``), and so is a key given
twice in one mapping; ``rate`` must be a number (Hz), ``entities`` and ``marker_map`` mappings of
labels.

Canonical markers: pelvis LASI RASI LPSI RPSI, or LASI RASI and one sacrum marker SACR (Plug-in-Gait
option; Vicon's older name VSAC is read as SACR, and a lab's PSIS midpoint can be mapped to SACR):
see ``pelvis_definition``; feet LHEE LTOE LMT5 / RHEE RTOE RMT5; head LFHD RFHD LBHD RBHD; table
TAB1 TAB2 TAB3 with TAB1->TAB2 along a long side and TAB1->TAB3 along a short side (TAB2 and TAB3
are opposite corners).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cobot_analysis.lazy import pandas as pd

from cobot_analysis.errors import InputError
from cobot_analysis.schema import as_text
from cobot_analysis.io.plausibility import INVALID_RATE_POLICIES

PELVIS_MARKERS = ("LASI", "RASI", "LPSI", "RPSI")
SACRUM = "SACR"
#: the two pelvis definitions, preferred first: 2 ASIS + 2 PSIS, or 2 ASIS + one sacrum marker.
PELVIS_DEFINITIONS = (PELVIS_MARKERS, ("LASI", "RASI", SACRUM))
#: labels that name a canonical marker without a marker map.
ALIASES = {"VSAC": SACRUM}
FOOT_MARKERS = ("LHEE", "LTOE", "LMT5", "RHEE", "RTOE", "RMT5")
HEAD_MARKERS = ("LFHD", "RFHD", "LBHD", "RBHD")
SUBJECT_MARKERS = PELVIS_MARKERS + FOOT_MARKERS + HEAD_MARKERS
TABLE_MARKERS = ("TAB1", "TAB2", "TAB3")
#: markers of a person that the import keeps (the sacrum besides the 14 markers of the studies).
KEPT_SUBJECT_MARKERS = SUBJECT_MARKERS + (SACRUM,)
ENTITIES = ("walker", "subject1", "subject2", "table")
DEFAULT_ENTITIES = {"S1": "subject1", "S2": "subject2", "Table": "table", "TABLE": "table"}
PROTOCOL_KEYS = ("study", "rate", "invalid_rate", "allow_outside", "entities", "marker_map", "subjects", "pairs", "trials")


def pelvis_definition(present) -> tuple[str, ...] | None:
    """The pelvis markers to use among the canonical markers ``present`` (LPSI and RPSI when both are
    there, else SACR), or None when neither definition is complete."""
    return next((d for d in PELVIS_DEFINITIONS if set(d) <= set(present)), None)


def pelvis_requirement() -> str:
    """'LASI RASI LPSI RPSI (or LASI RASI SACR)', for messages."""
    return " (or ".join(" ".join(d) for d in PELVIS_DEFINITIONS) + ")"


@dataclass
class Protocol:
    path: Path
    study: str
    trials: pd.DataFrame
    subjects: pd.DataFrame = field(default_factory=lambda: pd.DataFrame())
    pairs: pd.DataFrame = field(default_factory=lambda: pd.DataFrame())
    rate: float | None = None
    invalid_rate: str = "refuse"
    allow_outside: bool = False
    entities: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_ENTITIES))
    marker_map: dict[str, str] = field(default_factory=dict)

    def file_path(self, file: Any) -> Path:
        """A trial file named by the protocol (its ``file`` column), resolved from the protocol's folder."""
        return (self.path.parent / str(file)).resolve()

    def resolve_label(self, label: str, default_entity: str = "walker") -> tuple[str, str]:
        """Raw label -> (entity, canonical marker). ``"S1:LASI"`` -> ``("subject1", "LASI")``."""
        prefix, _, name = label.rpartition(":")
        name = self.marker_map.get(label, self.marker_map.get(name, name)).strip()
        name = ALIASES.get(name, name)
        entity = self.entities.get(prefix, prefix.lower()) if prefix else default_entity
        if name in TABLE_MARKERS and not prefix:
            entity = "table"
        return entity, name


OUTSIDE_REMEDY = ("move it into the protocol's folder, or write 'allow_outside: true' in the protocol to accept files outside it "
                  "(the import then lists them in its manifest and results.md)")


def outside(base: Path, path: Path) -> bool:
    """True when ``path`` (after ``..`` and symbolic links) lies outside the folder ``base``."""
    try:
        path.resolve().relative_to(base.resolve())
        return False
    except ValueError:
        return True


def _table(value: Any, base: Path, what: str, protocol_path: Path, allow_outside: bool = False) -> pd.DataFrame:
    """A protocol section given inline (a list of mappings) or as a CSV path."""
    if value is None:
        return pd.DataFrame()
    if isinstance(value, list):
        if not all(isinstance(v, dict) for v in value):
            raise InputError(f"'{what}' must be a list of mappings (one per row) or a CSV file name", path=protocol_path,
                             remedy=f"write each {what} row as {{column: value, ...}}")
        return pd.DataFrame(value)
    if not isinstance(value, str):
        raise InputError(f"'{what}' must be a CSV file name or a list of rows, not {type(value).__name__}", path=protocol_path,
                         remedy=f"write e.g. '{what}: {what}.csv'")
    csv = base / value
    if not csv.is_file():
        raise InputError(f"{what} file {value} not found", path=protocol_path, remedy="fix the path (relative to the protocol file)")
    if not allow_outside and outside(base, csv):
        raise InputError(f"the {what} file {value} is outside the protocol's folder ({csv.resolve()})", path=protocol_path,
                         remedy=OUTSIDE_REMEDY)
    try:
        return pd.read_csv(csv)
    except (UnicodeDecodeError, ValueError, pd.errors.ParserError) as exc:  # binary, empty or malformed CSV
        raise InputError(f"not a readable CSV table ({type(exc).__name__})", path=csv,
                         remedy=f"write the {what} as a UTF-8 CSV file with a header row") from exc


def _mapping(doc: dict, key: str, path: Path, example: str) -> dict[str, str]:
    """A protocol section that maps labels to names (``entities``, ``marker_map``)."""
    value = doc.get(key) or {}
    if not isinstance(value, dict) or not all(isinstance(v, str) for v in value.values()):
        raise InputError(f"'{key}' must map labels to names, not {value!r:.60}", path=path, remedy=f"write e.g. '{key}: {{{example}}}'")
    return {str(k): v for k, v in value.items()}


def _rate(doc: dict, path: Path) -> float | None:
    value = doc.get("rate")
    if value is None:
        return None
    try:
        rate = float(value)
    except (TypeError, ValueError):
        rate = float("nan")
    if isinstance(value, bool) or not rate > 0 or rate == float("inf"):
        raise InputError(f"'rate' must be a positive number of Hz, not {value!r:.40}", path=path, remedy="write e.g. 'rate: 200'")
    return rate


def read_yaml(path: Path, what: str, remedy: str) -> Any:
    """A YAML document; a key given twice in one mapping is an error (PyYAML would keep the last
    silently: ``marker_map: {SACR: LPSI, SACR: RPSI}`` is one mapping, not two)."""
    import yaml

    class Strict(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            keys = [self.construct_object(k, deep=deep) for k, _ in node.value]
            dup = next((k for i, k in enumerate(keys) if k in keys[:i]), None)
            if dup is not None:
                raise InputError(f"key {dup!r} given twice in the mapping at line {node.start_mark.line + 1}", path=path,
                                 remedy="give each key once; a label is one marker")
            return super().construct_mapping(node, deep=deep)

    try:
        return yaml.load(path.read_text(), Loader=Strict)  # noqa: S506 - a SafeLoader subclass
    except (yaml.YAMLError, UnicodeDecodeError, TypeError) as exc:  # TypeError: an unhashable key
        raise InputError(f"not a valid YAML {what} ({type(exc).__name__})", path=path, remedy=remedy) from exc
    except RecursionError:  # PyYAML composes nested collections recursively
        raise InputError(f"not a {what}: its YAML is nested too deeply", path=path, remedy=remedy) from None


def id_text(values: pd.Series) -> pd.Series:
    """Ids as text, 7 and 7.0 alike (a CSV column with a blank cell reads as floats); NaN stays NaN."""
    return values.map(lambda v: v if pd.isna(v) else as_text(v))


def check_ids(subjects: pd.DataFrame, pairs: pd.DataFrame, trials: pd.DataFrame | None, path) -> None:
    """Each id of the subjects and pairs tables once, a pair of two subjects, each pair's subjects ids of the subjects
    table, and each trial's subject (pair) an id of the subjects (pairs) table, where those tables are given: a typo
    (S99 for S09) would otherwise make a subject of its own in every per-subject question, and an id given twice
    leave its anthropometrics to chance. ``path``: the file the tables come from, for the message."""
    for table, rows in (("subjects", subjects), ("pairs", pairs)):
        twice = id_text(rows["id"]).dropna()[lambda v: v.duplicated()] if "id" in rows.columns else []
        if len(twice):
            raise InputError(f"the {table} table lists {twice.iloc[0]} twice", path=path,
                             remedy=f"give each row of the {table} table its own id")
    if {"subject1", "subject2"} <= set(pairs.columns):
        same = pairs[id_text(pairs["subject1"]).eq(id_text(pairs["subject2"]))]
        if len(same):
            raise InputError(f"pair {same['id'].iloc[0] if 'id' in same else same.index[0]} has "
                             f"{same['subject1'].iloc[0]} as both subject1 and subject2", path=path,
                             remedy="correct the pair's subject1 or subject2 in the pairs table")

    def ids(table: pd.DataFrame) -> set[str] | None:
        return set(id_text(table["id"]).dropna()) if "id" in table.columns and len(table) else None

    known_subjects, known_pairs = ids(subjects), ids(pairs)
    checks = [(pairs, "id", col, known_subjects, "subjects") for col in ("subject1", "subject2")]
    if trials is not None:
        checks += [(trials, "trial", "subject", known_subjects, "subjects"), (trials, "trial", "pair", known_pairs, "pairs")]
    for rows, key, col, known, table in checks:
        if known is None or col not in rows.columns:
            continue
        named = id_text(rows[col]).dropna()
        bad = named[~named.isin(known)]
        if len(bad):
            row = rows.loc[bad.index[0]]
            what = "trial" if key == "trial" else "pair"
            raise InputError(f"{what} {row[key]} names {col} {bad.iloc[0]}, which is not an id of the {table} table "
                             f"({', '.join(sorted(known)[:6])}{' ...' if len(known) > 6 else ''})", path=path,
                             remedy=f"correct the '{col}' column of the {what}s table, or add {bad.iloc[0]} to the {table} table")


def load_protocol(path: str | os.PathLike) -> Protocol:
    """Read and check a protocol file: every trial file it names must exist."""
    path = Path(path)
    if not path.is_file():
        raise InputError("protocol file not found", path=path, remedy="pass the protocol YAML written with the data (e.g. protocol.yaml)")
    doc = read_yaml(path, "protocol", "check its syntax")
    if not isinstance(doc, dict) or "trials" not in doc:
        raise InputError("protocol has no 'trials' section", path=path, remedy="list the trials (inline or as a CSV path)")
    unknown = [str(k) for k in doc if k not in PROTOCOL_KEYS]
    if unknown:
        raise InputError(f"unknown protocol key(s) {unknown}", path=path, remedy=f"use only {', '.join(PROTOCOL_KEYS)}")
    base = path.parent
    rate = _rate(doc, path)
    allow_outside = doc.get("allow_outside", False)
    if not isinstance(allow_outside, bool):
        raise InputError(f"'allow_outside' must be true or false, not {allow_outside!r:.40}", path=path,
                         remedy="write 'allow_outside: true' to accept files outside the protocol's folder, or leave it out")
    invalid_rate = doc.get("invalid_rate", "refuse")
    if invalid_rate not in INVALID_RATE_POLICIES or (invalid_rate == "protocol" and rate is None):
        raise InputError(f"'invalid_rate' must be {' or '.join(INVALID_RATE_POLICIES)} ('protocol' with a 'rate'), "
                         f"not {invalid_rate!r:.40}", path=path,
                         remedy="write 'invalid_rate: protocol' with 'rate: HZ' to replace a file's invalid rate, or leave it out")
    entities = _mapping(doc, "entities", path, "S1: subject1, Table: table")
    bad = sorted({e for e in entities.values() if e not in ENTITIES})
    if bad:
        raise InputError(f"'entities' names unknown entities {bad}", path=path, remedy=f"map label prefixes to {', '.join(ENTITIES)}")
    marker_map = _mapping(doc, "marker_map", path, "L_ASIS: LASI")
    trials = _table(doc["trials"], base, "trials", path, allow_outside)
    for col in ("trial", "file"):
        if col not in trials.columns:
            raise InputError(f"trials table has no '{col}' column", path=path, remedy="add it (see docs/protocol.md)")
    if trials.empty:
        raise InputError("protocol lists no trials", path=path, remedy="add at least one trial")
    if trials["file"].isna().any() or trials["trial"].isna().any():
        rows = [int(i) + 1 for i in trials.index[trials["file"].isna() | trials["trial"].isna()][:5]]
        raise InputError(f"trials rows {rows} have no trial id or no file", path=path, remedy="give every trial an id and a file")
    dup = trials["trial"][trials["trial"].duplicated()].unique()
    if len(dup):
        raise InputError(f"duplicated trial ids {list(dup[:5])}", path=path, remedy="make trial ids unique")
    proto = Protocol(
        path=path.resolve(),
        study=str(doc.get("study", path.parent.name)),
        trials=trials,
        subjects=_table(doc.get("subjects"), base, "subjects", path, allow_outside),
        pairs=_table(doc.get("pairs"), base, "pairs", path, allow_outside),
        rate=rate,
        invalid_rate=invalid_rate,
        allow_outside=allow_outside,
        entities={**DEFAULT_ENTITIES, **entities},
        marker_map=marker_map,
    )
    check_ids(proto.subjects, proto.pairs, proto.trials, path)
    root = base.resolve()
    for trial, file in zip(trials["trial"], trials["file"]):
        f = proto.file_path(file)
        if not f.is_file():
            raise InputError(f"trial {trial} names file {file}, which does not exist", path=path,
                             remedy="fix the 'file' column or restore the file")
        if not allow_outside and not f.is_relative_to(root):  # outside(base, f), f already resolved
            raise InputError(f"trial {trial} names file {file}, outside the protocol's folder ({f})", path=path,
                             remedy=OUTSIDE_REMEDY)
    return proto


def save_protocol(path: str | os.PathLike, study: str, trials: pd.DataFrame, *, subjects: pd.DataFrame | None = None,
                  pairs: pd.DataFrame | None = None, rate: float | None = None, marker_map: dict[str, str] | None = None,
                  entities: dict[str, str] | None = None) -> Path:
    """Write ``protocol.yaml`` with its trials (and subjects, pairs) as CSV files beside it."""
    import yaml

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    doc: dict[str, Any] = {"study": study}
    if rate:
        doc["rate"] = rate
    if entities:
        doc["entities"] = entities
    if marker_map:
        doc["marker_map"] = marker_map
    for name, df in (("subjects", subjects), ("pairs", pairs), ("trials", trials)):
        if df is not None and not df.empty:
            df.to_csv(path.parent / f"{name}.csv", index=False)
            doc[name] = f"{name}.csv"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path
