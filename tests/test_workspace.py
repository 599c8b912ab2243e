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


def test_a_refused_run_into_a_new_workspace_leaves_no_directory(tmp_path, cli):
    """A run that keeps nothing removes the directories of --out it created (the deepest first, while they are
    empty); an existing workspace, with what is in it, stays as it was."""
    from cobot_analysis.workspace import Stage

    new = tmp_path / "new" / "ws"
    code, _, err = cli("localisation", os.devnull, "--out", new)
    assert code == 2 and "not a readable ROS bag" in _one_line(err)
    assert sorted(tmp_path.iterdir()) == []  # neither new/ws nor new
    with pytest.raises(RuntimeError), Stage(new, "failed"):
        assert (new / ".failed.lock").exists()
        raise RuntimeError("failed inside the stage")
    assert sorted(tmp_path.iterdir()) == []
    old = tmp_path / "old"
    old.mkdir()
    (old / "notes.txt").write_text("mine\n")
    with pytest.raises(RuntimeError), Stage(old / "sub", "failed"):
        raise RuntimeError("failed inside the stage")
    assert sorted(p.name for p in old.iterdir()) == ["notes.txt"] and (old / "notes.txt").read_text() == "mine\n"
    with Stage(new, "kept") as stage:  # a run that is kept keeps its workspace
        stage.path("x.txt").write_text("x")
    assert (new / "kept" / "x.txt").read_text() == "x"
    with pytest.raises(RuntimeError), Stage(new, "failed"):  # the workspace existed before this run: left
        raise RuntimeError("failed inside the stage")
    assert sorted(p.name for p in new.iterdir()) == ["kept"]


def test_a_stage_closes_the_figures_it_draws_and_leaves_the_callers(tmp_path):
    """pyplot keeps every figure until it is closed: a stage that drew (and saved, or failed before saving) a
    figure leaves none open, in a notebook or a long process; a figure the caller had open stays open."""
    from cobot_analysis.plotting import pyplot
    from cobot_analysis.workspace import Stage

    plt = pyplot()
    plt.close("all")
    mine = plt.figure()
    with Stage(tmp_path, "drawn") as stage:
        stage.savefig(plt.subplots()[0], "saved")
        plt.subplots()  # drawn, never saved
        assert len(plt.get_fignums()) == 2
    assert plt.get_fignums() == [mine.number]
    assert (tmp_path / "drawn" / "saved.png").stat().st_size > 0
    with pytest.raises(RuntimeError), Stage(tmp_path, "failed"):
        plt.subplots()
        raise RuntimeError("failed after drawing")
    assert plt.get_fignums() == [mine.number] and not (tmp_path / "failed").exists()
    plt.close(mine)


def test_the_report_stage_leaves_no_figure_open(tmp_path, cli):
    """A real stage that saves figures (the report: paths, box plots) leaves ``get_fignums()`` empty."""
    from cobot_analysis.plotting import pyplot
    from cobot_analysis.schema import TRAJECTORIES, write_table
    from cobot_analysis.synth.tables import walking_table

    plt = pyplot()
    plt.close("all")
    ws = tmp_path / "ws"
    write_table(walking_table(n_subjects=2, n_conditions=2, n_trials=1, n=20), ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    for args in (["average"], ["compare"], ["report"]):
        code, _, err = cli("-q", *args, "--out", ws)
        assert code == 0, err
    assert len(list((ws / "report").glob("*.png"))) >= 3  # figures were drawn and saved
    assert plt.get_fignums() == []
