"""Python's cyclic garbage collector around code that makes many objects that outlive it.

The collector runs a full collection whenever the objects that survived young collections grow by a quarter
since the last one, and each full collection visits every tracked object of the process. A block that builds
a list of a few hundred thousand small objects (a robot run's ROS messages, before they are written) makes it
run several times, each over all of them: ``synth localisation`` spent 3.9 of its 9.0 s of CPU in the
collector (docs/benchmarks.md, "The test suite and CI").

- ``paused()``: no automatic collection inside the block. For blocks that make objects without reference
  cycles (freed by their reference counts as usual: the pause only skips the searches for cycles).
- ``frozen()``: the objects that exist before the block are left out of every collection inside it
  (``gc.freeze``), so that a library that collects explicitly pays only for what the block made.

Both put the collector back as they found it, also when the block raises; nested, the outer one does.

    >>> import gc
    >>> with paused():
    ...     rows = [(i, {"x": float(i)}) for i in range(1000)]
    ...     gc.isenabled()
    False
    >>> gc.isenabled(), gc.get_freeze_count() == 0
    (True, True)
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def paused() -> Iterator[None]:
    """No automatic collection inside the block (module docstring); re-enabled after it if it was enabled."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


@contextmanager
def frozen() -> Iterator[None]:
    """The objects that exist before the block out of the collections inside it (``gc.freeze``), handed back after
    it. Where the caller has frozen objects already, nothing is done: ``gc.unfreeze`` would hand back theirs too."""
    outer = gc.get_freeze_count() > 0
    if not outer:
        gc.freeze()
    try:
        yield
    finally:
        if not outer:
            gc.unfreeze()
