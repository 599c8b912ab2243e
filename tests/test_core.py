"""Workspace, manifest, Parquet schema and CLI conventions shared by every stage."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.parallel import map_tasks
from cobot_analysis.schema import MARKERS, TRIALS, read_table, table_metadata, write_table
from cobot_analysis.workspace import Stage


def _markers(n=3):
    return pd.DataFrame({
        "trial": ["t1"] * n, "frame": np.arange(n), "time": np.arange(n) / 200.0, "entity": ["walker"] * n,
        "marker": ["LASI"] * n, "x": np.ones(n), "y": np.zeros(n), "z": np.full(n, 0.9), "occluded": [False] * n,
    })


def test_table_round_trip_keeps_units_and_metadata(tmp_path):
    p = write_table(_markers(), tmp_path / "m.parquet", MARKERS, rate=200.0, source_units="mm")
    df = read_table(p, MARKERS)
    assert df["x"].tolist() == [1.0, 1.0, 1.0]
    meta = table_metadata(p)
    assert meta["table"] == "markers" and meta["rate"] == 200.0 and meta["source_units"] == "mm"
    assert meta["columns"]["x"]["unit"] == "m"
    assert df.attrs["cobot_analysis"]["rate"] == 200.0


def test_read_table_metadata_is_shared_read_only_and_travels_to_workers(tmp_path):
    """pandas deep-copies attrs into every frame an operation makes: the metadata is shared instead (one object
    in every group of a groupby), cannot be changed in place, and pickles to a worker as itself."""
    import copy
    import pickle

    df = read_table(write_table(_markers(), tmp_path / "m.parquet", MARKERS, rate=200.0), MARKERS)
    meta = df.attrs["cobot_analysis"]
    assert all(g.attrs["cobot_analysis"] is meta for _, g in df.groupby("frame"))
    assert df[["x"]].attrs["cobot_analysis"] is meta and copy.deepcopy(meta) is meta
    for change in (lambda m: m.__setitem__("rate", 100.0), lambda m: m.update(rate=100.0), lambda m: m.pop("rate")):
        with pytest.raises(TypeError, match="read-only"):
            change(meta)
    back = pickle.loads(pickle.dumps(df))
    assert back.attrs["cobot_analysis"] == meta and back.attrs["cobot_analysis"]["rate"] == 200.0
    assert {**meta, "rate": 100.0}["rate"] == 100.0 and json.loads(json.dumps(meta)) == meta  # a copy is a plain dict


def test_write_table_refuses_missing_columns(tmp_path):
    with pytest.raises(ValueError, match="lacks required columns"):
        write_table(_markers().drop(columns="z"), tmp_path / "m.parquet", MARKERS)
    assert not list(tmp_path.iterdir())


def test_read_table_rejects_corrupt_and_foreign_files(tmp_path):
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(b"PAR1 not really")
    with pytest.raises(InputError, match="bad.parquet: not a readable Parquet"):
        read_table(bad, MARKERS)
    other = tmp_path / "other.parquet"
    _markers().to_parquet(other)  # the right columns, but written by pandas: no table metadata
    with pytest.raises(InputError, match=r"other.parquet: has no cobot-analysis table metadata .*write_table\(df, PATH, "
                                         r"cobot_analysis.schema.SCHEMAS\['markers'\]\)"):
        read_table(other, MARKERS)
    write_table(_markers(), other, MARKERS)  # the remedy the line gives: stamped, it reads
    assert len(read_table(other, MARKERS)) == len(_markers())
    with pytest.raises(InputError, match=r"other.parquet: is not a trials table \(found 'markers'\); pass the right file"):
        read_table(other, TRIALS)


def test_stage_is_atomic_records_manifest_and_skips(tmp_path):
    src = tmp_path / "in.txt"
    src.write_text("a")
    out = tmp_path / "ws"
    with Stage(out, "demo", inputs=[src], params={"n": 1}) as st:
        assert not st.skipped and st.dir != st.final_dir  # writes go to a temporary directory
        st.path("result.txt").write_text("ok")
    manifest = json.loads((out / "demo" / "manifest.json").read_text())
    assert manifest["params"] == {"n": 1}
    assert manifest["inputs"][0]["sha256"] == "ca978112ca1bbdcafac231b39a23dc4da786eff8147c4e72b9807785afee48bb"
    assert [o["path"] for o in manifest["outputs"]] == ["result.txt"]
    assert "numpy" in manifest["versions"]
    with Stage(out, "demo", inputs=[src], params={"n": 1}) as st:
        assert st.skipped
    with Stage(out, "demo", inputs=[src], params={"n": 2}) as st:  # new parameters: redone
        assert not st.skipped
        st.path("result.txt").write_text("two")
    src.write_text("b")  # new input content: redone
    with Stage(out, "demo", inputs=[src], params={"n": 2}) as st:
        assert not st.skipped
        st.path("result.txt").write_text("three")
    assert (out / "demo" / "result.txt").read_text() == "three"


def test_failed_stage_leaves_previous_output_and_no_temporary(tmp_path):
    out = tmp_path / "ws"
    with Stage(out, "demo", params={"n": 1}) as st:
        st.path("result.txt").write_text("good")
    with pytest.raises(RuntimeError):
        with Stage(out, "demo", params={"n": 2}) as st:
            st.path("result.txt").write_text("partial")
            raise RuntimeError("boom")
    assert (out / "demo" / "result.txt").read_text() == "good"
    assert sorted(p.name for p in out.iterdir()) == ["demo"]


def _square(x):
    return x * x


@pytest.mark.parametrize("jobs", [1, 2])
def test_map_tasks_keeps_order(jobs):
    assert map_tasks(_square, list(range(7)), jobs=jobs) == [i * i for i in range(7)]


def test_cli_version_help_and_usage_errors(cli):
    code, out, _ = cli("--version")
    assert code == 0 and out.startswith("cobot-analysis ")
    assert cli("--help")[0] == 0
    code, _, err = cli("no-such-command")
    assert code == 2 and "No such command" in err


def test_input_error_is_one_line():
    err = InputError("missing\nmarker", path="a.c3d", remedy="map it")
    assert str(err) == "a.c3d: missing marker; map it"
