"""Parquet tables of the pipeline: documented columns, units, and file metadata.

Every table a stage writes is declared as a ``TableSchema``; ``write_table`` checks the columns,
gives every declared column its declared Arrow type (``ARROW_TYPES``: strings as large_string,
categoricals as dictionary<int32, string>, int64, float64, bool; nullable, so a column that
is null in one table is never written as Arrow's Null type and two tables of the same kind always
concatenate), stores each column's unit and description as Arrow field metadata
(``unit``, ``description``), stores the schema (name, version, per-column unit and description) and
any stage metadata (e.g. sampling rate, source units) as JSON in the Parquet key-value metadata under
``cobot_analysis``, gives every data page its CRC32 checksum (``VERIFY``: the readers check it, so that a
flipped bit is an error and never a changed value), and writes atomically (temporary file, then rename). ``read_table`` checks a
file is the table it claims to be (name, columns, the types and ``limits`` of its number columns:
``check_values``) and returns the DataFrame with its metadata in ``df.attrs["cobot_analysis"]``, read-only
(``TableMetadata``).

Angles are in radians, lengths in metres, times in seconds, unless a column says otherwise.
``docs/schemas.md`` is generated from the declarations (``cobot-analysis schemas``).
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cobot_analysis.lazy import pandas as pd

from cobot_analysis.errors import InputError

METADATA_KEY = b"cobot_analysis"
SCHEMAS: dict[str, "TableSchema"] = {}

#: keyword of pyarrow's readers: check the CRC32 of every data page that has one (all the tables ``write_table``
#: writes; a file without checksums reads as before)
VERIFY = {"page_checksum_verification": True}

#: m: largest |coordinate| from the lab origin (the largest motion-capture volumes span a few tens of
#: metres); a farther position is corrupt or not in metres (``import --lab-extent``'s default).
LAB_EXTENT = 100.0
#: the values of a position in the lab, an angle wrapped to (-pi, pi], a duration or a distance, any finite number
POSITION, WRAPPED, NONNEGATIVE, REAL = (-LAB_EXTENT, LAB_EXTENT), (-math.pi, math.pi), (0.0, math.inf), (-math.inf, math.inf)
#: turns: largest |angle| of an unwrapped orientation (theta). Measured: 1.32 turns (8.30 rad) in walking-2020's
#: trials (their headings start up to 5.7 rad from 0 and some turn 1.8 turns), 0.79 in pair-carriage-2022, 1.0 in
#: the synthetic tables; so a table whose headings reach 19 (degrees) is refused (one walking along x within
#: +-19 degrees still passes: its degrees look like radians). A trajectory's heading may pass it where its path
#: turns as often (laps of a track: ``angles.turns_with_path``, checked in ``check_values``)
TURNS = 3
UNWRAPPED = (-TURNS * 2 * math.pi, TURNS * 2 * math.pi)


@dataclass(frozen=True)
class Column:
    dtype: str  # pandas dtype family: "string", "int", "float", "bool"
    unit: str  # "m", "rad", "s", "%", "-" (dimensionless), "" for labels
    description: str
    required: bool = True
    limits: tuple[float, float] | None = None  # closed range of a float column's values (NaN: unknown); +-inf never


@dataclass(frozen=True)
class TableSchema:
    name: str
    version: int
    description: str
    columns: dict[str, Column] = field(default_factory=dict)

    def __post_init__(self) -> None:
        SCHEMAS[self.name] = self

    @property
    def required(self) -> list[str]:
        return [c for c, spec in self.columns.items() if spec.required]

    def metadata(self) -> dict[str, Any]:
        return {
            "table": self.name,
            "schema_version": self.version,
            "description": self.description,
            "columns": {c: {"unit": s.unit, "description": s.description} for c, s in self.columns.items()},
        }


# ---------------------------------------------------------------------------------------------
# Shared vocabulary of trial metadata (docs/methods.md sec. 1). Columns that do not apply are null.
TRIAL_COLUMNS: dict[str, Column] = {
    "study": Column("string", "", "study name, e.g. walking-2020, pair-carriage-2022, synthetic-walking"),
    "trial": Column("string", "", "trial identifier, unique within the study"),
    "kind": Column("string", "", "'trial' (one recording) or 'mean' (a published or computed mean)"),
    "n_trials": Column("int", "-", "number of recordings behind the row (1 for a trial)"),
    "subject": Column("string", "", "walking study: subject id", required=False),
    "pair": Column("string", "", "pair study: pair id", required=False),
    "condition": Column("string", "", "walking: start condition code (e.g. E4015); pairs: goal (e.g. d1_p4)"),
    "direction": Column("string", "", "pair study: 'forward' (start->goal) or 'return'", required=False),
    "scenario": Column("int", "-", "pair study: 1 = S1 leader, 2 = S2 leader, 3 = both know the goal", required=False),
    "configuration": Column("string", "", "pair study: end configuration family ('gris': 0/pi, 'jaune': +-pi/2)", required=False),
    "end_orientation": Column("float", "rad", "pair study: table orientation at the end of the path", required=False,
                              limits=UNWRAPPED),
    "repetition": Column("int", "-", "repetition number of the trial within its condition", required=False),
}

MARKERS = TableSchema(
    name="markers",
    version=1,
    description="Raw marker trajectories, tidy long format: one row per trial, frame and marker.",
    columns={
        "trial": Column("string", "", "trial identifier (protocol file)"),
        "frame": Column("int", "-", "frame index from 0"),
        "time": Column("float", "s", "frame / rate"),
        "entity": Column("string", "", "who carries the marker: walker, subject1, subject2, table"),
        "marker": Column("string", "", "canonical marker label (ISB: LASI RASI LPSI RPSI ...; table: TAB1..TAB3)"),
        "x": Column("float", "m", "position, laboratory frame"),
        "y": Column("float", "m", "position, laboratory frame"),
        "z": Column("float", "m", "position, laboratory frame (vertical)"),
        "occluded": Column("bool", "", "true where the system lost the marker (x, y, z are NaN there)"),
    },
)

TRIALS = TableSchema(
    name="trials",
    version=1,
    description="One row per imported recording: its protocol metadata and how it was read.",
    columns={
        **TRIAL_COLUMNS,
        "file": Column("string", "", "raw file, as named in the protocol (resolved path)"),
        "sha256": Column("string", "", "content hash of the raw file"),
        "source_format": Column("string", "", "c3d, vicon-csv or qualisys-tsv"),
        "source_units": Column("string", "", "length unit of the raw file (mm or m)"),
        "rate": Column("float", "Hz", "marker sampling rate"),
        "n_frames": Column("int", "-", "number of frames in the recording"),
        "pelvis_markers": Column("string", "", "pelvis markers per entity, e.g. 'walker: LASI,RASI,SACR' (docs/methods.md "
                                               "sec. 2.4)", required=False),
    },
)

TRAJECTORIES = TableSchema(
    name="trajectories",
    version=1,
    description=(
        "Time-normalised trajectories, long format: one row per trajectory (trial x entity) and "
        "sample. Orientation is NaN where it could not be computed (quality says why)."
    ),
    columns={
        **TRIAL_COLUMNS,
        "entity": Column("string", "", "walker (walking study), subject1, subject2 or table"),
        "sample": Column("int", "-", "sample index 0..N-1 of the time-normalised trajectory"),
        "phase": Column("float", "%", "100 * sample / (N - 1): 0 = onset, 100 = offset (both included)"),
        "time": Column("float", "s", "phase * travel_time / 100; NaN when the duration is unknown"),
        "record_time": Column("float", "s", "time in the raw recording (onset_time + time); NaN if unknown", required=False),
        "x": Column("float", "m", "pelvis CoM (subjects) or table centre, horizontal", limits=POSITION),
        "y": Column("float", "m", "pelvis CoM (subjects) or table centre, horizontal", limits=POSITION),
        "theta": Column("float", "rad", "global orientation (pelvis normal or table long axis), unwrapped", limits=UNWRAPPED),
        "gamma": Column("float", "rad", "local orientation: theta minus the path tangent, wrapped to (-pi, pi]", required=False,
                        limits=WRAPPED),
        "vx": Column("float", "m/s", "CoM velocity", required=False),
        "vy": Column("float", "m/s", "CoM velocity", required=False),
        "travel_time": Column("float", "s", "duration of the trajectory (onset to offset); NaN if unknown", limits=NONNEGATIVE),
        "travelled_distance": Column("float", "m", "straight-line distance start -> end position (docs/methods.md sec. 3)",
                                 limits=NONNEGATIVE),
        "quality": Column("string", "", "'ok' or ';'-separated flags, e.g. orientation_missing;long_gap;truncated "
                                        "(truncated: the walk or carriage runs off the recording)"),
        "pelvis_markers": Column("string", "", "pelvis markers the CoM and orientation come from, e.g. 'LASI,RASI,SACR' "
                                               "(empty for the table)", required=False),
    },
)


# ---------------------------------------------------------------------------------------------
def to_arrow(df: pd.DataFrame, schema: TableSchema, **metadata: Any):
    """``df`` as the Arrow table ``schema`` declares (types conformed, units and ``metadata`` attached): what
    ``write_table`` writes, and what reading the file gives back."""
    import pyarrow as pa

    missing = [c for c in schema.required if c not in df.columns]
    if missing:
        raise ValueError(f"table {schema.name} lacks required columns {missing}")
    table = conform(pa.Table.from_pandas(df, preserve_index=False), schema)
    meta = dict(table.schema.metadata or {})
    meta[METADATA_KEY] = json.dumps({**schema.metadata(), **metadata}, default=str).encode()
    return table.replace_schema_metadata(meta)


def write_table(df: pd.DataFrame | Any, path: str | os.PathLike, schema: TableSchema | None = None, **metadata: Any) -> Path:
    """Write ``df`` as the Parquet table ``schema`` at ``path`` (atomic: temp file then rename); ``df`` may be
    an Arrow table already made by ``to_arrow`` (then ``schema`` and ``metadata`` are not needed)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = df if schema is None else to_arrow(df, schema, **metadata)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        # No dictionary for float columns: they rarely repeat, and trying it costs memory (+36 MB on
        # 125,000 rows x 9 floats) and time before Parquet falls back to plain encoding.
        pq.write_table(table, tmp, compression="zstd", write_page_checksum=True,
                       use_dictionary=[f.name for f in table.schema if not pa.types.is_floating(f.type)])
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


#: Arrow type of each declared dtype (every Arrow type is nullable).
ARROW_TYPES = {"string": "large_string", "int": "int64", "float": "float64", "bool": "bool_"}


def arrow_type(column: Column, current=None):
    """The Arrow type ``column`` is written with; a dictionary-encoded (categorical) string column
    stays dictionary-encoded, as dictionary<int32, string> (what Parquet reads back)."""
    import pyarrow as pa

    if column.dtype == "string" and current is not None and pa.types.is_dictionary(current):
        return pa.dictionary(pa.int32(), pa.string())
    return getattr(pa, ARROW_TYPES[column.dtype])()


def field_metadata(column: Column) -> dict[bytes, bytes]:
    """Arrow field metadata of a declared column: its unit and description."""
    return {b"unit": column.unit.encode(), b"description": column.description.encode()}


def conform(table, schema: TableSchema):
    """Cast the declared columns of ``table`` (pyarrow) to their declared types, with field
    metadata; an undeclared column keeps its type (large_string if it is all null)."""
    import pyarrow as pa

    fields, arrays = [], []
    for name, array in zip(table.column_names, table.columns):
        spec = schema.columns.get(name)
        if spec is None:
            target, meta = (pa.large_string() if pa.types.is_null(array.type) else array.type), None
        else:
            target, meta = arrow_type(spec, array.type), field_metadata(spec)
        if array.type != target:
            try:
                array = array.cast(target)
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
                raise ValueError(f"table {schema.name}: column {name!r} ({array.type}) is not a {spec.dtype if spec else target} "
                                 f"column ({exc})") from exc
        fields.append(pa.field(name, target, nullable=True, metadata=meta))
        arrays.append(array)
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=_pandas_metadata(table.schema.metadata, schema)))


#: pandas dtype recorded for a declared column that pandas held in another dtype (or all null).
_PANDAS_DTYPE = {"string": ("object", "str"), "int": ("int64", "Int64"), "float": ("float64", "float64"),
                 "bool": ("bool", "object")}


def _pandas_metadata(meta: dict | None, schema: TableSchema) -> dict | None:
    """Update pyarrow's ``pandas`` metadata to the declared types, so that pandas reads a declared
    int column as int64 (no nulls, written as int64) or nullable Int64 (otherwise), never float."""
    if not meta or b"pandas" not in meta:
        return meta
    doc = json.loads(meta[b"pandas"])
    for entry in doc.get("columns", []):
        spec = schema.columns.get(entry.get("name"))
        if spec is None or entry.get("pandas_type") == "categorical":
            continue
        if spec.dtype == "int" and entry.get("numpy_type") in ("int8", "int16", "int32", "int64"):
            entry["pandas_type"], entry["numpy_type"] = "int64", "int64"
        elif spec.dtype == "int" or entry.get("pandas_type") == "empty":
            entry["pandas_type"], entry["numpy_type"] = _PANDAS_DTYPE[spec.dtype]
    return {**meta, b"pandas": json.dumps(doc).encode()}


class TableMetadata(dict):
    """A table's file metadata as ``read_table`` attaches it to ``df.attrs``: read-only, and shared rather
    than copied. pandas deep-copies ``attrs`` into every frame an operation makes (each group of a groupby,
    each column taken): with the ~3 kB of column descriptions that cost ~0.35 ms per group, more than the
    work on a 500-sample trial. Copy it with ``dict(meta)`` to change it."""

    def _read_only(self, *args, **kwargs):
        raise TypeError("a table's metadata is read-only: copy it with dict(...) to change it")

    __setitem__ = __delitem__ = __ior__ = clear = pop = popitem = setdefault = update = _read_only  # type: ignore[assignment]

    def __copy__(self) -> TableMetadata:
        return self

    def __deepcopy__(self, memo: dict) -> TableMetadata:
        return self

    def __reduce__(self):  # pickled (to a worker) as a plain dict's items, read-only again there
        return (TableMetadata, (dict(self),))


def as_text(value: Any) -> str:
    """A value as text, an integral float without its ``.0`` (``3.0`` -> ``"3"``): the ids and levels of a CSV or
    Parquet column that pandas read as floats (a blank cell makes a column of integers float).

        >>> as_text(3.0), as_text(3), as_text("S01"), as_text(2.5)
        ('3', '3', 'S01', '2.5')
    """
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def table_metadata(path: str | os.PathLike) -> dict[str, Any]:
    """The ``cobot_analysis`` metadata of a Parquet file (schema, units, stage metadata)."""
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(METADATA_KEY)
    return json.loads(raw) if raw else {}


def not_the_table(path, expected: str, found: str | None, remedy: str) -> InputError:
    """The one line for a Parquet file that is not the ``expected`` table: another table of the pipeline
    (``found``, with ``remedy``), or a file without the pipeline's metadata (``found`` None: written by another
    tool, or read and saved again with pandas, which does not keep it), with how to stamp a table of one's own."""
    if found is None:
        return InputError("has no cobot-analysis table metadata (written by another tool, or saved again with pandas, "
                          "which drops it)", path=path,
                          remedy=f"write your table with cobot_analysis.schema.write_table(df, PATH, cobot_analysis.schema"
                                 f".SCHEMAS[{expected!r}]) (read back, its columns and units are checked), or pass the "
                                 "DataFrame to the Python API (docs/api.md, \"The one input type\")")
    return InputError(f"is not a {expected} table (found {found!r})", path=path, remedy=remedy)


def read_table(path: str | os.PathLike, schema: TableSchema, columns: list[str] | None = None) -> pd.DataFrame:
    """Read a table written by ``write_table``; bad or foreign files raise ``InputError``."""
    import pyarrow.parquet as pq

    path = check_file(path, f"run the stage that writes {schema.name} first or check --out")
    try:
        meta = table_metadata(path)
        table = pq.read_table(path, columns=columns, **VERIFY)
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise InputError(f"not a readable Parquet file ({type(exc).__name__})", path=path, remedy="re-run the stage that wrote it") from exc
    if meta.get("table") != schema.name:
        raise not_the_table(path, schema.name, meta.get("table"), "pass the right file")
    need = schema.required if columns is None else [c for c in columns if c in schema.required]
    missing = [c for c in need if c not in table.column_names]
    if missing:
        raise InputError(f"{schema.name} table lacks columns {missing}", path=path, remedy="re-run the stage that wrote it")
    check_values(table, schema, path)
    try:
        df = table.to_pandas()
    except Exception as exc:
        raise InputError(f"not a readable Parquet file ({type(exc).__name__})", path=path, remedy="re-run the stage that wrote it") from exc
    df.attrs["cobot_analysis"] = TableMetadata(meta)
    return df


def check_file(path: str | os.PathLike, remedy: str) -> Path:
    """``path`` as a ``Path`` when it is a file, else ``InputError`` (missing, or a directory) with ``remedy``."""
    path = Path(path)
    if path.is_dir():
        raise InputError("is a directory, not a table", path=path, remedy="pass the Parquet file itself")
    if not path.is_file():
        raise InputError("file not found", path=path, remedy=remedy)
    return path


#: what a value outside a column's bounded limits most likely is, by the column's unit: the guess, and the remedy
_OUT_OF_LIMITS = {"m": ("millimetres?", "lengths in metres, not millimetres"),
                  "rad": ("degrees?", "angles in radians, not degrees: multiply degrees by pi/180")}


def check_values(table, schema: TableSchema, path: str | os.PathLike | None = None) -> None:
    """Refuse (``InputError``) what no stage writes: a declared number column holding no numbers (text,
    say), and in a float column with ``limits`` an infinite value or one outside its limits (e.g. positions
    in millimetres beyond the lab's ``LAB_EXTENT`` m, wrapped angles in degrees beyond pi, unwrapped ones beyond
    ``TURNS`` turns, unless the trajectory's path turns as often: ``_laps``). NaN is a value not known (a missing
    orientation) and passes. ``table``: a pyarrow Table."""
    import numpy as np
    import pyarrow as pa

    for name, column in zip(table.column_names, table.columns):
        spec = schema.columns.get(name)
        if spec is None or spec.dtype not in ("int", "float"):
            continue
        kind = column.type.value_type if pa.types.is_dictionary(column.type) else column.type
        if not (pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_null(kind)
                or (spec.dtype == "float" and pa.types.is_decimal(kind))):
            unit = f" in {spec.unit}" if spec.unit not in ("", "-") else ""
            raise InputError(f"column {name!r} holds {kind} values, not numbers", path=path,
                             remedy=f"write {name} as {spec.dtype} numbers{unit} (docs/schemas.md, {schema.name})")
        if spec.limits is None or pa.types.is_null(kind):
            continue
        values = column.to_numpy(zero_copy_only=False).astype(float)
        lo, hi = spec.limits
        bad = np.isinf(values) | (values < lo) | (values > hi)
        if bad.any() and spec.limits == UNWRAPPED:
            bad &= ~_laps(table, name, values, bad)
        if bad.any():
            example = float(values[np.argmax(bad)])
            bounded = math.isfinite(lo) and math.isfinite(hi)
            allowed = f"outside [{lo:.6g}, {hi:.6g}] {spec.unit}" if bounded else "negative or infinite" if lo == 0 else "infinite"
            guess, hint = _OUT_OF_LIMITS.get(spec.unit, ("", "docs/schemas.md")) if bounded else ("", "")
            if spec.limits == UNWRAPPED:
                hint += f"; a heading passes {TURNS} turns only along its path's own turning (laps)"
            guess = f"; {guess}" if guess and math.isfinite(example) else ""  # an infinite value is in no unit
            hint = f"{hint}; " if hint else ""
            raise InputError(f"column {name!r}: {int(bad.sum())} value(s) {allowed} (e.g. {example:g}{guess})", path=path,
                             remedy=f"give {name} in {spec.unit} ({hint}NaN for an unknown value), or re-run the stage that wrote it")


def _laps(table, name: str, values, bad):
    """Rows of the finite values of ``bad`` (an unwrapped heading ``name`` beyond ``TURNS`` turns) whose trajectory
    turns that often along its own path (``angles.turns_with_path``): laps, not degrees. A trajectory: the rows of
    one (study, trial, entity) in sample order, or, in a table read without them, a run of rows from a sample 0
    (the layout every stage writes). A table without the path (x, y, sample) has none."""
    import numpy as np

    if not {"x", "y", "sample"} <= set(table.column_names):
        return np.zeros(len(values), bool)
    from cobot_analysis.angles import turns_with_path

    keys = [c for c in ("study", "trial", "entity") if c in table.column_names]
    df = table.select([*keys, "sample", "x", "y"]).to_pandas()
    if not keys:
        keys = ["run"]
        df["run"] = np.cumsum(df["sample"].to_numpy() == 0)
    df[name], df["bad"] = values, bad & np.isfinite(values)
    df = df[df.groupby(keys, observed=True, sort=False)["bad"].transform("any")]
    laps = np.zeros(len(values), bool)
    for _, g in df.groupby(keys, observed=True, sort=False):
        g = g.sort_values("sample")
        if turns_with_path(g["x"], g["y"], g[name], UNWRAPPED[1]):
            laps[g.index.to_numpy()] = True
    return laps


def schemas_markdown() -> str:
    """Markdown documentation of every declared table (docs/schemas.md)."""
    lines = ["# Parquet tables", "", "Generated by `cobot-analysis schemas`.", "",
             "Every file carries its units and descriptions twice: per column, as Arrow field metadata "
             "(keys `unit` and `description`; pyarrow `pq.read_schema(path).field('x').metadata`, R arrow, "
             "arrow-rs/DataFusion and viewers that decode the Arrow schema), and for the whole table as JSON "
             "in the Parquet key-value metadata under `cobot_analysis` (table name, schema version, per-column "
             "unit and description, and the stage's parameters; polars `pl.read_parquet_metadata(path)`, duckdb "
             "`SELECT * FROM parquet_kv_metadata('file.parquet')`, pandas `cobot_analysis.schema.read_table(...)."
             "attrs`). polars and duckdb do not show Arrow field metadata.", "",
             "Types: string columns are `large_string` (categorical labels: `dictionary<int32, string>`), int "
             "columns `int64`, float columns `float64` (double), bool columns `bool`; every column is nullable and "
             "keeps its declared type when all its values are null, so any two tables of the same kind "
             "concatenate (polars `concat`, duckdb `read_parquet([...])`, `pandas.concat`). pandas reads an int "
             "column holding nulls as the nullable `Int64`.", "",
             "Limits: a stage refuses a table whose number column holds no numbers (text, say) or, where a column "
             "gives its limits, an infinite value or one outside them (`schema.check_values`: positions within "
             f"{LAB_EXTENT:g} m of the lab origin, so not millimetres; wrapped angles within pi and unwrapped ones within "
             f"{TURNS} turns, so not degrees, unless the trajectory's path turns as often (laps of a track); "
             "durations and distances >= 0). NaN is a value not known and passes.", ""]
    for schema in sorted(SCHEMAS.values(), key=lambda s: s.name):
        lines += [f"## `{schema.name}` (version {schema.version})", "", schema.description, "",
                  "| column | type | unit | description |", "|---|---|---|---|"]
        for name, col in schema.columns.items():
            opt = "" if col.required else " (optional)"
            unit = col.unit if col.limits is None else f"{col.unit}, {_limits_text(col.limits)}".lstrip(", ")
            lines.append(f"| `{name}` | {col.dtype}{opt} | {unit} | {col.description} |")
        lines.append("")
    return "\n".join(lines)


def _limits_text(limits: tuple[float, float]) -> str:
    lo, hi = limits
    if limits == REAL:
        return "finite"
    if limits == WRAPPED:
        return "[-pi, pi]"
    if limits == UNWRAPPED:
        return f"[-{2 * TURNS}pi, {2 * TURNS}pi] ({TURNS} turns)"
    return f">= {lo:g}, finite" if hi == math.inf else f"[{lo:g}, {hi:g}]"
