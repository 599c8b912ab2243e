"""``cobot-analysis preprocess``: raw markers -> time-normalised trajectories (docs/methods.md sec. 2)."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import PANEL_PROCESS, DEFAULT_OUT_PATH, ForceOpt, JobsOpt, OutOpt, SchedulerOpt, app, examples, finished_with_refusals


class OrderConvention(str, Enum):
    design = "design"
    effective = "effective"


class OrientationMarkers(str, Enum):
    pelvis = "pelvis"
    asis = "asis"


@app.command("preprocess", rich_help_panel=PANEL_PROCESS, epilog=examples(
    "cobot-analysis preprocess --out walking",
    "cobot-analysis preprocess --out walking --cutoff 6 --max-gap 0.2",
    "cobot-analysis preprocess --out pairs --keep-approach"))
def preprocess_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    markers: Annotated[Optional[Path], typer.Option("--markers", help="markers.parquet (default: OUT/import/markers.parquet).")] = None,
    trials: Annotated[Optional[Path], typer.Option("--trials", help="trials.parquet (default: beside the markers file).")] = None,
    max_gap: Annotated[float, typer.Option("--max-gap", help="Longest gap filled by cubic spline (s); longer gaps stay missing (>= 0).")] = 0.1,
    cutoff: Annotated[float, typer.Option("--cutoff", help="Low-pass cut-off (Hz) (> 0).")] = 10.0,
    order: Annotated[int, typer.Option("--order", help="Butterworth order (see --order-convention) (>= 1).")] = 4,
    order_convention: Annotated[OrderConvention, typer.Option(
        "--order-convention",
        help="effective: ORDER/2 design run forward-backward, cut-off corrected (Winter) so the zero-phase "
             "result is ORDER-th order with -3 dB at the cut-off; design: ORDER-th order design run "
             "forward-backward (effective order 2*ORDER, -6 dB at the cut-off).")] = OrderConvention.effective,
    samples: Annotated[int, typer.Option("--samples", "-n", help="Samples per time-normalised trajectory (endpoints included) (>= 2).")] = 500,
    lift_threshold: Annotated[float, typer.Option("--lift-threshold", help="Pair study: table height above the floor level that marks a carriage (m) (>= 0).")] = 0.005,
    floor_window: Annotated[float, typer.Option("--floor-window", help="Pair study: floor level = median table height over the first seconds (this many) in which the table is seen (>= 0).")] = 0.5,
    min_set_down: Annotated[float, typer.Option("--min-set-down", help="Pair study: two lifts of the table set down for less than this (s) between them are one carriage (the carriers re-grip it); 0: never (>= 0).")] = 0.0,
    speed_threshold: Annotated[float, typer.Option("--speed-threshold", help="Walking: CoM speed that marks walking (m/s) (>= 0).")] = 0.1,
    rest_speed: Annotated[float, typer.Option("--rest-speed", help="Walking: the walk is extended to where the CoM speed falls below this (m/s) (>= 0).")] = 0.05,
    min_duration: Annotated[float, typer.Option("--min-duration", help="Shortest carriage / walk kept (s); shorter runs are ignored (>= 0).")] = 0.5,
    min_rest: Annotated[float, typer.Option("--min-rest", help="Walking: standing still this long (s, below --rest-speed) between two walks of a recording makes them two walks: the first is the trial, the later ones (e.g. back to the start) are left out and the trial flagged 'later_walks' (>= 0).")] = 1.0,
    gamma_min_speed: Annotated[float, typer.Option("--gamma-min-speed", help="Below this speed (m/s) gamma holds its last well-defined value (>= 0).")] = 0.1,
    keep_approach: Annotated[bool, typer.Option("--keep-approach", help="Pair study: also keep each subject's walk to the table as a trial '<recording>_approach'.")] = False,
    orientation_markers: Annotated[OrientationMarkers, typer.Option(
        "--orientation-markers",
        help="pelvis: a long gap on any pelvis marker used (LASI RASI LPSI RPSI, or LASI RASI SACR) makes theta/gamma "
             "missing for the trajectory; asis: only a gap on LASI or RASI does (theta needs only them).")] = OrientationMarkers.pelvis,
    skip_bad: Annotated[bool, typer.Option("--skip-bad/--strict", help="--skip-bad (default): the good recordings go on, the refused ones are listed (raw file, reason, remedy) on the console, in OUT/preprocess/results.md and manifest.json, and the exit code is 3; --strict: refuse the run (exit 2, nothing written).")] = True,
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Fill short gaps, low-pass filter, compute pelvis/table kinematics, segment and time-normalise.

    Reads OUT/import/markers.parquet and trials.parquet; writes OUT/preprocess/trajectories.parquet
    (one row per trajectory and sample, with the pelvis markers used), gaps.parquet (every gap of
    the pelvis and table markers) and results.md (gap and quality summary). A walk or carriage that
    runs off the start or end of its recording is flagged 'truncated'; a walking recording holding more walks
    (e.g. back to the start) keeps the first, flagged 'later_walks'.
    """
    from cobot_analysis.stages import data

    done = data.preprocess(out, markers=markers, trials=trials, max_gap=max_gap, cutoff=cutoff, order=order,
                           order_convention=order_convention.value, n_samples=samples, lift_threshold=lift_threshold,
                           floor_window=floor_window, min_set_down=min_set_down, speed_threshold=speed_threshold, rest_speed=rest_speed,
                           min_duration=min_duration, min_rest=min_rest, gamma_min_speed=gamma_min_speed, keep_approach=keep_approach,
                           orientation_markers=orientation_markers.value, skip_bad=skip_bad, jobs=jobs, scheduler=scheduler,
                           force=force)
    finished_with_refusals("preprocess", done)
