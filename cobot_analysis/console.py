"""Terminal output of the pipeline: one rich console on stderr, a verbosity level, progress bars.

Stages print through ``info``/``debug``/``warn`` and wrap every loop over trials in ``track`` so
that ``--quiet`` silences everything but errors and ``-v`` adds details.
"""

from __future__ import annotations

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
_level = 1  # 0 quiet, 1 normal, 2 verbose


def set_verbosity(level: int) -> None:
    global _level
    _level = level


def verbosity() -> int:
    return _level


def info(message: str) -> None:
    if _level >= 1:
        console.print(message, soft_wrap=True)  # a message is one line, whatever the terminal's width


def debug(message: str) -> None:
    if _level >= 2:
        console.print(f"[dim]{message}[/dim]")


def warn(message: str) -> None:
    """Warnings are shown unless --quiet; they never stop a stage."""
    if _level >= 1:
        console.print(f"[yellow]warning:[/yellow] {message}", soft_wrap=True)  # one line, like errors


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
