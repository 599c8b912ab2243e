"""Tables a stage reads that no stage could have written: numbers stored as text, +-inf, positions in
millimetres, angles in degrees, negative durations, trajectories of one sample, a damaged data page, a
directory instead of a file. Each is refused by the reader every stage shares (``schema.check_values``,
``compare.read_trajectory_set``) with one line naming the file, exit code 2, nothing written and the
input unchanged."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cobot_analysis.averaging import MEANS
from cobot_analysis.schema import TRAJECTORIES, write_table
from cobot_analysis.synth.tables import walking_table


@pytest.fixture(scope="module")
def table(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("tables") / "trajectories.parquet"
    write_table(walking_table(seed=1, n_subjects=2, n_conditions=2, n_trials=2, missing_theta=0.0), path, TRAJECTORIES)
    return path


def edited(src: Path, dst: Path, edit) -> Path:
    """``src`` with its DataFrame changed by ``edit``, keeping the table's cobot_analysis metadata."""
    t = pq.read_table(src)
    out = pa.Table.from_pandas(edit(t.to_pandas()), preserve_index=False)
    pq.write_table(out.replace_schema_metadata({**out.schema.metadata, b"cobot_analysis": t.schema.metadata[b"cobot_analysis"]}), dst)
    return dst


def one_row(col, value):
    def edit(df):
        df.loc[3, col] = value
        return df
    return edit


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def refused(cli, ws: Path, bad: Path, *args) -> str:
    """Run a stage on ``bad``: exit 2, one line naming ``bad``, nothing in the workspace, ``bad`` unchanged."""
    before = sha(bad) if bad.is_file() else None
    code, _, err = cli(*args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert str(bad) in lines[0]
    assert not ws.exists() or not any(ws.iterdir())
    assert (sha(bad) if bad.is_file() else None) == before
    return " ".join(lines[0].split())


CASES = {
    "x as text": (lambda df: df.assign(x=df["x"].astype(str)), "column 'x' holds large_string values, not numbers; write x as float numbers in m"),
    "positions in mm": (lambda df: df.assign(x=df["x"] * 1000, y=df["y"] * 1000), "column 'y': 280 value(s) outside [-100, 100] m"),
    "x infinite": (one_row("x", np.inf), "column 'x': 1 value(s) outside [-100, 100] m (e.g. inf)"),
    "theta infinite": (one_row("theta", -np.inf), "column 'theta': 1 value(s) outside [-18.8496, 18.8496] rad (e.g. -inf); give "
                                                  "theta in rad"),
    "gamma in degrees": (lambda df: df.assign(gamma=np.degrees(df["gamma"] + 0.5)), "outside [-3.14159, 3.14159] rad"),
    # theta is unwrapped: no +-pi limit; without gamma (optional) degrees passed (3 turns: schema.TURNS)
    "theta in degrees, no gamma": (lambda df: df.assign(theta=np.degrees(df["theta"])).drop(columns="gamma"),
                                   "column 'theta': 320 value(s) outside [-18.8496, 18.8496] rad (e.g. 90; degrees?); give theta "
                                   "in rad (angles in radians, not degrees: multiply degrees by pi/180; a heading passes 3 turns only along "
                                   "its path's own turning (laps); NaN for an unknown value)"),
    "negative duration": (lambda df: df.assign(travel_time=-df["travel_time"]), "column 'travel_time'"),
    "one sample": (lambda df: df[df["sample"] == 0], "trajectories of 1 sample: no path; time-normalise every trajectory to N >= 2"),
}


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("stage", ["average", "compare", "stats"])
def test_a_table_no_stage_writes_is_refused_by_every_stage(table, tmp_path, cli, case, stage):
    edit, expected = CASES[case]
    bad = edited(table, tmp_path / "bad.parquet", edit)
    ws = tmp_path / "ws"
    line = refused(cli, ws, bad, stage, "--out", ws, "--trajectories", bad)
    assert expected in line, line


@pytest.mark.parametrize("stage", ["average", "compare", "stats", "predict"])
def test_a_table_saved_again_by_pandas_says_how_to_stamp_it(table, tmp_path, cli, stage):
    """pandas does not keep the file's table metadata: read and saved again, the table is refused with one line
    that gives the way to stamp it; stamped that way, it goes through (its values are checked on reading)."""
    import pandas as pd

    resaved = tmp_path / "mine.parquet"
    pd.read_parquet(table).to_parquet(resaved)
    ws = tmp_path / "ws"
    line = refused(cli, ws, resaved, stage, "--out", ws, "--trajectories", resaved)
    assert line == (f"error: {resaved}: has no cobot-analysis table metadata (written by another tool, or saved again with "
                    "pandas, which drops it); write your table with cobot_analysis.schema.write_table(df, PATH, "
                    "cobot_analysis.schema.SCHEMAS['trajectories']) (read back, its columns and units are checked), or pass "
                    'the DataFrame to the Python API (docs/api.md, "The one input type")')
    if stage == "average":
        write_table(pd.read_parquet(resaved), resaved, TRAJECTORIES)
        code, _, err = cli("average", "--out", ws, "--trajectories", resaved)
        assert code == 0, err


def test_the_same_values_pass(table, tmp_path, cli):
    """The editing itself is harmless: the unchanged table goes through."""
    same = edited(table, tmp_path / "same.parquet", lambda df: df)
    code, _, err = cli("average", "--out", tmp_path / "ws", "--trajectories", same)
    assert code == 0, err


def test_nan_orientation_is_unknown_not_refused(table, tmp_path, cli):
    bad = edited(table, tmp_path / "nan.parquet", one_row("theta", np.nan))
    code, _, err = cli("average", "--out", tmp_path / "ws", "--trajectories", bad)
    assert code == 0, err


def test_a_damaged_data_page_is_one_line(table, tmp_path, cli):
    data = bytearray(table.read_bytes())
    data[100:400] = bytes(300)  # inside the first column chunks
    bad = tmp_path / "damaged.parquet"
    bad.write_bytes(bytes(data))
    line = refused(cli, tmp_path / "ws", bad, "average", "--out", tmp_path / "ws", "--trajectories", bad)
    assert "not a readable Parquet file" in line and "re-run the stage that wrote it" in line


def test_a_directory_is_not_a_missing_file(tmp_path, cli):
    folder = tmp_path / "folder"
    folder.mkdir()
    line = refused(cli, tmp_path / "ws", folder, "average", "--out", tmp_path / "ws", "--trajectories", folder)
    assert "is a directory, not a table; pass the Parquet file itself" in line


@pytest.mark.parametrize("edit, expected", [
    (lambda df: df.assign(x=df["x"] * 1000, y=df["y"] * 1000), "column 'y': 70 value(s) outside [-100, 100] m"),
    (lambda df: df.assign(theta=np.degrees(df["theta"])), "column 'theta': 80 value(s) outside [-18.8496, 18.8496] rad (e.g. 90; "
                                                          "degrees?)"),
    (lambda df: df[df["sample"] == 0], "trajectories of 1 sample: no path"),
])
def test_means_no_stage_writes_are_refused_before_fitting(table, tmp_path, cli, edit, expected):
    """Before: millimetres gave an internal error (no target with a model and a measured duration), one
    sample a KeyError (exit 1)."""
    from cobot_analysis.cli import run

    ws = tmp_path / "good"
    assert run(["-q", "average", "--out", str(ws), "--trajectories", str(table)]) == 0
    bad = edited(ws / "average" / "means.parquet", tmp_path / "means.parquet", edit)
    line = refused(cli, tmp_path / "ws", bad, "fit-ioc", "--out", tmp_path / "ws", "--means", bad, "--max-evaluations", "2",
                   "--no-compare", "-j", "1")
    assert expected in line, line
    assert MEANS.columns["x"].limits == TRAJECTORIES.columns["x"].limits


@pytest.mark.parametrize("edit, expected", [
    (one_row("x", np.inf), "column 'x': 1 value(s) outside [-100, 100] m"),
    (lambda df: df[df["sample"] == 0], "trajectory 'clothoid' has 1 sample"),
])
def test_velocity_commands_of_a_damaged_path(tmp_path, cli, edit, expected):
    from cobot_analysis.cli import run

    ws = tmp_path / "gen"
    assert run(["-q", "generate", "--out", str(ws), "-m", "clothoid", "--start", "-1.5", "-3.4", "0", "-j", "1"]) == 0
    bad = edited(next(ws.glob("generate*/generated.parquet")), tmp_path / "generated.parquet", edit)
    line = refused(cli, tmp_path / "ws", bad, "velocity-commands", "--out", tmp_path / "ws", "--generated", bad)
    assert expected in line, line


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    """A workspace with one imported synthetic walking trial."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("study") / "study"
    assert run(["-q", "synth", "walking", "--out", str(ws), "--subjects", "1", "--repetitions", "1", "--conditions", "1", "-j", "1"]) == 0
    assert run(["-q", "import", str(ws / "synth-walking" / "protocol.yaml"), "--out", str(ws), "-j", "1"]) == 0
    return ws


def test_a_trials_table_with_a_rate_in_words(imported, tmp_path, cli):
    ws = imported
    bad = edited(ws / "import" / "trials.parquet", tmp_path / "trials.parquet", lambda df: df.assign(rate="fast"))
    line = refused(cli, tmp_path / "ws", bad, "preprocess", "--out", tmp_path / "ws", "--markers", ws / "import" / "markers.parquet",
                   "--trials", bad, "-j", "1")
    assert "column 'rate' holds large_string values, not numbers; write rate as float numbers in Hz" in line


def test_velocity_commands_at_an_infinite_rate(tmp_path, cli):
    from cobot_analysis.cli import run

    ws = tmp_path / "gen"
    assert run(["-q", "generate", "--out", str(ws), "-m", "clothoid", "--start", "-1.5", "-3.4", "0", "-j", "1"]) == 0
    before = sorted(p.name for p in ws.iterdir())
    code, _, err = cli("velocity-commands", "--out", ws, "--rate", "inf")
    assert code == 2 and err.strip().splitlines() == ["error: --rate must be >= 0.1, got inf; e.g. --rate 10"]
    assert sorted(p.name for p in ws.iterdir()) == before


@pytest.mark.parametrize("reader", ["read_trajectory_set", "read_table"])
def test_a_flipped_bit_in_a_data_page_is_an_error_never_a_changed_value(table, tmp_path, reader):
    """Every data page carries its CRC32 (``schema.write_table``), checked by the readers: 40 single-bit
    flips across the x and theta column chunks each give an ``InputError``, none a silently changed value
    (without checksums, a flip inside zstd's literals decodes to other numbers)."""
    from cobot_analysis.compare import read_trajectory_set
    from cobot_analysis.errors import InputError
    from cobot_analysis.schema import read_table

    def read(path):
        if reader == "read_table":
            return read_table(path, TRAJECTORIES)[["x", "y", "theta", "gamma"]].to_numpy()
        ts = read_trajectory_set(path)
        return np.stack([ts.x, ts.y, ts.theta, ts.gamma])

    data, ref = table.read_bytes(), read(table)
    meta = pq.ParquetFile(table).metadata.row_group(0)
    chunks = [meta.column(i) for i in range(meta.num_columns) if meta.column(i).path_in_schema in ("x", "theta")]
    outcomes = []
    for k in range(40):
        chunk = chunks[k % 2]
        offset = chunk.data_page_offset + 30 + (k * 7919) % (chunk.total_compressed_size - 30)
        flipped = bytearray(data)
        flipped[offset] ^= 1 << (k % 8)
        bad = tmp_path / "flipped.parquet"
        bad.write_bytes(bytes(flipped))
        try:
            outcomes.append("same" if np.array_equal(read(bad), ref, equal_nan=True) else "changed")
        except InputError as exc:
            assert "not a readable Parquet file" in str(exc)
            outcomes.append("refused")
    assert "changed" not in outcomes and outcomes.count("refused") >= 30, outcomes


@pytest.mark.parametrize("back", [100, 3000])
def test_a_flipped_bit_in_the_markers_is_refused_by_preprocess(imported, tmp_path, cli, back):
    """The markers table ``import`` streams has page checksums too. Before, these two flips (``back`` bytes
    before the end of the x column's page) decoded to other coordinates, and preprocess wrote other
    trajectories from them with exit 0."""
    markers = imported / "import" / "markers.parquet"
    meta = pq.ParquetFile(markers).metadata.row_group(0)
    x = next(meta.column(i) for i in range(meta.num_columns) if meta.column(i).path_in_schema == "x")
    flipped = bytearray(markers.read_bytes())
    flipped[x.data_page_offset + x.total_compressed_size - back] ^= 1 << (back % 8)
    bad = tmp_path / "markers.parquet"
    bad.write_bytes(bytes(flipped))
    line = refused(cli, tmp_path / "ws", bad, "-q", "preprocess", "--out", tmp_path / "ws", "--markers", bad,
                   "--trials", imported / "import" / "trials.parquet", "-j", "1")
    assert "cannot read the marker columns" in line and "re-run `cobot-analysis import`" in line


@pytest.mark.parametrize("edit, expected", [
    (lambda df: df.assign(d_xy=-df["d_xy"]), "column 'd_xy': 8 value(s) negative or infinite"),
    (lambda df: df.assign(d_theta=np.where(df.index == 0, np.inf, df["d_theta"])), "column 'd_theta': 1 value(s) negative or infinite"),
])
def test_stats_on_distances_no_comparison_gives(table, tmp_path, cli, edit, expected):
    """Distances are >= 0 and finite (before: stats ran its tests on them, exit 0)."""
    from cobot_analysis.cli import run

    ws = tmp_path / "good"
    for args in (["average"], ["compare"]):
        assert run(["-q", *args, "--out", str(ws), "--trajectories", str(table)]) == 0
    bad = edited(ws / "compare" / "distances.parquet", tmp_path / "distances.parquet", edit)
    line = refused(cli, tmp_path / "ws", bad, "stats", "--out", tmp_path / "ws", "--trajectories", table, "--distances", bad)
    assert expected in line, line


@pytest.mark.parametrize("dataset, largest", [("walking-2020", 8.30), ("pair-carriage-2022", 4.98)])
def test_published_orientations_pass_the_unwrapped_limit_and_their_degrees_do_not(datasets, dataset, largest):
    """theta's limit (schema.TURNS turns) is above the largest |theta| of the published trajectories (walking-2020:
    8.30 rad, 1.32 turns), and the same table in degrees without gamma is refused (before: it passed)."""
    from cobot_analysis.api import import_published, trajectory_set
    from cobot_analysis.errors import InputError

    t = import_published(dataset, datasets / dataset).trajectories
    assert round(float(t["theta"].abs().max()), 2) == largest
    assert len(trajectory_set(t)) == t.groupby(["trial", "entity"]).ngroups
    with pytest.raises(InputError, match=r"column 'theta': .* rad \(e\.g\. .*; degrees\?\); give theta in rad"):
        trajectory_set(t.assign(theta=np.degrees(t["theta"])).drop(columns="gamma"))


def _laps_recording(trial, turns, r=1.5, duration=40.0):
    """Marker rows of a walker at rest 1 s, then ``turns`` laps of a circle of radius ``r`` (min-jerk along the
    circle, facing the way it walks), then at rest: its heading turns ``turns`` times with its path."""
    from test_preprocess import RATE, _min_jerk, _rows, pelvis

    t = np.arange(0, duration, 1 / RATE)
    phi = 2 * np.pi * turns * _min_jerk(t, 1.0, duration - 1.0)
    return _rows(trial, "walker", pelvis(r * np.sin(phi), r * (1 - np.cos(phi)), phi))


def test_a_walker_lapping_a_track_goes_through_and_the_same_heading_in_degrees_does_not(tmp_path, cli):
    """4 and 4.5 laps of a circle: preprocess wrote headings up to 28.3 rad (4.5 turns), and every later stage
    refused its own table as 'degrees?' (schema.TURNS = 3). A heading beyond 3 turns now passes where the path
    turns as often (angles.turns_with_path); in degrees, or one turning 3 times more than its path, it does not."""
    from test_preprocess import trials_row, write_workspace

    ws = tmp_path / "ws"
    write_workspace(ws, _laps_recording("L1", 4.0) + _laps_recording("L2", 4.5),
                    [trials_row("L1", subject="S01"), trials_row("L2", subject="S02")])
    for stage in ("preprocess", "average", "compare"):
        code, _, err = cli(stage, "--out", ws, *(["--jobs", "1", "--samples", "101"] if stage == "preprocess" else []))
        assert code == 0, err
    traj = ws / "preprocess" / "trajectories.parquet"
    theta = pq.read_table(traj, columns=["trial", "theta"]).to_pandas().groupby("trial")["theta"].max()
    assert theta["L1"] == pytest.approx(8 * np.pi, abs=0.05) and theta["L2"] == pytest.approx(9 * np.pi, abs=0.05)
    means = ws / "average" / "means.parquet"
    assert pq.read_table(means, columns=["theta"])["theta"].to_numpy().max() > 6 * np.pi  # the mean laps too
    for name, edit in [("degrees", lambda df: df.assign(theta=np.degrees(df["theta"])).drop(columns="gamma")),
                       ("three times", lambda df: df.assign(theta=3 * df["theta"]).drop(columns="gamma"))]:
        bad = edited(traj, tmp_path / f"{name}.parquet", edit)
        line = refused(cli, tmp_path / f"ws-{name}", bad, "average", "--out", tmp_path / f"ws-{name}", "--trajectories", bad)
        assert "column 'theta'" in line and "degrees?" in line and "laps" in line, line


@pytest.mark.parametrize("case, expected", [
    ("laps", True),  # 4 laps of a circle, facing the way it walks
    ("laps, starting 2 turns round", True),
    ("laps in degrees", False),  # spans 57 times its path's turning
    ("straight in degrees", False),  # starts beyond 3 turns (90)
    ("a quarter turn in degrees from 0", False),  # starts within 3 turns, spans 90 for a path turning pi/2
    ("spinning on a straight path", False),  # 4 turns of the heading, none of the path
    ("at rest", False),  # no path to turn with
])
def test_turns_with_path_on_analytic_headings(case, expected):
    from cobot_analysis.angles import turns_with_path

    s = np.linspace(0, 1, 500)
    phi = 8 * np.pi * s
    circle = (1.5 * np.sin(phi), 1.5 * (1 - np.cos(phi)))
    arc = (np.sin(np.pi / 2 * s), 1 - np.cos(np.pi / 2 * s))
    x, y, theta = {
        "laps": (*circle, phi),
        "laps, starting 2 turns round": (*circle, phi + 4 * np.pi),
        "laps in degrees": (*circle, np.degrees(phi)),
        "straight in degrees": (3 * s, 0 * s, np.full_like(s, 90.0)),
        "a quarter turn in degrees from 0": (*arc, 90 * s),
        "spinning on a straight path": (3 * s, 0 * s, phi),
        "at rest": (0 * s, 0 * s, phi),
    }[case]
    assert turns_with_path(x, y, theta, 6 * np.pi) is expected
