"""One run end to end: read the streams from the bag, level them (vertical axis), compare, goal
accuracy (one task per bag). What a run needs to be read with care (a frame that is not z-up, a
delay on the edge of its window, dropped messages, a frozen truth) is warned about and kept in
``warnings``; streams in other units than each other are refused (``_check_units``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cobot_analysis.console import warn
from cobot_analysis.errors import InputError
from cobot_analysis.localisation import vertical
from cobot_analysis.localisation.bags import PoseSpec, read_streams, run_files
from cobot_analysis.localisation.compare import compare
from cobot_analysis.localisation.goals import StopRule, goal_accuracy, goal_summary, goals_from_stream


@dataclass(frozen=True)
class Options:
    truth: str = "/mocap/pose"
    icp: str = "/icp/pose"
    time: str = "header"
    delay: float | None = None
    window: tuple[float, float] = (0.0, 1.5)
    weights: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    alignment: str = "mean"
    association: str = "interpolate"
    max_gap: float | None = None  # None: from the truth's sample spacing (compare.default_max_gap)
    up: tuple[str | None, str | None] = (None, None)  # vertical axis of truth and ICP; None: detect
    scale: tuple[float, float] = (1.0, 1.0)  # metres per unit of the truth's and the ICP's positions (--units)
    max_diff: float = 0.01
    distance_window: float = 2.0
    min_samples: int = 20
    goal_topic: str | None = "/goal"
    goals: tuple[tuple[float, float, float], ...] | None = None  # from --goals CSV, for every run
    rule: StopRule = field(default_factory=StopRule)


def _return_freed_memory() -> None:
    """Have glibc give freed large arrays back to the system at once: its dynamic mmap threshold
    otherwise rises to the size of the arrays freed and keeps them in the heap of the thread that
    freed them, where the tables written afterwards cannot reuse them (peak memory of a 10-minute
    run: 205 -> 183 MiB). A fixed threshold of 128 KiB (glibc's initial one); no-op elsewhere.
    (Arrow's allocator is the command line's choice, not this library's: ``cli.main`` sets
    ``ARROW_DEFAULT_MEMORY_POOL=system``.)"""
    import ctypes

    try:
        ctypes.CDLL(None).mallopt(-3, 128 * 1024)  # M_MMAP_THRESHOLD, in the C library the process has loaded
    except (OSError, AttributeError, TypeError):  # no glibc (macOS, musl: no mallopt; Windows: no CDLL(None))
        pass


def _unfrozen(truth):
    """The truth without the poses that repeat the one before them exactly (x, y, z and quaternion: a
    tracked rigid body's noise never does; a bridge repeating the last pose of a lost one does), and the
    warning that says how many were dropped and the longest stretch (None when none were)."""
    same = np.all(np.diff(np.column_stack([truth.xyz, truth.quat]), axis=0) == 0, axis=1)
    if not same.any():
        return truth, None
    edges = np.flatnonzero(np.diff(np.concatenate([[0], same.astype(int), [0]])))  # runs of repeats: [start, end)
    start, end = edges[0::2], edges[1::2]
    k = int(np.argmax(truth.t[end] - truth.t[start]))
    text = (f"{int(same.sum())} motion-capture poses repeating the pose before them exactly dropped (a lost rigid body whose "
            f"last pose the bridge repeats; the longest stretch {truth.t[end[k]] - truth.t[start[k]]:.2g} s from "
            f"{truth.t[start[k]] - truth.t[0]:.1f} s into the stream)")
    return truth.select(np.concatenate([[True], ~same])), text


CLOCKS = 1.0  # s: header stamps whose offsets to the bag's record times differ more between the streams are in other clocks


def _clocks(o: Options, truth, icp) -> str | None:
    """The warning when the two streams' header stamps stand ``CLOCKS`` s or more apart against the bag's
    record times (a motion-capture PC's clock not synchronised with the robot's): the delay includes it."""
    a, b = truth.meta.get("clock"), icp.meta.get("clock")
    if o.time != "header" or a is None or b is None or abs(a - b) < CLOCKS:
        return None
    return (f"the header stamps of {o.truth} are {a:+.3g} s from the bag's record times, those of {o.icp} {b:+.3g} s: their "
            f"clocks differ by about {a - b:.2g} s, which the delay includes (--time record compares them on the bag's clock)")


SCALE_RATIO = 5.0  # the spreads of the truth's and the ICP's positions over their common time differ at most this much
MOVING = 0.05  # m: ... when the larger spread is at least this (below it both may be noise: a robot standing still)


def _check_units(path: Path, o: Options, truth, icp) -> str | None:
    """Refuse streams whose positions spread ``SCALE_RATIO`` times as far as the other's over their common
    time (the same motion in other units: millimetres), naming the ``--units`` that reads them. Returns a warning
    when both spread less than ``MOVING`` only because ``--units`` read them as millimetres (a robot standing still,
    or positions in metres read as millimetres)."""
    lo, hi = max(truth.t[0], icp.t[0]), min(truth.t[-1], icp.t[-1])
    common = [s.xyz[(s.t >= lo) & (s.t <= hi)] for s in (truth, icp)]
    sd = [float(np.sqrt(np.sum(np.var(xyz, axis=0)))) if len(xyz) > 1 else 0.0 for xyz in common]
    as_given = [v / scale for v, scale in zip(sd, o.scale)]  # the spreads in the units the bag stores
    if max(sd) < MOVING <= max(as_given):
        return (f"read with --units {','.join('mm' if v == 0.001 else 'm' for v in o.scale)} the poses spread "
                f"{1000 * max(sd):.3g} mm over the run, as a robot standing still; read in metres they spread "
                f"{max(as_given):.3g} m: if the robot moved, its positions are in metres (--units m)")
    if min(sd) <= 0 or max(sd) < MOVING or max(sd) < SCALE_RATIO * min(sd):
        return None
    ratio = sd[0] / sd[1]
    unit = ["mm" if v == 0.001 else "m" for v in o.scale]
    remedy = "check that --truth and --icp are the same robot's poses, and their units (--units TRUTH,ICP)"
    if 300 < ratio < 3000 and unit[0] == "m":
        remedy = f"a stream in millimetres: read it with --units mm,{unit[1]}"
    elif 300 < 1 / ratio < 3000 and unit[1] == "m":
        remedy = f"a stream in millimetres: read it with --units {unit[0]},mm"
    raise InputError(f"the positions of {o.truth} spread {ratio:.3g} times as far as those of {o.icp} (sd {sd[0]:.3g} against "
                     f"{sd[1]:.3g} over their common time): not the same units", path=path, remedy=remedy)


def analyse_run(task: tuple[str | tuple[str, ...], str, str, Options]) -> dict:
    """``(path, run label, map label, options)`` -> poses, comparison, goals and the per-run row; ``path``: a bag,
    or the pieces of a split recording (read as one run, named ``DIR/run_0.bag+run_1.bag``)."""
    _return_freed_memory()
    files, run, map_label, o = task
    path = run_files(files)[1]
    specs = {"truth": PoseSpec.parse(o.truth), "icp": PoseSpec.parse(o.icp)}
    if o.goals is None and o.goal_topic:
        specs["goals"] = PoseSpec.parse(o.goal_topic)
    streams = read_streams(files, specs, o.time, optional=("goals",), sparse=("goals",),
                           scale={"truth": o.scale[0], "icp": o.scale[1], "goals": o.scale[1]})  # goals: in the ICP's map
    goal_from_bag = "goals" in streams
    (truth, frozen), icp = _unfrozen(streams["truth"]), streams["icp"]
    for spec, s in ((o.truth, truth), (o.icp, icp)):
        if len(s) < 2:
            raise InputError(f"{spec}: {len(s)} pose(s), too few to compare", path=path,
                             remedy="check the stream with `cobot-analysis bag-info` (for tf: both edges must overlap in time)")
    units = _check_units(path, o, truth, icp)
    notes = [n for s in (truth, icp) for n in s.meta.get("notes", [])]
    for text in (units, frozen, _clocks(o, truth, icp)):
        if text:
            warn(f"{path}: {text}")
            notes.append(text)
    up_truth, up_icp = vertical.find(truth, o.up[0]), vertical.find(icp, o.up[1])
    for name, v in (("motion-capture", up_truth), ("ICP", up_icp)):
        text = vertical.warning(name, v)
        if text:
            warn(f"{path}: {text}")
            notes.append(text)
    truth, icp = vertical.level(truth, up_truth), vertical.level(icp, up_icp)
    if goal_from_bag:
        streams["goals"] = vertical.level(streams["goals"], up_icp)  # goals are poses of the ICP map frame
    cmp = compare(truth, icp, delay=o.delay, window=o.window, weights=o.weights, alignment=o.alignment,
                  association=o.association, max_gap=o.max_gap, max_diff=o.max_diff,
                  distance_window=o.distance_window, min_samples=o.min_samples, path=path)
    for text in (cmp.delay.edge_warning(), *cmp.notes):
        if text:
            warn(f"{path}: {text}")
            notes.append(text)
    row = {"run": run, "file": str(path), "map": map_label, "truth": o.truth, "icp": o.icp, "time_base": o.time,
           "up_truth": up_truth.describe(), "up_icp": up_icp.describe(), **{k: v for k, v in cmp.summary.items()}}
    goals_df = None
    goals = np.asarray(o.goals, dtype=float) if o.goals is not None else goals_from_stream(streams["goals"]) if goal_from_bag else None
    if goals is not None:
        goal_times = streams["goals"].t if goal_from_bag else None
        goals_df = goal_accuracy(truth, icp, goals, cmp.alignment, cmp.delay.value, o.rule, goal_times)
        row.update(goal_summary(goals_df))
        if not goals_df["found"].all():
            text = (f"{int((~goals_df['found']).sum())} of {len(goals_df)} goals without a matching stop "
                    f"({goals_df.attrs['n_stops']} stops detected); see --speed-threshold and --min-stop")
            warn(f"{path}: {text}")
            notes.append(text)
        goals_df.insert(0, "run", run)
    row["warnings"] = " | ".join(notes)
    samples = cmp.samples.copy()
    samples.insert(0, "run", run)
    poses = [truth.to_frame(run, "truth"), icp.to_frame(run, "icp")]
    return {"run": run, "row": row, "samples": samples, "goals": goals_df, "comparison": cmp, "poses": poses}
