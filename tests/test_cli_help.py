"""`cobot-analysis <command> -h` readable at 80 columns: no line wider than the terminal, nothing cut
short (rich's option tables ended option names, defaults and paths with "…" at this width), every
option name, every help text and every default printed whole, none split across two lines."""

from __future__ import annotations

import re

import pytest
import typer.main

from cobot_analysis.cli.app import app

WIDTH = 80


def commands(group=None, path=()) -> list[tuple[tuple[str, ...], object]]:
    group = group if group is not None else typer.main.get_command(app)
    out = [(path, group)]
    for name, cmd in group.commands.items():
        out += commands(cmd, (*path, name)) if hasattr(cmd, "commands") else [((*path, name), cmd)]
    return out


def flat(text: str) -> str:
    """``text`` with its line breaks and indentation as single spaces (what a reader reads)."""
    return " ".join(text.split())


@pytest.fixture
def help_at_80(cli, monkeypatch):
    monkeypatch.setenv("COLUMNS", str(WIDTH))

    def get(path: tuple[str, ...]) -> str:
        code, out, err = cli(*path, "-h")
        assert code == 0, err
        return out
    return get


@pytest.mark.parametrize("path,cmd", commands(), ids=lambda v: " ".join(v) or "root" if isinstance(v, tuple) else "")
def test_help_is_whole_at_80_columns(help_at_80, path, cmd):
    text = help_at_80(path)
    wide = [line for line in text.splitlines() if len(line) > WIDTH]
    assert not wide, wide
    assert "…" not in text  # nothing cut short
    printed = flat(text)
    ctx = cmd.make_context(" ".join(("cobot-analysis", *path)), [], resilient_parsing=True)
    for param in cmd.get_params(ctx):
        record = param.get_help_record(ctx)
        if record is None:
            continue
        names, help_text = record
        for name in (*param.opts, *param.secondary_opts):  # option names as typed, never split
            assert re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", text), (path, name)
        # the help with its "[default: ...]" whole, words neither cut nor split at a hyphen
        assert flat(help_text) in printed, (path, names, help_text)
    if cmd.help:
        first = cmd.help.split("\n\n")[0]
        assert flat(first) in printed, (path, first)


def test_the_checks_fail_on_rich_tables(cli, monkeypatch):
    """The same command through typer's rich help (what -h printed before): the checks above fire."""
    monkeypatch.setenv("COLUMNS", str(WIDTH))
    from typer import rich_utils

    cmd = typer.main.get_command(app).commands["preprocess"]
    ctx = cmd.make_context("cobot-analysis preprocess", [], resilient_parsing=True)
    import io

    from rich.console import Console

    buffer = io.StringIO()
    monkeypatch.setattr(rich_utils, "_get_rich_console", lambda stderr=False: Console(file=buffer, width=WIDTH))
    rich_utils.rich_format_help(obj=cmd, ctx=ctx, markup_mode="rich")
    assert "…" in buffer.getvalue()
