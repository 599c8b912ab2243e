"""Where a command is told to write, and options that name files: refused before any work, in one line
naming the path, exit code 2 (before: an internal error, or the option silently ignored)."""

from __future__ import annotations

from pathlib import Path

import pytest


def one_line(code: int, err: str) -> str:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    return lines[0]


@pytest.fixture
def a_file(tmp_path) -> Path:
    path = tmp_path / "notes.txt"
    path.write_text("mine\n")
    return path


@pytest.mark.parametrize("to, named", [("{f}", "{f}: is a file, not a directory; give --to a directory"),
                                       ("{f}/report", "{f}: is a file, not a directory; give --to a path whose parents")])
def test_report_to_a_file(tmp_path, cli, a_file, to, named):
    ws = tmp_path / "ws"
    ws.mkdir()
    line = one_line(*cli("report", "--out", ws, "--to", to.format(f=a_file))[::2])
    assert named.format(f=a_file) in line
    assert a_file.read_text() == "mine\n" and not any(ws.iterdir())


def test_report_out_a_file(cli, a_file):
    line = one_line(*cli("report", "--out", a_file)[::2])
    assert f"{a_file}: is not a directory; pass a workspace directory" in line


@pytest.mark.parametrize("to, named", [("{f}/results.md", "{f}: is a file, not a directory"),
                                       ("{d}", "{d}: is a directory; give --to a file name")])
def test_results_to_a_path_that_cannot_be_written(tmp_path, cli, a_file, to, named):
    d = tmp_path / "folder"
    d.mkdir()
    line = one_line(*cli("results", tmp_path, "--to", to.format(f=a_file, d=d))[::2])
    assert named.format(f=a_file, d=d) in line
    assert a_file.read_text() == "mine\n" and not any(d.iterdir())


def compared_workspace(tmp_path, cli) -> Path:
    """A small synthetic walking study averaged and compared: what stats reads."""
    from cobot_analysis.schema import TRAJECTORIES, write_table
    from cobot_analysis.synth.tables import walking_table

    ws = tmp_path / "ws"
    write_table(walking_table(seed=3, n_subjects=3, n_conditions=2, n_trials=2, missing_theta=0.0),
                ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    for args in (["average"], ["compare"]):
        assert cli("-q", *args, "--out", ws)[0] == 0
    return ws


def test_stats_anthropometrics_without_its_files_is_not_ignored(tmp_path, cli):
    ws = compared_workspace(tmp_path, cli)
    empty = tmp_path / "anthro"
    empty.mkdir()
    line = one_line(*cli("stats", "--out", ws, "--anthropometrics", empty)[::2])
    assert f"{empty}: no subjects.csv and pairs.csv in this directory; pass the folder of the study's subjects.csv and pairs.csv" in line
    assert not (ws / "stats").exists()


@pytest.mark.parametrize("subjects, pairs, named", [
    ("id,weight,height\nS01,60,1.6\nS02,70,1.7\nS01,80,1.9\n", "id,subject1,subject2\nP01,S01,S02\n",
     "the subjects table lists S01 twice; give each row of the subjects table its own id"),
    ("id,weight,height\nS01,60,1.6\nS02,70,1.7\n", "id,subject1,subject2\nP01,S01,S03\n",
     "pair P01 names subject2 S03, which is not an id of the subjects table (S01, S02)"),
])
def test_stats_anthropometrics_whose_ids_do_not_match(tmp_path, cli, subjects, pairs, named):
    """A subject listed twice (two weights) stopped stats with an internal error (pandas' InvalidIndexError, exit 1);
    a pair naming a subject the table lacks gave a NaN weight difference without a word."""
    ws = compared_workspace(tmp_path, cli)
    anthro = tmp_path / "anthro"
    anthro.mkdir()
    (anthro / "subjects.csv").write_text(subjects)
    (anthro / "pairs.csv").write_text(pairs)
    code, out, err = cli("stats", "--out", ws, "--anthropometrics", anthro)
    assert code == 2 and f"{anthro}: {named}" in one_line(code, err), err
    assert not (ws / "stats").exists()


@pytest.mark.parametrize("start", [["inf", "0", "0"], ["0", "0", "nan"]])
def test_generate_from_a_start_that_is_not_finite(tmp_path, cli, start):
    line = one_line(*cli("generate", "--out", tmp_path / "ws", "--start", *start)[::2])
    assert "--start (" in line and ") has a NaN or infinite value; give --start as three finite numbers (m, m, rad)" in line
    assert not (tmp_path / "ws").exists() or not any((tmp_path / "ws").iterdir())


def test_metrics_show_of_a_workspace_without_metrics(tmp_path, cli):
    """Before: 'study: unknown' and exit 0, as if the workspace had been read."""
    ws = tmp_path / "ws"
    ws.mkdir()
    line = one_line(*cli("metrics", "show", ws)[::2])
    assert line == f"error: {ws}: no stage metrics (metrics.json) in the workspace(s); run the study's stages with this --out first"


def test_every_metrics_command_refuses_a_workspace_without_metrics(tmp_path, cli):
    """The check lived in the show command (cli/); regression.baseline.collect makes it now, for show, check and update
    alike (before: check named the baseline's first stage as missing, update had its own wording)."""
    from cobot_analysis.errors import InputError
    from cobot_analysis.regression.baseline import collect

    ws = tmp_path / "ws"
    ws.mkdir()
    expected = f"{ws}: no stage metrics (metrics.json) in the workspace(s); run the study's stages with this --out first"
    with pytest.raises(InputError) as refused:
        collect([ws])
    assert str(refused.value) == expected
    baseline = Path(__file__).parent / "baselines" / "walking-2020.json"
    for args in (("check", baseline), ("update", tmp_path / "new.json")):
        assert one_line(*cli("metrics", *args, ws)[::2]) == f"error: {expected}"
    assert not (tmp_path / "new.json").exists()
