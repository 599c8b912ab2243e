"""The ``cobot-analysis`` typer application and the options every stage shares.

Command modules in this package register their commands on ``app`` (or on a sub-app such as
``synth_app``); they import heavy libraries inside the command body so that ``--help`` is fast.
"""

from __future__ import annotations

import copy
import re
from collections.abc import MutableMapping
from pathlib import Path
from typing import Annotated, Optional

import typer
from typer.core import TyperGroup

from cobot_analysis.console import set_verbosity, the_console, verbosity, warn
from cobot_analysis.workspace import DEFAULT_OUT

#: Options of the whole program, accepted anywhere on the command line (moved before the command).
GLOBAL_OPTIONS = ("-v", "--verbose", "-q", "--quiet", "--version")

#: Old spellings kept as deprecated aliases, per command: {old: new}, for option names ("--label")
#: and for values of the command's arguments ("walking", a study of `report`). They are rewritten
#: before parsing (so --help never shows them) and each use prints one warning naming the new spelling.
DEPRECATED = {
    ("compare",): {"--label": "--comparison"},
    ("fit-ioc",): {"-w": "--start-weights"},
    ("predict",): {"--study": "--only-study", "--nominal-speed": "--v-nominal"},
    ("localisation",): {"--map": "--map-name", "--goals": "--goals-csv"},
    ("synth", "walking"): {"--trials": "--repetitions"},
    ("report",): {"walking": "walking-2020", "pairs": "pair-carriage-2022"},
}
_NOTES = "cobot_analysis.deprecated"


def _deprecated(token: str, aliases: dict[str, str]) -> tuple[str, str] | None:
    """(old, new token) when ``token`` is a deprecated spelling: ``--old``, ``--old=V``, ``-oV``, ``value``."""
    name = token.partition("=")[0] if token.startswith("--") else token
    if name in aliases:
        return name, aliases[name] + token[len(name):]
    if token.startswith("-") and not token.startswith("--") and token[:2] in aliases:  # a short option with its value attached
        return token[:2], f"{aliases[token[:2]]}={token[2:]}"
    return None


def normalise_args(group, args: list[str]) -> tuple[list[str], list[str]]:
    """The command line as click parses it: global options moved before the command, deprecated
    spellings replaced by the new ones (``DEPRECATED``), ``--start X,Y,THETA`` split into its values
    (any option of several values); returns (args, one deprecation warning per old spelling used)."""
    args, i, path, head = list(args), 0, [], []
    command = group
    while i < len(args) and hasattr(command, "commands"):  # group levels: their options, the command names
        token = args[i]
        i += 1
        if not token.startswith("-"):
            if token not in command.commands:
                return args, []  # an unknown command: click says so
            path.append(token)
            command = command.commands[token]
        head.append(token)
    if hasattr(command, "commands"):
        return args, []
    options = {name: p for p in command.params if p.param_type_name == "option" for name in (*p.opts, *p.secondary_opts)}
    aliases = {old: new for old, new in DEPRECATED.get(tuple(path), {}).items() if old not in options}
    hoisted, tail, notes = [], [], []
    while i < len(args):
        token = args[i]
        i += 1
        if token == "--":
            tail += args[i - 1:]
            break
        if token in GLOBAL_OPTIONS and token not in options:
            hoisted.append(token)
            continue
        alias = _deprecated(token, aliases)
        if alias is not None:
            old, token = alias
            note = f"{old} is deprecated in `{' '.join(path)}`: use {aliases[old]}"
            notes += [note] if note not in notes else []
        tail.append(token)
        option = options.get(token)  # an option whose values follow (not --name=value)
        if option is None or option.is_flag or option.count:
            continue
        if option.nargs > 1 and i < len(args) and len(args[i].split(",")) == option.nargs:
            tail += args[i].split(",")
            i += 1
        else:
            tail += args[i:i + option.nargs]
            i += option.nargs
    return [*hoisted, *head, *tail], notes


#: a hyphen inside a word ("import-published", "walking-2021"): no place to break a help line.
_WORD_HYPHEN = re.compile(r"(?<=\w)-(?=\w)")
_NO_BREAK = "\u2011"  # stands for such a hyphen while click wraps the text


class HelpFormatter(typer.Context.formatter_class):
    """click's help formatter (wraps at the terminal width, keeps ``\\b`` blocks), except that it never
    breaks a line at a hyphen: paths (OUT/import-published/...) and defaults (walking-2021) stay whole."""

    def _whole_words(self, write, *args) -> None:
        start = len(self.buffer)
        write(*args)
        self.buffer[start:] = [s.replace(_NO_BREAK, "-") for s in self.buffer[start:]]

    def write_text(self, text: str) -> None:
        self._whole_words(super().write_text, _WORD_HYPHEN.sub(_NO_BREAK, text))

    def write_dl(self, rows, col_max: int = 30, col_spacing: int = 2) -> None:
        rows = [(a, _WORD_HYPHEN.sub(_NO_BREAK, b)) for a, b in rows]
        self._whole_words(super().write_dl, rows, col_max, col_spacing)


class HelpContext(typer.Context):
    formatter_class = HelpFormatter


class PanelGroup(TyperGroup):
    """A group whose help lists its commands under their panel headings (``PANELS`` order), each with
    the first paragraph of its help, wrapped at the terminal width; its commands format their help
    with ``HelpFormatter``."""

    context_class = HelpContext

    def get_command(self, ctx, cmd_name: str):
        cmd = super().get_command(ctx, cmd_name)
        if cmd is not None and not isinstance(cmd, TyperGroup):
            cmd.context_class = HelpContext
        return cmd

    def format_commands(self, ctx, formatter) -> None:
        panels: dict[str, list[tuple[str, str]]] = {}
        for name in self.list_commands(ctx):
            cmd = self.get_command(ctx, name)
            if cmd is None or cmd.hidden:
                continue
            panel = getattr(cmd, "rich_help_panel", None) or "Commands"
            first = " ".join((cmd.short_help or (cmd.help or "").split("\n\n")[0]).split())
            panels.setdefault(panel, []).append((name, first))
        for panel, rows in sorted(panels.items(), key=lambda kv: PANELS.index(kv[0]) if kv[0] in PANELS else len(PANELS)):
            with formatter.section(panel):
                formatter.write_dl(rows)


class CobotGroup(PanelGroup):
    """The top-level group: normalises the command line (``normalise_args``) before parsing it."""

    def parse_args(self, ctx, args):
        args, notes = normalise_args(self, args)
        ctx.meta[_NOTES] = notes
        return super().parse_args(ctx, args)


class Commands(MutableMapping):
    """A group's commands by name, each built (typer: its click parameters) when first looked up."""

    def __init__(self, builders: dict):
        self._builders, self._built = dict(builders), {}

    def __getitem__(self, name: str):
        if name not in self._built:
            self._built[name] = self._builders[name]()
        return self._built[name]

    def __setitem__(self, name: str, command) -> None:
        self._builders[name], self._built[name] = (lambda: command), command

    def __delitem__(self, name: str) -> None:
        del self._builders[name]
        self._built.pop(name, None)

    def __contains__(self, name) -> bool:
        return name in self._builders

    def __iter__(self):
        return iter(self._builders)

    def __len__(self) -> int:
        return len(self._builders)


def click_group(typer_app: typer.Typer):
    """typer's click group of ``typer_app`` (``typer.main.get_command``), its commands built when first looked up:
    a run builds the one command it runs, not the options of all 23 (0.03 s of CPU)."""
    from typer import main

    bare = copy.copy(typer_app)
    bare.registered_commands, bare.registered_groups = [], []
    group = main.get_group(bare)
    options = {"pretty_exceptions_short": typer_app.pretty_exceptions_short, "rich_markup_mode": typer_app.rich_markup_mode}
    builders = {info.name: (lambda info=info: main.get_command_from_info(info, **options))
                for info in typer_app.registered_commands}
    builders.update({info.name: (lambda info=info: main.get_group_from_info(info, suggest_commands=typer_app.suggest_commands, **options))
                     for info in typer_app.registered_groups})
    assert None not in builders, "every command and group of the app is registered with its name"
    group.commands = Commands(builders)
    return group


def finished(stage: str, what: str, where) -> None:
    """The line every stage ends with: ``stage: what -> where`` (one line, silent under --quiet)."""
    if verbosity() >= 1:
        from rich.markup import escape

        the_console().print(f"[green]{escape(stage)}[/green]: {escape(str(what))} -> {escape(str(where))}", soft_wrap=True)


def finished_with_refusals(stage: str, done) -> None:
    """The end of ``import`` and ``preprocess``: their summary line (when the stage ran), then exit 3 when
    some trials were refused (the good ones went on; ``cobot_analysis.refusals``)."""
    from cobot_analysis.console import info
    from cobot_analysis.refusals import exit_code

    if not done.skipped:
        summary = done.result.summary(where=f"listed above and in {done.directory / 'results.md'}")
        info(f"[green]{stage}[/green]: {summary} -> {done.directory}")
    code = exit_code(done.directory)
    if code:
        raise typer.Exit(code)


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``1 figure``, ``2 figures`` (``plural`` where it is not noun + s)."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def examples(*lines: str) -> str:
    """The ``Examples:`` block of a command's help (``tests/test_cli_examples.py`` runs every line)."""
    return "Examples:\n\n\b\n" + "\n".join(f"  {line}" for line in lines)  # \b: click keeps the lines as they are


EXIT_CODES = ("Exit codes: 0 success, 1 internal error, 2 bad usage or bad input, 130 interrupted (Ctrl-C), "
              "143 terminated (SIGTERM). An interrupted stage writes nothing and stops its workers.")
app = typer.Typer(
    name="cobot-analysis",
    cls=CobotGroup,
    help="Reproducible analysis of motion-capture studies of walking and collaborative carriage (CoBot).",
    epilog=EXIT_CODES,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # click's plain help, wrapped at the terminal width: rich's option tables cut option names, defaults
    # and paths short ("--orientation-mark…") at 80 columns (tests/test_cli_help.py)
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"]},
)
synth_app = typer.Typer(help="Generate a deterministic synthetic study (raw C3D, trials, bags) with its ground truth.",
                        cls=PanelGroup, no_args_is_help=True, rich_markup_mode=None)
app.add_typer(synth_app, name="synth", rich_help_panel="Data")

# Panels that group the commands in --help, in pipeline order.
PANEL_DATA = "Data"
PANEL_PROCESS = "Processing"
PANEL_ANALYSIS = "Analysis"
PANEL_MODELS = "Models"
PANEL_LOCALISATION = "Localisation"
PANEL_REPORT = "Reports"
PANELS = [PANEL_DATA, PANEL_PROCESS, PANEL_ANALYSIS, PANEL_MODELS, PANEL_LOCALISATION, PANEL_REPORT]

# ---- options shared by stages --------------------------------------------------------------------
OutOpt = Annotated[Path, typer.Option("--out", "-o", help="Workspace directory: one sub-directory per stage.")]
ForceOpt = Annotated[bool, typer.Option("--force", help="Redo the stage even if inputs and parameters are unchanged.")]
JobsOpt = Annotated[Optional[int], typer.Option("--jobs", "-j", min=1, help="Local worker processes (default: all cores).")]
SchedulerOpt = Annotated[Optional[str], typer.Option("--scheduler", help="Dask scheduler ADDRESS (e.g. tcp://host:8786); default: local process pool.")]
SeedOpt = Annotated[int, typer.Option("--seed", help="Random seed (results are deterministic for a given seed).")]
ConventionOpt = Annotated[Optional[str], typer.Option(
    "--convention", help="published (the authors' discrete conventions, reproduces the papers) or continuous (ours); "
                         "docs/methods.md sec. 11. Outputs of the published convention go to STAGE-published/.")]
DEFAULT_OUT_PATH = DEFAULT_OUT


def _version(value: bool) -> None:
    if value:
        from cobot_analysis import __version__

        typer.echo(f"cobot-analysis {__version__}")
        raise typer.Exit()


@app.callback()
def _global(
    ctx: typer.Context,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="More details (and tracebacks on internal errors).")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Only errors; no progress bars.")] = False,
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True, help="Show the version and exit.")] = False,
) -> None:
    """Stages read and write Parquet in the workspace (--out); each writes a manifest.json.

    -v, -q and --version are accepted anywhere on the command line. Exit codes: see EXIT_CODES (the
    epilog of --help).
    """
    set_verbosity(0 if quiet else 2 if verbose else 1)
    for note in ctx.meta.pop(_NOTES, []):
        warn(note)
