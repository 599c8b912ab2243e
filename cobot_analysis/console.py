"""Messages and progress of the pipeline.

Library code reports through ``info`` / ``debug`` / ``warn``, which log to the ``cobot_analysis``
logger (``logging``): what is shown, and where, is the caller's choice. The command line installs
``ConsoleHandler`` with ``set_verbosity`` (one rich console on stderr: ``--quiet`` shows errors only,
``-v`` adds details); a notebook or script configures ``logging`` as it likes (without any
configuration, Python shows the warnings on stderr). Loops over trials are wrapped in ``track`` (a
progress bar, silent under ``--quiet``).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Iterator
from typing import TypeVar

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

T = TypeVar("T")

console = Console(stderr=True, highlight=False)
logger = logging.getLogger("cobot_analysis")
_level = 1  # 0 quiet, 1 normal, 2 verbose (progress bars are shown from 1)
_LOGGING_LEVEL = {0: logging.ERROR, 1: logging.INFO, 2: logging.DEBUG}


class ConsoleHandler(logging.Handler):
    """The command line's output of the log records: one line each on the rich console (markup allowed),
    warnings prefixed ``warning:``, details dimmed."""

    def emit(self, record: logging.LogRecord) -> None:
        message = record.getMessage()
        if record.levelno >= logging.WARNING:
            console.print(f"[yellow]warning:[/yellow] {message}", soft_wrap=True)  # one line, like errors
        elif record.levelno >= logging.INFO:
            console.print(message, soft_wrap=True)  # a message is one line, whatever the terminal's width
        else:
            console.print(f"[dim]{message}[/dim]")


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


def info(message: str) -> None:
    """What a stage did (shown by the command line unless --quiet)."""
    logger.info(message)


def debug(message: str) -> None:
    """Details (shown with -v)."""
    logger.debug(message)


def warn(message: str) -> None:
    """Something to read with care; it never stops a stage (shown unless --quiet)."""
    logger.warning(message)


def progress() -> Progress:
    """A rich progress display (disabled under --quiet); use ``with progress() as p: p.add_task(...)``."""
    return Progress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        TextColumn("{task.fields[status]}"),
        console=console,
        disable=_level < 1,
        transient=False,
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
