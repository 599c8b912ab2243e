"""Localisation accuracy of a robot's on-board (ICP) localisation against motion capture
(docs/methods.md sec. 9): per bag, the delay, the structural offset, per-axis errors, the APE, the
drift and the accuracy at the commanded goals. Returns the result's tables; nothing is written."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cobot_analysis.lazy import pandas as pd

from cobot_analysis.api.options import at_least, floats
from cobot_analysis.errors import InputError
from cobot_analysis.metrics import localisation as headline
from cobot_analysis.metrics.records import Metrics, collect


def run_labels(runs: list) -> list[str]:
    """Run labels: the bags' stems (their names where two stems are the same, and for a ROS2 bag directory); for
    the pieces of a split recording (a tuple of paths) the stem they share; ``localise`` below shows ``run`` for
    ``run.bag``.

        >>> from pathlib import Path
        >>> run_labels([Path("robot/run_ros2"), (Path("robot/lap_0.bag"), Path("robot/lap_1.bag"))])
        ['run_ros2', 'lap']
    """
    from cobot_analysis.localisation.bags import PIECE, run_files

    files = [run_files(r) for r in runs]
    stems = [PIECE.match(paths[0].stem)["stem"] if len(paths) > 1 else paths[0].stem if paths[0].is_file() else paths[0].name
             for paths, _ in files]
    return [name.name if stems.count(s) > 1 else s for (_, name), s in zip(files, stems)]


@dataclass
class LocalisationResult:
    """Per run (``runs``: one row per bag, ``localisation.tables.RUNS``), per associated ICP sample (``errors``),
    per commanded goal (``goals``), both pose streams (``poses``); ``per_run`` keeps each run's arrays for
    the figures."""

    options: Any  # localisation.analysis.Options
    labels: list[str]
    maps: list[str]
    runs: pd.DataFrame
    errors: pd.DataFrame
    goals: pd.DataFrame | None
    poses: pd.DataFrame
    per_run: list[dict]

    def summary(self) -> str:
        return f"{len(self.per_run)} run(s)"

    def metrics(self, *, stage: str = "localisation") -> Metrics:
        """Headline numbers (``metrics.localisation.localisation``): per run, delay, offsets, per-axis errors,
        APE, drift and goal accuracy."""
        return collect(stage, headline.localisation, self.runs)

    def figures(self) -> dict[str, Any]:
        """Matplotlib figures by name, those the stage writes (``reports.localisation``): ``paths``, ``error_time``,
        ``error_distribution``, ``delay_cost`` and one ``timeseries_<run>`` per run."""
        import re

        from cobot_analysis.reports import localisation as report

        runs = self.per_run
        figs = {"paths": report.figure_paths(runs), "error_time": report.figure_error_time(runs),
                "error_distribution": report.figure_error_distribution(runs), "delay_cost": report.figure_delay(runs)}
        for r in runs:
            figs["timeseries_" + re.sub(r"[^A-Za-z0-9_-]+", "_", r["run"])] = report.figure_timeseries(r)
        return figs

    def run_lines(self, where: str = "the warnings column of .runs") -> list[str]:
        """One line per run: delay, RMSE, goals, how many warnings (``where``: where to read them; the command line
        names the stage's results.md)."""
        lines = []
        for r in self.per_run:
            row = r["row"]
            d = (f"{row['delay']:.3f} s (at the edge of the search window: see the warning)" if row["delay_at_edge"]
                 else f"{row['delay']:.3f} s (given)" if row["delay_method"] == "given" else f"{row['delay']:.3f} ± {row['delay_sd']:.3f} s")
            lines.append(f"{r['run']}: delay {d}, RMSE {1000 * row['ape_rmse']:.1f} mm"
                         + (f", goals {row['goals_found']}/{row['goals_commanded']}" if "goals_found" in row else "")
                         + (f", {len(row['warnings'].split(' | '))} warning(s) ({where})" if row["warnings"] else ""))
        return lines


UNITS = {"m": 1.0, "mm": 0.001}  # metres per unit of a stream's positions (--units)


def localisation_options(bags: list[Path], *, truth: str = "/mocap/pose", icp: str = "/icp/pose", time: str = "header",
                         label: list[str] | None = None, map_name: list[str] | None = None, delay: float | None = None,
                         delay_window: str = "0,1.5", delay_weights: str = "1,1,1,1", alignment: str = "mean",
                         association: str = "interpolate", max_gap: float | None = None, max_diff: float = 0.01,
                         goals_csv: str | os.PathLike | None = None, goal_topic: str = "/goal", speed_threshold: float = 0.02,
                         yaw_rate_threshold: float = 0.03, min_stop: float = 3.0, tol_xy: float = 0.08, tol_yaw: float = 0.07,
                         distance_window: float = 2.0, up: str = "auto", min_samples: int = 20, units: str = "m",
                         join: bool | None = None):
    """(Options, runs, labels, maps): the options of ``localise`` checked (one line naming the option otherwise);
    ``runs``: the bags of each run (``localisation.bags.runs_of``: the pieces of a split recording, ``run_0.bag``,
    ``run_1.bag``, ..., are one run with ``join=True``, each a run with ``join=False``, refused with ``None``).

        >>> from pathlib import Path
        >>> opts, runs, labels, maps = localisation_options([Path("run.bag")], delay_window="0,2", label=["lab-run"])
        >>> opts.window, opts.alignment, runs, labels, maps
        ((0.0, 2.0), 'mean', [(PosixPath('run.bag'),)], ['lab-run'], [''])
        >>> localisation_options([Path("run.bag")], alignment="umeyama")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --alignment must be mean, se3, yaw or none, not 'umeyama'
    """
    from cobot_analysis.localisation.analysis import Options
    from cobot_analysis.localisation.bags import PoseSpec, runs_of
    from cobot_analysis.localisation.goals import StopRule, read_goals_csv

    goals = goals_csv
    from cobot_analysis.localisation import vertical

    window = floats(delay_window, 2, "--delay-window")
    if window[0] >= window[1]:
        raise InputError(f"--delay-window MIN,MAX needs MIN < MAX, got {delay_window!r}", remedy="e.g. --delay-window 0,1.5")
    weights = floats(delay_weights, 4, "--delay-weights")
    if min(weights) < 0 or max(weights) <= 0:
        raise InputError(f"--delay-weights must be >= 0 with at least one > 0, got {delay_weights!r}", remedy="e.g. --delay-weights 1,1,1,1")
    if delay is not None and not math.isfinite(delay):
        raise InputError(f"--delay must be a number of seconds, got {delay}", remedy="e.g. --delay 0.55")
    at_least(max_gap, "--max-gap", example="0.2")
    at_least(max_diff, "--max-diff", example="0.01")
    at_least(distance_window, "--distance-window", example="2")
    at_least(speed_threshold, "--speed-threshold", example="0.02")
    at_least(yaw_rate_threshold, "--yaw-rate-threshold", example="0.03")
    at_least(min_stop, "--min-stop", strict=False, example="3")
    at_least(tol_xy, "--tol-xy", strict=False, example="0.08")
    at_least(tol_yaw, "--tol-yaw", strict=False, example="0.07")
    at_least(min_samples, "--min-samples", low=3, strict=False, example="20")
    try:
        up_axes = vertical.parse(up)
    except ValueError:
        raise InputError(f"--up must be auto, x, y, z, -x, -y, -z or TRUTH,ICP, got {up!r}", remedy="e.g. --up -y,z") from None
    scale = tuple(UNITS.get(u.strip().lower()) for u in (units.split(",") * 2 if "," not in units else units.split(",")))
    if len(scale) != 2 or None in scale:
        raise InputError(f"--units must be m, mm or TRUTH,ICP (e.g. mm,m), got {units!r}", remedy="e.g. --units mm,m")
    if time not in ("header", "record"):
        raise InputError(f"--time must be header or record, not {time!r}")
    if PoseSpec.parse(truth) == PoseSpec.parse(icp):
        raise InputError(f"--truth and --icp are the same stream {PoseSpec.parse(truth)}",
                         remedy="pass the motion capture with --truth and the robot's estimate with --icp (`cobot-analysis "
                                "bag-info BAG` lists the streams)")
    if alignment not in ("mean", "se3", "yaw", "none"):
        raise InputError(f"--alignment must be mean, se3, yaw or none, not {alignment!r}")
    if association not in ("interpolate", "nearest"):
        raise InputError(f"--association must be interpolate or nearest, not {association!r}")
    runs = runs_of(bags, join)
    labels = list(label) if label else run_labels(runs)
    what = "runs (split recordings joined)" if len(runs) < len(bags) else "bags"
    if len(labels) != len(runs):
        raise InputError(f"{len(labels)} --label for {len(runs)} {what}", remedy="give one --label per run")
    for i, r in enumerate(runs):  # a run's label names its rows and metrics: two runs cannot share one
        j = labels.index(labels[i])
        if j < i and [b.resolve() for b in runs[j]] == [b.resolve() for b in r]:
            raise InputError("bag given twice", path=r[0], remedy="give each bag once")
        if j < i:
            raise InputError(f"run label {labels[i]!r} given to two bags ({runs[j][0]} and this one)", path=r[0],
                             remedy="give each bag its own --label, once per bag, in order")
    maps = list(map_name or [""])
    if len(maps) == 1:
        maps = maps * len(runs)
    if len(maps) != len(runs):
        raise InputError(f"{len(maps)} --map-name for {len(runs)} {what}", remedy="give one --map-name for all runs or one per run")
    goal_rows = tuple(map(tuple, read_goals_csv(goals))) if goals else None
    opts = Options(truth=truth, icp=icp, time=time, delay=delay, window=window, weights=weights, alignment=alignment,
                   association=association, max_gap=max_gap, max_diff=max_diff, distance_window=distance_window,
                   min_samples=min_samples, up=up_axes, scale=scale,
                   goal_topic=goal_topic or None, goals=goal_rows,
                   rule=StopRule(speed_threshold=speed_threshold, yaw_rate_threshold=yaw_rate_threshold,
                                 min_duration=min_stop, tol_xy=tol_xy, tol_yaw=tol_yaw))
    return opts, runs, labels, maps


def localise(bags: str | os.PathLike | list[str | os.PathLike], *, jobs: int | None = None, scheduler: str | None = None,
             **options: Any) -> LocalisationResult:
    """Localisation accuracy of ICP against motion capture in each bag (ROS1 .bag, ROS2 bag directory,
    .mcap; one bag, or a list): delay, structural offset, per-axis errors, APE, drift, goal accuracy
    (docs/methods.md sec. 9).
    ``options``: those of ``localisation_options`` (the command line's, e.g. ``truth="/mocap/pose"``,
    ``icp="/icp/pose"``, ``delay=None`` to estimate it, ``alignment="mean"``).

    A synthetic run of 14 s to one goal, ICP planted 0.55 s late and offset by (0.12, -0.085, 0.045) m:

        >>> import tempfile
        >>> from pathlib import Path
        >>> from cobot_analysis.api import localise
        >>> from cobot_analysis.localisation import synth
        >>> tmp = tempfile.TemporaryDirectory()
        >>> bag = synth.write_ros1(synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)), Path(tmp.name) / "run.bag")
        >>> r = localise([bag], truth="/mocap/pose", icp="/icp/pose")
        >>> r.run_lines()
        ['run: delay 0.547 ± 0.003 s, RMSE 9.0 mm, goals 1/1']
        >>> run = r.runs.iloc[0]
        >>> round(float(run["offset_x"]), 2), round(float(run["offset_y"]), 2), round(float(run["offset_z"]), 2)
        (0.12, -0.08, 0.04)
        >>> localise(bag, delay=0.55).runs["run"].tolist()   # one bag alone; the delay given
        ['run']
        >>> localise(bag, tol=0.1)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: unknown localise option(s) ['tol']; use truth, icp, time, label, map_name, delay, delay_window, delay_weights, alignment, association, max_gap, max_diff, goals_csv, goal_topic, speed_threshold, yaw_rate_threshold, min_stop, tol_xy, tol_yaw, distance_window, up, min_samples, units, join
        >>> tmp.cleanup()
    """
    import inspect

    known = [p for p in inspect.signature(localisation_options).parameters if p != "bags"]
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise InputError(f"unknown localise option(s) {unknown}", remedy=f"use {', '.join(known)}")
    bags = [Path(bags)] if isinstance(bags, (str, os.PathLike)) else [Path(b) for b in bags]
    for b in bags:
        if not b.exists():
            raise InputError("no such file or directory", path=b, remedy="check the path")
    opts, runs, labels, maps = localisation_options(bags, **options)
    return analyse(runs, opts, labels, maps, jobs=jobs, scheduler=scheduler)


def analyse(runs: list, opts, labels: list[str], maps: list[str], *, jobs: int | None = None,
            scheduler: str | None = None) -> LocalisationResult:
    """Analyse each run (a bag, or a tuple of the pieces of a split recording) with checked options
    (``localisation_options``): ``localise`` without its checks of the paths; the ``localisation`` stage
    calls it after recording the checked options.

        >>> import tempfile
        >>> from pathlib import Path
        >>> from cobot_analysis.localisation import synth
        >>> tmp = tempfile.TemporaryDirectory()
        >>> bag = synth.write_mcap(synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)), Path(tmp.name) / "run.mcap")
        >>> opts, runs, labels, maps = localisation_options([bag], delay=0.55)
        >>> r = analyse(runs, opts, labels, maps)
        >>> float(r.runs.loc[0, "delay"]), r.runs.loc[0, "delay_method"], int(r.runs.loc[0, "n"]) == len(r.errors)
        (0.55, 'given', True)
        >>> tmp.cleanup()
    """
    from cobot_analysis.localisation.analysis import analyse_run
    from cobot_analysis.localisation.bags import run_files
    from cobot_analysis.parallel import map_tasks

    tasks = [(tuple(str(p) for p in run_files(r)[0]), lab, m, opts) for r, lab, m in zip(runs, labels, maps)]
    n_jobs = 1 if len(tasks) == 1 else jobs
    results = map_tasks(analyse_run, tasks, jobs=n_jobs, scheduler=scheduler, description="localisation runs",
                        status=lambda r: f"{r['run']}: delay {r['row']['delay']:.3f} s")
    goal_frames = [r["goals"] for r in results if r["goals"] is not None]
    # The runs' pose frames are views of their streams: once concatenated, neither is kept (-9 MiB on a 10-minute run).
    poses = pd.concat([p for r in results for p in r.pop("poses")], ignore_index=True)
    return LocalisationResult(opts, labels, maps, pd.DataFrame([r["row"] for r in results]),
                              pd.concat([r["samples"] for r in results], ignore_index=True),
                              pd.concat(goal_frames, ignore_index=True) if goal_frames else None, poses, results)


def bag_topics(bag: str | os.PathLike) -> tuple[list[dict], list[dict]]:
    """The topics of a bag (topic, type, count, rate, start, end, pose-like) and its tf frame pairs: what
    to pass as ``truth`` / ``icp`` to ``localise`` (a topic, or ``tf:PARENT->CHILD``).

        >>> import tempfile
        >>> from pathlib import Path
        >>> from cobot_analysis.localisation import synth
        >>> tmp = tempfile.TemporaryDirectory()
        >>> bag = synth.write_ros1(synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)), Path(tmp.name) / "run.bag")
        >>> topics, frames = bag_topics(bag)
        >>> [(t["topic"], t["type"], t["rate"]) for t in topics if t["topic"] in ("/mocap/pose", "/icp/pose")]
        [('/icp/pose', 'geometry_msgs/PoseStamped', 10.0), ('/mocap/pose', 'geometry_msgs/PoseStamped', 200.0)]
        >>> [(f["parent"], f["child"]) for f in frames if not f["static"]]
        [('map', 'odom'), ('odom', 'base_link')]
        >>> tmp.cleanup()
    """
    from cobot_analysis.localisation.bags import bag_info

    return bag_info(Path(bag))
