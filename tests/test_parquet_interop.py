"""Parquet outputs read and concatenate in polars, duckdb and pandas; units are field metadata.

Workspaces are made by the real stages (CLI): a small synthetic walking study and a small synthetic
pair study (import, preprocess, average, compare, stats), and the published datasets when present.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pl = pytest.importorskip("polars")
duckdb = pytest.importorskip("duckdb")
pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")

from cobot_analysis.schema import SCHEMAS, TRAJECTORIES, Column, TableSchema, read_table, write_table  # noqa: E402

STAGES = (["average"], ["compare"], ["stats"])  # after import and preprocess (fixture ``preprocessed``)


def _run(*args) -> None:
    from cobot_analysis.cli import run

    code = run(["-q", *map(str, args)])
    assert code == 0, args


@pytest.fixture(scope="module")
def preprocessed(tmp_path_factory) -> dict[str, Path]:
    """Two synthetic workspaces (walking, pairs) taken through import and preprocess by the CLI (all the slow
    test below needs: .ci/run's slow selection then runs no analysis stage for it)."""
    root = tmp_path_factory.mktemp("interop")
    walking, pairs = root / "walking", root / "pairs"
    _run("synth", "walking", "--out", walking, "--subjects", "2", "--repetitions", "1", "--conditions", "3")
    _run("synth", "pairs", "--out", pairs, "--pairs", "1", "--goals", "2")
    for ws, study in ((walking, "synth-walking"), (pairs, "synth-pairs")):
        _run("import", ws / study / "protocol.yaml", "--out", ws)
        _run("preprocess", "--out", ws)
    return {"walking": walking, "pairs": pairs}


@pytest.fixture(scope="module")
def workspaces(preprocessed) -> dict[str, Path]:
    """The same two workspaces taken on through average, compare and stats by the CLI."""
    for ws in preprocessed.values():
        for stage in STAGES:
            _run(*stage, "--out", ws)
    return preprocessed


def _parquet_files(ws: Path) -> dict[str, Path]:
    return {str(p.relative_to(ws)): p for p in sorted(ws.rglob("*.parquet"))}


def test_walking_and_pair_trajectories_concatenate_in_polars_duckdb_and_pandas(workspaces):
    a = workspaces["walking"] / "preprocess" / "trajectories.parquet"
    b = workspaces["pairs"] / "preprocess" / "trajectories.parquet"
    da, db = pl.read_parquet(a), pl.read_parquet(b)
    both = pl.concat([da, db])  # failed with "SchemaError ... column 'pair'" when 'pair' was Null-typed
    assert both.height == da.height + db.height
    assert both.schema["pair"] == pl.String and both.schema["scenario"] == pl.Int64
    assert both.filter(pl.col("entity") == "walker")["pair"].null_count() == da.height
    assert both.filter(pl.col("entity") == "table")["pair"].null_count() == 0
    assert set(both.filter(pl.col("entity") == "walker")["subject"].unique()) == {"S01", "S02"}

    rows, pairs, walkers = duckdb.sql(
        f"SELECT count(*), count(pair), count(*) FILTER (WHERE entity = 'walker') FROM read_parquet(['{a}', '{b}'])").fetchall()[0]
    assert (rows, pairs, walkers) == (da.height + db.height, db.height, da.height)

    df = pd.concat([pd.read_parquet(a), pd.read_parquet(b)], ignore_index=True)
    assert isinstance(df["pair"].dtype, pd.StringDtype) and isinstance(df["subject"].dtype, pd.StringDtype)
    assert str(df["scenario"].dtype) == "Int64" and df["scenario"].isna().sum() == da.height


def test_every_table_of_both_studies_concatenates_in_polars(workspaces):
    fw, fp = _parquet_files(workspaces["walking"]), _parquet_files(workspaces["pairs"])
    common = sorted(set(fw) & set(fp))
    assert {"import/markers.parquet", "preprocess/trajectories.parquet", "average/means.parquet",
            "compare/distances.parquet", "stats/stats.parquet"} <= set(common)
    for name in common:
        a, b = pl.read_parquet(fw[name]), pl.read_parquet(fp[name])
        same = a.columns == b.columns
        both = pl.concat([a, b], how="vertical" if same else "diagonal")
        assert both.height == a.height + b.height, name
        if name in ("preprocess/trajectories.parquet", "average/means.parquet", "compare/distances.parquet"):
            assert same, (name, set(a.columns) ^ set(b.columns))


def test_no_null_typed_column_and_declared_types(workspaces):
    types = {"string": ("large_string",), "int": ("int64",), "float": ("double",), "bool": ("bool",)}
    checked = 0
    for ws in workspaces.values():
        for name, path in _parquet_files(ws).items():
            schema = pq.read_schema(path)
            assert not [f.name for f in schema if pa.types.is_null(f.type)], name
            table = json.loads(schema.metadata[b"cobot_analysis"])["table"]
            for column, spec in SCHEMAS[table].columns.items():
                if column not in schema.names:
                    continue
                t = schema.field(column).type
                if pa.types.is_dictionary(t):  # categorical labels (markers, truth)
                    assert spec.dtype == "string" and t == pa.dictionary(pa.int32(), pa.string()), (name, column, t)
                else:
                    assert str(t) in types[spec.dtype], (name, column, t)
                checked += 1
    assert checked > 300


def test_units_are_field_metadata_and_file_metadata(workspaces):
    path = workspaces["pairs"] / "preprocess" / "trajectories.parquet"
    schema = pq.read_schema(path)
    units = {f.name: f.metadata[b"unit"].decode() for f in schema}
    assert units["x"] == "m" and units["theta"] == "rad" and units["travel_time"] == "s" and units["phase"] == "%"
    assert units["scenario"] == "-" and units["pair"] == ""
    assert schema.field("gamma").metadata[b"description"].decode() == TRAJECTORIES.columns["gamma"].description
    assert units == {c: TRAJECTORIES.columns[c].unit for c in schema.names}
    # file-level JSON, the way polars and duckdb see it
    meta = json.loads(pl.read_parquet_metadata(path)["cobot_analysis"])
    assert meta["table"] == "trajectories" and meta["columns"]["vx"]["unit"] == "m/s"
    raw = duckdb.sql(f"SELECT value FROM parquet_kv_metadata('{path}') WHERE key = 'cobot_analysis'").fetchall()[0][0]
    assert json.loads(raw)["columns"]["theta"]["unit"] == "rad"
    # the field metadata survives a pyarrow round trip through pandas
    assert pq.read_table(path).schema.field("y").metadata[b"unit"] == b"m"


def test_published_and_synthetic_trajectories_concatenate(datasets, preprocessed, tmp_path):
    paths = []
    for name in ("walking-2020", "pair-carriage-2022"):
        _run("import-published", name, datasets / name, "--out", tmp_path / name)
        paths.append(tmp_path / name / "import-published" / "trajectories.parquet")
    paths += [preprocessed[k] / "preprocess" / "trajectories.parquet" for k in ("walking", "pairs")]
    frames = [pl.read_parquet(p) for p in paths]
    both = pl.concat(frames)
    assert both.height == sum(f.height for f in frames)
    assert set(both["study"].unique()) == {"walking-2020", "pair-carriage-2022", "synthetic-walking", "synthetic-pairs"}
    listed = ", ".join(f"'{p}'" for p in paths)
    n, n_pairs = duckdb.sql(f"SELECT count(*), count(DISTINCT study) FROM read_parquet([{listed}])").fetchall()[0]
    assert (n, n_pairs) == (both.height, 4)
    assert str(pd.concat([pd.read_parquet(p) for p in paths])["scenario"].dtype) == "Int64"


# ---- write_table on hand-made frames --------------------------------------------------------------
DEMO = TableSchema(name="interop-demo", version=1, description="test table", columns={
    "label": Column("string", "", "a label"), "count": Column("int", "-", "a count", required=False),
    "length": Column("float", "m", "a length"), "flag": Column("bool", "", "a flag", required=False)})
SCHEMAS.pop(DEMO.name)  # a test table: keep it out of `cobot-analysis schemas`


def test_all_null_columns_take_their_declared_type(tmp_path):
    df = pd.DataFrame({"label": [None, None], "count": [np.nan, 3.0], "length": [1, 2], "flag": [None, None],
                       "extra": [None, None]})
    path = write_table(df, tmp_path / "demo.parquet", DEMO)
    schema = pq.read_schema(path)
    assert [str(schema.field(c).type) for c in schema.names] == ["large_string", "int64", "double", "bool", "large_string"]
    assert schema.field("length").metadata == {b"unit": b"m", b"description": b"a length"}
    assert schema.field("extra").metadata is None  # undeclared: no unit
    back = read_table(path, DEMO)
    assert str(back["count"].dtype) == "Int64" and back["count"].isna().tolist() == [True, False]
    assert back["count"].iloc[1] == 3 and back["length"].tolist() == [1.0, 2.0]
    assert back.attrs["cobot_analysis"]["columns"]["length"]["unit"] == "m"


def test_a_fractional_value_in_an_int_column_is_refused(tmp_path):
    df = pd.DataFrame({"label": ["a"], "count": [1.5], "length": [math.pi]})
    with pytest.raises(ValueError, match="count"):
        write_table(df, tmp_path / "bad.parquet", DEMO)
    assert not (tmp_path / "bad.parquet").exists()


def test_schemas_command_documents_the_field_metadata(cli):
    code, out, _ = cli("schemas")
    assert code == 0
    assert "Arrow field metadata" in out and "parquet_kv_metadata" in out and "`unit`" in out
    assert "| `travel_time` | float | s |" in out
