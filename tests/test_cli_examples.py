"""Every command's ``--help`` examples run as written: the Examples block of each command's help, as
printed at 80 columns, is parsed and every line run in-process, in the order the data flows, in one
temporary directory that holds only what the examples make, plus what a checkout has beside them:
the repository's ``pipelines/`` and the baselines' ``tolerances.toml`` (and, for ``import-published``,
the published datasets at ``../shared/datasets``). Each run must succeed without a deprecation
warning and end with its summary line ``stage: what -> where``."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest
import typer.main

from cobot_analysis.cli.app import app

ROOT = Path(__file__).resolve().parents[1]

#: Every command, in the order its examples run: each uses what the earlier ones wrote.
ORDER = ["synth walking", "synth pairs", "synth localisation", "import", "import-published", "preprocess", "average",
         "fit-ioc", "generate", "velocity-commands", "compare", "stats", "reconstruct", "report", "predict", "bag-info",
         "localisation", "results", "schemas", "metrics show", "metrics update", "metrics check", "demo"]
#: Commands that print a table or a report on stdout rather than end a stage.
NO_SUMMARY = {"metrics show", "metrics update", "metrics check"}
SUMMARY = re.compile(r"^(?P<stage>[a-z][a-z-]*)(?: \([^)]*\))?: .+ -> \S.*$")


def commands(group=None, path=()) -> list[str]:
    group = group if group is not None else typer.main.get_command(app)
    out = []
    for name, cmd in group.commands.items():
        out += commands(cmd, (*path, name)) if hasattr(cmd, "commands") else [" ".join((*path, name))]
    return out


def examples_of(text: str) -> list[str]:
    """The example command lines after ``Examples:`` (a line ending in a backslash continues)."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip() == "Examples:")
    out, current = [], ""
    for line in lines[start + 1:]:
        part = line.strip()
        if not part or part == "\b":  # the epilog's mark that click keeps the block's lines as they are
            continue
        current += part
        if current.endswith("\\"):
            current = current[:-1]
        else:
            out.append(" ".join(current.split()))
            current = ""
    return out


@pytest.fixture
def help_examples(cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")

    def get(command: str) -> list[str]:
        code, out, err = cli(*command.split(), "--help")
        assert code == 0, err
        return examples_of(out)
    return get


def test_every_command_has_examples_that_its_help_prints_whole(help_examples):
    assert sorted(ORDER) == sorted(commands())  # a new command gets a place in ORDER (and examples)
    group = typer.main.get_command(app)
    for command in ORDER:
        cmd = group
        for name in command.split():
            cmd = cmd.commands[name]
        printed = help_examples(command)
        assert printed and printed == examples_of(cmd.epilog), command  # nothing cut or wrapped at 80 columns
        for line in printed:
            assert shlex.split(line)[:1 + len(command.split())] == ["cobot-analysis", *command.split()], line


def run_examples(cli, help_examples, command: str) -> None:
    for line in help_examples(command):
        code, _, err = cli(*shlex.split(line)[1:])
        assert code == 0, f"{line}\n{err}"
        assert "deprecated" not in err, f"{line}\n{err}"
        if command not in NO_SUMMARY:
            last = err.strip().splitlines()[-1]
            match = SUMMARY.match(last)
            assert match and match["stage"] == command.replace(" ", "-"), f"{line}: last line {last!r}"


@pytest.mark.slow
def test_help_examples_run_as_written(cli, help_examples, tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    (work / "pipelines").symlink_to(ROOT / "pipelines")
    shutil.copy(ROOT / "tests" / "baselines" / "tolerances.toml", work)
    monkeypatch.chdir(work)
    for command in ORDER:
        if command != "import-published":  # needs the published datasets: the test below
            run_examples(cli, help_examples, command)
    # what the examples made, as their options say
    assert (work / "walking" / "synth-walking").is_dir() and (work / "walking2" / "synth-walking").is_dir()
    assert (work / "walking-report" / "README.md").is_file() and (work / "pairs-report" / "README.md").is_file()
    assert (work / "walking" / "predict-fitted").is_dir() and (work / "walking" / "velocity-commands" / "commands.parquet").is_file()
    assert (work / "results.md").is_file() and (work / "robot-baseline.json").is_file()
    check_small_demo(cli, work / "demo")  # the last example, `demo --size small`: the README's main job
    # the metric regression's synthetic studies are this demo's steps (tests/regression.py: demo_steps(out, "small")):
    # .ci/run checks their baselines here rather than running the small demo a second time
    for study in ("walking", "pairs"):
        code, out, err = cli("metrics", "check", ROOT / "tests" / "baselines" / f"synthetic-{study}.json", work / "demo" / study,
                             "--failures-only")
        assert code == 0, out + err


def check_small_demo(cli, out: Path) -> None:
    """What `cobot-analysis demo --out OUT --size small` (run by the examples above: one run of the small demo
    in the suite) must have made: every study end to end, the report, and nothing redone by a second run."""
    import pandas as pd

    from cobot_analysis.schema import TRAJECTORIES, read_table

    report = (out / "report.md").read_text()
    for section in ("Preprocessing", "Statistics", "Localisation accuracy"):
        assert section in report
    walking = read_table(out / "walking" / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    assert walking.groupby(["trial", "entity"]).ngroups == 16  # 2 subjects x 8 conditions x 1 trial
    pairs = read_table(out / "pairs" / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    # 2 pairs x 3 goals x 3 scenarios recordings -> forward + return trials, 3 entities each
    assert pairs.groupby(["trial", "entity"]).ngroups == 2 * 3 * 3 * 2 * 3
    assert (out / "reports" / "walking" / "README.md").is_file() and (out / "reports" / "pairs" / "README.md").is_file()
    runs = pd.read_parquet(out / "localisation" / "localisation" / "localisation.parquet")
    assert len(runs) == 3  # ROS1, ROS2 and MCAP versions of the same run
    # a second run finds every stage up to date and changes nothing
    before = (out / "walking" / "preprocess" / "manifest.json").read_text()
    assert cli("-q", "demo", "--out", out, "--size", "small", "--jobs", "1")[0] == 0
    assert (out / "walking" / "preprocess" / "manifest.json").read_text() == before


@pytest.mark.datasets
def test_import_published_examples_run_as_written(cli, help_examples, datasets, tmp_path, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "datasets").symlink_to(datasets)
    monkeypatch.chdir(work)
    run_examples(cli, help_examples, "import-published")
    assert (work / "walking-2020" / "import-published" / "trajectories.parquet").is_file()
    assert (work / "pair-carriage-2022" / "import-published" / "trajectories.parquet").is_file()
