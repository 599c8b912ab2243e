"""Cost-weight presets of the walking-path models (docs/methods.md sec. 5) and fitted-weights files.

Single-walker weights are one vector ``(a0, a1, a2, a3, a4, a5, a6, b0, b1, b2, b3)``:
running cost ``a0 + a1 u1^2 + a2 u2^2 + a3 u3^2 + a4 psi^2 + a5 r^2 + a6 (thf - theta)^2``
(a5, a6 only in the Mombaur model) and terminal cost
``b0 r^2 + b1 (thf - theta)^2 + b2 (v_forw^2 + v_orth^2) + b3 omega^2`` (improved model).
The coupled model (two carriers) has its own vector ``(a0..a10, b0..b3)``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cobot_analysis.errors import InputError

WALKER_WEIGHTS = ("a0", "a1", "a2", "a3", "a4", "a5", "a6", "b0", "b1", "b2", "b3")
COUPLED_WEIGHTS = tuple(f"a{i}" for i in range(11)) + ("b0", "b1", "b2", "b3")

PRESETS: dict[str, dict[str, float]] = {
    # Mombaur & Laumond 2010 (a0..a4) with the position / heading weights a5, a6 of docs/methods.md 5.4.
    "mombaur-2010": dict(zip(WALKER_WEIGHTS, (1.0, 1.2, 0.7, 1.7, 5.2, 5.0, 8.0, 0.0, 0.0, 0.0, 0.0))),
    # Improved OC, IOC on the walking means (CMBBE 2021).
    "walking-2021": dict(zip(WALKER_WEIGHTS, (7.87, 4.00, 20.15, 1.00e-6, 10.00, 0.0, 0.0, 10.00, 10.00, 0.38, 3.36))),
    # Improved OC fitted to table trajectories (Humanoids 2022).
    "table-2022": dict(zip(WALKER_WEIGHTS, (3.01e-3, 6.03, 5.99, 8.63e-2, 1.00e-7, 0.0, 0.0, 9.98, 7.99, 14.99, 0.42))),
    # Running weights a0..a3 of the table predictor in the authors' code (estimation_table.py of
    # imaroger/table_trajectories_during_collaborative_carriage), which differ from table-2022: used by the
    # published convention's table prediction (docs/methods.md sec. 7, 11).
    "table-prediction-2022": dict(zip(WALKER_WEIGHTS, (3.71803398, 5.80814113, 6.06995099, 1.42647176e-1, 0.0, 0.0, 0.0,
                                                      0.0, 0.0, 0.0, 0.0))),
    # Coupled OC of two carriers (Sci. Rep. 2022).
    "pair-2022": dict(zip(COUPLED_WEIGHTS, (3.85, 2.29, 10.37, 0.10, 2.7, 8.99, 3.00, 10.42, 1.81e-6, 0.50, 0.03,
                                            19.77, 30.24, 8.77, 9.15))),
}

#: which preset each model uses by default.
DEFAULT_PRESET = {"unicycle": "walking-2021", "mombaur": "mombaur-2010", "improved": "walking-2021",
                  "table": "table-2022", "coupled": "pair-2022"}


def names_for(model: str) -> tuple[str, ...]:
    return COUPLED_WEIGHTS if model == "coupled" else WALKER_WEIGHTS


def weights_vector(weights: dict[str, float], model: str = "improved") -> np.ndarray:
    """The weights as the model's ordered vector (missing names are 0)."""
    return np.array([float(weights.get(n, 0.0)) for n in names_for(model)])


_WARNED: set[str] = set()  # what this process said already (a stage reads its weights more than once)


def _warn_once(message: str) -> None:
    from cobot_analysis.console import warn

    if message not in _WARNED:
        _WARNED.add(message)
        warn(message)


def load_weights(spec: str | Path | dict | None, model: str = "improved") -> dict[str, float]:
    """Weights from a preset name, a fitted-weights JSON file (``{"weights": {...}}`` or a plain
    ``{name: value}`` mapping, or a list in the model's order), or a mapping (either form: a fit's
    ``weights_json()`` too). ``None``: the model's default."""
    names = names_for(model)
    if spec is None:
        spec = DEFAULT_PRESET.get(model, "walking-2021")
    if isinstance(spec, dict):
        data = spec["weights"] if isinstance(spec.get("weights"), (dict, list)) else spec  # a weights.json as a mapping
        path = None
    elif str(spec) in PRESETS:
        w = PRESETS[str(spec)]
        if set(w) != set(names):
            raise InputError(f"preset {spec!r} is for another model than {model!r}",
                             remedy=f"use one of {', '.join(p for p, v in PRESETS.items() if set(v) == set(names))}")
        return dict(w)
    else:
        path = Path(spec)
        if not path.is_file():
            raise InputError(f"unknown preset or missing weights file {str(spec)!r}",
                             remedy=f"use a preset ({', '.join(PRESETS)}) or the weights.json written by fit-ioc")
        try:
            data = json.loads(path.read_text())
        except ValueError as exc:
            raise InputError(f"not a JSON weights file ({exc.msg})", path=path, remedy="pass the weights.json written by fit-ioc") from exc
        if isinstance(data, dict) and "weights" in data:
            data = data["weights"]
    if isinstance(data, list):
        if len(data) != len(names):
            raise InputError(f"weights file has {len(data)} values, model {model!r} needs {len(names)} ({', '.join(names)})",
                             path=path, remedy="pass a weights file written for this model")
        data = dict(zip(names, data))
    if not isinstance(data, dict):
        raise InputError("weights must be a mapping name -> value or a list", path=path, remedy="pass the weights.json written by fit-ioc")
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise InputError(f"weights {unknown} are not weights of model {model!r} ({', '.join(names)})", path=path,
                         remedy="pass a weights file written for this model")
    missing = [n for n in names if n not in data]
    if path is not None and missing:  # fit-ioc writes every weight: a file without some is typed by hand
        _warn_once(f"{path}: weights {', '.join(missing)} of model {model!r} not given, taken as 0")
    try:
        values = {n: float(data.get(n, 0.0)) for n in names}
    except (TypeError, ValueError) as exc:
        raise InputError("weights must be numbers", path=path, remedy="fix the weights file") from exc
    if not all(np.isfinite(v) and v >= 0 for v in values.values()):
        raise InputError("weights must be finite and non-negative", path=path, remedy="fix the weights file")
    return values


def weights_convention(spec: str | Path | dict | None, model: str = "improved") -> str | None:
    """The convention weights were made under (docs/methods.md sec. 11): ``published`` for the presets
    (the papers' weights) and for the model default (None), the ``convention`` of a fitted-weights
    file or of its mapping (``FitIOCResult.weights_json()``), None when unknown (a plain ``{name: value}``
    mapping, or a file without one: the caller's default applies). A ``convention`` that is not one is refused."""
    from cobot_analysis.conventions import NAMES

    if isinstance(spec, dict):  # a plain {name: value}: unknown; a fit's weights_json(): its convention
        data, path = spec, None
    elif spec is None or str(spec) in PRESETS:
        return "published"
    else:
        path = Path(spec)
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError):
            return None
    name = data.get("convention") if isinstance(data, dict) else None
    if name is not None and name not in NAMES:
        raise InputError(f"its \"convention\" {name!r} is not a convention", path=path,
                         remedy=f"write one of {', '.join(NAMES)} or pass --convention")
    return name
