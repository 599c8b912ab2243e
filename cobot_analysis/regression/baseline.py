"""Baselines of the stage metrics, their tolerances, and the comparison with a workspace.

A baseline (``tests/baselines/<name>.json``) holds one study's metrics, keyed by metric name (with
``@convention`` for model stages), one metric per line so that a review sees each changed number.
Its tolerances are TOML rules kept next to it: ``<name>.tolerances.toml`` first, then the
directory's ``tolerances.toml``; the first rule whose ``match`` patterns (fnmatch, on the key) and
optional ``unit`` fit a metric applies:

    [[rule]]
    match = ["stats.*.p", "stats.*.p_holm"]
    rel = 1e-6              # passes when |now - baseline| <= abs + rel * |baseline|
    abs = 1e-12
    reason = "deterministic: only floating-point rounding of other library versions may move them"

``exact = true`` instead of ``rel``/``abs`` demands equality. Text and flags (test names, skip
reasons, significance) always compare exactly and need no rule; every number needs one.
"""

from __future__ import annotations

import fnmatch
import json
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from cobot_analysis.errors import InputError
from cobot_analysis.regression.extract import Metric, workspace_metrics

BASELINE_FORMAT = "cobot-analysis-metrics-baseline/1"
SHARED_TOLERANCES = "tolerances.toml"
OK, FAIL, MISSING, NEW = "ok", "FAIL", "MISSING", "NEW"


# ---- tolerances -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Rule:
    patterns: tuple[str, ...]
    units: tuple[str, ...] | None
    exact: bool
    rel: float
    abs: float
    reason: str
    source: str

    def matches(self, key: str, unit: str) -> bool:
        if self.units is not None and unit not in self.units:
            return False
        return any(fnmatch.fnmatchcase(key, p) for p in self.patterns)

    def describe(self) -> str:
        if self.exact:
            return "exact"
        parts = ([f"rel {self.rel:g}"] if self.rel else []) + ([f"abs {self.abs:g}"] if self.abs else [])
        return " + ".join(parts) or "exact"

    def passes(self, base: Any, now: Any) -> bool:
        """Text and flags: equal; numbers: equal (exact) or within abs + rel * |base|."""
        if isinstance(base, (bool, str)) or isinstance(now, (bool, str)):
            return type(base) is type(now) and base == now
        b, n = _num(base), _num(now)
        if b is None or n is None:
            return False
        return b == n if self.exact else abs(n - b) <= self.abs + self.rel * abs(b)


def _num(v: Any) -> float | None:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v)


def tolerance_files(baseline: Path) -> list[Path]:
    """The tolerance files of a baseline, in the order their rules apply."""
    own = baseline.with_name(baseline.stem + ".tolerances.toml")
    shared = baseline.with_name(SHARED_TOLERANCES)
    return [f for f in (own, shared) if f.is_file()]


def load_rules(baseline: Path) -> list[Rule]:
    """Every tolerance rule of a baseline (``InputError`` for a malformed file or rule)."""
    import tomllib

    rules: list[Rule] = []
    for f in tolerance_files(baseline):
        try:
            doc = tomllib.loads(f.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise InputError(f"not valid TOML ({exc})", path=f, remedy="fix the syntax (see the rules already in the file)") from None
        for i, r in enumerate(doc.get("rule", []), 1):
            where = f"rule {i}"
            if not isinstance(r, dict):
                raise InputError(f"{where} is not a table", path=f, remedy="write each rule as a [[rule]] table")
            patterns = r.get("match")
            patterns = [patterns] if isinstance(patterns, str) else patterns
            if not patterns or not all(isinstance(p, str) for p in patterns):
                raise InputError(f"{where} has no match pattern", path=f, remedy='add match = ["stage.metric.*", ...]')
            if not str(r.get("reason", "")).strip():
                raise InputError(f"{where} ({patterns[0]}) gives no reason", path=f, remedy='add reason = "why this tolerance"')
            exact = bool(r.get("exact", False))
            try:
                rel, ab = float(r.get("rel", 0.0)), float(r.get("abs", 0.0))
            except (TypeError, ValueError):
                raise InputError(f"{where} ({patterns[0]}): rel and abs must be numbers", path=f, remedy="e.g. rel = 1e-6") from None
            if exact == bool("rel" in r or "abs" in r) or rel < 0 or ab < 0:
                raise InputError(f"{where} ({patterns[0]}) needs either exact = true or a non-negative rel and/or abs", path=f,
                                 remedy="e.g. exact = true, or rel = 1e-6")
            units = r.get("unit")
            units = None if units is None else tuple([units] if isinstance(units, str) else units)
            rules.append(Rule(tuple(patterns), units, exact, rel, ab, str(r["reason"]).strip(), str(f)))
    return rules


def rule_for(rules: list[Rule], key: str, unit: str) -> Rule | None:
    return next((r for r in rules if r.matches(key, unit)), None)


def _is_text(v: Any) -> bool:
    return isinstance(v, (bool, str))


def untolerated(rules: list[Rule], metrics: dict[str, Metric]) -> list[str]:
    """Numeric metrics that no rule covers (text and flags always compare exactly)."""
    return [k for k, m in metrics.items() if not _is_text(m.value) and rule_for(rules, k, m.unit) is None]


# ---- baselines ------------------------------------------------------------------------------------
def load_baseline(path: Path) -> dict[str, Any]:
    """A baseline file (``InputError`` when missing, not JSON, or not a baseline)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("baseline not found", path=path, remedy="check the path, or create it with `cobot-analysis metrics update`")
    try:
        doc = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"baseline is not valid JSON ({exc})", path=path,
                         remedy="restore it (git checkout) or regenerate it with `cobot-analysis metrics update`") from None
    if not isinstance(doc, dict) or doc.get("format") != BASELINE_FORMAT:
        found = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise InputError(f"not a metrics baseline (format {found!r}, expected {BASELINE_FORMAT})", path=path,
                         remedy="pass a file written by `cobot-analysis metrics update`")
    metrics = doc.get("metrics")
    if not isinstance(metrics, dict) or not all(isinstance(v, dict) and "value" in v and "stage" in v for v in metrics.values()):
        raise InputError("baseline has no well-formed 'metrics' table", path=path,
                         remedy="regenerate it with `cobot-analysis metrics update`")
    return doc


def baseline_metrics(doc: dict[str, Any]) -> dict[str, Metric]:
    out = {}
    for key, r in doc["metrics"].items():
        conv = r.get("convention")
        name = key[: -len(conv) - 1] if conv and key.endswith(f"@{conv}") else key
        out[key] = Metric(name, r["value"], str(r.get("unit", "")), str(r["stage"]), conv)
    return out


def collect(workspaces: list[Path]) -> tuple[str | None, dict[str, Metric], list[str], set[tuple[str, str | None]]]:
    """The metrics of one study's workspaces: (study, metrics by key, extraction errors, (stage, convention)s).

    ``InputError`` when the workspaces hold no stage metrics (nothing to show, check or update), hold different
    studies, or disagree on a metric they share."""
    studies: dict[str, Path] = {}
    metrics: dict[str, tuple[Metric, Path]] = {}
    errors: list[str] = []
    stages: set[tuple[str, str | None]] = set()
    for ws in workspaces:
        for payload in workspace_metrics(ws):
            stage_dir = Path(ws) / payload["stage"]
            if payload.get("study"):
                studies.setdefault(str(payload["study"]), stage_dir)
                if len(studies) > 1:
                    names = ", ".join(f"{s} ({p})" for s, p in studies.items())
                    raise InputError(f"the workspaces hold different studies: {names}", path=", ".join(map(str, workspaces)),
                                     remedy="check one study at a time: one baseline with the workspaces of that study")
            stages.add((payload["stage"], payload.get("convention")))
            if payload.get("error"):
                errors.append(f"{stage_dir}: metrics could not be computed ({payload['error']})")
            for rec in payload["metrics"]:
                m = Metric.from_json(rec)
                if m.key in metrics and metrics[m.key][0].value != m.value:
                    raise InputError(f"metric {m.key} differs between {metrics[m.key][1]} and {ws} "
                                     f"({metrics[m.key][0].value!r} vs {m.value!r})", path=ws,
                                     remedy="pass workspaces of one run of the study (model stages of each convention in their own workspace)")
                metrics.setdefault(m.key, (m, Path(ws)))
    if not metrics and not errors:  # before: 'study: unknown' and exit 0 (show), an empty comparison (check)
        raise InputError("no stage metrics (metrics.json) in the workspace(s)", path=", ".join(map(str, workspaces)),
                         remedy="run the study's stages with this --out first")
    study = next(iter(studies), None)
    return study, {k: m for k, (m, _) in metrics.items()}, errors, stages


# ---- comparison ---------------------------------------------------------------------------------------
@dataclass
class Row:
    key: str
    unit: str
    base: Any
    now: Any
    tolerance: str
    status: str

    @property
    def change(self) -> str:
        b, n = _num(self.base), _num(self.now)
        if b is None or n is None or b == n:
            return ""
        return f"{100 * (n - b) / abs(b):+.3g} %" if b else f"{n - b:+.3g}"


def compare(baseline: Path, workspaces: list[Path]) -> tuple[list[Row], list[str]]:
    """Rows of the comparison table (baseline order, then new metrics) and notes; ``InputError`` for a
    bad baseline or tolerance file, a metric without tolerance, a missing stage or mixed studies."""
    doc = load_baseline(baseline)
    base = baseline_metrics(doc)
    rules = load_rules(baseline)
    if not rules:
        raise InputError("no tolerance file", path=baseline.with_name(baseline.stem + ".tolerances.toml"),
                         remedy=f"write tolerance rules there or in {baseline.with_name(SHARED_TOLERANCES)}")
    missing = untolerated(rules, base)
    if missing:
        files = " or ".join(str(f) for f in tolerance_files(baseline))
        raise InputError(f"{len(missing)} metric(s) of the baseline have no tolerance, e.g. {missing[0]}", path=baseline,
                         remedy=f"add a [[rule]] matching them, with its reason, to {files}")
    study, now, errors, stages = collect(workspaces)
    if doc.get("study") and study and doc["study"] != study:
        raise InputError(f"baseline is for study {doc['study']}, the workspaces hold {study}", path=baseline,
                         remedy="pass the baseline of that study")
    wanted = sorted({(m.stage, m.convention) for m in base.values()} - stages, key=str)
    if wanted:
        stage, conv = wanted[0]
        label = stage + (f" (convention {conv})" if conv else "")
        raise InputError(f"no stage {label} in the workspaces ({len([m for m in base.values() if (m.stage, m.convention) == (stage, conv)])} "
                         f"baseline metrics come from it)", path=", ".join(map(str, workspaces)),
                         remedy=f"run `cobot-analysis {stage}` with --out on one of them, or drop its metrics with `cobot-analysis metrics update`")
    rows = []
    exact = Rule(("*",), None, True, 0.0, 0.0, "text and flags", "")
    for key, m in base.items():
        rule = exact if _is_text(m.value) else rule_for(rules, key, m.unit)
        value = now[key].value if key in now else None
        status = MISSING if key not in now else OK if rule.passes(m.value, value) else FAIL
        rows.append(Row(key, m.unit, m.value, value, "exact" if _is_text(value) else rule.describe(), status))
    for key, m in now.items():
        if key not in base:
            rule = exact if _is_text(m.value) else rule_for(rules, key, m.unit)
            rows.append(Row(key, m.unit, None, m.value, rule.describe() if rule else "none", NEW))
    return rows, errors


def _fmt(v: Any, other: Any = None) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool) or isinstance(v, str):
        return repr(v) if isinstance(v, str) else str(v)
    if isinstance(v, int):
        return str(v)
    text = f"{v:.6g}"
    if isinstance(other, float) and other != v and f"{other:.6g}" == text:
        text = repr(v)  # equal at 6 digits: show every digit so that the difference is visible
    return text


VALUE_WIDTH = 32


def _cell(text: str, width: int = VALUE_WIDTH) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def table(rows: list[Row], only_failures: bool = False) -> str:
    """The comparison as a plain-text table: metric, baseline, now, tolerance, change, status; long
    text values are cut in the table and given in full below it when they differ."""
    head = ("metric", "baseline", "now", "tolerance", "change", "status")
    shown = [r for r in rows if not only_failures or r.status != OK]
    body = [(r.key, _cell(_fmt(r.base, r.now)), _cell(_fmt(r.now, r.base)), r.tolerance, r.change, r.status) for r in shown]
    widths = [max(len(h), *(len(b[i]) for b in body)) if body else len(h) for i, h in enumerate(head)]

    def line(cells) -> str:
        return "  ".join(c.ljust(w) if i in (0, 3, 5) else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths))).rstrip()

    notes = [f"{r.key}:\n  baseline {_fmt(r.base)}\n  now      {_fmt(r.now)}" for r in shown
             if r.status == FAIL and max(len(_fmt(r.base)), len(_fmt(r.now))) > VALUE_WIDTH]
    return "\n".join([line(head), line(tuple("-" * w for w in widths)), *map(line, body), *notes])


def summary(rows: list[Row]) -> str:
    counts = {s: sum(r.status == s for r in rows) for s in (OK, FAIL, MISSING, NEW)}
    return (f"{len(rows)} metrics: {counts[OK]} ok, {counts[FAIL]} outside tolerance, {counts[MISSING]} missing, "
            f"{counts[NEW]} new")


# ---- update -------------------------------------------------------------------------------------------
def _record(m: Metric) -> dict[str, Any]:
    return {"value": m.value, "unit": m.unit, "stage": m.stage, "convention": m.convention}


def render(study: str | None, metrics: dict[str, Metric], produced_by: dict[str, Any]) -> str:
    """Baseline JSON, one metric per line (reviewable diffs)."""
    head = {"format": BASELINE_FORMAT, "study": study, "produced_by": produced_by}
    lines = ["{"] + [f"  {json.dumps(k)}: {json.dumps(v)}," for k, v in head.items()] + ['  "metrics": {']
    items = [f"    {json.dumps(k)}: {json.dumps(_record(m))}" for k, m in metrics.items()]
    lines += [",\n".join(items), "  }", "}"] if items else ["  }", "}"]
    return "\n".join(lines) + "\n"


def diff(old: dict[str, Metric], new: dict[str, Metric]) -> list[str]:
    """Lines describing what an update changes: changed, added and removed metrics."""
    out = []
    for k, m in new.items():
        if k in old and old[k].value != m.value:
            row = Row(k, m.unit, old[k].value, m.value, "", "")
            out.append(f"changed  {k}: {_fmt(old[k].value, m.value)} -> {_fmt(m.value, old[k].value)}"
                       + (f" ({row.change})" if row.change else ""))
    out += [f"added    {k}: {_fmt(m.value)}" for k, m in new.items() if k not in old]
    out += [f"removed  {k}: {_fmt(m.value)}" for k, m in old.items() if k not in new]
    return out


def update(baseline: Path, workspaces: list[Path], *, write: bool = True) -> tuple[list[str], list[str], bool]:
    """Replace the baseline's metrics by the workspaces' (diff lines, warnings, whether it changed).

    A new baseline takes the workspaces' study; an existing one must be of the same study."""
    from cobot_analysis import __version__
    from cobot_analysis.provenance import git_commit

    baseline = Path(baseline)
    old: dict[str, Metric] = {}
    old_study = None
    if baseline.exists():
        doc = load_baseline(baseline)
        old, old_study = baseline_metrics(doc), doc.get("study")
    study, now, errors, _ = collect(workspaces)
    if not now:  # only stages whose metrics could not be computed
        raise InputError(f"no stage metrics in the workspaces ({errors[0]})", path=", ".join(map(str, workspaces)),
                         remedy="re-run that stage with --force, then update")
    if old_study and study and old_study != study:
        raise InputError(f"baseline is for study {old_study}, the workspaces hold {study}", path=baseline,
                         remedy="pass the baseline of that study, or a new file name for a new baseline")
    warnings = list(errors)
    rules = load_rules(baseline)
    missing = untolerated(rules, now)
    if missing:
        warnings.append(f"{len(missing)} metric(s) have no tolerance rule (e.g. {missing[0]}): add rules to "
                        f"{baseline.with_name(baseline.stem + '.tolerances.toml')} or {baseline.with_name(SHARED_TOLERANCES)} "
                        "before `metrics check`")
    lines = diff(old, now)
    changed = bool(lines) or not baseline.exists() or list(old) != list(now)
    if write and changed:
        produced_by = {"cobot_analysis": __version__, "commit": git_commit(), "date": f"{datetime.now(timezone.utc):%Y-%m-%d}"}
        baseline.parent.mkdir(parents=True, exist_ok=True)
        tmp = baseline.with_name(f".{baseline.name}.tmp")
        tmp.write_text(render(study, now, produced_by))
        os.replace(tmp, baseline)
    return lines, warnings, changed

