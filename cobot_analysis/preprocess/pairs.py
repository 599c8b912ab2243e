"""A pair recording against the pair protocol (docs/methods.md sec. 1.2 and 2.7).

The carriages the table height gives (``segmentation.carriages``) are labelled forward and return by
their order. The protocol says more about them, and a recording that contradicts it is refused, with
what was found, rather than labelled wrong:

- ``check_count``: as many carriages as the trial's labels; the refusal lists them and the set-downs
  between them, and names the ``--min-set-down`` that joins a re-grip (the table set down briefly
  during a carriage);
- ``check_return``: the return carries the table back to the start, so it ends nearer the forward
  carriage's start than its end (the two lifts of a forward carriage set down to re-grip it would
  otherwise be a forward and a "return" to the goal).
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from cobot_analysis.errors import InputError


def _spans(found: Sequence[tuple[int, int]], rate: float) -> str:
    return ", ".join(f"{a / rate:.1f}-{b / rate:.1f} s" for a, b in found)


def _joining(samples: int, rate: float) -> float:
    """The ``--min-set-down`` (s, one decimal) that joins two lifts set down ``samples`` apart."""
    return math.floor(samples / rate * 10 + 1) / 10


def check_count(trial: str, source: str, found: list[tuple[int, int]], labels: list[str], h0: float, rate: float,
                threshold: float, min_duration: float) -> None:
    """Refuse a recording with another number of carriages than ``labels``, naming them and the set-downs."""
    if len(found) == len(labels):
        return
    what = f" ({_spans(found, rate)}" if found else ""
    downs = [(b[0] - a[1]) / rate for a, b in zip(found, found[1:])]
    if downs:
        what += f"; set down {', '.join(f'{d:.2f} s' for d in downs)} between them"
    what += ")" if found else ""
    remedy = "check the table markers, or adjust --lift-threshold / --floor-window / --min-duration"
    extra = len(found) - len(labels)
    if extra > 0:  # the shortest set-downs would join: a re-grip if shorter than the others
        short = sorted(downs)
        join = _joining(short[extra - 1] * rate, rate)
        if extra == len(short) or join < short[extra]:
            remedy = (f"if the table was set down briefly during a carriage (a re-grip), join the lifts with "
                      f"--min-set-down {join:g}; else {remedy}")
    raise InputError(f"trial {trial}: found {len(found)} table carriages{what}, height above the floor level "
                     f"{h0:.3f} m + {threshold * 1000:g} mm for {min_duration:g} s; expected {len(labels)} "
                     f"({', '.join(labels)})", path=source, remedy=remedy)


def check_return(trial: str, source: str, found: list[tuple[int, int]], table_xy: np.ndarray, rate: float) -> None:
    """Refuse a forward + return recording whose second carriage does not carry the table back to the start."""
    (f0, f1), (r0, r1) = found
    start, goal, end = table_xy[f0], table_xy[f1], table_xy[r1]
    to_start, to_goal = float(np.hypot(*(end - start))), float(np.hypot(*(end - goal)))
    if not to_start >= to_goal:  # nearer the start, or a position unknown (NaN): nothing to tell
        return
    join = _joining(r0 - f1, rate)
    raise InputError(f"trial {trial}: the second table carriage ({_spans([(r0, r1)], rate)}) ends {to_start:.2f} m "
                     f"from where the first ({_spans([(f0, f1)], rate)}) started and {to_goal:.2f} m from where it "
                     "ended: it does not carry the table back to the start, so it is no return (the table set down "
                     "to re-grip it during the forward carriage, the return not recorded?)", path=source,
                     remedy=f"if the file holds the forward carriage only, give it direction 'forward' in the trials "
                            f"table and join its lifts with --min-set-down {join:g}; else leave it out")
