"""Interrupts: Ctrl-C (SIGINT) and SIGTERM end a command promptly and cleanly.

- ``signals()``: while a command runs (``cli.run``), both signals raise ``Interrupted`` in the main
  thread; the command line prints one line and exits with ``128 + signal number`` (130, 143).
  Python runs signal handlers between bytecodes of the main thread, and an exception raised there
  is lost when that happens inside a finaliser, an at-fork hook or a C library that checks for
  signals itself (casadi): until a frame of ours has seen the ``Interrupted`` (``seen``), it is
  raised again every ``RETRY`` seconds.
- ``deferred()``: a section an interrupt must not cut (removing a temporary directory, committing a
  stage's outputs): a signal received inside is raised at its end.
- ``interruptible(fn, *args)``: runs ``fn`` in a helper thread while the main thread waits, so that
  an interrupt ends the wait at once even when ``fn`` is a long call into C that does not return to
  Python (an OC solve: casadi releases the GIL, never checks signals in fatrop and turns a SIGINT
  seen in IPOPT into a failed solve). The abandoned call ends with the process.
- ``blocked()``: SIGINT and SIGTERM held back (e.g. while pool processes are forked).
- ``keep(what)``: record an output this command completed (a committed stage, a resumable partial
  result); the interrupt message lists them, or says that nothing was written.
- ``worker_init``: initializer of pool processes: SIGINT ignored (the parent stops its workers),
  SIGTERM default, and on Linux killed with their parent (``PR_SET_PDEATHSIG``), even a SIGKILLed one.
"""

from __future__ import annotations

import _thread
import os
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

R = TypeVar("R")
SIGNALS = (signal.SIGINT, signal.SIGTERM)
RETRY = 0.5  # s: an interrupt no frame of ours has seen yet is raised again after this
_state: dict[str, Any] = {"active": None, "depth": 0, "pending": None, "received": None, "seen": False, "kept": []}


class Interrupted(BaseException):
    """A command was interrupted by ``signum`` (not an ``Exception``: nothing catches it by accident)."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        self.exit_code = 128 + self.signum
        super().__init__(signal.Signals(self.signum).name)


def _handler(signum: int, frame) -> None:
    if _state["received"] is None:
        _state["received"] = signum
        threading.Thread(target=_watchdog, args=(_state["active"],), name="interrupt-watchdog", daemon=True).start()
    if _state["depth"]:
        _state["pending"] = signum
        return
    raise Interrupted(signum)


def _watchdog(token: object) -> None:
    """Raise the interrupt again in the main thread until it is seen (see module doc)."""
    stop = threading.Event()
    while not stop.wait(RETRY):
        if _state["active"] is not token or _state["seen"]:
            return
        _thread.interrupt_main(_state["received"])


def seen(exc: BaseException | None) -> None:
    """Called by the frames that clean up (stages, executors, the command line) with their exception."""
    if isinstance(exc, Interrupted):
        _state["seen"] = True


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def signals() -> Iterator[None]:
    """SIGINT and SIGTERM raise ``Interrupted`` inside the block (main thread only; else a no-op)."""
    if not _main_thread() or _state["active"] is not None:
        yield
        return
    previous = {s: signal.getsignal(s) for s in SIGNALS}
    _state.update(active=object(), depth=0, pending=None, received=None, seen=False, kept=[])
    for s in SIGNALS:
        signal.signal(s, _handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
        _state.update(active=None, depth=0, pending=None, received=None, seen=False, kept=[])


@contextmanager
def deferred() -> Iterator[None]:
    """A section that runs to its end; an interrupt received meanwhile is raised after it."""
    _state["depth"] += 1
    try:
        yield
    finally:
        _state["depth"] -= 1
        pending = _state["pending"]
        if pending is not None and not _state["depth"]:
            _state["pending"] = None
            raise Interrupted(pending)


@contextmanager
def blocked() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the end of the block (delivered then); threads and processes
    started inside inherit the mask (``worker_init`` lifts it)."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def keep(what: str | os.PathLike) -> None:
    """Record a complete output of this command (listed if it is interrupted later)."""
    if _state["active"] is not None:
        _state["kept"].append(str(what))


def outcome() -> str:
    """What an interrupted command leaves: ``nothing written`` or ``kept: ...``."""
    return "kept: " + ", ".join(_state["kept"]) if _state["kept"] else "nothing written"


def interruptible(fn: Callable[..., R], /, *args: Any, **kwargs: Any) -> R:
    """``fn(*args, **kwargs)``, interruptible within a fraction of a second (see module doc).

    A direct call when interrupts are not handled here (outside ``signals()``, or not in the main
    thread: in a pool worker the parent stops the process)."""
    if _state["active"] is None or not _main_thread() or _state["depth"]:
        return fn(*args, **kwargs)
    box: dict[str, Any] = {}

    def target() -> None:
        try:
            box["result"] = fn(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller's thread
            box["error"] = exc

    helper = threading.Thread(target=target, name=f"interruptible:{getattr(fn, '__name__', 'call')}", daemon=True)
    helper.start()
    while helper.is_alive():
        helper.join(0.1)  # a lock wait: a signal runs the handler in this thread at once
    if "error" in box:
        raise box.pop("error")
    return box["result"]


def worker_init() -> None:
    """Pool process set-up (see module doc)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
        if os.getppid() == 1:  # the parent died before prctl
            os._exit(1)
    except (OSError, AttributeError):  # not Linux: the parent still stops its workers on an interrupt
        pass
