"""One vocabulary across the command line: one meaning per option name, old spellings that still
work with one warning naming the new one, global options anywhere, `--start X Y THETA`."""

from __future__ import annotations

import json
from collections import defaultdict

import pandas as pd
import pytest
import typer.main

from cobot_analysis import __version__
from cobot_analysis.cli.app import DEPRECATED, app, normalise_args

GROUP = typer.main.get_command(app)


def leaves(group=GROUP, path=()):
    for name, cmd in group.commands.items():
        yield from leaves(cmd, (*path, name)) if hasattr(cmd, "commands") else [((*path, name), cmd)]


def command(path: tuple[str, ...]):
    cmd = GROUP
    for name in path:
        cmd = cmd.commands[name]
    return cmd


def test_the_overloaded_names_have_one_meaning():
    owners = defaultdict(list)
    for path, cmd in leaves():
        for p in cmd.params:
            for name in (*p.opts, *p.secondary_opts):
                owners[name].append(" ".join(path))
    assert owners["--map"] == ["import"]  # LAB=CANON marker label mappings
    assert owners["--label"] == ["localisation"]  # run labels
    assert owners["--comparison"] == ["compare"]
    assert owners["--study"] == ["generate"] and owners["--only-study"] == ["predict"]
    assert owners["--trials"] == ["preprocess"]  # a trials.parquet
    assert owners["--goals"] == ["synth pairs"] and owners["--goals-csv"] == ["localisation"]
    assert sorted(owners["--v-nominal"]) == ["fit-ioc", "generate", "predict"]
    for path in ("generate", "predict"):  # -w is --weights wherever it exists
        assert next(p for p in command((path,)).params if "-w" in p.opts).opts == ["--weights", "-w"]
    assert sorted(owners["-w"]) == ["generate", "predict"]
    for path, aliases in DEPRECATED.items():  # old spellings are gone from --help, the new ones are there
        names = {n for p in command(path).params for n in (*p.opts, *p.secondary_opts)}
        for old, new in aliases.items():
            if old.startswith("-"):
                assert old not in names and new.split("=")[0] in names, (path, old)


@pytest.mark.parametrize("argv, expected, warnings", [
    (["compare", "--label", "model"], ["compare", "--comparison", "model"], ["--label is deprecated in `compare`: use --comparison"]),
    (["fit-ioc", "-w", "ones"], ["fit-ioc", "--start-weights", "ones"], ["-w is deprecated in `fit-ioc`: use --start-weights"]),
    (["fit-ioc", "-wones"], ["fit-ioc", "--start-weights=ones"], ["-w is deprecated in `fit-ioc`: use --start-weights"]),
    (["predict", "--study=walking-2020", "--study", "x", "--nominal-speed", "1.2"],
     ["predict", "--only-study=walking-2020", "--only-study", "x", "--v-nominal", "1.2"],
     ["--study is deprecated in `predict`: use --only-study", "--nominal-speed is deprecated in `predict`: use --v-nominal"]),
    (["localisation", "a.bag", "--map", "scanned", "--goals", "g.csv"],
     ["localisation", "a.bag", "--map-name", "scanned", "--goals-csv", "g.csv"],
     ["--map is deprecated in `localisation`: use --map-name", "--goals is deprecated in `localisation`: use --goals-csv"]),
    (["synth", "walking", "--trials", "2"], ["synth", "walking", "--repetitions", "2"],
     ["--trials is deprecated in `synth walking`: use --repetitions"]),
    (["report", "walking", "--out", "walking"], ["report", "walking-2020", "--out", "walking"],
     ["walking is deprecated in `report`: use walking-2020"]),
    (["report", "--to", "pairs", "pairs"], ["report", "--to", "pairs", "pair-carriage-2022"],
     ["pairs is deprecated in `report`: use pair-carriage-2022"]),
    # the same names where they are current: untouched
    (["import", "p.yaml", "--map", "L=LASI"], ["import", "p.yaml", "--map", "L=LASI"], []),
    (["generate", "-w", "walking-2021"], ["generate", "-w", "walking-2021"], []),
    (["localisation", "--label", "run1"], ["localisation", "--label", "run1"], []),
    (["preprocess", "--trials", "t.parquet"], ["preprocess", "--trials", "t.parquet"], []),
    (["synth", "pairs", "--goals", "2"], ["synth", "pairs", "--goals", "2"], []),
    (["report", "synthetic-walking", "--out", "walking"], ["report", "synthetic-walking", "--out", "walking"], []),
])
def test_deprecated_spellings_are_rewritten(argv, expected, warnings):
    assert normalise_args(GROUP, argv) == (expected, warnings)


@pytest.mark.parametrize("argv, expected", [
    (["synth", "walking", "--out", "ws", "-q"], ["-q", "synth", "walking", "--out", "ws"]),
    (["metrics", "show", "ws", "--verbose"], ["--verbose", "metrics", "show", "ws"]),
    (["-v", "schemas", "--version"], ["--version", "-v", "schemas"]),
    (["compare", "--comparison", "-q"], ["compare", "--comparison", "-q"]),  # the value of an option stays
    (["generate", "--start", "-1.5,-3,0.5", "-v"], ["-v", "generate", "--start", "-1.5", "-3", "0.5"]),
    (["generate", "--start", "-1.5", "-3", "0.5", "--goal", "0,0,1.5"],
     ["generate", "--start", "-1.5", "-3", "0.5", "--goal", "0", "0", "1.5"]),
    (["results", "ws", "--", "-q"], ["results", "ws", "--", "-q"]),
    (["no-such-command", "-q"], ["no-such-command", "-q"]),  # click names the unknown command
])
def test_global_options_are_moved_before_the_command(argv, expected):
    assert normalise_args(GROUP, argv) == (expected, [])


def test_global_options_anywhere(cli, tmp_path):
    ws = tmp_path / "ws"
    code, out, err = cli("synth", "walking", "--out", ws, "--subjects", "1", "--repetitions", "1", "--conditions", "1", "-q")
    assert code == 0 and out == "" and err == ""
    assert (ws / "synth-walking" / "protocol.yaml").is_file()
    code, _, err = cli("synth", "walking", "--out", ws, "--subjects", "1", "--repetitions", "1", "--conditions", "1", "-v")
    assert code == 0
    assert err.strip().splitlines()[-1] == f"synth-walking: up to date, skipped (--force redoes it) -> {ws / 'synth-walking'}"
    assert cli("schemas", "--version") == (0, f"cobot-analysis {__version__}\n", "")


def test_a_command_run_in_process_leaves_the_callers_logging_as_it_was(cli, tmp_path, caplog):
    """-q and the console handler hold for the run only: a notebook's later warnings still reach its logging."""
    import logging

    from cobot_analysis.console import verbosity, warn

    logger = logging.getLogger("cobot_analysis")
    before = verbosity(), logger.level, list(logger.handlers), logger.propagate
    code, out, err = cli("synth", "walking", "--out", tmp_path / "ws", "--subjects", "1", "--repetitions", "1",
                         "--conditions", "1", "-q")
    assert code == 0 and out == err == ""
    assert (verbosity(), logger.level, list(logger.handlers), logger.propagate) == before
    warn("after the run")
    assert [r.getMessage() for r in caplog.records if r.name == "cobot_analysis"] == ["after the run"]


def test_an_old_spelling_works_with_one_warning(cli, tmp_path):
    ws = tmp_path / "ws"
    code, _, err = cli("synth", "walking", "--out", ws, "--subjects", "1", "--trials", "2", "--conditions", "1")
    assert code == 0
    assert [line for line in err.splitlines() if "warning" in line] == [
        "warning: --trials is deprecated in `synth walking`: use --repetitions"]
    assert json.loads((ws / "synth-walking" / "manifest.json").read_text())["params"]["trials"] == 2
    assert err.strip().splitlines()[-1] == f"synth-walking: 2 trials -> {ws / 'synth-walking'}"
    # fit-ioc -w is --start-weights: parsed (not "No such option"), warned, then the missing means stop it
    code, _, err = cli("fit-ioc", "--out", tmp_path / "empty", "-w", "ones")
    assert code == 2 and err.startswith("warning: -w is deprecated in `fit-ioc`: use --start-weights\nerror: ")


def test_generate_start_reads_x_y_theta_either_way(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("COLUMNS", "120")
    code, out, _ = cli("generate", "--help")
    start = next(line for line in out.splitlines() if "--start" in line and "Start pose" in line)
    assert "X Y THETA" in start and "<float,float,float>" not in out
    tables = []
    for i, pose in enumerate((["2", "3", "0.5"], ["2,3,0.5"])):
        ws = tmp_path / f"ws{i}"
        code, _, err = cli("generate", "--out", ws, "--model", "clothoid", "--start", *pose)
        assert code == 0, err
        assert err.strip().splitlines()[-1] == (f"generate (continuous): 1 trajectory, all at their goal, mean speed 1 m/s -> "
                                                f"{ws / 'generate' / 'generated.parquet'}")
        tables.append(pd.read_parquet(ws / "generate" / "generated.parquet"))
    first = tables[0].sort_values("sample").iloc[0]
    assert (first["x"], first["y"], first["theta"]) == pytest.approx((2.0, 3.0, 0.5))
    pd.testing.assert_frame_equal(tables[0], tables[1])
