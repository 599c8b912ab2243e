"""``cobot-analysis synth walking`` and ``synth pairs``: deterministic synthetic studies (raw C3D + truth)."""

from __future__ import annotations

from typing import Annotated

import typer

from cobot_analysis.cli.app import DEFAULT_OUT_PATH, ForceOpt, JobsOpt, OutOpt, SchedulerOpt, SeedOpt, examples, finished, synth_app


@synth_app.command("walking", epilog=examples(
    "cobot-analysis synth walking --out walking --subjects 2 --repetitions 1 \\",
    "    --conditions N1500,E1515",
    "cobot-analysis synth walking --out walking2 --subjects 1 --repetitions 1 \\",
    "    --conditions 2 --seed 7"))
def walking_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    seed: SeedOpt = 0,
    subjects: Annotated[int, typer.Option("--subjects", help="Number of subjects (>= 1).")] = 10,
    repetitions: Annotated[int, typer.Option("--repetitions", help="Trials of each subject per start condition (>= 1).")] = 3,
    conditions: Annotated[str, typer.Option("--conditions", help="Start conditions: all, N (the first N of the design), or codes like E4015,N1500.")] = "all",
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Synthetic single-walking study (10 subjects x 40 start conditions x 3 trials by default).

    Writes OUT/synth-walking/: protocol.yaml (each key explained in a comment; docs/protocol.md),
    trials.csv, subjects.csv, raw/*.c3d (200 Hz, mm, 14 markers), truth.parquet (true CoM and
    pelvis orientation per frame), truth_trials.parquet.
    """
    from cobot_analysis.stages import data

    done = data.synth_walking(out, seed=seed, subjects=subjects, repetitions=repetitions, conditions=conditions, jobs=jobs,
                              scheduler=scheduler, force=force)
    if not done.skipped:
        finished("synth-walking", done.result.summary(), done.directory)


@synth_app.command("pairs", epilog=examples(
    "cobot-analysis synth pairs --out pairs --pairs 1 --goals 1 --scenarios 3",
    "cobot-analysis synth pairs --out pairs2 --pairs 1 --goals d3_p7_gris \\",
    "    --scenarios 1,3"))
def pairs_command(
    out: OutOpt = DEFAULT_OUT_PATH,
    seed: SeedOpt = 0,
    pairs: Annotated[int, typer.Option("--pairs", help="Number of pairs (2 subjects each; >= 1).")] = 20,
    goals: Annotated[str, typer.Option("--goals", help="Goals: all, N (the first N of the design), or stems like d1_p4_gris,d3_p7_gris.")] = "all",
    scenarios: Annotated[str, typer.Option("--scenarios", help="Scenarios of the forward carriage: all or a list like 1,3 (1 = S1 leader, 2 = S2 leader, 3 = both know).")] = "all",
    jobs: JobsOpt = None,
    scheduler: SchedulerOpt = None,
    force: ForceOpt = False,
) -> None:
    """Synthetic pair-carriage study (20 pairs x 9 goals x 3 scenarios = 540 recordings by default).

    Each recording holds walk-to-table, forward carriage, pause and return carriage. Writes
    OUT/synth-pairs/: protocol.yaml (each key explained in a comment; docs/protocol.md), trials.csv,
    subjects.csv, pairs.csv, raw/*.c3d (200 Hz, mm, S1:/S2:/Table: labels), truth.parquet,
    truth_trials.parquet (with the planted effects).
    """
    from cobot_analysis.stages import data

    done = data.synth_pairs(out, seed=seed, pairs=pairs, goals=goals, scenarios=scenarios, jobs=jobs, scheduler=scheduler,
                            force=force)
    if not done.skipped:
        finished("synth-pairs", done.result.summary(), done.directory)
