"""``cobot-analysis localisation``, ``bag-info`` and ``synth localisation`` (docs/methods.md sec. 9)."""

from __future__ import annotations

import gc
import os
import sys
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

    from cobot_analysis.api.localisation import bag_topics
    from cobot_analysis.console import console

    rows, edges = bag_topics(bag)
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
    laps: Annotated[int, typer.Option(help="Tours through the 6 goals (about 10 m and 2.4 min each; >= 1).")] = 1,
    goals_per_lap: Annotated[int, typer.Option(help="Goals per lap (the first N of the 6, 1-6; fewer = shorter run).")] = 6,
    speed: Annotated[float, typer.Option(help="Walking speed (m/s, >= 0.01).")] = 0.12,
    delay: Annotated[float, typer.Option(help="Planted ICP delay (s, >= 0).")] = 0.55,
    offset: Annotated[str, typer.Option(help="Planted structural offset x,y,z,yaw (m, rad), ICP minus truth.")] = "0.12,-0.085,0.045,0.03",
    noise: Annotated[str, typer.Option(help="ICP noise sd x,y,z,yaw (m, rad).")] = "0.006,0.006,0.003,0.004",
    stop: Annotated[float, typer.Option(help="Stop duration on each goal (s, >= 0).")] = 8.0,
    formats: Annotated[str, typer.Option(help="Comma list of ros1 (run.bag), ros2 (run_ros2/, sqlite3), mcap (run.mcap).")] = "ros1,ros2,mcap",
) -> None:
    """Synthetic robot run: mocap 200 Hz, ICP 10 Hz with a known delay, offset and noise, goals and
    cmd_vel, written as a ROS1 bag, a ROS2 bag and an MCAP file, with truth.json and goals.csv."""
    from cobot_analysis.stages.localisation import SYNTH_STAGE, synth_localisation

    done = synth_localisation(out, force=force, seed=seed, laps=laps, goals_per_lap=goals_per_lap, speed=speed, delay=delay,
                              offset=offset, noise=noise, stop=stop, formats=formats)
    if not done.skipped:
        finished(SYNTH_STAGE, done.result.summary(), done.directory)


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
    truth: Annotated[str, typer.Option(help="Motion-capture stream: a topic, or tf:PARENT->CHILD (TOPIC:PARENT->CHILD on a tf topic other than /tf).")] = "/mocap/pose",
    icp: Annotated[str, typer.Option(help="ICP stream: a topic, or tf:PARENT->CHILD (TOPIC:PARENT->CHILD on a tf topic other than /tf).")] = "/icp/pose",
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
    min_samples: Annotated[int, typer.Option(help="Fewest associated ICP poses accepted (>= 3).")] = 20,
    units: Annotated[str, typer.Option(help="Unit of the positions: m or mm, or TRUTH,ICP (e.g. mm,m for a motion-capture bridge publishing millimetres).")] = "m",
    join: Annotated[Optional[bool], typer.Option("--join/--no-join", help="Bags named STEM_N (rosbag record --split: run_0.bag, run_1.bag, ...) whose record times continue one another: one run (--join) or a run each (--no-join); without either they are refused.")] = None,
    figures: Annotated[bool, typer.Option("--figures/--no-figures", help="Draw the figures (PNG and PDF).")] = True,
) -> None:
    """Localisation accuracy of ICP against motion capture: delay, structural offset, per-axis errors,
    drift, goal accuracy; one row per bag in localisation.parquet, figures and results.md."""
    if "numpy" not in sys.modules:
        # One OpenBLAS thread (unless the user chose): the analysis' products are (N, 3) x (3, 3), and OpenBLAS's
        # pool of threads started at numpy's import costs 0.04 s of CPU. Set before numpy is first imported,
        # inherited by the workers; a process that has numpy already (in-process runs) is left as it is.
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from cobot_analysis.console import info
    from cobot_analysis.stages.localisation import STAGE, localisation

    # Python's cyclic garbage collector paused for the rest of the process (``cli.run`` turns it on again for an
    # in-process caller): its 180 collections (most while numpy, pandas and pyarrow are imported) cost 0.04-0.05 s
    # of CPU and free about 800 objects, 50 more per further bag; the figures' cycles wait for the end of the
    # process (peak memory +3 MiB). Turned on again here, it would go through all that the run made at once.
    gc.disable()
    done = localisation(out, bags, figures=figures, jobs=jobs, scheduler=scheduler, force=force, truth=truth, icp=icp, time=time,
                        label=label, map_name=map_name, delay=delay, delay_window=delay_window, delay_weights=delay_weights,
                        alignment=alignment, association=association, max_gap=max_gap, max_diff=max_diff, goals_csv=goals,
                        goal_topic=goal_topic, speed_threshold=speed_threshold, yaw_rate_threshold=yaw_rate_threshold,
                        min_stop=min_stop, tol_xy=tol_xy, tol_yaw=tol_yaw, distance_window=distance_window, up=up,
                        min_samples=min_samples, units=units, join=join)
    if done.skipped:
        return
    for line in done.result.run_lines(where=str(done.directory / "results.md")):
        run, _, rest = line.partition(": ")
        info(f"[green]{run}[/green]: {rest}")
    finished(STAGE, done.result.summary(), done.directory)
