"""A metric record and how a stage's records are named (``Collector``).

A record: ``name`` (``<stage>.<what>...``, stable, e.g. ``compare.individual-mean.walker.d_xy.mean``),
``value`` (number, bool or string; NaN is not recorded), ``unit``, ``stage`` and ``convention`` (model
stages only, ``registry.is_model_stage``). A stage and its ``-published`` twin name their metrics alike;
the convention tells them apart (``Metric.key``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from cobot_analysis import registry
from cobot_analysis.schema import as_text


@dataclass(frozen=True)
class Metric:
    """One headline number of a stage."""

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
    if value is None or isinstance(value, str):
        return value
    import numpy as np

    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (bool, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return str(value)




class Collector:
    """Metric records of one stage (names prefixed by the stage name, ``registry.base_stage``)."""

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
        full = ".".join([self.prefix, *(as_text(p) for p in parts if p is not None and p != "")])
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


class Metrics(list):
    """The records of one stage (a list of ``Metric``) with the ``stage``, its ``convention`` (model stages)
    and the ``study`` of its rows; ``as_dict()``: name -> value."""

    def __init__(self, items: list[Metric], stage: str, convention: str | None, study: str | None):
        super().__init__(items)
        self.stage, self.convention, self.study = stage, convention, study

    def as_dict(self) -> dict[str, Any]:
        return {m.name: m.value for m in self}


def convention_of(stage: str) -> str | None:
    """The convention a stage directory's metrics carry: ``published`` for a ``-published`` twin, else
    ``continuous``; None for a stage without conventions (``registry.is_model_stage``)."""
    if not registry.is_model_stage(stage):
        return None
    return "published" if registry.base_stage(stage) != stage else "continuous"


def collect(stage: str, fill, *tables: Any) -> Metrics:
    """The records ``fill(collector, *tables)`` adds for the stage directory ``stage``."""
    out = Collector(stage, convention_of(stage))
    fill(out, *tables)
    return Metrics(checked(out.items), stage, out.convention, out.study)


def checked(items: list[Metric]) -> list[Metric]:
    """``items``, after checking that no two records share a key (ValueError: a bug of a metric function,
    not of the data)."""
    keys = [m.key for m in items]
    if len(set(keys)) != len(keys):
        dup = sorted({k for k in keys if keys.count(k) > 1})
        raise ValueError(f"duplicate metric names {dup[:3]}")
    return items


def study_of(df) -> str | None:
    """The study (or ``a+b`` studies) of a table's rows; None without a ``study`` column."""
    if "study" not in df:
        return None
    studies = sorted(str(s) for s in df["study"].dropna().unique())
    return "+".join(studies) if studies else None


def groups(df, keys: list[str], fmt: dict[str, str] | None = None) -> Iterator[tuple[tuple, Any]]:
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
        parts = tuple("-" if pd.isna(v) else fmt.get(k, "{}").format(as_text(v)) for k, v in zip(keys, key))
        yield parts, g


def flatten(out: Collector, prefix: tuple, value: Any) -> None:
    """Records of a nested document: a dict by its keys, a list of plain values joined by commas
    (else its length ``n``), ints as counts."""
    if isinstance(value, dict):
        for k, v in value.items():
            flatten(out, (*prefix, k), v)
    elif isinstance(value, list):
        if all(isinstance(v, (str, int, float)) and not isinstance(v, bool) for v in value):
            out.add(prefix, ",".join(as_text(v) for v in value))
        else:
            out.count((*prefix, "n"), len(value))
    elif isinstance(value, (bool, str)):
        out.add(prefix, value)
    elif isinstance(value, int):
        out.count(prefix, value)
    else:
        out.add(prefix, value)
