"""Reading data: raw marker files of a protocol, the published CoBot datasets, and preprocessing raw
markers into time-normalised trajectories (docs/methods.md sec. 1-2). Each function returns a result
holding its tables; nothing is written (``cobot_analysis.stages`` writes them into a workspace)."""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from cobot_analysis.io.markers import ImportedTrial, ImportPlan, Refused
from cobot_analysis.io.plausibility import LAB_EXTENT, MAX_SPEED, MAX_SPIKE
from cobot_analysis.metrics import data as headline
from cobot_analysis.metrics.records import Metrics, collect
from cobot_analysis.preprocess.stage import Params


@dataclass
class ImportResult:
    """Raw markers of a protocol's trials: ``markers`` (trial, frame, time, entity, marker, x, y, z in m,
    occluded), ``trials`` (one row per trial), ``meta`` (rates, units, formats, pelvis markers, skipped)."""

    plan: ImportPlan
    markers: pd.DataFrame | None  # None when the markers were streamed to ``markers_path``
    trials: pd.DataFrame
    meta: dict[str, Any]
    refused: list[Refused]
    imported: list[ImportedTrial]  # the trials imported (their arrays dropped: ``markers`` holds them)
    markers_path: Path | None = None
    n_samples: int = 0
    n_occluded: int = 0
    preprocessed: list[Any] | None = None  # with ``preprocess``: each imported trial's preprocessing, done where it was read
    preprocess_params: Params | None = None

    @property
    def notes(self) -> list[str]:
        return [n for t in self.imported for n in t.notes]

    def summary(self, where: str = "why: .refused") -> str:
        """Trials, refused ones, marker samples and the share occluded; ``where``: where the refused trials' reasons
        are (the command line: its warnings and the stage's results.md)."""
        skipped = f", {len(self.refused)} refused ({where})" if self.refused else ""
        return (f"{len(self.trials)} trials{skipped}, {self.n_samples} marker samples "
                f"({self.n_occluded / max(self.n_samples, 1):.1%} occluded)")

    def metrics(self, *, stage: str = "import") -> Metrics:
        """Headline numbers (``metrics.data.import_markers``): recordings, frames, marker samples, rate."""
        return collect(stage, headline.import_markers, self.trials, self.n_samples)


def import_markers(protocol: str | os.PathLike | ImportPlan, *, units: str = "auto", marker_map: dict[str, str] | None = None,
                   marker_map_file: str | os.PathLike | None = None, keep_all_markers: bool = False, skip_bad: bool = True,
                   lab_extent: float = LAB_EXTENT, max_speed: float = MAX_SPEED, max_spike: float = MAX_SPIKE, up: str = "auto",
                   jobs: int | None = None, scheduler: str | None = None,
                   markers_path: str | os.PathLike | None = None, preprocess: dict[str, Any] | None = None) -> ImportResult:
    """Import every trial of a protocol (C3D, Vicon Nexus CSV, Qualisys TSV; docs/protocol.md).

    ``up``: the lab's vertical axis (z, y, x, -z, -y, -x), each trial rotated to z up; ``auto`` (the default) finds it
    from the pelvis markers (``io.markers.lab_vertical``; ``result.meta["vertical"]`` says, per trial).
    Every trial is read and checked before anything is returned: with ``skip_bad`` (the default) the
    refused ones are left out and listed in ``result.refused`` (``cobot_analysis.refusals``); without
    it, or when every trial is refused, they are named together in one ``InputError``. With
    ``markers_path``, the markers are written there trial by trial as Parquet (``io.markers.stream_import``:
    memory flat in the number of trials) and ``result.markers`` is None; else they are returned in
    ``result.markers``. With ``markers_path`` and ``preprocess`` (the options of ``preprocess``, ``{}`` for
    its defaults), each worker also preprocesses the trial it has just read (``preprocess.stage.import_and_process``)
    and ``preprocess(result)`` assembles it: the same trajectories as ``preprocess(markers_path)``, without
    reading the markers back.

    A synthetic walking study of 2 subjects x 1 start condition x 1 repetition, written as C3D files:

        >>> import tempfile
        >>> from pathlib import Path
        >>> from cobot_analysis.api import import_markers
        >>> from cobot_analysis.synth import walking
        >>> tmp = tempfile.TemporaryDirectory()
        >>> protocol = walking.generate(Path(tmp.name), n_subjects=2, n_trials=1, conditions=["E4015"])
        >>> result = import_markers(protocol, jobs=1)
        >>> print(result.trials[["trial", "subject", "condition", "rate", "source_format"]].to_string(index=False))
              trial subject condition  rate source_format
        S01_E4015_1     S01     E4015 200.0           c3d
        S02_E4015_1     S02     E4015 200.0           c3d
        >>> result.meta["pelvis_markers"]["S01_E4015_1"], result.meta["source_units"]["S01_E4015_1"]
        ({'walker': ['LASI', 'RASI', 'LPSI', 'RPSI']}, 'mm')
        >>> bool(result.markers[["x", "y", "z"]].abs().max().max() < 10)   # metres, whatever the file's unit
        True
        >>> import_markers(protocol, max_spike=float("nan"))   # options checked before any file is read
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --max-spike must be >= 0, got nan; e.g. --max-spike 0.05
        >>> tmp.cleanup()
    """
    from cobot_analysis.api.options import import_limits
    from cobot_analysis.errors import InputError
    from cobot_analysis.io.markers import import_or_refuse, imported_tables, plan_import, refusal_error, repeated, stream_import
    from cobot_analysis.parallel import map_tasks

    import_limits(lab_extent, max_speed, max_spike)
    if marker_map is not None and not isinstance(marker_map, dict):
        raise InputError(f"marker_map maps the lab's marker labels to the canonical ones, as a dict; got {marker_map!r}",
                         remedy='e.g. marker_map={"L_ASIS": "LASI"} (--map L_ASIS=LASI)')
    plan = protocol if isinstance(protocol, ImportPlan) else plan_import(
        protocol, units=units, marker_map=marker_map, marker_map_file=marker_map_file, keep_all=keep_all_markers,
        skip_bad=skip_bad, lab_extent=lab_extent, max_speed=max_speed, max_spike=max_spike, up=up)
    if preprocess is not None and markers_path is None:
        raise InputError("preprocess in the same pass needs markers_path (the markers are written as they are read)",
                         remedy="pass markers_path, or call preprocess() on the import's result")
    if markers_path is not None:
        one_pass = None
        if preprocess is not None:
            from cobot_analysis.preprocess.stage import import_and_process, one_pass_items

            one_pass = Params(**preprocess)
            streamed = stream_import(plan, Path(markers_path), jobs=jobs, scheduler=scheduler, worker=import_and_process,
                                     items=one_pass_items(plan, one_pass))
        else:
            streamed = stream_import(plan, Path(markers_path), jobs=jobs, scheduler=scheduler)
        if streamed.refused and (not plan.params["skip_bad"] or not streamed.imported):
            Path(markers_path).unlink(missing_ok=True)  # a refused import leaves no file
            raise refusal_error(streamed.refused, len(plan.tasks), plan.protocol.path, "import")
        return ImportResult(plan, None, streamed.trials, streamed.meta, streamed.refused, streamed.imported, Path(markers_path),
                            streamed.n_samples, streamed.n_occluded, streamed.also if one_pass else None, one_pass)
    results = map_tasks(import_or_refuse, plan.tasks, jobs=jobs, scheduler=scheduler, description="import")
    first, files = {}, {t.trial: t.path for t in plan.tasks}
    results = [r if isinstance(r, Refused) else repeated(r, first, files) or r for r in results]
    refused = [r for r in results if isinstance(r, Refused)]
    imported: list[ImportedTrial] = [r for r in results if isinstance(r, ImportedTrial)]
    if refused and (not plan.params["skip_bad"] or not imported):
        raise refusal_error(refused, len(plan.tasks), plan.protocol.path, "import")
    markers, trials, meta = imported_tables(plan, imported, refused)
    for t in imported:  # the long table holds a copy of the arrays (their frames are kept: n_frames)
        t.xyz = np.empty((len(t.xyz), 0, 3))  # its frames only (a view would keep the samples alive)
    return ImportResult(plan, markers, trials, meta, refused, imported, None, len(markers), int(markers["occluded"].sum()))


@dataclass
class PublishedResult:
    """A published dataset as trajectories (500 samples each), with its checked facts; the pair study
    also gives ``durations`` and ``subject_wrt_table``."""

    dataset: str
    path: Path
    trajectories: pd.DataFrame
    facts: dict[str, Any]
    durations: pd.DataFrame | None = None
    subject_wrt_table: pd.DataFrame | None = None

    def metrics(self, *, stage: str = "import-published") -> Metrics:
        """Headline numbers (``metrics.data.import_published``): every fact checked against the dataset README."""
        return collect(stage, headline.import_published, self.trajectories, self.facts)

    def summary(self) -> str:
        return f"{self.dataset}: {self.trajectories.groupby(['trial', 'entity'], observed=True).ngroups} trajectories"


def import_published(dataset: str, path: str | os.PathLike, *, gamma_limit: float | None = None) -> PublishedResult:
    """Read a published CoBot dataset (``walking-2020`` or ``pair-carriage-2022``) from its folder
    (docs/methods.md sec. 1.1, 1.2); ``gamma_limit`` (rad, default 0.5) flags implausible gamma.

    The datasets are not part of the package (``import-published -h`` says where they live); reading one
    takes a few seconds, so only the checks run here:

        >>> from cobot_analysis.api import import_published
        >>> walking = import_published("walking-2020", "../shared/datasets/walking-2020")    # doctest: +SKIP
        >>> walking.summary()                                                                # doctest: +SKIP
        'walking-2020: ... trajectories'
        >>> import_published("walking-2021", "datasets/walking-2020")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: unknown dataset 'walking-2021'; use one of walking-2020, pair-carriage-2022
        >>> import_published("walking-2020", "datasets/walking-2020", gamma_limit=-0.5)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --gamma-limit must be >= 0, got -0.5; e.g. --gamma-limit 0.5
    """
    from cobot_analysis.api.options import at_least
    from cobot_analysis.errors import InputError
    from cobot_analysis.io import published as pub

    at_least(gamma_limit, "--gamma-limit", strict=False, example="0.5")
    if dataset not in pub.DATASETS:
        raise InputError(f"unknown dataset {dataset!r}", remedy=f"use one of {', '.join(pub.DATASETS)}")
    path = Path(path)
    if not path.is_dir():
        raise InputError("dataset folder not found", path=path, remedy=pub.REMEDY_DATASET)
    if dataset == pub.WALKING:
        traj, facts = pub.read_walking_2020(path, gamma_limit=pub.GAMMA_LIMIT if gamma_limit is None else gamma_limit)
        return PublishedResult(dataset, path, traj, facts)
    traj, durations, rel, facts = pub.read_pair_carriage_2022(path)
    return PublishedResult(dataset, path, traj, facts, durations, rel)


@dataclass
class PreprocessResult:
    """Trajectories (one row per trajectory and sample, ``schema.TRAJECTORIES``), the gaps of the pelvis and
    table markers, and the recordings refused (with ``skip_bad``)."""

    params: Params
    trajectories: pd.DataFrame
    gaps: pd.DataFrame
    n_recordings: int
    refused: list[Refused] = field(default_factory=list)

    def summary(self, where: str = "why: .refused") -> str:
        """Trajectories, recordings, and the refused ones (``where``: where their reasons are; the command line: its
        warnings and the stage's results.md)."""
        n = self.trajectories[["trial", "entity"]].drop_duplicates().shape[0]
        k = len(self.refused)
        refused = f", {k} recording{'s' if k != 1 else ''} refused and left out ({where})" if k else ""
        return f"{n} trajectories from {self.n_recordings} recordings{refused}"

    def params_dict(self) -> dict[str, Any]:
        return asdict(self.params)

    def metrics(self, *, stage: str = "preprocess") -> Metrics:
        """Headline numbers (``metrics.data.preprocess``): trajectories per entity and direction, travel times and
        distances, quality flags, marker gaps."""
        return collect(stage, headline.preprocess, self.trajectories, self.gaps)


def preprocess(markers: str | os.PathLike | ImportResult, trials: str | os.PathLike | None = None, *, jobs: int | None = None,
               scheduler: str | None = None, **options: Any) -> PreprocessResult:
    """Fill short gaps, low-pass filter, compute pelvis / table kinematics, segment and time-normalise the
    recordings of an import (docs/methods.md sec. 2): ``markers`` is the result of ``import_markers``, or
    the path of the ``markers.parquet`` the ``import`` stage wrote (``trials.parquet`` beside it by
    default). ``options`` are the fields of ``preprocess.stage.Params`` (``max_gap``, ``cutoff``,
    ``order``, ``order_convention``, ``n_samples`` (``--samples``), ..., ``skip_bad``), with the CLI's defaults.

        >>> import tempfile
        >>> from pathlib import Path
        >>> from cobot_analysis.api import import_markers, preprocess
        >>> from cobot_analysis.synth import walking
        >>> tmp = tempfile.TemporaryDirectory()
        >>> protocol = walking.generate(Path(tmp.name), n_subjects=2, n_trials=1, conditions=["E4015"])
        >>> result = preprocess(import_markers(protocol, jobs=1), n_samples=100, jobs=1)
        >>> result.summary()
        '2 trajectories from 2 recordings'
        >>> walks = result.trajectories
        >>> walks.groupby("trial")["sample"].count().tolist(), sorted(walks["entity"].unique())
        ([100, 100], ['walker'])
        >>> tmp.cleanup()
        >>> preprocess("import/markers.parquet")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: import/markers.parquet: file not found; pass the markers.parquet the import stage wrote, or import_markers()'s result
    """
    from cobot_analysis.errors import InputError
    from cobot_analysis.preprocess.stage import process

    unknown = sorted(set(options) - set(Params.__dataclass_fields__))
    if unknown:
        raise InputError(f"unknown preprocess option(s) {unknown}", remedy=f"use {', '.join(Params.__dataclass_fields__)}")
    p = Params(**options)
    if isinstance(markers, ImportResult) and markers.preprocessed is not None:  # preprocessed where it was imported
        from cobot_analysis.preprocess.stage import finish_one_pass

        if markers.preprocess_params != p:
            raise InputError("the import was preprocessed in the same pass with other parameters",
                             remedy="pass the same preprocess options, or preprocess the import's markers.parquet")
        path = Path(markers.markers_path)
        traj, gap_df, n, refused = finish_one_pass(markers.imported, markers.preprocessed, p, path,
                                                   Path(trials) if trials is not None else path.with_name("trials.parquet"))
        return PreprocessResult(p, traj, gap_df, n, refused)
    if isinstance(markers, ImportResult):  # the stage reads the markers from Parquet, a few columns at a time
        import tempfile

        from cobot_analysis.schema import MARKERS, TRIALS, write_table

        if trials is not None:
            raise InputError("trials is given with an import result, which holds its own trials",
                             remedy="pass the import result alone")
        with tempfile.TemporaryDirectory() as tmp:
            path = markers.markers_path or Path(tmp) / "markers.parquet"  # streamed (markers_path) or in memory
            if markers.markers is not None:
                write_table(markers.markers, path, MARKERS, **markers.meta)
            write_table(markers.trials, Path(tmp) / "trials.parquet", TRIALS, study=markers.plan.protocol.study)
            traj, gap_df, n, refused = process(path, Path(tmp) / "trials.parquet", p, jobs=jobs, scheduler=scheduler)
        return PreprocessResult(p, traj, gap_df, n, refused)
    markers = Path(markers)
    if not markers.is_file():  # named before the trials file beside it
        raise InputError("file not found", path=markers, remedy="pass the markers.parquet the import stage wrote, or import_markers()'s result")
    trials = Path(trials) if trials is not None else markers.with_name("trials.parquet")
    traj, gap_df, n, refused = process(markers, trials, p, jobs=jobs, scheduler=scheduler)
    return PreprocessResult(p, traj, gap_df, n, refused)
