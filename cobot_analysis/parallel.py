"""Heavy work on a local process pool by default, or on a Dask cluster (``--scheduler ADDRESS``).

Both are driven through the ``concurrent.futures.Executor`` interface (Dask's
``Client.get_executor()``), so the same code runs locally and on a cluster:

    results = map_tasks(solve_one, items, jobs=2, scheduler=None, description="IOC lower level")

``jobs=1`` runs in-process (no pickling), which is also what tests and debuggers want.
Task functions must be importable top-level functions and their arguments picklable.

Interrupts (``cobot_analysis.interrupt``): an in-process task runs through ``interruptible``; on
any exception, Ctrl-C or SIGTERM leaving ``executor()``, the local workers are stopped at once
(SIGTERM, then SIGKILL after ``STOP_GRACE`` s) and a Dask executor cancels its futures. A scheduler address that nothing answers is refused in
``CONNECT_TIMEOUT`` s with one line (``check_scheduler``).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any, TypeVar

from cobot_analysis.console import progress
from cobot_analysis.errors import InputError
from cobot_analysis.interrupt import Interrupted, blocked, deferred, interruptible, seen, worker_init

T = TypeVar("T")
R = TypeVar("R")
STOP_GRACE = 1.0  # s between SIGTERM and SIGKILL of a worker that is still alive
CONNECT_TIMEOUT = 5.0  # s to reach a Dask scheduler (Dask's own default waits 30 s, then an OSError)
DASK_PORT = 8786  # the scheduler's default port


class InlineExecutor(Executor):
    """Runs each task at submission, in this process (interruptible)."""

    def submit(self, fn, /, *args, **kwargs):  # type: ignore[override]
        future: Future = Future()
        try:
            future.set_result(interruptible(fn, *args, **kwargs))
        except Interrupted:
            raise  # not delivered through the future: the remaining tasks are not started
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

        check_scheduler(scheduler)
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT * 2:g}s")
        except OSError as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect to the Dask scheduler ({exc})", remedy=SCHEDULER_REMEDY) from None
        with client:
            ex = client.get_executor()
            try:
                yield ex
            except BaseException as exc:
                seen(exc)
                ex.shutdown(wait=False)  # cancels the futures on the cluster
                raise
        return
    jobs = default_jobs() if jobs is None else jobs
    if jobs <= 1:
        yield InlineExecutor()
        return
    # BLAS threads would oversubscribe the cores: one per worker process.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    pool = ProcessPoolExecutor(max_workers=jobs, initializer=worker_init)
    try:
        with blocked():  # an interrupt during a fork would be lost in an at-fork hook
            pool.submit(os.getpid)  # starts the workers (all of them: fork context)
        yield pool
    except BaseException as exc:
        seen(exc)
        stop(pool)
        raise
    pool.shutdown(wait=True)


SCHEDULER_REMEDY = "start it (`dask scheduler`), check the address, or leave --scheduler out to run on this machine"


def check_scheduler(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Fail fast, with one line, when a TCP scheduler address (``tcp://host:port`` or ``host:port``)
    is malformed or nothing listens there (a closed port took Dask 30 s and ended in an OSError).
    Other protocols (``tls://``, ``inproc://``, ...) are left to Dask."""
    import socket

    scheme, sep, rest = address.rpartition("://")
    if sep and scheme != "tcp":
        return
    host, colon, port = rest.rpartition(":") if ":" in rest else (rest, "", str(DASK_PORT))
    try:
        number = int(port)
        if not 0 < number < 65536 or not host.strip("[]"):
            raise ValueError
    except ValueError:
        raise InputError(f"--scheduler {address!r} is not a scheduler address", remedy="give it as tcp://HOST:PORT") from None
    try:
        socket.create_connection((host.strip("[]"), number), timeout=timeout).close()
    except OSError as exc:
        reason = exc.strerror or ("timed out" if isinstance(exc, TimeoutError) else type(exc).__name__)
        raise InputError(f"--scheduler {address}: no Dask scheduler answers at {host}:{number} ({reason})",
                         remedy=SCHEDULER_REMEDY) from None


def stop(pool: ProcessPoolExecutor) -> None:
    """Stop a local pool now: pending tasks cancelled, workers terminated (killed if they linger)."""
    with deferred():
        workers = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for w in workers:
            w.terminate()
        for w in workers:
            w.join(STOP_GRACE)
            if w.is_alive():
                w.kill()
                w.join(STOP_GRACE)
        results = getattr(pool, "_result_queue", None)
        if results is not None:  # a worker killed while sending left half a message: EOF ends the wait for the rest
            results._writer.close()


def map_tasks(fn: Callable[..., R], items: Sequence[Any], *, jobs: int | None = None, scheduler: str | None = None,
              description: str = "tasks", pool: Executor | None = None,
              status: Callable[[R], str] | None = None) -> list[R]:
    """``[fn(item) for item in items]`` in parallel, in order, with a progress bar.

    ``status(result)`` may return a short text shown beside the bar (e.g. the current objective).
    An exception in any task is re-raised here; the executor then stops the other tasks.
    """
    results: list[Any] = [None] * len(items)

    def run(ex: Executor) -> None:
        futures = {ex.submit(fn, item): i for i, item in enumerate(items)}
        with progress() as bar:
            task = bar.add_task(description, total=len(items), status="")
            for fut in as_completed(futures):
                results[futures[fut]] = fut.result()
                bar.update(task, advance=1, status=status(results[futures[fut]]) if status else "")

    if pool is not None:
        run(pool)
    else:
        with executor(jobs, scheduler) as ex:
            run(ex)
    return results


def imap_tasks(fn: Callable[..., R], items: Sequence[Any], *, jobs: int | None = None, scheduler: str | None = None,
               description: str = "tasks", window: int | None = None, chunk: int = 1) -> Iterator[R]:
    """``fn(item)`` for each item, yielded in order as they finish, with a progress bar: at most ``window``
    tasks (default 16 items' worth per worker, so that one slow task does not leave the other workers idle) are
    submitted ahead of the one awaited, so the results a caller consumes one by one (e.g. writes and
    drops) are never all held at once. ``chunk``: items per task sent to a worker (``run_chunk``: the
    pool's cost per task, about 1 ms of the parent's and the worker's CPU, paid once per chunk; results
    still yielded one by one); in-process (``jobs=1``) each item is its own task. An exception in a task
    is re-raised here; the executor then stops the other tasks."""
    n_jobs = max(jobs or default_jobs(), 1)
    size = chunk if (scheduler or n_jobs > 1) and chunk > 1 else 1
    ahead = window or max(2 * n_jobs, 16 * n_jobs // size)
    with executor(jobs, scheduler) as ex, progress() as bar:
        task = bar.add_task(description, total=len(items), status="")
        pending: list[Future] = []
        it = iter(chunked(items, size))

        def submit(part: Sequence[Any]) -> Future:
            return ex.submit(fn, part[0]) if size == 1 else ex.submit(run_chunk, fn, part)

        for part in it:
            pending.append(submit(part))
            if len(pending) > ahead:
                break
        while pending:
            result = pending.pop(0).result()
            for part in it:
                pending.append(submit(part))
                break
            for r in (result if size > 1 else [result]):
                bar.update(task, advance=1, status="")
                yield r


def run_chunk(fn: Callable[..., R], items: Sequence[Any]) -> list[R]:
    """``[fn(item) for item in items]``: one pool task for several items (``imap_tasks``' ``chunk``)."""
    return [fn(item) for item in items]


def chunked(items: Sequence[T], size: int) -> Iterable[Sequence[T]]:
    """Consecutive slices of ``size`` items (to amortise per-task overhead on many small tasks)."""
    for start in range(0, len(items), size):
        yield items[start:start + size]
