"""The headline numbers of each stage, from the stage's own outputs -> ``<stage>/metrics.json``.

``STAGE_METRICS`` maps a stage name to a function ``(outputs, out, params)`` that reads the tables
the stage wrote (``Outputs``: the Arrow tables and JSON the stage kept in memory as it wrote them,
``Stage.write_table`` / ``write_json``, else its files) and adds metric records to ``out``: the numbers
``docs/results.md`` reports (distances mean and sd, test statistics and p, fitted D and weights,
prediction errors, localisation delay, offsets, errors, goals) and the counts behind them.
``workspace.Stage`` calls ``write_stage_metrics`` inside the stage's temporary directory, so the
file appears atomically with the other outputs and is listed in the manifest.

A record: ``name`` (``<stage>.<what>...``, stable, e.g. ``compare.individual-mean.walker.d_xy.mean``),
``value`` (number, bool or string; NaN is not recorded), ``unit``, ``stage`` and ``convention``
(model stages only: the stage's ``convention`` parameter or Parquet metadata, else ``continuous``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from cobot_analysis import registry

METRICS_FILE = "metrics.json"
FORMAT = "cobot-analysis-metrics/1"
DEFAULT_CONVENTION = "continuous"
LOCALISATION_STUDY = "localisation"


@dataclass(frozen=True)
class Metric:
    name: str
    value: Any
    unit: str
    stage: str
    convention: str | None = None

    @property
    def key(self) -> str:
        """The identity compared with a baseline: the name, with ``@convention`` for model stages."""
        return self.name if self.convention is None else f"{self.name}@{self.convention}"

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "value": self.value, "unit": self.unit, "stage": self.stage, "convention": self.convention}

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> "Metric":
        return cls(str(d["name"]), d.get("value"), str(d.get("unit", "")), str(d["stage"]), d.get("convention"))


def plain(value: Any) -> Any:
    """A JSON value: Python bool/int/float/str; NaN, inf and None -> None."""
    if value is None:
        return None
    if isinstance(value, str):
        return value
    try:
        import numpy as np

        if isinstance(value, np.generic):
            value = value.item()
    except ImportError:  # pragma: no cover - numpy is a dependency
        pass
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return str(value)


def _part(v: Any) -> str:
    if isinstance(v, float) and v.is_integer():
        v = int(v)
    return str(v)


class Collector:
    """Metric records of one stage (names prefixed by the stage name)."""

    def __init__(self, stage: str, convention: str | None):
        self.stage, self.convention = stage, convention
        self.prefix = registry.base_stage(stage)  # a stage and its -published twin name their metrics alike (@convention apart)
        self.study: str | None = None
        self.items: list[Metric] = []

    def add(self, name: str | tuple, value: Any, unit: str = "") -> None:
        v = plain(value)
        if v is None:
            return
        parts = name if isinstance(name, tuple) else (name,)
        full = ".".join([self.prefix, *(_part(p) for p in parts if p is not None and p != "")])
        self.items.append(Metric(full, v, unit, self.stage, self.convention))

    def count(self, name: str | tuple, value: Any) -> None:
        self.add(name, None if value is None else int(value), "count")

    def mean_sd(self, name: tuple, values, unit: str, n: bool = False) -> None:
        """Mean and sample sd (ddof 1) of the finite values; with ``n`` also their number."""
        import numpy as np

        v = np.asarray(values, dtype=float)
        v = v[np.isfinite(v)]
        if n:
            self.count((*name, "n"), len(v))
        if len(v):
            self.add((*name, "mean"), float(v.mean()), unit)
        if len(v) > 1:
            self.add((*name, "sd"), float(v.std(ddof=1)), unit)


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


def _study(df) -> str | None:
    if "study" not in df:
        return None
    studies = sorted(str(s) for s in df["study"].dropna().unique())
    return "+".join(studies) if studies else None


def _groups(df, keys: list[str], fmt: dict[str, str] | None = None):
    """``groupby`` over the keys that exist and are not all null, yielding (name parts, group);
    ``fmt`` formats a key's values (e.g. ``{"scenario": "s{}"}``); a null level is named ``-``."""
    keys = [k for k in keys if k in df and df[k].notna().any()]
    if not keys:
        yield (), df
        return
    import pandas as pd

    fmt = fmt or {}
    for key, g in df.groupby(keys, dropna=False, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        parts = tuple("-" if pd.isna(v) else fmt.get(k, "{}").format(_part(v)) for k, v in zip(keys, key))
        yield parts, g


# ---- per stage ---------------------------------------------------------------------------------------
def _synth_study(d: Outputs, out: Collector, params: dict) -> None:
    """synth-walking / synth-pairs: design counts, true travel times and paths, planted losses."""
    import yaml

    proto = yaml.safe_load((d.directory / "protocol.yaml").read_text()) or {}
    out.study = proto.get("study")
    out.count("recordings", len(d.csv("trials.csv")))
    for name in ("subjects", "pairs"):
        if d.exists(f"{name}.csv"):
            out.count(name, len(d.csv(f"{name}.csv")))
    tt = d.table("truth_trials.parquet")
    for key, g in _groups(tt, ["entity", "segment", "scenario"], {"scenario": "s{}"}):
        out.count((*key, "n"), len(g))
        out.mean_sd((*key, "travel_time"), g["travel_time"], "s")
        out.add((*key, "path_length", "mean"), g["path_length"].mean(), "m")
        out.add((*key, "peak_speed", "mean"), g["peak_speed"].mean(), "m/s")
        out.count((*key, "orientation_lost"), g["orientation_lost"].sum())
        if "optimal" in g and g["optimal"].notna().any():
            out.add((*key, "optimal", "share"), g["optimal"].astype(float).mean())


def _synth_localisation(d: Outputs, out: Collector, params: dict) -> None:
    """synth-localisation: length of the run, poses, goals and the realised ICP noise."""
    out.study = LOCALISATION_STUDY
    truth = d.json("truth.json")
    out.add("distance", truth.get("distance"), "m")
    out.add("duration", truth.get("duration"), "s")
    out.count("mocap_poses", truth.get("n_mocap"))
    out.count("icp_poses", truth.get("n_icp"))
    out.count("goals", len(truth.get("goals", [])))
    out.add("delay", truth.get("delay"), "s")
    for axis, r in (truth.get("noise_realised") or {}).items():
        out.add(("noise", axis, "rmse"), r.get("rmse"), "rad" if axis == "yaw" else "m")
    out.count("bags", d.count("run*"))


def _import(d: Outputs, out: Collector, params: dict) -> None:
    """import: recordings, frames, marker samples, sampling rate."""

    trials = d.table("trials.parquet")
    out.study = _study(trials)
    out.count("recordings", len(trials))
    out.count("frames", trials["n_frames"].sum())
    out.add(("rate", "median"), trials["rate"].median(), "Hz")
    out.count("marker_samples", d.rows("markers.parquet"))


def _flatten(out: Collector, prefix: tuple, value: Any) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(out, (*prefix, k), v)
    elif isinstance(value, list):
        if all(isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in value):
            out.add(prefix, ",".join(_part(v) for v in value))
        else:
            out.count((*prefix, "n"), len(value))
    elif isinstance(value, bool) or isinstance(value, str):
        out.add(prefix, value)
    elif isinstance(value, int):
        out.count(prefix, value)
    else:
        out.add(prefix, value)


def _import_published(d: Outputs, out: Collector, params: dict) -> None:
    """import-published: every fact the stage checked against the dataset README (facts.json)."""
    out.study = _study(d.table("trajectories.parquet", ["study"]))
    facts = d.json("facts.json") if d.exists("facts.json") else {}
    for k, v in facts.items():
        _flatten(out, ("facts", k), v)


def _preprocess(d: Outputs, out: Collector, params: dict) -> None:
    """preprocess: trajectories per entity, travel times, distances, quality flags and marker gaps."""
    t = d.table("trajectories.parquet", ["study", "entity", "direction", "quality", "travel_time", "travelled_distance",
                                               "theta", "sample"], sample0=True)
    out.study = _study(t)
    out.count("trajectories", len(t))
    for key, g in _groups(t, ["entity", "direction"]):
        out.count((*key, "trajectories"), len(g))
        out.mean_sd((*key, "travel_time"), g["travel_time"], "s")
        out.mean_sd((*key, "travelled_distance"), g["travelled_distance"], "m")
    flags: dict[str, int] = {}
    for q in t["quality"].fillna(""):
        for f in filter(None, str(q).split(";")):
            flags[f] = flags.get(f, 0) + 1
    for f, n in sorted(flags.items()):
        out.count(("quality", f), n)
    if d.exists("gaps.parquet"):
        gaps = d.table("gaps.parquet")
        filled = gaps["filled"].astype(bool)
        out.count(("gaps", "total"), len(gaps))
        out.count(("gaps", "filled"), filled.sum())
        out.count(("gaps", "open"), (~filled).sum())
        out.count(("gaps", "open_frames"), gaps.loc[~filled, "n_frames"].sum())


def _average(d: Outputs, out: Collector, params: dict) -> None:
    """average: mean trajectories per entity, trials behind them, spread of the individual paths."""
    m = d.table("means.parquet", ["study", "trial", "entity", "sample", "n_trials", "n_theta", "x_sd", "y_sd",
                                       "travelled_distance", "travel_time"])
    out.study = _study(m)
    first = m[m["sample"] == 0]
    out.count("means", len(first))
    for key, g in _groups(m, ["entity"]):
        f = g[g["sample"] == 0]
        out.count((*key, "means"), len(f))
        out.count((*key, "trials"), f["n_trials"].sum())
        out.count((*key, "without_orientation"), (f["n_theta"] == 0).sum())
        out.add((*key, "x_sd", "mean"), g["x_sd"].mean(), "m")
        out.add((*key, "y_sd", "mean"), g["y_sd"].mean(), "m")
        out.add((*key, "travelled_distance", "mean"), f["travelled_distance"].mean(), "m")
        out.add((*key, "travel_time", "mean"), f["travel_time"].mean(), "s")


def _compare(d: Outputs, out: Collector, params: dict) -> None:
    """compare: d_xy, d_theta, d_gamma mean and sd per comparison and entity (docs/methods.md sec. 3)."""
    dist = d.table("distances.parquet", ["study", "comparison", "entity", "d_xy", "d_theta", "d_gamma"])
    out.study = _study(dist)
    for key, g in _groups(dist, ["comparison", "entity"]):
        out.count((*key, "n"), len(g))
        out.mean_sd((*key, "d_xy"), g["d_xy"], "m")
        for c in ("d_theta", "d_gamma"):
            out.mean_sd((*key, c), g[c], "rad", n=True)


def _stats(d: Outputs, out: Collector, params: dict) -> None:
    """stats: per question, the test run, n, statistic, p, Holm p, effect size; or why it was skipped."""
    s = d.table("stats.parquet")
    out.study = _study(s)
    ok = s["status"].eq("ok")
    out.count("tests_run", ok.sum())
    out.count("significant", s["significant"].fillna(False).astype(bool).sum())
    for _, r in s.iterrows():
        key = str(r["id"])
        if r["status"] != "ok":
            out.add((key, "status"), r["status"])
            continue
        out.add((key, "test"), r["test"])
        out.count((key, "n"), r["n"])
        for c in ("statistic", "p", "p_holm", "effect_size"):
            out.add((key, c), r[c])
        if r["test"] not in ("describe", "largest_subset"):
            out.add((key, "significant"), bool(r["significant"]))


def _reconstruct(d: Outputs, out: Collector, params: dict) -> None:
    """reconstruct: accuracy of the subjects rebuilt from the table (docs/methods.md sec. 8)."""
    rec = d.table("reconstruction.parquet")
    out.study = _study(rec)
    for key, g in _groups(rec, ["relative_pose", "kind", "direction", "entity"]):
        out.count((*key, "n"), len(g))
        out.mean_sd((*key, "d_xy"), g["d_xy"], "m")
        out.mean_sd((*key, "d_theta"), g["d_theta"], "rad")


def _fit_ioc(d: Outputs, out: Collector, params: dict) -> None:
    """fit-ioc (and -subjects, -coupled): D at the start and fitted, evaluations, fitted weights;
    distances of each compared model to the means (docs/methods.md sec. 6)."""
    w = d.json("weights.json")
    for fit, r in (w.get("fits") or {}).items():
        per = r.get("per_target") or []
        out.count((fit, "paths"), len(per))
        out.add((fit, "D", "start"), r.get("start_objective"))
        out.add((fit, "D", "fitted"), r.get("objective"))
        out.count((fit, "evaluations"), r.get("evaluations"))
        out.count((fit, "not_converged"), r.get("failed"))
        out.count((fit, "T_at_bound"), sum(1 for p in per if p.get("T_at_bound")))
        for name in (r.get("spec") or {}).get("fitted", []):
            out.add((fit, "weights", name), (r.get("weights") or {}).get(name))
    if d.exists("distances.parquet"):
        dist = d.table("distances.parquet")
        keys = ["model", *(["fit"] if out.stage == "fit-ioc-subjects" else []), "carrier"]
        for key, g in _groups(dist, keys, {"carrier": "carrier{}"}):
            out.count(("distances", *key, "n"), len(g))
            out.mean_sd(("distances", *key, "d_xy"), g["d_xy"], "m")
            for c in ("d_theta", "d_gamma"):
                out.mean_sd(("distances", *key, c), g[c], "rad")
            out.add(("distances", *key, "D", "mean"), g["D"].mean() if "D" in g else None)


def _generate(d: Outputs, out: Collector, params: dict) -> None:
    """generate: per model, paths, duration T, optimal cost and end error to the goal."""
    import numpy as np

    g = d.table("generated.parquet", ["trial", "model", "sample", "x", "y", "travel_time", "cost"])
    ends = g.sort_values("sample").groupby("trial").tail(1)
    # each case's goal (params: cases = [condition, start, goal]; trial = model_condition, or model)
    goals = {f"{m}_{c}" if c else m: goal for m in params.get("models", []) for c, _, goal in params.get("cases", [])}
    for key, e in _groups(ends, ["model"]):
        out.count((*key, "paths"), len(e))
        out.mean_sd((*key, "T"), e["travel_time"], "s")
        out.mean_sd((*key, "cost"), e["cost"], "")
        known = e[e["trial"].isin(list(goals))]
        if len(known):
            err = [np.hypot(r.x - goals[r.trial][0], r.y - goals[r.trial][1]) for r in known.itertuples()]
            out.add((*key, "end_error", "max"), float(max(err)), "m")


def _predict(d: Outputs, out: Collector, params: dict) -> None:
    """predict, predict-*: per (N0, N_OC) and predictor, the error metrics' mean and sd over
    trajectories, r with the global distance; OC vs each baseline (Wilcoxon); windows used and failed."""
    p = d.table("predictions.parquet", ["study", "trial", "entity", "n0", "n_oc", "predictor", "n_used", "n_skipped", "n_failed"])
    out.study = _study(p)
    out.count("trajectories", p.drop_duplicates(["study", "trial", "entity"]).shape[0])
    for (n0, n_oc, pred), g in p.groupby(["n0", "n_oc", "predictor"], sort=True):
        setting = f"{n0}:{n_oc}"
        out.count((setting, pred, "windows_used"), g["n_used"].sum())
        out.count((setting, pred, "windows_failed"), g["n_failed"].sum())
    s = d.table("prediction_summary.parquet")
    for _, r in s.iterrows():
        key = (f"{r['n0']}:{r['n_oc']}", r["predictor"], r["metric"])
        out.add((*key, "mean"), r["mean"], r["unit"])
        out.add((*key, "sd"), r["sd"], r["unit"])
        out.add((*key, "pearson_r"), r["pearson_r"])
    c = d.table("prediction_comparison.parquet")
    for _, r in c[c["group"] == "all"].iterrows():
        key = (f"{r['n0']}:{r['n_oc']}", f"oc_vs_{r['baseline']}")
        out.add((*key, "median_difference"), r["median_difference"], "m")
        out.add((*key, "oc_wins"), r["oc_wins"])
        out.add((*key, "wilcoxon_p"), r["wilcoxon_p"])


_RUN_COLUMNS = {
    "distance": "m", "delay": "s", "delay_sd": "s", "offset_x": "m", "offset_y": "m", "offset_z": "m", "offset_yaw": "rad",
    **{f"err_{a}_{s}": ("rad" if a == "yaw" else "m") for a in ("x", "y", "z", "yaw") for s in ("mean", "sd", "max")},
    "ape_rmse": "m", "ape_max": "m", "drift": "m/m", "drift_sd": "m/m",
    "goal_err_xy_mean": "m", "goal_err_xy_sd": "m", "goal_err_yaw_mean": "rad", "goal_err_yaw_sd": "rad",
}
_RUN_COUNTS = ("n_truth", "n_icp", "n", "goals_commanded", "goals_found", "goals_within_tolerance")


def _localisation(d: Outputs, out: Collector, params: dict) -> None:
    """localisation: per run, delay, structural offset, per-axis errors, APE, drift and goal accuracy
    (docs/methods.md sec. 9)."""
    out.study = LOCALISATION_STUDY
    runs = d.table("localisation.parquet")
    out.count("runs", len(runs))
    for _, r in runs.iterrows():
        for c in _RUN_COUNTS:
            if c in r:
                out.count((r["run"], "associated" if c == "n" else c), r[c])
        for c, unit in _RUN_COLUMNS.items():
            if c in r:
                out.add((r["run"], c), r[c], unit)


def _report(d: Outputs, out: Collector, params: dict) -> None:
    """report: the figures drawn."""
    out.count("figures", d.count("*.png"))


def _velocity_commands(d: Outputs, out: Collector, params: dict) -> None:
    """velocity-commands: commands written and the share saturated."""

    cmd = d.csv("commands.csv") if d.exists("commands.csv") else d.table("commands.parquet")
    out.count("commands", len(cmd))
    out.add(("saturated", "share"), cmd["saturated"].astype(float).mean())


STAGE_METRICS: dict[str, Callable[[Outputs, Collector, dict], None]] = {
    "synth-walking": _synth_study, "synth-pairs": _synth_study, "synth-localisation": _synth_localisation,
    "import": _import, "import-published": _import_published, "preprocess": _preprocess, "average": _average,
    "compare": _compare, "stats": _stats, "reconstruct": _reconstruct, "fit-ioc": _fit_ioc, "fit-ioc-subjects": _fit_ioc,
    "fit-ioc-coupled": _fit_ioc, "fit-ioc-single": _fit_ioc, "fit-ioc-subjects-single": _fit_ioc,
    "generate": _generate, "predict": _predict, "localisation": _localisation,
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


def stage_metrics(stage: str, stage_dir: Path, params: dict | None = None, memory: dict[str, Any] | None = None) -> dict[str, Any] | None:
    """The content of ``metrics.json`` for a stage directory, or None for a stage without metrics; ``memory``: the
    outputs the stage kept as it wrote them (``Stage.outputs``), read before the files."""
    fn = extractor(stage)
    if fn is None:
        return None
    params = params or {}
    out = Collector(stage, stage_convention(stage, Path(stage_dir), params))
    fn(Outputs(Path(stage_dir), memory), out, params)
    keys = [m.key for m in out.items]
    if len(set(keys)) != len(keys):  # a bug of an extractor, not of the data
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"duplicate metric names {dup[:3]}")
    return {"format": FORMAT, "stage": stage, "study": out.study, "convention": out.convention,
            "metrics": [m.to_json() for m in out.items]}


def write_stage_metrics(stage: str, stage_dir: Path, params: dict | None = None, memory: dict[str, Any] | None = None) -> None:
    """Write ``stage_dir/metrics.json``; an extraction error is recorded there (and warned about),
    never raised: the stage's own outputs stand, and ``metrics check`` reports the missing numbers."""
    from cobot_analysis.console import warn

    try:
        payload = stage_metrics(stage, Path(stage_dir), params, memory)
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
