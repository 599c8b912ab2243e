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


#: seconds between two progress lines when stderr is not a terminal (a log file, CI, a pipe).
PLAIN_EVERY = 5.0


class PlainProgress(Progress):
    """A rich ``Progress`` that, when the console is not a terminal (where rich would print the bars
    only at the end), prints one plain line per task when it starts, at most every ``PLAIN_EVERY``
    seconds while it advances, and when it completes: "IOC all: 12/50 (24 %), 0:01:10, about 0:03:40 left; D = 0.41"."""

    def __init__(self, *columns, plain: bool = False, **kwargs):
        super().__init__(*columns, **kwargs)
        self._plain = plain
        self._last: dict = {}

    def add_task(self, description: str, *args, **kwargs):
        task = super().add_task(description, *args, **kwargs)
        if self._plain:
            self._say(task, force=True)
        return task

    def update(self, task_id, **kwargs) -> None:
        super().update(task_id, **kwargs)
        if self._plain:
            self._say(task_id)

    def advance(self, task_id, advance: float = 1) -> None:
        super().advance(task_id, advance)
        if self._plain:
            self._say(task_id)

    def _say(self, task_id, force: bool = False) -> None:
        import time
        from datetime import timedelta

        task = self._tasks[task_id]
        now = time.monotonic()
        done = task.total is not None and task.completed >= task.total
        if not force and not done and now - self._last.get(task_id, -1e9) < PLAIN_EVERY:
            return
        if done and self._last.get(task_id) == "done":
            return
        self._last[task_id] = "done" if done else now
        total = f"/{task.total:g} ({100 * task.completed / task.total:.0f} %)" if task.total else ""
        elapsed = timedelta(seconds=round(task.elapsed or 0))
        left = task.time_remaining
        eta = f", about {timedelta(seconds=round(left))} left" if left is not None and not done and task.completed else ""
        status = task.fields.get("status") or ""
        console.print(f"{task.description}: {task.completed:g}{total}, {elapsed}{eta}" + (f"; {status}" if status else ""),
                      soft_wrap=True, markup=False)


def progress() -> Progress:
    """A rich progress display (disabled under --quiet); use ``with progress() as p: p.add_task(...)``.
    When stderr is not a terminal, plain lines instead (``PlainProgress``)."""
    plain = _level >= 1 and not console.is_terminal
    return PlainProgress(
        TextColumn("[progress.description]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        TextColumn("{task.fields[status]}"),
        console=console,
        disable=_level < 1 or plain,
        transient=False,
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
