"""``cobot-analysis localisation``, ``bag-info`` and ``synth localisation`` (docs/methods.md sec. 9)."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import (
    DEFAULT_OUT_PATH,
    PANEL_LOCALISATION,
    ForceOpt,
    JobsOpt,
    OutOpt,
    SchedulerOpt,
    SeedOpt,
    app,
    examples,
    finished,
    synth_app,
)
from cobot_analysis.errors import InputError

SYNTH_STAGE = "synth-localisation"
STAGE = "localisation"
SYNTH_FILES = ("run.bag", "run_ros2", "run.mcap")


def _floats(text: str, n: int, option: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise InputError(f"{option} needs {n} comma-separated numbers, got {text!r}", remedy=f"e.g. {option} " + ",".join(["0"] * n))
    return values


def _at_least(value: float | None, option: str, low: float = 0.0, strict: bool = True, example: str = "") -> None:
    """Range check of a number option (before any work): one line naming the option."""
    if value is None:
        return
    if not math.isfinite(value) or value < low or (strict and value == low):
        raise InputError(f"{option} must be {'>' if strict else '>='} {low:g}, got {value:g}",
                         remedy=f"e.g. {option} {example}" if example else None)


@app.command("bag-info", rich_help_panel=PANEL_LOCALISATION, epilog=examples(
    "cobot-analysis bag-info robot/synth-localisation/run.mcap"))
def bag_info_command(
    bag: Annotated[Path, typer.Argument(help="ROS1 .bag, ROS2 bag directory, or .mcap/.db3 file.")],
) -> None:
    """List the topics of a bag (type, count, rate, time span) and its tf frame pairs.

    Pose topics (PoseStamped, PoseWithCovarianceStamped, TransformStamped, Odometry) can be passed to `localisation --truth/--icp`
    as they are; tf frames as tf:PARENT->CHILD (any two connected frames).
    """
    from rich.table import Table

    from cobot_analysis.console import console
    from cobot_analysis.localisation.bags import bag_info

    rows, edges = bag_info(bag)
    table = Table(title=str(bag))
    for col in ("topic", "type", "count", "rate (Hz)", "start (s)", "span (s)", "pose"):
        table.add_column(col, justify="right" if col in ("count", "rate (Hz)", "start (s)", "span (s)") else "left")
    for r in rows:
        table.add_row(r["topic"], r["type"], str(r["count"]), f"{r['rate']:.2f}" if r["rate"] == r["rate"] else "-",
                      f"{r['start']:.3f}", f"{r['end'] - r['start']:.3f}", "yes" if r["pose"] else "")
    _print_whole(console, table)
    if edges:
        tf = Table(title="tf frame pairs (use tf:PARENT->CHILD)")
        for col in ("parent", "child", "transforms", "static"):
            tf.add_column(col)
        for e in edges:
            tf.add_row(e["parent"], e["child"], str(e["count"]), "yes" if e["static"] else "")
        _print_whole(console, tf)
    # Also plain lines on stdout, for scripts.
    for r in rows:
        typer.echo(f"{r['topic']}\t{r['type']}\t{r['count']}\t{r['rate']:.3f}\t{r['start']:.9f}\t{r['end']:.9f}")
    for e in edges:
        typer.echo(f"tf:{e['parent']}->{e['child']}\t{e['count']}\t{'static' if e['static'] else 'dynamic'}")
    finished("bag-info", f"{len(rows)} topics ({sum(bool(r['pose']) for r in rows)} of poses), {len(edges)} tf frame pairs", "stdout")


def _print_whole(console, table) -> None:
    """A table as wide as its cells need (topic and frame names are never cut), even beyond the terminal."""
    from rich.console import Console
    from rich.measure import Measurement

    width = max(console.width, Measurement.get(console, console.options.update_width(10_000), table).maximum)
    Console(stderr=True, width=width, highlight=False, force_terminal=console.is_terminal or None).print(table)


@synth_app.command("localisation", epilog=examples(
    "cobot-analysis synth localisation --out robot --goals-per-lap 2 \\",
    "    --formats mcap",
    "cobot-analysis synth localisation --out robot2 --goals-per-lap 1 \\",
    "    --delay 0.3"))
def synth_localisation_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    force: ForceOpt = False,
    seed: SeedOpt = 0,
    laps: Annotated[int, typer.Option(min=1, help="Tours through the 6 goals (about 10 m and 2.4 min each).")] = 1,
    goals_per_lap: Annotated[int, typer.Option(min=1, max=6, help="Goals per lap (the first N of the 6; fewer = shorter run).")] = 6,
    speed: Annotated[float, typer.Option(min=0.01, help="Walking speed (m/s).")] = 0.12,
    delay: Annotated[float, typer.Option(min=0.0, help="Planted ICP delay (s).")] = 0.55,
    offset: Annotated[str, typer.Option(help="Planted structural offset x,y,z,yaw (m, rad), ICP minus truth.")] = "0.12,-0.085,0.045,0.03",
    noise: Annotated[str, typer.Option(help="ICP noise sd x,y,z,yaw (m, rad).")] = "0.006,0.006,0.003,0.004",
    stop: Annotated[float, typer.Option(min=0.0, help="Stop duration on each goal (s).")] = 8.0,
    formats: Annotated[str, typer.Option(help="Comma list of ros1 (run.bag), ros2 (run_ros2/, sqlite3), mcap (run.mcap).")] = "ros1,ros2,mcap",
) -> None:
    """Synthetic robot run: mocap 200 Hz, ICP 10 Hz with a known delay, offset and noise, goals and
    cmd_vel, written as a ROS1 bag, a ROS2 bag and an MCAP file, with truth.json and goals.csv."""
    from cobot_analysis.console import track
    from cobot_analysis.localisation import synth
    from cobot_analysis.workspace import Stage

    fmts = [f.strip() for f in formats.split(",") if f.strip()]
    unknown = sorted(set(fmts) - {"ros1", "ros2", "mcap"})
    if unknown or not fmts:
        raise InputError(f"unknown format(s) {unknown or formats!r}", remedy="use --formats ros1,ros2,mcap")
    params = synth.SynthParams(seed=seed, laps=laps, n_goals=goals_per_lap, speed=speed, delay=delay, offset=_floats(offset, 4, "--offset"),
                               noise=_floats(noise, 4, "--noise"), stop=stop)
    with Stage(out, SYNTH_STAGE, params={**params.__dict__, "formats": fmts}, force=force) as stage:
        if stage.skipped:
            return
        run = synth.make_run(params)
        writers = {"ros1": ("run.bag", synth.write_ros1), "ros2": ("run_ros2", synth.write_ros2), "mcap": ("run.mcap", synth.write_mcap)}
        for fmt in track(fmts, "write bags"):
            name, write = writers[fmt]
            write(run, stage.path(name))
        synth.write_goals_csv(run, stage.path("goals.csv"))
        synth.write_truth(run, stage.path("truth.json"))
    finished(SYNTH_STAGE, f"{len(run.t_mocap)} mocap and {len(run.t_icp)} ICP poses, {run.distance:.2f} m, {len(run.goals)} goals",
             stage.final_dir)


@app.command("localisation", rich_help_panel=PANEL_LOCALISATION, epilog=examples(
    "cobot-analysis localisation --out robot --map-name synthetic",
    "cobot-analysis localisation robot/synth-localisation/run.mcap \\",
    "    --out robot --label run1 --no-figures \\",
    "    --goals-csv robot/synth-localisation/goals.csv"))
def localisation_command(
    bags: Annotated[Optional[list[Path]], typer.Argument(help="Bags (ROS1 .bag, ROS2 directory, .mcap); default: the synthetic runs of `synth localisation` in --out.")] = None,
    out: OutOpt = DEFAULT_OUT_PATH,
    force: ForceOpt = False,
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    truth: Annotated[str, typer.Option(help="Motion-capture stream: a topic or tf:PARENT->CHILD.")] = "/mocap/pose",
    icp: Annotated[str, typer.Option(help="ICP stream: a topic or tf:PARENT->CHILD.")] = "/icp/pose",
    time: Annotated[str, typer.Option(help="Stamps: 'header' (message header) or 'record' (bag receive time).")] = "header",
    label: Annotated[Optional[list[str]], typer.Option(help="Run label, once per bag (default: file stem).")] = None,
    map_name: Annotated[Optional[list[str]], typer.Option("--map-name", help="Name of the map the ICP localised in (e.g. scanned), once for all bags or once per bag.")] = None,
    delay: Annotated[Optional[float], typer.Option(help="Use this delay (s) instead of estimating it.")] = None,
    delay_window: Annotated[str, typer.Option(help="Delay search window MIN,MAX (s; MIN < MAX, MIN may be negative). An estimate on an end of it is warned about.")] = "0,1.5",
    delay_weights: Annotated[str, typer.Option(help="Weights of x,y,z,yaw in the delay cost (yaw in m/rad; 0 drops an axis).")] = "1,1,1,1",
    alignment: Annotated[str, typer.Option(help="Offset removal: mean (docs/methods.md), se3 (Umeyama), yaw (4 DoF), none.")] = "mean",
    association: Annotated[str, typer.Option(help="interpolate (truth at the ICP stamps) or nearest (nearest stamp, as evo).")] = "interpolate",
    max_gap: Annotated[Optional[float], typer.Option(help="Longest truth gap to interpolate across (s); default: twice the median sample spacing of the truth stream, at least 0.05 s.")] = None,
    max_diff: Annotated[float, typer.Option(help="Nearest association: largest stamp difference (s).")] = 0.01,
    goals: Annotated[Optional[Path], typer.Option("--goals-csv", help="Commanded goals CSV (x,y,yaw in the ICP map frame, levelled to z-up when --up is not z) for every run.")] = None,
    goal_topic: Annotated[str, typer.Option(help="Topic of the commanded goals in the bag (used when --goals-csv is not given).")] = "/goal",
    speed_threshold: Annotated[float, typer.Option(help="Stop: planar speed below this (m/s).")] = 0.02,
    yaw_rate_threshold: Annotated[float, typer.Option(help="Stop: |yaw rate| below this (rad/s).")] = 0.03,
    min_stop: Annotated[float, typer.Option(help="Stop: minimum duration (s).")] = 3.0,
    tol_xy: Annotated[float, typer.Option(help="Controller stop tolerance, position (m).")] = 0.08,
    tol_yaw: Annotated[float, typer.Option(help="Controller stop tolerance, yaw (rad).")] = 0.07,
    distance_window: Annotated[float, typer.Option(help="Moving-average window for the travelled distance (s).")] = 2.0,
    up: Annotated[str, typer.Option(help="Vertical axis of the frames: auto (detected from the motion, warned when not z), x, y, z, -x, -y, -z, or TRUTH,ICP (e.g. -y,z for a camera-frame truth). Planar quantities (distance, drift, stops, yaw) are computed in the plane normal to it.")] = "auto",
    min_samples: Annotated[int, typer.Option(min=3, help="Fewest associated ICP poses accepted.")] = 20,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Draw the figures (PNG and PDF).")] = True,
) -> None:
    """Localisation accuracy of ICP against motion capture: delay, structural offset, per-axis errors,
    drift, goal accuracy; one row per bag in localisation.parquet, figures and results.md."""
    import pandas as pd

    from cobot_analysis.console import info
    from cobot_analysis.localisation.analysis import Options, analyse_run
    from cobot_analysis.localisation.goals import StopRule, read_goals_csv
    from cobot_analysis.localisation.poses import POSES
    from cobot_analysis.localisation import report
    from cobot_analysis.parallel import map_tasks
    from cobot_analysis.schema import write_table
    from cobot_analysis.workspace import Stage

    if not bags:
        base = Path(out) / SYNTH_STAGE
        bags = [base / f for f in SYNTH_FILES if (base / f).exists()]
        if not bags:
            raise InputError("no bag given and no synthetic runs in the workspace", path=base,
                             remedy="pass bag files, or run `cobot-analysis synth localisation` first with the same --out")
    for b in bags:
        if not b.exists():
            raise InputError("no such file or directory", path=b, remedy="check the path")
    from cobot_analysis.localisation import vertical

    window = _floats(delay_window, 2, "--delay-window")
    if window[0] >= window[1]:
        raise InputError(f"--delay-window MIN,MAX needs MIN < MAX, got {delay_window!r}", remedy="e.g. --delay-window 0,1.5")
    weights = _floats(delay_weights, 4, "--delay-weights")
    if min(weights) < 0 or max(weights) <= 0:
        raise InputError(f"--delay-weights must be >= 0 with at least one > 0, got {delay_weights!r}", remedy="e.g. --delay-weights 1,1,1,1")
    if delay is not None and not math.isfinite(delay):
        raise InputError(f"--delay must be a number of seconds, got {delay}", remedy="e.g. --delay 0.55")
    _at_least(max_gap, "--max-gap", example="0.2")
    _at_least(max_diff, "--max-diff", example="0.01")
    _at_least(distance_window, "--distance-window", example="2")
    _at_least(speed_threshold, "--speed-threshold", example="0.02")
    _at_least(yaw_rate_threshold, "--yaw-rate-threshold", example="0.03")
    _at_least(min_stop, "--min-stop", strict=False, example="3")
    _at_least(tol_xy, "--tol-xy", strict=False, example="0.08")
    _at_least(tol_yaw, "--tol-yaw", strict=False, example="0.07")
    try:
        up_axes = vertical.parse(up)
    except ValueError:
        raise InputError(f"--up must be auto, x, y, z, -x, -y, -z or TRUTH,ICP, got {up!r}", remedy="e.g. --up -y,z") from None
    if time not in ("header", "record"):
        raise InputError(f"--time must be header or record, not {time!r}")
    if alignment not in ("mean", "se3", "yaw", "none"):
        raise InputError(f"--alignment must be mean, se3, yaw or none, not {alignment!r}")
    if association not in ("interpolate", "nearest"):
        raise InputError(f"--association must be interpolate or nearest, not {association!r}")
    labels = list(label) if label else _labels(bags)
    if len(labels) != len(bags):
        raise InputError(f"{len(labels)} --label for {len(bags)} bags", remedy="give one --label per bag")
    maps = list(map_name or [""])
    if len(maps) == 1:
        maps = maps * len(bags)
    if len(maps) != len(bags):
        raise InputError(f"{len(maps)} --map-name for {len(bags)} bags", remedy="give one --map-name for all bags or one per bag")
    goal_rows = tuple(map(tuple, read_goals_csv(goals))) if goals else None
    opts = Options(truth=truth, icp=icp, time=time, delay=delay, window=window, weights=weights, alignment=alignment,
                   association=association, max_gap=max_gap, max_diff=max_diff, distance_window=distance_window,
                   min_samples=min_samples, up=up_axes,
                   goal_topic=goal_topic or None, goals=goal_rows,
                   rule=StopRule(speed_threshold=speed_threshold, yaw_rate_threshold=yaw_rate_threshold,
                                 min_duration=min_stop, tol_xy=tol_xy, tol_yaw=tol_yaw))
    params = {"options": opts, "labels": labels, "maps": maps, "figures": figures}
    inputs = [*bags, *([goals] if goals else [])]
    with Stage(out, STAGE, inputs=inputs, params=params, force=force) as stage:
        if stage.skipped:
            return
        tasks = [(str(b), lab, m, opts) for b, lab, m in zip(bags, labels, maps)]
        n_jobs = 1 if len(tasks) == 1 else jobs
        results = map_tasks(analyse_run, tasks, jobs=n_jobs, scheduler=scheduler, description="localisation runs",
                            status=lambda r: f"{r['run']}: delay {r['row']['delay']:.3f} s")
        write_table(pd.concat([p for r in results for p in r["poses"]], ignore_index=True), stage.path("poses.parquet"), POSES,
                    time_base=time)
        runs = pd.DataFrame([r["row"] for r in results])
        write_table(runs, stage.path("localisation.parquet"), report.RUNS)
        write_table(pd.concat([r["samples"] for r in results], ignore_index=True), stage.path("errors.parquet"), report.ERRORS)
        goal_frames = [r["goals"] for r in results if r["goals"] is not None]
        if goal_frames:
            write_table(pd.concat(goal_frames, ignore_index=True), stage.path("goals.parquet"), report.GOALS,
                        tol_xy=tol_xy, tol_yaw=tol_yaw)
        names = []
        if figures:
            for fig, stem in [(report.figure_paths(results), "paths"), (report.figure_error_time(results), "error_time"),
                              (report.figure_error_distribution(results), "error_distribution"),
                              (report.figure_delay(results), "delay_cost")]:
                stage.savefig(fig, stem)
                names.append(f"{stem}.png")
            for r in results:
                stem = "timeseries_" + re.sub(r"[^A-Za-z0-9_-]+", "_", r["run"])
                stage.savefig(report.figure_timeseries(r), stem)
                names.append(f"{stem}.png")
        stage.path("results.md").write_text(report.results_markdown(runs, names, tol_xy, tol_yaw))
    for r in results:
        row = r["row"]
        d = (f"{row['delay']:.3f} s (at the edge of the search window: see the warning)" if row["delay_at_edge"]
             else f"{row['delay']:.3f} s (given)" if row["delay_method"] == "given" else f"{row['delay']:.3f} ± {row['delay_sd']:.3f} s")
        info(f"[green]{r['run']}[/green]: delay {d}, RMSE {1000 * row['ape_rmse']:.1f} mm"
             + (f", goals {row['goals_found']}/{row['goals_commanded']}" if "goals_found" in row else "")
             + (f", {len(row['warnings'].split(' | '))} warning(s) (results.md)" if row["warnings"] else ""))
    finished(STAGE, f"{len(results)} run(s)", stage.final_dir)


def _labels(bags: list[Path]) -> list[str]:
    stems = [b.stem if b.is_file() else b.name for b in bags]
    return [b.name if stems.count(s) > 1 else s for b, s in zip(bags, stems)]
