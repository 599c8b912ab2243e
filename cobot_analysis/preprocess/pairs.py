"""A pair recording against the pair protocol (docs/methods.md sec. 1.2 and 2.7).

The carriages the table height gives (``segmentation.carriages``) are labelled forward and return by
their order. The protocol says more about them, and a recording that contradicts it is refused, with
what was found, rather than labelled wrong:

- ``check_labels``: ``direction`` (when given) is ``forward`` or ``return``, ``configuration`` ``gris`` or
  ``jaune`` and ``scenario`` 1, 2 or 3, as written (another label would make a direction or scenario of its
  own: a "Return" not scenario 3; a configuration "Gris" snaps no end orientation, and each return, grouped by
  its measured one, would be a mean of its own);
- ``check_floor``: the floor level is measured while the table rests (the first ``--floor-window``
  seconds): a table that rests later more than ``FLOOR_MARGIN`` lower was lifted when the recording
  started, and its first carriage is cut off (its onset would be a second lift, or none);
- ``check_count``: as many carriages as the trial's labels; the refusal lists them and the set-downs
  between them, and names the ``--min-set-down`` that joins a re-grip (the table set down briefly
  during a carriage);
- ``check_return``: the return carries the table back to the start, so it ends nearer the forward
  carriage's start than its end (the two lifts of a forward carriage set down to re-grip it would
  otherwise be a forward and a "return" to the goal);
- ``end_orientation``: the trials table's ``end_orientation`` is the table's orientation at the
  end of the forward carriage (within ``END_TOLERANCE``) and one of its configuration's two
  (``design.CONFIGURATIONS``); else the trial would be grouped by a configuration it did not end in
  (``compare.snap_configurations``): a quarter or half turn off, or an angle in degrees. A forward carriage without
  one takes its configuration's orientation nearer the measured one, as returns do (refused when the table ended
  more than ``END_TOLERANCE`` from both);
- ``subject1_end`` and ``swapped_subjects``: Subject 1 holds the same end of the table (the TAB1 or the
  TAB2 end of its long axis) in every recording of the study; a recording where it holds the other end
  has the labels S1 and S2 swapped, and its scenario (who knows the goal) would be the other subject's.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Sequence

import numpy as np

from cobot_analysis.angles import angle_diff
from cobot_analysis.design import CONFIGURATIONS
from cobot_analysis.errors import InputError
from cobot_analysis.preprocess.segmentation import runs
from cobot_analysis.refusals import Refused

#: largest difference (rad) between a declared end orientation and the measured one, or its configuration's:
#: half of a quarter turn (a carriage ends within a few degrees of its marks).
END_TOLERANCE = math.pi / 4
#: a rest this much (m) below the floor level measured says the table was lifted in the floor window (more
#: than the lift threshold: floors differ by a few millimetres across a lab).
FLOOR_MARGIN = 0.02
#: least distance (m) between the two subjects along the table's long axis for the end each holds to count.
MIN_APART = 0.5


def _spans(found: Sequence[tuple[int, int]], rate: float) -> str:
    return ", ".join(f"{a / rate:.1f}-{b / rate:.1f} s" for a, b in found)


def _joining(set_down: float) -> float:
    """The ``--min-set-down`` (s, one decimal) that joins two lifts set down ``set_down`` seconds apart."""
    return math.floor(set_down * 10 + 1) / 10


def check_labels(trial: str, source: str, meta: dict) -> None:
    """Refuse a ``direction`` other than forward or return, a ``configuration`` not of ``design.CONFIGURATIONS``, or a
    ``scenario`` other than 1, 2 or 3."""
    direction, scenario, family = meta.get("direction"), meta.get("scenario"), meta.get("configuration")
    if isinstance(direction, str) and direction and direction not in ("forward", "return"):
        raise InputError(f"trial {trial}: direction {direction!r} is neither 'forward' nor 'return'", path=source,
                         remedy="write forward or return (lower case) in the direction column of the trials table, or "
                                "leave it empty for a file holding both carriages, and re-import")
    if isinstance(family, str) and family and family not in CONFIGURATIONS:
        raise InputError(f"trial {trial}: configuration {family!r} is neither "
                         f"{' nor '.join(repr(f) for f in CONFIGURATIONS)}: its returns would be grouped by their "
                         "measured end orientation, one mean each", path=source,
                         remedy=f"write {' or '.join(CONFIGURATIONS)} (lower case) in the configuration column of the "
                                "trials table and re-import (goals of other end orientations: leave it empty, and choose "
                                "the groups of their means with average --by)")
    try:
        known = scenario is None or np.isnan(float(scenario)) or float(scenario) in (1.0, 2.0, 3.0)
    except (TypeError, ValueError):  # NA: not given
        known = True
    if not known:
        raise InputError(f"trial {trial}: scenario {scenario} is not 1 (Subject 1 knows the goal), 2 (Subject 2) or 3 "
                         "(both)", path=source, remedy="correct the scenario column of the trials table and re-import")


def check_floor(trial: str, source: str, height: np.ndarray, h0: float, rate: float, window: float,
                min_duration: float) -> None:
    """Refuse a recording whose table rests, for ``min_duration`` or more, ``FLOOR_MARGIN`` below the floor level
    ``h0`` measured over its first ``window`` seconds."""
    with np.errstate(invalid="ignore"):
        low = runs(np.asarray(height) < h0 - FLOOR_MARGIN, max(1, int(round(min_duration * rate))))
    if not low:
        return
    a, b = low[0]
    rest = float(np.median(height[a:b + 1]))
    raise InputError(f"trial {trial}: the table rests at {rest:.3f} m at {_spans([(a, b)], rate)}, {h0 - rest:.3f} m "
                     f"below the floor level measured over the first {window:g} s ({h0:.3f} m): it was lifted when the "
                     "recording started, and its first carriage is cut off", path=source,
                     remedy="re-export the recording from before the table is lifted, or leave the trial out")


def check_count(trial: str, source: str, found: list[tuple[int, int]], labels: list[str], h0: float, rate: float,
                threshold: float, min_duration: float, min_set_down: float) -> None:
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
    if extra < 0 and found:
        joined = f" (or lower --min-set-down {min_set_down:g}, which joins lifts set down for less)" if min_set_down else ""
        remedy = ("if the file holds one carriage, give its direction (forward or return) in the trials table; if the "
                  "table was carried back without being set down, its carriages cannot be told apart: leave the trial "
                  f"out{joined}; else {remedy}")
    if extra > 0:  # the shortest set-downs would join: a re-grip if shorter than the others
        short = sorted(downs)
        join = _joining(short[extra - 1])
        if extra == len(short) or join < short[extra]:
            remedy = (f"if the table was set down briefly during a carriage (a re-grip), join the lifts with "
                      f"--min-set-down {join:g}; else {remedy}")
        if labels != ["forward", "return"] and len(found) == 2:
            remedy = ("if the file holds a forward and a return carriage, leave its direction empty in the trials table; "
                      + remedy)
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
    join = _joining((r0 - f1) / rate)
    raise InputError(f"trial {trial}: the second table carriage ({_spans([(r0, r1)], rate)}) ends {to_start:.2f} m "
                     f"from where the first ({_spans([(f0, f1)], rate)}) started and {to_goal:.2f} m from where it "
                     "ended: it does not carry the table back to the start, so it is no return (the table set down "
                     "to re-grip it during the forward carriage, the return not recorded?)", path=source,
                     remedy=f"if the file holds the forward carriage only, give it direction 'forward' in the trials "
                            f"table and join its lifts with --min-set-down {join:g}; else leave it out")


def end_orientation(trial: str, source: str, meta: dict, measured: float) -> tuple[float | None, bool]:
    """(the end orientation of a forward carriage whose table ended at ``measured`` rad, whether it was measured).

    Declared in the trials table (``meta``): refused more than ``END_TOLERANCE`` off the measured one or off both
    orientations of its configuration. Not declared: the orientation of its configuration nearer the measured one
    (returns are snapped so, ``compare.snap_configurations``), refused when the measured one is more than
    ``END_TOLERANCE`` from both; (None, False) without a configuration (average then refuses the trial's group)."""
    options = CONFIGURATIONS.get(meta.get("configuration"))
    try:
        declared = float(meta.get("end_orientation"))
    except (TypeError, ValueError):  # None or NA: not given
        declared = math.nan
    if not np.isfinite(declared):
        if not options:
            return None, False
        off = [abs(float(angle_diff(measured, o))) for o in options]
        if min(off) > END_TOLERANCE:
            other = [f"{f} ends at {o:.3f}" for f, opts in CONFIGURATIONS.items() for o in opts
                     if f != meta["configuration"] and abs(float(angle_diff(measured, o))) <= END_TOLERANCE]
            raise InputError(f"trial {trial}: no end_orientation in the trials table, and the table ended its forward "
                             f"carriage at {float(angle_diff(measured, 0.0)):.3f} rad, {min(off):.3f} rad from both "
                             f"orientations of configuration {meta['configuration']} "
                             f"({' or '.join(f'{o:.3f}' for o in options)} rad)", path=source,
                             remedy="write the orientation the table ended in (radians, TAB1 -> TAB2) as its end_orientation "
                                    "in the trials table, or correct its configuration"
                                    + (f" ({', '.join(other)})" if other else "") + ", and re-import")
        return float(options[int(np.argmin(off))]), True
    remedy = ("give end_orientation in radians, the direction TAB1 -> TAB2 of the table at the goal, in the trials "
              "table and re-import")
    off = abs(float(angle_diff(declared, measured)))
    if off > END_TOLERANCE:
        turns = {1: "a quarter turn off", 2: "a half turn off"}.get(round(off / (math.pi / 2)), f"{off:.2f} rad off")
        raise InputError(f"trial {trial}: end_orientation {declared:.3f} rad in the trials table, but the table ended its "
                         f"forward carriage at {float(angle_diff(measured, 0.0)):.3f} rad (the direction TAB1 -> TAB2), "
                         f"{turns}{' (degrees?)' if abs(declared) > 2 * math.pi else ''}", path=source, remedy=remedy)
    if options and min(abs(float(angle_diff(declared, o))) for o in options) > END_TOLERANCE:
        raise InputError(f"trial {trial}: end_orientation {declared:.3f} rad is no end orientation of configuration "
                         f"{meta['configuration']} ({' or '.join(f'{o:.3f}' for o in options)} rad)", path=source,
                         remedy="correct its configuration or end_orientation in the trials table and re-import")
    return declared, False


def subject1_end(xy1: np.ndarray, xy2: np.ndarray, theta: np.ndarray) -> int:
    """The end of the table Subject 1 holds over the frames given: +1 the TAB2 end (Subject 2 the TAB1 end), -1 the
    TAB1 end, 0 unknown (positions missing, or the subjects less than ``MIN_APART`` apart along the long axis)."""
    along = np.sum((xy1 - xy2) * np.column_stack([np.cos(theta), np.sin(theta)]), axis=1)
    along = along[np.isfinite(along)]
    median = float(np.median(along)) if along.size else 0.0
    return int(np.sign(median)) if abs(median) >= MIN_APART else 0


def swapped_subjects(ends: list[tuple[str, str, int]]) -> list[Refused]:
    """The recordings ``(trial, raw file, subject1_end)`` whose Subject 1 holds the other end of the table than in
    most of the others (at a tie, all of them: which is right cannot be told)."""
    known = [e for e in ends if e[2]]
    total = sum(end for _, _, end in known)
    name = {1: "TAB2", -1: "TAB1"}
    out = []
    for trial, source, end in known:
        if total * end > 0:
            continue
        other = sum(1 for _, _, e in known if e == -end)
        out.append(Refused(trial, Path(source), f"Subject 1 holds the {name[end]} end of the table, Subject 2 the "
                           f"{name[-end]} end, the other way round in {other} other pair recording{'s' * (other != 1)}"
                           f"{'' if total else ' (as many as the same way: which is right cannot be told)'}: "
                           "S1 and S2 swapped in this file?",
                           "check who is labelled Subject 1 in the file (the capture's subject names, the protocol's "
                           "entities), fix it and re-import, or leave the trial out"))
    return out
