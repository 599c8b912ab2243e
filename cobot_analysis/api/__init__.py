"""The public Python API of cobot-analysis: every stage of the pipeline as a function.

Each function takes the documented tables (pandas DataFrames, as ``schema.TRAJECTORIES`` and the
stages' schemas describe; ``cobot-analysis schemas`` prints them) or the paths of the files that hold
them, keyword-only options with the command line's names and defaults, and returns a result object
that carries its tables (and ``summary()``). Nothing is written to disk (but by the synthetic studies'
``synth_*``, whose product is raw files): ``cobot_analysis.stages`` runs the same functions into a
workspace, which is what the command line does.

    >>> import cobot_analysis.api as ca
    >>> from cobot_analysis.synth.tables import walking_table
    >>> walks = walking_table(n_subjects=3, n_conditions=2, n_trials=2)   # or ca.import_published(...).trajectories
    >>> means = ca.average(walks).means
    >>> distances = ca.compare(walks, means).distances
    >>> len(distances), sorted(distances["comparison"].unique())
    (12, ['individual-mean'])

See docs/api.md for every function and docs/examples/ for two worked examples.
"""

from __future__ import annotations

import importlib
from typing import Any

#: public name -> module of ``cobot_analysis.api`` that defines it (imported on first use, so that
#: ``import cobot_analysis`` and the command line's start-up stay fast)
EXPORTS = {
    # data
    "import_markers": "data", "ImportResult": "data", "import_published": "data", "PublishedResult": "data",
    "preprocess": "data", "PreprocessResult": "data",
    # analyses
    "trajectory_set": "analysis", "study_of": "analysis", "check_by": "analysis",
    "average": "analysis", "AverageResult": "analysis", "compare": "analysis", "CompareResult": "analysis",
    "statistics": "analysis", "StatisticsResult": "analysis", "distances_table": "analysis", "reconstruct": "analysis", "ReconstructResult": "analysis",
    # models
    "generate": "models", "GenerateResult": "models", "walking_cases": "models", "fit_ioc": "models", "FitResult": "models",
    "velocity_commands": "models", "VelocityCommands": "models",
    # prediction and localisation
    "predict": "prediction", "PredictionResult": "prediction",
    "localise": "localisation", "LocalisationResult": "localisation", "bag_topics": "localisation",
    # synthetic studies (raw inputs written to a directory)
    "synth_walking": "synth", "synth_pairs": "synth", "synth_localisation": "synth", "synth_options": "synth",
    "SynthStudy": "synth", "SynthRobotRun": "synth",
}
__all__ = sorted(EXPORTS)


def __getattr__(name: str) -> Any:
    if name in EXPORTS:
        value = getattr(importlib.import_module(f"{__name__}.{EXPORTS[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *EXPORTS])
