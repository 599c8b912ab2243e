"""Heavy work on a local process pool by default, or on a Dask cluster (``--scheduler ADDRESS``).

Both are driven through the ``concurrent.futures.Executor`` interface (Dask's
``Client.get_executor()``), so the same code runs locally and on a cluster:

    results = map_tasks(solve_one, items, jobs=2, scheduler=None, description="IOC lower level")

``jobs=1`` runs in-process (no pickling), which is also what tests and debuggers want.
Task functions must be importable top-level functions and their arguments picklable.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any, TypeVar

from cobot_analysis.console import progress

T = TypeVar("T")
R = TypeVar("R")


class _InlineExecutor(Executor):
    """Runs each task at submission, in this process."""

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - delivered through the future
            future.set_exception(exc)
        return future


def default_jobs() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


@contextmanager
def executor(jobs: int | None = None, scheduler: str | None = None) -> Iterator[Executor]:
    """An executor: Dask cluster at ``scheduler`` if given, else ``jobs`` local processes."""
    if scheduler:
        from distributed import Client

        with Client(scheduler) as client:
            yield client.get_executor()
        return
    jobs = default_jobs() if jobs is None else jobs
    if jobs <= 1:
        yield _InlineExecutor()
        return
    # BLAS threads would oversubscribe the cores: one per worker process.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        yield pool


def map_tasks(fn: Callable[..., R], items: Sequence[Any], *, jobs: int | None = None, scheduler: str | None = None,
              description: str = "tasks", pool: Executor | None = None,
              status: Callable[[R], str] | None = None) -> list[R]:
    """``[fn(item) for item in items]`` in parallel, in order, with a progress bar.

    ``status(result)`` may return a short text shown beside the bar (e.g. the current objective).
    An exception in any task is re-raised here after the others are cancelled.
    """
    results: list[Any] = [None] * len(items)

    def run(ex: Executor) -> None:
        futures = {ex.submit(fn, item): i for i, item in enumerate(items)}
        with progress() as bar:
            task = bar.add_task(description, total=len(items), status="")
            try:
                for fut in as_completed(futures):
                    results[futures[fut]] = fut.result()
                    bar.update(task, advance=1, status=status(results[futures[fut]]) if status else "")
            except BaseException:
                for f in futures:
                    f.cancel()
                raise

    if pool is not None:
        run(pool)
    else:
        with executor(jobs, scheduler) as ex:
            run(ex)
    return results


def chunked(items: Sequence[T], size: int) -> Iterable[Sequence[T]]:
    """Consecutive slices of ``size`` items (to amortise per-task overhead on many small tasks)."""
    for start in range(0, len(items), size):
        yield items[start:start + size]
