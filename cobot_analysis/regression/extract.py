"""The headline numbers of each stage -> ``<stage>/metrics.json`` (what they are: ``cobot_analysis.metrics``).

A stage that ran in this process gives its API result's own numbers (``result.metrics()``, the result
the runner handed to ``workspace.Stage.result``). Otherwise ``STAGE_METRICS`` maps a stage name to a
function ``(outputs, out, params)`` that reads the tables the stage wrote (``Outputs``: the Arrow tables
and JSON the stage kept in memory as it wrote them, ``Stage.write_table`` / ``write_json``, else its
files) and passes them to the same ``cobot_analysis.metrics`` function: the synthetic studies and the
report (no API result), and a stage directory written before ``metrics.json`` existed.
``workspace.Stage`` calls ``write_stage_metrics`` inside the stage's temporary directory, so the file
appears atomically with the other outputs and is listed in the manifest.

A record (``cobot_analysis.metrics.Metric``): ``name`` (``<stage>.<what>...``, stable, e.g.
``compare.individual-mean.walker.d_xy.mean``), ``value`` (number, bool or string; NaN is not recorded),
``unit``, ``stage`` and ``convention`` (model stages only: the stage's ``convention`` parameter or
Parquet metadata, else ``continuous``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Callable

from cobot_analysis import registry
from cobot_analysis.metrics import analysis, data, localisation, models, prediction
from cobot_analysis.metrics.records import Collector, Metric, checked

METRICS_FILE = "metrics.json"
FORMAT = "cobot-analysis-metrics/1"
DEFAULT_CONVENTION = "continuous"

__all__ = ["FORMAT", "METRICS_FILE", "Metric", "Outputs", "STAGE_METRICS", "read_stage_metrics", "stage_metrics",
           "workspace_metrics", "write_stage_metrics"]


class Outputs:
    """A stage's outputs as its metrics read them: the tables and JSON documents the stage kept in memory as it
    wrote them (``Stage.write_table`` / ``write_json``), else the files of its directory."""

    def __init__(self, directory: Path, memory: dict[str, Any] | None = None):
        self.directory, self.memory = Path(directory), memory or {}

    def exists(self, name: str) -> bool:
        return name in self.memory or (self.directory / name).is_file()

    def table(self, name: str, columns: list[str] | None = None, sample0: bool = False):
        """A Parquet table as pandas (only the ``columns`` that exist; ``sample0``: the rows of sample 0)."""
        import pyarrow.compute as pc
        import pyarrow.parquet as pq

        table = self.memory.get(name)
        if table is None:
            names = pq.read_schema(self.directory / name).names
            cols = None if columns is None else [c for c in columns if c in names]
            table = pq.read_table(self.directory / name, columns=cols, filters=[("sample", "=", 0)] if sample0 else None)
        else:
            if columns is not None:
                table = table.select([c for c in columns if c in table.column_names])
            if sample0:
                table = table.filter(pc.equal(table["sample"], 0))
        df = table.to_pandas()
        df.attrs = {}
        return df

    def rows(self, name: str) -> int:
        import pyarrow.parquet as pq

        return self.memory[name].num_rows if name in self.memory else pq.ParquetFile(self.directory / name).metadata.num_rows

    def json(self, name: str) -> Any:
        return json.loads(self.memory[name] if name in self.memory else (self.directory / name).read_text())

    def csv(self, name: str):
        import pandas as pd

        return pd.read_csv(self.directory / name)

    def count(self, pattern: str) -> int:
        return sum(1 for _ in self.directory.glob(pattern))


# ---- per stage: its outputs -> cobot_analysis.metrics ------------------------------------------------
def _synth_study(d: Outputs, out: Collector, params: dict) -> None:
    import yaml

    proto = yaml.safe_load((d.directory / "protocol.yaml").read_text()) or {}
    entities = {name: len(d.csv(f"{name}.csv")) for name in ("subjects", "pairs") if d.exists(f"{name}.csv")}
    data.synth_study(out, proto.get("study"), len(d.csv("trials.csv")), entities, d.table("truth_trials.parquet"))


def _synth_localisation(d: Outputs, out: Collector, params: dict) -> None:
    data.synth_localisation(out, d.json("truth.json"), d.count("run*"))


def _import(d: Outputs, out: Collector, params: dict) -> None:
    data.import_markers(out, d.table("trials.parquet"), d.rows("markers.parquet"))


def _import_published(d: Outputs, out: Collector, params: dict) -> None:
    data.import_published(out, d.table("trajectories.parquet", ["study"]), d.json("facts.json") if d.exists("facts.json") else {})


def _preprocess(d: Outputs, out: Collector, params: dict) -> None:
    t = d.table("trajectories.parquet", ["study", "entity", "direction", "quality", "travel_time", "travelled_distance", "sample"],
                sample0=True)
    data.preprocess(out, t, d.table("gaps.parquet") if d.exists("gaps.parquet") else None)


def _average(d: Outputs, out: Collector, params: dict) -> None:
    analysis.average(out, d.table("means.parquet", ["study", "trial", "entity", "sample", "n_trials", "n_theta", "x_sd", "y_sd",
                                                    "travelled_distance", "travel_time"]))


def _compare(d: Outputs, out: Collector, params: dict) -> None:
    analysis.compare(out, d.table("distances.parquet", ["study", "comparison", "entity", "d_xy", "d_theta", "d_gamma"]))


def _stats(d: Outputs, out: Collector, params: dict) -> None:
    analysis.statistics(out, d.table("stats.parquet"))


def _reconstruct(d: Outputs, out: Collector, params: dict) -> None:
    analysis.reconstruct(out, d.table("reconstruction.parquet"))


def _fit_ioc(d: Outputs, out: Collector, params: dict) -> None:
    models.fit_ioc(out, d.json("weights.json"), d.table("distances.parquet") if d.exists("distances.parquet") else None)


def _generate(d: Outputs, out: Collector, params: dict) -> None:
    g = d.table("generated.parquet", ["trial", "model", "sample", "x", "y", "travel_time", "cost"])
    models.generate(out, g, params.get("models", []), params.get("cases", []))


def _predict(d: Outputs, out: Collector, params: dict) -> None:
    p = d.table("predictions.parquet", ["study", "trial", "entity", "n0", "n_oc", "predictor", "n_used", "n_skipped", "n_failed"])
    prediction.predict(out, p, d.table("prediction_summary.parquet"), d.table("prediction_comparison.parquet"))


def _localisation(d: Outputs, out: Collector, params: dict) -> None:
    localisation.localisation(out, d.table("localisation.parquet"))


def _report(d: Outputs, out: Collector, params: dict) -> None:
    """report: the figures drawn."""
    out.count("figures", d.count("*.png"))


def _velocity_commands(d: Outputs, out: Collector, params: dict) -> None:
    models.velocity_commands(out, d.csv("commands.csv") if d.exists("commands.csv") else d.table("commands.parquet"))


STAGE_METRICS: dict[str, Callable[[Outputs, Collector, dict], None]] = {
    "synth-walking": _synth_study, "synth-pairs": _synth_study, "synth-localisation": _synth_localisation,
    "import": _import, "import-published": _import_published, "preprocess": _preprocess, "average": _average,
    "compare": _compare, "stats": _stats, "reconstruct": _reconstruct, "fit-ioc": _fit_ioc, "fit-ioc-subjects": _fit_ioc,
    "fit-ioc-coupled": _fit_ioc, "generate": _generate, "predict": _predict, "localisation": _localisation,
    "report": _report, "velocity-commands": _velocity_commands,
}


def extractor(stage: str) -> Callable | None:
    """The metric function of a stage directory (``predict-<label>`` stages share ``predict``'s; a
    ``-published`` directory its base stage's)."""
    return STAGE_METRICS.get(registry.spec(registry.base_stage(stage)).name) if registry.known(stage) else None


def _find_key(obj: Any, key: str) -> Any:
    if isinstance(obj, dict):
        if key in obj:
            return obj[key]
        for v in obj.values():
            found = _find_key(v, key)
            if found is not None:
                return found
    return None


def stage_convention(stage: str, stage_dir: Path, params: dict) -> str | None:
    """Model stages: the ``convention`` of the stage's parameters, else of its Parquet metadata, else
    ``continuous``; None for the other stages."""
    if not registry.is_model_stage(stage):
        return None
    conv = _find_key(params, "convention")
    if conv is None:
        from cobot_analysis.schema import table_metadata

        for p in sorted(stage_dir.glob("*.parquet")):
            try:
                conv = table_metadata(p).get("convention")
            except Exception:  # noqa: BLE001 - an unreadable table has no convention to give
                conv = None
            if conv is not None:
                break
    return str(conv) if conv is not None else DEFAULT_CONVENTION


def stage_metrics(stage: str, stage_dir: Path, params: dict | None = None, memory: dict[str, Any] | None = None,
                  result: Any = None) -> dict[str, Any] | None:
    """The content of ``metrics.json`` for a stage directory, or None for a stage without metrics: the
    ``result``'s own numbers (``result.metrics(stage=...)``, the API result of the run), else read from its
    outputs (``memory``: the outputs the stage kept as it wrote them, ``Stage.outputs``, read before the files)."""
    fn = extractor(stage)
    if fn is None:
        return None
    if hasattr(result, "metrics"):
        items = result.metrics(stage=stage)
        study, convention = items.study, items.convention
    else:
        params = params or {}
        out = Collector(stage, stage_convention(stage, Path(stage_dir), params))
        fn(Outputs(Path(stage_dir), memory), out, params)
        items, study, convention = checked(out.items), out.study, out.convention
    return {"format": FORMAT, "stage": stage, "study": study, "convention": convention, "metrics": [m.to_json() for m in items]}


def write_stage_metrics(stage: str, stage_dir: Path, params: dict | None = None, memory: dict[str, Any] | None = None,
                        result: Any = None) -> None:
    """Write ``stage_dir/metrics.json`` (``stage_metrics``); an extraction error is recorded there (and warned
    about), never raised: the stage's own outputs stand, and ``metrics check`` reports the missing numbers."""
    from cobot_analysis.console import warn

    try:
        payload = stage_metrics(stage, Path(stage_dir), params, memory, result)
    except Exception as exc:  # noqa: BLE001 - see docstring
        warn(f"{stage}: metrics.json records an error instead of the metrics ({type(exc).__name__}: {exc})")
        try:
            conv = stage_convention(stage, Path(stage_dir), params or {})
        except Exception:  # noqa: BLE001 - the stage's outputs are what failed to read
            conv = None
        payload = {"format": FORMAT, "stage": stage, "study": None, "convention": conv, "metrics": [],
                   "error": f"{type(exc).__name__}: {exc}"}
    if payload is not None:
        (Path(stage_dir) / METRICS_FILE).write_text(json.dumps(payload, indent=1) + "\n")


def read_stage_metrics(stage_dir: Path) -> dict[str, Any] | None:
    """A stage directory's metrics: its ``metrics.json``, or (a stage written before metrics.json
    existed) computed now from its outputs and manifest parameters. None: not a stage with metrics."""
    from cobot_analysis.errors import InputError

    f = stage_dir / METRICS_FILE
    if f.is_file():
        try:
            payload = json.loads(f.read_text())
            if not isinstance(payload, dict) or not isinstance(payload.get("metrics"), list):
                raise ValueError("no list of metrics")
            return payload
        except ValueError as exc:
            raise InputError(f"not a valid metrics file ({exc})", path=f,
                             remedy=f"re-run the stage with --force (cobot-analysis {stage_dir.name} --force ...)") from None
    manifest = stage_dir / "manifest.json"
    if not manifest.is_file() or extractor(stage_dir.name) is None:
        return None
    try:
        params = json.loads(manifest.read_text()).get("params") or {}
    except ValueError:
        params = {}
    try:
        payload = stage_metrics(stage_dir.name, stage_dir, params)
    except Exception as exc:  # noqa: BLE001 - reported like a recorded extraction error
        payload = {"format": FORMAT, "stage": stage_dir.name, "study": None, "convention": None, "metrics": [],
                   "error": f"{type(exc).__name__}: {exc}"}
    return payload


def workspace_metrics(workspace: Path) -> list[dict[str, Any]]:
    """The metrics payload of every stage of a workspace, in pipeline order."""
    from cobot_analysis.errors import InputError

    workspace = Path(workspace)
    if not workspace.is_dir():
        raise InputError("workspace not found", path=workspace, remedy="run the study's stages with this --out first")
    payloads = []
    for d in sorted(p for p in workspace.iterdir() if p.is_dir() and not p.name.startswith(".")):
        payload = read_stage_metrics(d)
        if payload is not None:
            payload["workspace"] = str(workspace)
            payloads.append(payload)
    payloads.sort(key=lambda p: (registry.order(p["stage"]), p["stage"]))
    return payloads
