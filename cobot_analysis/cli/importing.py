"""``cobot-analysis import``: raw marker files of a protocol -> markers.parquet + trials.parquet."""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Optional

import typer

from cobot_analysis.cli.app import DEFAULT_OUT_PATH, PANEL_DATA, ForceOpt, JobsOpt, OutOpt, SchedulerOpt, app, examples, finished_with_refusals


class Units(str, Enum):
    auto = "auto"
    mm = "mm"
    m = "m"


@app.command("import", rich_help_panel=PANEL_DATA, epilog=examples(
    "cobot-analysis import walking/synth-walking/protocol.yaml --out walking",
    "cobot-analysis import walking/synth-walking/protocol.yaml --out walking \\",
    "    --map L_ASIS=LASI --strict",
    "cobot-analysis import pairs/synth-pairs/protocol.yaml --out pairs"))
def import_command(
    protocol: Annotated[Path, typer.Argument(help="Protocol YAML naming each trial's file, subject/pair and condition.")],
    out: OutOpt = DEFAULT_OUT_PATH,
    marker_map: Annotated[Optional[Path], typer.Option("--marker-map", help="YAML file of 'LAB: CANON' label mappings.")] = None,
    map_: Annotated[Optional[list[str]], typer.Option("--map", help="Map a lab label to a canonical one: LAB=CANON (repeatable).")] = None,
    units: Annotated[Units, typer.Option("--units", help="Length unit of the raw files; auto = as the file states (C3D POINT:UNITS, CSV header), checked for plausibility.")] = Units.auto,
    keep_all_markers: Annotated[bool, typer.Option("--keep-all-markers", help="Keep markers the pipeline does not use (model outputs stored as C3D points, e.g. Plug-in-Gait angles and moments, are never markers).")] = False,
    skip_bad: Annotated[bool, typer.Option("--skip-bad/--strict", help="--skip-bad (default): the good trials go on, the refused ones are listed (raw file, reason, remedy) on the console, in OUT/import/results.md and manifest.json, and the exit code is 3; --strict: refuse the run (exit 2, nothing written).")] = True,
    lab_extent: Annotated[float, typer.Option("--lab-extent", help="Largest |coordinate| of a marker from the lab origin (m, at most 100: the limit of every later stage's tables); farther positions are refused as corrupt (docs/methods.md sec. 2) (>= 0).")] = 100.0,
    max_speed: Annotated[float, typer.Option("--max-speed", help="Largest marker speed between consecutive visible samples (m/s); faster jumps are refused as corrupt or mislabelled (docs/methods.md sec. 2) (>= 0).")] = 20.0,
    max_spike: Annotated[float, typer.Option("--max-spike", help="Largest distance of a sample from the midpoint of its two neighbours (m; raised below 100 Hz to what 100 g allows); larger single-sample spikes are refused as corrupt (docs/methods.md sec. 2) (>= 0).")] = 0.05,
    up: Annotated[str, typer.Option("--up", help="Vertical axis of the lab frame: auto (found from the pelvis markers; trials whose vertical is not z are rotated to z up, and the import says so), z, y (OptiTrack Motive), x, -z, -y, -x.")] = "auto",
    preprocess: Annotated[bool, typer.Option("--preprocess", help="Also run the preprocess stage (its default parameters) in the same pass: each trial is preprocessed where it is read; the same outputs as `preprocess --out OUT` after the import.")] = False,
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Import raw markers (C3D, Vicon Nexus CSV, Qualisys TSV) into OUT/import/markers.parquet
    (trial, frame, time, entity, marker, x, y, z in m, occluded) and OUT/import/trials.parquet.

    The format is detected from each file's content. Labels such as "S1:LASI" resolve to
    (subject1, LASI) through the protocol's entities and marker map (--map accepts labels as the
    file lists them, e.g. Daphnee:ASISr=RASI). Every person needs a pelvis: LASI RASI LPSI RPSI, or
    LASI RASI and one sacrum marker SACR (VSAC is read as SACR); a table needs TAB1-TAB3. Every
    trial is checked before anything is written: the bad ones are left out and listed, exit code 3
    (or, with --strict, named together and nothing written).
    """
    from cobot_analysis.io.markers import parse_map_options
    from cobot_analysis.stages import data

    options = dict(units=units.value, marker_map=parse_map_options(map_ or []), marker_map_file=marker_map,
                   keep_all_markers=keep_all_markers, skip_bad=skip_bad, lab_extent=lab_extent, max_speed=max_speed,
                   max_spike=max_spike, up=up, jobs=jobs, scheduler=scheduler, force=force)
    if not preprocess:
        finished_with_refusals("import", data.import_markers(out, protocol, **options))
        return
    done, pre = data.import_and_preprocess(out, protocol, **options)
    try:
        finished_with_refusals("import", done)
    finally:  # both summaries; the exit code says whether either stage refused trials
        finished_with_refusals("preprocess", pre)
