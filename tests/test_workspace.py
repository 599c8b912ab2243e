"""The workspace (--out) and its stage directories: what is not a workspace is refused in one line
(exit code 2, nothing changed); a missing input names the command that writes it; stage
directories get the user's umask."""

from __future__ import annotations

import os
from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """A tiny synthetic walking study (raw files and protocol) and its import stage."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("study")
    assert run(["-q", "synth", "walking", "--out", str(ws), "--subjects", "1", "--repetitions", "1", "--conditions", "2"]) == 0
    assert run(["-q", "import", str(ws / "synth-walking" / "protocol.yaml"), "--out", str(ws), "--jobs", "1"]) == 0
    return ws


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return " ".join(lines[0].split())


def test_out_that_is_a_file(study, tmp_path, cli):
    out = tmp_path / "results.txt"
    out.write_text("mine\n")
    code, _, err = cli("import", study / "synth-walking" / "protocol.yaml", "--out", out)
    assert code == 2 and _one_line(err) == (f"error: {out}: is not a directory; pass a workspace directory (new or "
                                            "existing) with --out")
    code, _, err = cli("preprocess", "--out", out)  # a stage that looks for its input in the workspace
    assert code == 2 and f"{out}: is not a directory" in _one_line(err)
    assert out.read_text() == "mine\n"


def test_stage_directory_that_is_a_file_is_not_replaced(study, tmp_path, cli):
    ws = tmp_path / "ws"
    ws.mkdir()
    (ws / "import").write_text("my notes\n")
    code, _, err = cli("import", study / "synth-walking" / "protocol.yaml", "--out", ws)
    assert code == 2 and _one_line(err) == (f"error: {ws / 'import'}: exists and is not a stage directory; move or delete "
                                            f"it (stage import writes the directory {ws / 'import'}), or pass another --out")
    assert (ws / "import").read_text() == "my notes\n" and sorted(p.name for p in ws.iterdir()) == ["import"]


def test_unwritable_out(study, tmp_path, cli):
    if os.geteuid() == 0:  # root writes anywhere a permission allows: use a place no one can write
        if not Path("/sys").is_dir():
            pytest.skip("no unwritable place for root on this system")
        out = Path("/sys/cobot-analysis-test/ws")
    else:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        out = locked / "ws"
    code, _, err = cli("import", study / "synth-walking" / "protocol.yaml", "--out", out)
    line = _one_line(err)
    assert code == 2 and "cannot write the workspace (" in line and line.endswith("pass a writable directory with --out")
    assert not out.exists()


def test_missing_input_of_a_later_stage_names_the_command_that_writes_it(study, tmp_path, cli):
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(study / "import", ws / "import")
    (ws / "import" / "trials.parquet").unlink()
    code, _, err = cli("preprocess", "--out", ws)
    line = _one_line(err)
    assert code == 2 and line.startswith(f"error: {(ws / 'import' / 'trials.parquet').resolve()}: input file not found; "
                                         "re-run the command that wrote it: `cobot-analysis ")
    assert " import " in line and "protocol.yaml" in line
    assert sorted(p.name for p in ws.iterdir()) == ["import"]


def test_stage_directories_follow_the_umask(study, tmp_path, cli):
    old = os.umask(0o027)
    try:
        code, _, err = cli("-q", "import", study / "synth-walking" / "protocol.yaml", "--out", tmp_path / "ws", "--jobs", "1")
    finally:
        os.umask(old)
    assert code == 0, err
    assert (tmp_path / "ws").stat().st_mode & 0o777 == 0o750
    assert (tmp_path / "ws" / "import").stat().st_mode & 0o777 == 0o750
    assert (tmp_path / "ws" / "import" / "manifest.json").stat().st_mode & 0o777 == 0o640
