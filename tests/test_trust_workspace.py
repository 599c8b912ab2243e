"""Issue 21: a skip verifies what it reuses, one run per stage and workspace, and what a killed
run leaves is removed by the next. Real processes where concurrency is the point."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.workspace import Stage

CLI = [sys.executable, "-m", "cobot_analysis"]
ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A tiny synthetic walking study, imported and preprocessed."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("study")
    assert run(["-q", "synth", "walking", "--out", str(ws), "--subjects", "1", "--repetitions", "1", "--conditions", "2"]) == 0
    assert run(["-q", "import", str(ws / "synth-walking" / "protocol.yaml"), "--out", str(ws), "--jobs", "1"]) == 0
    assert run(["-q", "preprocess", "--out", str(ws), "--jobs", "1"]) == 0
    return ws


def _shift_x(path: Path, dx: float) -> None:
    """Edit a Parquet table by hand: x shifted by ``dx`` m, metadata kept."""
    table = pq.read_table(path)
    df = table.to_pandas()
    df["x"] = df["x"] + dx
    import pyarrow as pa

    pq.write_table(pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(table.schema.metadata), path)


def test_an_edited_output_is_not_reused_the_stage_runs_again(study, tmp_path, cli):
    """Editing preprocess/trajectories.parquet (x + 5 m) and re-running printed 'up to date, skipped'."""
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(study, ws, symlinks=True)
    out = ws / "preprocess" / "trajectories.parquet"
    original = pq.read_table(out).to_pandas()["x"].to_numpy()
    assert cli("preprocess", "--out", ws, "--jobs", "1")[0] == 0  # the copy's inputs have other paths: runs once
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 0 and "up to date, skipped" in err, err  # unchanged: skipped
    _shift_x(out, 5.0)
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")
    assert code == 0, err
    message = " ".join(err.split())
    assert "preprocess: trajectories.parquet changed since the stage wrote it (not as its manifest records): running it again" in message
    assert "skipped" not in message
    assert (pq.read_table(out).to_pandas()["x"].to_numpy() == original).all()  # the stage's own result again


def test_same_size_same_mtime_edit_is_caught_by_the_hash_when_the_time_differs(study, tmp_path):
    """The cheap check: size and mtime; a same-size edit with another mtime is hashed."""
    import shutil

    from cobot_analysis.workspace import changed_outputs

    ws = tmp_path / "ws"
    shutil.copytree(study, ws, symlinks=True)
    stage = ws / "preprocess"
    manifest = json.loads((stage / "manifest.json").read_text())
    assert changed_outputs(stage, manifest) == []
    f = stage / "results.md"
    text = f.read_bytes()
    f.write_bytes(text[:-2] + (b"X" if text[-2:-1] != b"X" else b"Y") + text[-1:])  # same size, other bytes, new mtime
    assert changed_outputs(stage, manifest) == ["results.md"]
    os.utime(f, ns=(os.stat(f).st_atime_ns, next(o["mtime_ns"] for o in manifest["outputs"] if o["path"] == "results.md")))
    assert changed_outputs(stage, manifest) == []  # the cheap check trusts an identical size and time (documented)


def test_a_stage_does_not_compute_from_an_edited_upstream_output(study, tmp_path, cli):
    """Editing average/means.parquet's input and running the next stage: refused, the file named."""
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(study, ws, symlinks=True)
    out = ws / "preprocess" / "trajectories.parquet"
    _shift_x(out, 5.0)
    code, _, err = cli("average", "--out", ws)
    assert code == 2, err
    message = " ".join(err.split())
    assert f"{out}: changed since stage preprocess wrote it (its SHA-256 differs from preprocess/manifest.json)" in message
    assert "re-run `cobot-analysis preprocess`" in message
    assert not (ws / "average").exists()


HOLD = textwrap.dedent("""
    import sys, time
    from cobot_analysis.workspace import Stage
    with Stage(sys.argv[1], "demo", params={"a": 1}, force=True) as stage:
        stage.path("out.txt").write_text("first")
        print("holding", flush=True)
        if sys.argv[2] == "kill":
            import os, signal
            os.kill(os.getpid(), signal.SIGKILL)
        time.sleep(float(sys.argv[2]))
""")


def _holder(ws: Path, arg: str) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-c", HOLD, str(ws), arg], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    assert p.stdout.readline().strip() == "holding", p.communicate()
    return p


def test_a_second_concurrent_run_of_a_stage_is_refused_in_one_line(tmp_path):
    ws = tmp_path / "ws"
    p = _holder(ws, "30")
    try:
        with pytest.raises(InputError, match=rf"stage demo is being run into this workspace by another process \(pid {p.pid}\); "
                                             "wait for it to finish, or pass another --out"):
            with Stage(ws, "demo", params={"a": 2}, force=True) as stage:
                stage.path("out.txt").write_text("second")
        with Stage(ws, "other", params={}) as stage:  # another stage of the same workspace is free
            stage.path("x.txt").write_text("x")
    finally:
        p.terminate()
        p.wait(30)
    with Stage(ws, "demo", params={"a": 2}, force=True) as stage:  # free again once the first run has ended
        stage.path("out.txt").write_text("second")
    assert (ws / "demo" / "out.txt").read_text() == "second"


def test_two_concurrent_imports_one_is_refused(tmp_path, study):
    """Two `import` at once into one workspace: both exited 0 and the last writer won; now the second
    is refused (exit 2, one line) while the first holds the stage."""
    ws = tmp_path / "ws"
    p = _holder_stage(ws, "import")
    try:
        r = subprocess.run([*CLI, "import", str(study / "synth-walking" / "protocol.yaml"), "--out", str(ws), "--jobs", "1", "--force"],
                           capture_output=True, text=True, env=ENV, timeout=300)
    finally:
        p.terminate()
        p.wait(30)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "stage import is being run into this workspace by another process" in lines[0], r.stderr


def _holder_stage(ws: Path, name: str) -> subprocess.Popen:
    code = HOLD.replace('"demo"', repr(name))
    p = subprocess.Popen([sys.executable, "-c", code, str(ws), "30"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    assert p.stdout.readline().strip() == "holding", p.communicate()
    return p


def test_the_tmp_of_a_killed_stage_is_removed_by_the_next_run(tmp_path, caplog):
    caplog.set_level("INFO", logger="cobot_analysis")
    ws = tmp_path / "ws"
    p = _holder(ws, "kill")
    assert p.wait(30) == -signal.SIGKILL
    (left,) = ws.glob(".demo.*.tmp")
    assert (left / "out.txt").read_text() == "first" and not (ws / "demo").exists()
    with Stage(ws, "demo", params={"a": 1}) as stage:
        stage.path("out.txt").write_text("again")
    assert not left.exists() and (ws / "demo" / "out.txt").read_text() == "again"
    assert "left by an interrupted run" in " ".join(caplog.text.split())


def test_edited_means_are_not_reused_by_average_nor_read_by_compare(study, tmp_path, cli):
    """The issue's second case: average/means.parquet shifted by 5 m by hand."""
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(study, ws, symlinks=True)
    assert cli("preprocess", "--out", ws, "--jobs", "1")[0] == 0
    assert cli("average", "--out", ws)[0] == 0
    means = ws / "average" / "means.parquet"
    original = pq.read_table(means).to_pandas()["x"].to_numpy()
    _shift_x(means, 5.0)
    code, _, err = cli("compare", "--out", ws)
    assert code == 2 and f"{means}: changed since stage average wrote it" in " ".join(err.split()), err
    code, _, err = cli("average", "--out", ws)
    assert code == 0 and "average: means.parquet changed since the stage wrote it" in " ".join(err.split()), err
    assert (pq.read_table(means).to_pandas()["x"].to_numpy() == original).all()
    assert cli("compare", "--out", ws)[0] == 0


@pytest.mark.parametrize("case", ["new workspace", "--force", "earlier import"])
def test_an_import_refuses_a_raw_file_changed_since_synth_wrote_it(study, tmp_path, cli, case):
    """The raw files are hashed by the import's workers when the stage cannot be skipped (a new workspace,
    --force) and on entering otherwise: either way an edited raw file of a synth stage refuses the run, and
    the import keeps nothing of it."""
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(study, ws, symlinks=True)
    raw = sorted((ws / "synth-walking" / "raw").glob("*.c3d"))[0]
    data = bytearray(raw.read_bytes())
    data[-1] ^= 0x01  # the last byte of the point data
    raw.write_bytes(bytes(data))
    out = tmp_path / "new" if case == "new workspace" else ws
    before = (ws / "import" / "manifest.json").read_text()
    code, _, err = cli("import", ws / "synth-walking" / "protocol.yaml", "--out", out, "--jobs", "2",
                       *(["--force"] if case == "--force" else []))
    assert code == 2, err
    assert f"{raw}: changed since stage synth-walking wrote it" in " ".join(err.split()), err
    assert "re-run `cobot-analysis synth walking` with its --out" in " ".join(err.split()), err  # a command that exists
    assert not (tmp_path / "new" / "import").exists()
    assert (ws / "import" / "manifest.json").read_text() == before


def test_a_renamed_stage_directory_names_the_command_of_its_stage(study, tmp_path, cli):
    """The remedy names the command of the stage the manifest records, not of the directory's name (a synth
    study copied to a folder of its own)."""
    import shutil

    mine = tmp_path / "my-study"
    shutil.copytree(study / "synth-walking", mine, symlinks=True)
    raw = sorted((mine / "raw").glob("*.c3d"))[0]
    raw.write_bytes(raw.read_bytes()[:-1] + bytes([raw.read_bytes()[-1] ^ 0x01]))
    code, _, err = cli("import", mine / "protocol.yaml", "--out", tmp_path / "ws", "--jobs", "1")
    line = " ".join(err.split())
    assert code == 2 and f"{raw}: changed since stage synth-walking wrote it (its SHA-256 differs from my-study/manifest.json)" in line, err
    assert "re-run `cobot-analysis synth walking` with its --out" in line, err
    assert not (tmp_path / "ws").exists()


def test_the_inputs_a_run_hashes_are_described_as_on_entering(study, tmp_path):
    """``hashed_by_run``: the manifest's inputs are the same whether the run or the stage hashes them."""
    from cobot_analysis.provenance import file_sha256

    files = sorted((study / "synth-walking" / "raw").glob("*.c3d"))
    manifests = []
    for run_hashes in (False, True):
        with Stage(tmp_path / f"ws{run_hashes}", "demo", inputs=[study / "synth-walking" / "protocol.yaml", *files],
                   hashed_by_run=files if run_hashes else ()) as stage:
            assert (str(files[0]) in stage.input_hashes) is not run_hashes
            stage.inputs_hashed({str(files[0]): file_sha256(files[0])})  # the others hashed here
            stage.path("out.txt").write_text("x")
        manifests.append(json.loads((tmp_path / f"ws{run_hashes}" / "demo" / "manifest.json").read_text())["inputs"])
    assert manifests[0] == manifests[1] and len(manifests[0]) == len(files) + 1
