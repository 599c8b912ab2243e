"""Messages and progress of the pipeline.

Library code reports through ``info`` / ``debug`` / ``warn``, which log to the ``cobot_analysis``
logger (``logging``): what is shown, and where, is the caller's choice. The command line installs
``ConsoleHandler`` with ``set_verbosity`` (one rich console on stderr: ``--quiet`` shows errors only,
``-v`` adds details); a notebook or script configures ``logging`` as it likes (without any
configuration, Python shows the warnings on stderr). Loops over trials are wrapped in ``track`` (a
progress bar, silent under ``--quiet``).
"""

from __future__ import annotations

import functools
import logging
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

T = TypeVar("T")

logger = logging.getLogger("cobot_analysis")
_level = 1  # 0 quiet, 1 normal, 2 verbose (progress bars are shown from 1)
_LOGGING_LEVEL = {0: logging.ERROR, 1: logging.INFO, 2: logging.DEBUG}


def the_console():
    """The command line's rich console on stderr (also ``console``), made when first used: importing rich costs
    0.02 s, and a run under --quiet that succeeds prints nothing."""
    if "console" not in globals():
        from rich.console import Console

        globals()["console"] = Console(stderr=True, highlight=False)
    return globals()["console"]


def __getattr__(name: str) -> Any:
    if name == "console":
        return the_console()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class ConsoleHandler(logging.Handler):
    """The command line's output of the log records: one line each on the rich console (markup allowed),
    warnings prefixed ``warning:``, details dimmed."""

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        if record.levelno >= logging.WARNING:
            the_console().print(f"[yellow]warning:[/yellow] {message}", soft_wrap=True)  # one line, like errors
        elif record.levelno >= logging.INFO:
            the_console().print(message, soft_wrap=True)  # a message is one line, whatever the terminal's width
        else:
            the_console().print(f"[dim]{message}[/dim]")


def set_verbosity(level: int) -> None:
    """Show the pipeline's messages on the console at ``level`` (0 quiet, 1 normal, 2 verbose): the command
    line's ``-q`` / ``-v``."""
    global _level
    _level = level
    logger.setLevel(_LOGGING_LEVEL[level])
    if not any(isinstance(h, ConsoleHandler) for h in logger.handlers):
        logger.addHandler(ConsoleHandler())
    logger.propagate = False


def verbosity() -> int:
    return _level


@contextmanager
def verbosity_restored() -> Iterator[None]:
    """Put the ``cobot_analysis`` logger and the verbosity back as they were on leaving: a command run
    in-process (``cli.run``, a test, a notebook) leaves its ``-q`` / ``-v`` and console handler behind it
    no more than a run in its own process does."""
    global _level
    saved = _level, logger.level, list(logger.handlers), logger.propagate
    try:
        yield
    finally:
        _level, level, handlers, logger.propagate = saved
        logger.setLevel(level)
        logger.handlers[:] = handlers


def info(message: str) -> None:
    """What a stage did (shown by the command line unless --quiet)."""
    logger.info(message)


def debug(message: str) -> None:
    """Details (shown with -v)."""
    logger.debug(message)


def warn(message: str) -> None:
    """Something to read with care; it never stops a stage (shown unless --quiet)."""
    logger.warning(message)


#: seconds between two progress lines when stderr is not a terminal (a log file, CI, a pipe); work quicker than it
#: prints none.
PLAIN_EVERY = 5.0


class QuietProgress:
    """``progress()`` under --quiet: shows nothing, as a disabled rich ``Progress`` does, without importing rich."""

    def __init__(self):
        self._tasks = 0

    def __enter__(self) -> "QuietProgress":
        return self

    def __exit__(self, *exc) -> None:
        return None

    def start(self) -> None:
        pass

    def stop(self) -> None:
        pass

    def add_task(self, description: str, *args, **kwargs) -> int:
        self._tasks += 1
        return self._tasks - 1

    def update(self, task_id, **kwargs) -> None:
        pass

    def advance(self, task_id, advance: float = 1) -> None:
        pass


@functools.cache
def _plain_progress():
    """``PlainProgress``: a rich ``Progress`` that, when the console is not a terminal (where rich would print the
    bars only at the end), prints plain lines for a task that has run ``PLAIN_EVERY`` seconds: at most one every
    ``PLAIN_EVERY`` seconds while it advances, and one when it completes: "predict: 12/50 (24 %), 0:01:10, about
    0:03:40 left". A task added with ``budget=True`` counts up to a most, not to its end (a search stops when it
    converges): "IOC all: 12 of at most 2000, 0:01:10; D = 0.41", no time left foreseen. Quicker work says nothing: a
    stage that then fails prints its error line alone, one that succeeds its summary line. Defined at first use,
    with rich."""
    from rich.progress import Progress

    class PlainProgress(Progress):
        def __init__(self, *columns, plain: bool = False, **kwargs):
            super().__init__(*columns, **kwargs)
            self._plain = plain
            self._last: dict = {}

        def add_task(self, description: str, *args, **kwargs):
            task = super().add_task(description, *args, **kwargs)
            if self._plain:
                self._say(task)
            return task

        def update(self, task_id, **kwargs) -> None:
            super().update(task_id, **kwargs)
            if self._plain:
                self._say(task_id)

        def advance(self, task_id, advance: float = 1) -> None:
            super().advance(task_id, advance)
            if self._plain:
                self._say(task_id)

        def _say(self, task_id) -> None:
            import time
            from datetime import timedelta

            task = self._tasks[task_id]
            now = time.monotonic()
            done = task.total is not None and task.completed >= task.total
            if (task.elapsed or 0.0) < PLAIN_EVERY:
                return
            if not done and now - self._last.get(task_id, -1e9) < PLAIN_EVERY:
                return
            if done and self._last.get(task_id) == "done":
                return
            self._last[task_id] = "done" if done else now
            budget = task.fields.get("budget") and not done  # the total is a most (a search's budget): no end to foresee
            total = (f" of at most {task.total:g}" if budget else
                     f"/{task.total:g} ({100 * task.completed / task.total:.0f} %)" if task.total else "")
            elapsed = timedelta(seconds=round(task.elapsed or 0))
            left = None if budget else task.time_remaining
            eta = f", about {timedelta(seconds=round(left))} left" if left is not None and not done and task.completed else ""
            status = task.fields.get("status") or ""
            the_console().print(f"{task.description}: {task.completed:g}{total}, {elapsed}{eta}" + (f"; {status}" if status else ""),
                                soft_wrap=True, markup=False)

    return PlainProgress


def progress():
    """A rich progress display (nothing under --quiet: ``QuietProgress``); use ``with progress() as p:
    p.add_task(...)``. When stderr is not a terminal, plain lines instead (``PlainProgress``)."""
    if _level < 1:
        return QuietProgress()
    from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn
    from rich.text import Text

    class Remaining(TimeRemainingColumn):
        """The time left, none for a task whose total is a budget (``budget=True``)."""

        def render(self, task):
            return Text("") if task.fields.get("budget") else super().render(task)

    console = the_console()
    plain = not console.is_terminal
    return _plain_progress()(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        Remaining(),
        TextColumn("{task.fields[status]}"),
        console=console,
        disable=plain,
        transient=True,  # the bars go when their work ends: the stage's summary line or its error line stays alone
        plain=plain,
    )


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a progress bar: ``for trial in track(trials, "import"): ...``."""
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with progress() as bar:
        task = bar.add_task(description, total=total, status="")
        for item in items:
            yield item
            bar.advance(task)
