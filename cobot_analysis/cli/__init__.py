"""Command-line entry point: ``cobot-analysis`` (see ``cobot_analysis.cli.app``).

``run(argv)`` returns the exit code (0 ok, 1 internal error, 2 bad usage or bad input, 128 + the
signal number when interrupted: 130 Ctrl-C, 143 SIGTERM) and is what tests call (the caller's garbage
collector left on); ``main()`` exits with it.
"""

from __future__ import annotations

import atexit
import gc
import importlib
import os
import pkgutil
import sys
import threading
import traceback

import typer
from typer.exceptions import TyperException

from cobot_analysis.cli.app import app, click_group
from cobot_analysis.console import the_console, verbosity, verbosity_restored
from cobot_analysis.errors import InputError, SolverError
from cobot_analysis.interrupt import Interrupted, outcome, seen, signals

# Every module of this package registers its commands on import; pipeline order first, so that
# --help lists the panels as the data flows (data, processing, analysis, models, localisation).
_ORDER = ["synth", "importing", "published", "preprocess", "analysis", "models", "predict", "localisation", "metrics"]
for _name in sorted((m.name for m in pkgutil.iter_modules(__path__) if m.name != "app"),
                    key=lambda n: (_ORDER.index(n) if n in _ORDER else len(_ORDER), n)):
    importlib.import_module(f"{__name__}.{_name}")


def _error(message: str) -> None:
    the_console().print(f"[bold red]error:[/bold red] {message}", soft_wrap=True, markup=True, highlight=False)


def run(argv: list[str] | None = None) -> int:
    collecting = gc.isenabled()
    try:
        return _command(argv)
    finally:  # a command may pause the garbage collector for the rest of its process (``localisation``)
        if collecting:
            gc.enable()


def _command(argv: list[str] | None) -> int:
    from cobot_analysis import workspace

    workspace.COMMAND[:] = ["cobot-analysis", *(sys.argv[1:] if argv is None else argv)]
    try:
        with signals(), verbosity_restored():
            return _run(argv)
    finally:
        workspace.COMMAND.clear()


def _run(argv: list[str] | None) -> int:
    try:
        rv = click_group(app)(args=argv, prog_name="cobot-analysis", standalone_mode=False)
        return rv if isinstance(rv, int) else 0
    except Interrupted as exc:  # stages have removed their temporary output and stopped their workers
        seen(exc)
        _error(f"interrupted ({exc}); {outcome()}".replace("[", r"\["))
        return exc.exit_code
    except (InputError, SolverError) as exc:
        _error(str(exc).replace("[", r"\["))
        return 2
    except typer.Exit as exc:
        return exc.exit_code
    except TyperException as exc:  # usage errors (typer's click): it prints them itself
        exc.show()
        return 2
    except typer.Abort:
        _error("aborted")
        return 130
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except Exception as exc:  # noqa: BLE001 - the last line of defence of the CLI
        if verbosity() >= 2:
            traceback.print_exc()
        _error(f"internal error: {type(exc).__name__}: {exc} (re-run with -v for the traceback and report it)".replace("[", r"\["))
        return 1


def main() -> None:
    # Arrow's buffers from the C allocator, not Arrow's mimalloc pool, which keeps what it frees (peak memory
    # of a 10-minute localisation run 188 -> 178 MiB, measured). Process-wide, so the command
    # line's choice and not the library's; set before pyarrow is first imported, inherited by the workers.
    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    code = _command(None)  # the process ends after it: a garbage collector the command paused stays paused
    if code >= 128:  # interrupted: exit now, without waiting for what the interrupt abandoned
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    if threading.active_count() == 1 and sys.gettrace() is None and sys.getprofile() is None:
        # Done and alone (no other thread, no tracer or profiler waiting to write its results): run the exit
        # handlers, flush, and end without the interpreter's teardown (freeing every module and object one by
        # one: 0.1 s after pandas and pyarrow, a tenth of a localisation run).
        atexit._run_exitfuncs()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):  # a closed pipe: Python's own exit then returns 120 too
                code = code or 120
        os._exit(code)
    sys.exit(code)
