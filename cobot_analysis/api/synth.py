"""The synthetic studies (docs/methods.md sec. 1, each study's synthetic twin): a walking study and a pair-carriage study as raw C3D files
with their protocol, study file and ground truth, and a robot run as ROS bags with its truth, as ``cobot-analysis
synth walking|pairs|localisation`` write them. Unlike the other functions of the API these write files: raw
inputs of the pipeline, into the directory given (``import_markers(result.protocol)`` reads a study back,
``localise(result.bags)`` a robot run)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cobot_analysis.api.options import at_least, choose, floats, whole

#: the file each bag format is written to (``synth_localisation``'s ``formats``)
BAG_FILES = {"ros1": "run.bag", "ros2": "run_ros2", "mcap": "run.mcap"}


@dataclass
class SynthStudy:
    """A synthetic study written into ``directory``: ``protocol`` (protocol.yaml, what ``import_markers`` takes;
    study.toml, subjects.csv, trials.csv and raw/*.c3d beside it), ``truth_trials`` (table ``truth_trials``: the
    planted values per trial and entity; the per-frame truth is truth.parquet beside it)."""

    directory: Path
    protocol: Path
    study: str
    recordings: int
    truth_trials: Any  # pd.DataFrame

    def summary(self) -> str:
        return f"{self.recordings} {'trials' if self.study == 'synthetic-walking' else 'recordings'}"


@dataclass
class SynthRobotRun:
    """A synthetic robot run written into ``directory``: ``bags`` (one per format), goals.csv and truth.json
    beside them, and ``run`` (``localisation.synth.SynthRun``: the planted delay, offset, noise, goals and both
    pose streams)."""

    directory: Path
    bags: list[Path]
    run: Any  # localisation.synth.SynthRun

    def summary(self) -> str:
        run = self.run
        return f"{len(run.t_mocap)} mocap and {len(run.t_icp)} ICP poses, {run.distance:.2f} m, {len(run.goals)} goals"


def synth_options(study: str, **options: Any) -> dict[str, Any]:
    """The options of ``synth_walking``, ``synth_pairs`` or ``synth_localisation`` (``study``: walking, pairs,
    localisation) checked and spelled out (defaults filled in, ``all`` and counts as the lists they name): what
    the functions use and the stages record. A bad option is one line naming it, before anything is written.

        >>> from cobot_analysis.api.synth import synth_options
        >>> synth_options("walking", subjects=2, conditions="2")
        {'seed': 0, 'subjects': 2, 'repetitions': 3, 'conditions': ['N1500', 'E1500']}
        >>> synth_options("pairs", pairs=1, goals="d3_p7_gris", scenarios=[3])
        {'seed': 0, 'pairs': 1, 'goals': ['d3_p7_gris'], 'scenarios': [3]}
        >>> synth_options("walking", seed=-1)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --seed must be a whole number >= 0, got -1; e.g. --seed 0
        >>> synth_options("localisation", goals_per_lap=7)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --goals-per-lap must be a whole number in [1, 6], got 7; e.g. --goals-per-lap 1
    """
    from cobot_analysis.api.options import name_list, one_of
    from cobot_analysis.errors import InputError

    defaults = {
        "walking": {"seed": 0, "subjects": 10, "repetitions": 3, "conditions": "all"},
        "pairs": {"seed": 0, "pairs": 20, "goals": "all", "scenarios": "all"},
        "localisation": {"seed": 0, "laps": 1, "goals_per_lap": 6, "speed": 0.12, "delay": 0.55,
                         "offset": "0.12,-0.085,0.045,0.03", "noise": "0.006,0.006,0.003,0.004", "stop": 8.0,
                         "formats": "ros1,ros2,mcap"},
    }[one_of(study, "synthetic study", ("walking", "pairs", "localisation"))]
    unknown = sorted(set(options) - set(defaults))
    if unknown:
        raise InputError(f"unknown synth_{study} option(s) {unknown}", remedy=f"use {', '.join(defaults)}")
    o = {**defaults, **options}
    o["seed"] = whole(o["seed"], "--seed")
    if study == "walking":
        from cobot_analysis.design import WALKING_CONDITIONS

        o["subjects"], o["repetitions"] = whole(o["subjects"], "--subjects", 1), whole(o["repetitions"], "--repetitions", 1)
        o["conditions"] = choose(o["conditions"], WALKING_CONDITIONS, "--conditions")
    elif study == "pairs":
        from cobot_analysis.design import PAIR_GOALS, SCENARIOS

        o["pairs"] = whole(o["pairs"], "--pairs", 1)
        o["goals"] = choose(o["goals"], [g.stem for g in PAIR_GOALS], "--goals")
        o["scenarios"] = choose(o["scenarios"], sorted(SCENARIOS), "--scenarios", counts=False)
    else:
        o["laps"], o["goals_per_lap"] = whole(o["laps"], "--laps", 1), whole(o["goals_per_lap"], "--goals-per-lap", 1, 6)
        at_least(o["speed"], "--speed", 0.01, strict=False, example="0.12")
        for name in ("delay", "stop"):
            at_least(o[name], f"--{name}", strict=False, example=str(defaults[name]))
        o["offset"], o["noise"] = floats(o["offset"], 4, "--offset"), floats(o["noise"], 4, "--noise")
        formats = name_list(o["formats"], "--formats", example="ros1,mcap") or []
        bad = sorted(set(formats) - set(BAG_FILES))
        if bad or not formats:
            raise InputError(f"unknown format(s) {bad or formats!r}", remedy=f"use --formats {','.join(BAG_FILES)} (or some of them)")
        o["formats"] = list(dict.fromkeys(formats))
    return o


def synth_walking(directory: str | os.PathLike, *, seed: int = 0, subjects: int = 10, repetitions: int = 3,
                  conditions: str | int | list[str] = "all", jobs: int | None = None, scheduler: str | None = None) -> SynthStudy:
    """A synthetic single-walking study (``subjects`` x ``conditions`` x ``repetitions`` trials; ``conditions``:
    all 40 start conditions of walking-2020, the first N, or codes such as ``"E4015,N1500"``) written into
    ``directory``: raw/*.c3d (200 Hz, mm, 14 markers), protocol.yaml, study.toml, subjects.csv, trials.csv, the
    truth (truth.parquet, truth_trials.parquet) and results.md. Deterministic for a given ``seed``.

        >>> from cobot_analysis.api import import_markers, synth_walking
        >>> study = synth_walking("synth", subjects=1, repetitions=1, conditions="N1500", jobs=1)
        >>> study.summary(), study.protocol.name, len(study.truth_trials)
        ('1 trials', 'protocol.yaml', 1)
        >>> import_markers(study.protocol, jobs=1).summary()
        '1 trials, 11368 marker samples (1.0% occluded)'
    """
    from cobot_analysis import study as st
    from cobot_analysis.schema import read_table
    from cobot_analysis.synth import walking
    from cobot_analysis.synth.truth import TRUTH_TRIALS

    o = synth_options("walking", seed=seed, subjects=subjects, repetitions=repetitions, conditions=conditions)
    directory = Path(directory)
    protocol = walking.generate(directory, seed=o["seed"], n_subjects=o["subjects"], n_trials=o["repetitions"],
                                conditions=o["conditions"], jobs=jobs, scheduler=scheduler)
    st.write_synthetic(directory, walking.STUDY, "walking-2020")
    return SynthStudy(directory, Path(protocol), walking.STUDY, o["subjects"] * len(o["conditions"]) * o["repetitions"],
                      read_table(directory / "truth_trials.parquet", TRUTH_TRIALS))


def synth_pairs(directory: str | os.PathLike, *, seed: int = 0, pairs: int = 20, goals: str | int | list[str] = "all",
                scenarios: str | list[int] = "all", jobs: int | None = None, scheduler: str | None = None) -> SynthStudy:
    """A synthetic pair-carriage study (``pairs`` x ``goals`` x ``scenarios`` recordings, each a walk to the table,
    the forward carriage, a pause and the return; ``goals``: all 9 of pair-carriage-2022, the first N, or stems such
    as ``"d3_p7_gris"``; ``scenarios``: all, or some of 1, 2, 3) written into ``directory``: raw/*.c3d (200 Hz, mm,
    S1:/S2:/Table: labels), protocol.yaml, study.toml, subjects.csv, pairs.csv, trials.csv, the truth with the
    planted effects and results.md. Deterministic for a given ``seed``.

        >>> from cobot_analysis.api import synth_pairs
        >>> study = synth_pairs("pairs", pairs=1, goals="d3_p7_gris", scenarios=[3], jobs=1)
        >>> study.summary(), sorted(study.truth_trials["entity"].unique())
        ('1 recordings', ['subject1', 'subject2', 'table'])
        >>> synth_pairs("pairs", scenarios="4")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --scenarios: unknown value(s) ['4']; use all, or a comma-separated list of 1, 2, 3
    """
    from cobot_analysis import study as st
    from cobot_analysis.schema import read_table
    from cobot_analysis.synth import pairs as synth
    from cobot_analysis.synth.truth import TRUTH_TRIALS

    o = synth_options("pairs", seed=seed, pairs=pairs, goals=goals, scenarios=scenarios)
    directory = Path(directory)
    protocol = synth.generate(directory, seed=o["seed"], n_pairs=o["pairs"], goals=o["goals"], scenarios=o["scenarios"],
                              jobs=jobs, scheduler=scheduler)
    st.write_synthetic(directory, synth.STUDY, "synthetic-pairs")
    return SynthStudy(directory, Path(protocol), synth.STUDY, o["pairs"] * len(o["goals"]) * len(o["scenarios"]),
                      read_table(directory / "truth_trials.parquet", TRUTH_TRIALS))


def synth_localisation(directory: str | os.PathLike, *, seed: int = 0, laps: int = 1, goals_per_lap: int = 6,
                       speed: float = 0.12, delay: float = 0.55, offset: str | tuple = "0.12,-0.085,0.045,0.03",
                       noise: str | tuple = "0.006,0.006,0.003,0.004", stop: float = 8.0,
                       formats: str | list[str] = "ros1,ros2,mcap", progress=None) -> SynthRobotRun:
    """A synthetic robot run (docs/methods.md sec. 9): motion capture at 200 Hz, ICP at 10 Hz with a planted
    ``delay`` (s), structural ``offset`` (x, y, z, yaw; m, rad; ICP minus truth) and ``noise`` (sd per axis),
    ``laps`` tours through the first ``goals_per_lap`` of 6 goals at ``speed`` (m/s) stopping ``stop`` s on each,
    with goals and cmd_vel, written into ``directory`` in each of ``formats`` (ros1: run.bag, ros2: run_ros2/
    (sqlite3), mcap: run.mcap), with goals.csv and truth.json. ``progress``: as ``console.track`` (the bags written).

        >>> from cobot_analysis.api import localise, synth_localisation
        >>> robot = synth_localisation("robot", goals_per_lap=1, stop=3.0, speed=0.3, formats="mcap")
        >>> robot.summary(), [b.name for b in robot.bags]
        ('2813 mocap and 135 ICP poses, 1.67 m, 1 goals', ['run.mcap'])
        >>> localise(robot.bags).run_lines()
        ['run: delay 0.547 ± 0.003 s, RMSE 9.0 mm, goals 1/1']
    """
    from cobot_analysis.localisation import synth

    o = synth_options("localisation", seed=seed, laps=laps, goals_per_lap=goals_per_lap, speed=speed, delay=delay,
                      offset=offset, noise=noise, stop=stop, formats=formats)
    run = synth.make_run(synth.SynthParams(seed=o["seed"], laps=o["laps"], n_goals=o["goals_per_lap"], speed=o["speed"],
                                           delay=o["delay"], offset=o["offset"], noise=o["noise"], stop=o["stop"]))
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    writers = {"ros1": synth.write_ros1, "ros2": synth.write_ros2, "mcap": synth.write_mcap}
    for fmt in progress(o["formats"], "write bags") if progress else o["formats"]:
        writers[fmt](run, directory / BAG_FILES[fmt])
    synth.write_goals_csv(run, directory / "goals.csv")
    synth.write_truth(run, directory / "truth.json")
    return SynthRobotRun(directory, [directory / BAG_FILES[f] for f in o["formats"]], run)
