"""The checks of the API's options that the command line's parser makes for its own: number ranges,
choices, and list options given as a list or as the command line's comma-separated text. A function
called from a notebook refuses a bad option with the same one-line ``InputError``, naming the option
(as the command line spells it), before any work."""

from __future__ import annotations

import math
from typing import Any, Iterable

from cobot_analysis.errors import InputError


def floats(text: str | Iterable[float], n: int, option: str) -> tuple[float, ...]:
    """``n`` finite numbers of an option, comma-separated (``--delay-window 0,1.5``) or a sequence.

        >>> floats("0,1.5", 2, "--delay-window"), floats((0, 1.5), 2, "--delay-window")
        ((0.0, 1.5), (0.0, 1.5))
        >>> floats("0", 2, "--delay-window")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --delay-window needs 2 comma-separated numbers, got '0'; e.g. --delay-window 0,0
    """
    try:
        values = tuple(float(v) for v in (text.split(",") if isinstance(text, str) else text))
    except (TypeError, ValueError):
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise InputError(f"{option} needs {n} comma-separated numbers, got {text!r}", remedy=f"e.g. {option} " + ",".join(["0"] * n))
    return values


def at_least(value: float | None, option: str, low: float = 0.0, strict: bool = True, example: str = "") -> None:
    """Range check of a number option (None: not given): one line naming the option.

        >>> at_least(0.08, "--tol-xy", strict=False)
        >>> at_least(-1.0, "--tol-xy", strict=False, example="0.08")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --tol-xy must be >= 0, got -1; e.g. --tol-xy 0.08
        >>> at_least("10", "--rate")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --rate must be a number, got '10'
    """
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        import numpy as np

        if not isinstance(value, (np.integer, np.floating)):
            raise InputError(f"{option} must be a number, got {value!r}", remedy=f"e.g. {option} {example}" if example else None)
    if not math.isfinite(value) or value < low or (strict and value == low):
        raise InputError(f"{option} must be {'>' if strict else '>='} {low:g}, got {value:g}",
                         remedy=f"e.g. {option} {example}" if example else None)


def one_of(value: Any, option: str, choices: Iterable[str]) -> str:
    """``value`` when it is one of ``choices``, else one line naming the option and the choices.

        >>> one_of("subject", "--per", ("all", "subject"))
        'subject'
        >>> one_of("subjects", "--per", ("all", "subject"))
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: unknown --per 'subjects'; use one of all, subject
    """
    choices = tuple(choices)
    if value not in choices:
        raise InputError(f"unknown {option} {value!r}", remedy=f"use one of {', '.join(choices)}")
    return value


def name_list(value: str | Iterable[str] | None, option: str, example: str = "") -> list[str] | None:
    """A list option: a list (or any iterable) of names, or one string of comma-separated names as the command
    line takes it (``"condition,entity"``); None or empty: not given.

        >>> name_list("condition", "--by"), name_list("condition, entity", "--by")
        (['condition'], ['condition', 'entity'])
        >>> name_list(("condition",), "--by"), name_list(None, "--by")
        (['condition'], None)
        >>> name_list(3, "--by", example="condition,entity")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --by takes names (a list, or one comma-separated string), got 3; e.g. --by condition,entity
    """
    if value is None:
        return None
    try:
        items = value.split(",") if isinstance(value, str) else list(value)
    except TypeError:
        items = [value]
    if not all(isinstance(v, str) for v in items):
        raise InputError(f"{option} takes names (a list, or one comma-separated string), got {value!r}",
                         remedy=f"e.g. {option} {example}" if example else None)
    return [v.strip() for v in items if v.strip()] or None


def table_of(value: Any, what: str, *fields: str) -> Any:
    """A table argument as given (a DataFrame, or the path of a Parquet file), or the table held by the result of
    another API function (``fields``: the result's fields that may hold it, first found), so that
    ``compare(walks, average(walks))`` is ``compare(walks, average(walks).means)``; anything else one line
    naming the argument (``what``).

        >>> import pandas as pd
        >>> from cobot_analysis.api import AverageResult
        >>> result = AverageResult(pd.DataFrame({"x": [0.0]}), [], "", "", 0)
        >>> table_of(result, "means", "means").equals(result.means), table_of("means.parquet", "means", "means")
        (True, 'means.parquet')
        >>> table_of(None, "means", "means")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: means must be a DataFrame or the path of a Parquet file, not None; pass the table (docs/api.md, "The one input type")
    """
    import os

    from cobot_analysis.lazy import pandas as pd

    if isinstance(value, (pd.DataFrame, str, os.PathLike)):
        return value
    for name in fields:
        table = getattr(value, name, None)
        if isinstance(table, pd.DataFrame):
            return table
    kind = "None" if value is None else f"a {type(value).__name__}"
    raise InputError(f"{what} must be a DataFrame or the path of a Parquet file, not {kind}",
                     remedy='pass the table (docs/api.md, "The one input type")')


def whole(value: Any, option: str, low: int = 0, high: int | None = None) -> int:
    """A whole-number option within ``[low, high]`` (``high`` None: no upper bound): one line naming the option.

        >>> whole(3, "--subjects", 1)
        3
        >>> whole(0, "--subjects", 1)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --subjects must be a whole number >= 1, got 0; e.g. --subjects 1
        >>> whole(2.5, "--goals-per-lap", 1, 6)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --goals-per-lap must be a whole number in [1, 6], got 2.5; e.g. --goals-per-lap 1
    """
    import numpy as np

    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not ok or value < low or (high is not None and value > high):
        allowed = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise InputError(f"{option} must be a whole number {allowed}, got {value!r}", remedy=f"e.g. {option} {low}")
    return int(value)


def choose(value: str | int | Iterable, universe: Iterable, option: str, counts: bool = True) -> list:
    """The items of ``universe`` an option names: ``all`` (or None), a count N (the first N; when ``counts``), or a
    list (a list, or one comma-separated string) of them, each checked.

        >>> choose("2", ["N1500", "E1500", "S1500"], "--conditions"), choose(["S1500"], ["N1500", "E1500", "S1500"], "--conditions")
        (['N1500', 'E1500'], ['S1500'])
        >>> choose("1,3", [1, 2, 3], "--scenarios", counts=False)
        [1, 3]
        >>> choose("X1500", ["N1500", "E1500"], "--conditions")
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --conditions: unknown value(s) ['X1500']; use all, a count, or a comma-separated list of N1500, E1500
    """
    universe = list(universe)
    spec = value if isinstance(value, str) else str(value) if isinstance(value, int) and not isinstance(value, bool) else None
    if value is None or (spec is not None and spec.strip().lower() == "all"):
        return universe
    if counts and spec is not None and spec.strip().isdigit():
        n = int(spec)
        if not 1 <= n <= len(universe):
            raise InputError(f"{option} {spec}: must be between 1 and {len(universe)}", remedy=f"pass {option} all, a count, or a list")
        return universe[:n]
    names = {str(u): u for u in universe}
    try:
        chosen = [str(s).strip() for s in (spec.split(",") if spec is not None else value) if str(s).strip()]
    except TypeError:  # not a list: named below as an unknown value
        chosen = []
    unknown = [s for s in chosen if s not in names]
    if unknown or not chosen:
        raise InputError(f"{option}: unknown value(s) {unknown or [value]}",
                         remedy=f"use all{', a count' if counts else ''}, or a comma-separated list of {', '.join(names)}")
    return [names[s] for s in dict.fromkeys(chosen)]


def import_limits(lab_extent: float | None = None, max_speed: float | None = None, max_spike: float | None = None) -> None:
    """The plausibility limits of ``import`` (``--lab-extent`` m, ``--max-speed`` m/s, ``--max-spike`` m; None: not
    given), each a number >= 0: checked by ``import_markers`` and by the ``import`` stage before it plans the import.

        >>> import_limits(lab_extent=100.0, max_spike=0.05)
        >>> import_limits(max_speed=-1)
        Traceback (most recent call last):
        cobot_analysis.errors.InputError: --max-speed must be >= 0, got -1; e.g. --max-speed 20
    """
    at_least(lab_extent, "--lab-extent", strict=False, example="100")
    at_least(max_speed, "--max-speed", strict=False, example="20")
    at_least(max_spike, "--max-spike", strict=False, example="0.05")
