"""The pipeline's stages, in the order data flows through them: one registry for their names, their
workspace directories, the convention twins of the model stages, and the runner of each.

A stage writes ``OUT/<directory>/`` (``runtime.Stage``); a model stage run under the published
convention writes ``OUT/<name>-published/`` beside the continuous one (docs/methods.md sec. 11):
``directory(name, convention)`` is the one place that rule lives. ``runner`` names the function of
``cobot_analysis.stages`` that runs the stage into a workspace (the CLI calls it); the computation
itself is the public API (``cobot_analysis.api``).

    >>> directory("fit-ioc", "published")
    'fit-ioc-published'
    >>> directory("predict-fitted", "continuous")
    'predict-fitted'
    >>> base_stage("compare-published")
    'compare'
"""

from __future__ import annotations

import re
from dataclasses import dataclass

PUBLISHED_SUFFIX = "-published"


@dataclass(frozen=True)
class StageSpec:
    """One stage: its name (the CLI command), whether it runs under an OC convention (and so has a
    ``-published`` twin directory), and the ``cobot_analysis.stages`` function that runs it."""

    name: str
    conventioned: bool
    runner: str


STAGES: tuple[StageSpec, ...] = (
    StageSpec("synth-walking", False, "data.synth_walking"),
    StageSpec("synth-pairs", False, "data.synth_pairs"),
    StageSpec("synth-localisation", False, "localisation.synth_localisation"),
    StageSpec("import-published", False, "data.import_published"),
    StageSpec("import", False, "data.import_markers"),
    StageSpec("preprocess", False, "data.preprocess"),
    StageSpec("average", False, "analysis.average"),
    StageSpec("compare", True, "analysis.compare"),
    StageSpec("stats", True, "analysis.statistics"),  # on compare/ or compare-published/ distances
    StageSpec("reconstruct", False, "analysis.reconstruct"),
    StageSpec("fit-ioc", True, "models.fit_ioc"),
    StageSpec("fit-ioc-subjects", True, "models.fit_ioc"),
    StageSpec("fit-ioc-coupled", True, "models.fit_ioc"),
    StageSpec("fit-ioc-single", True, "models.fit_ioc"),  # the single-level method beside the bi-level fit-ioc
    StageSpec("fit-ioc-subjects-single", True, "models.fit_ioc"),
    StageSpec("generate", True, "models.generate"),
    StageSpec("velocity-commands", True, "models.velocity_commands"),
    StageSpec("predict", True, "predict.predict"),
    StageSpec("localisation", False, "localisation.localisation"),
    StageSpec("report", False, "analysis.report"),
)
_BY_NAME = {s.name: s for s in STAGES}
#: a predict stage may carry a label of the user's (``--stage-name predict-fitted``)
PREDICT_LABEL = re.compile(r"predict[-_A-Za-z0-9]*")


def directory(name: str, convention: str | None = None) -> str:
    """The workspace directory of stage ``name`` run under ``convention``: ``name`` (continuous, or a
    stage without conventions) or ``name-published``."""
    return name + PUBLISHED_SUFFIX if convention == "published" and spec(name).conventioned else name


def base_stage(directory_name: str) -> str:
    """The stage of a workspace directory: ``fit-ioc-published`` -> ``fit-ioc``; ``import-published`` is a
    stage of its own; ``predict-<label>`` keeps its label."""
    if directory_name.endswith(PUBLISHED_SUFFIX):
        base = directory_name[: -len(PUBLISHED_SUFFIX)]
        if base in _BY_NAME and _BY_NAME[base].conventioned or PREDICT_LABEL.fullmatch(base):
            return base
    return directory_name


def spec(name: str) -> StageSpec:
    """The registry entry of a stage (a labelled predict stage is a predict stage)."""
    if name in _BY_NAME:
        return _BY_NAME[name]
    if PREDICT_LABEL.fullmatch(name):
        return _BY_NAME["predict"]
    raise KeyError(f"no stage {name!r}")


def command(directory_name: str) -> str:
    """The command (without ``--out``) that writes a stage directory, for a message's remedy:
    ``synth-walking`` -> ``synth walking``, ``fit-ioc-subjects-single-published`` -> ``fit-ioc --per subject
    --method single-level --convention published``, ``predict-goal`` -> ``predict --stage-name predict-goal``.

    >>> command("preprocess"), command("compare-published")
    ('preprocess', 'compare --convention published')
    """
    base = base_stage(directory_name)
    options = []
    if base.startswith("synth-"):
        name = "synth " + base[len("synth-"):]
    elif base.startswith("fit-ioc"):
        name = "fit-ioc"
        options += ["--per subject"] if "-subjects" in base else []
        options += ["--model coupled"] if "-coupled" in base else []
        options += ["--method single-level"] if base.endswith("-single") else []
    elif base != "predict" and PREDICT_LABEL.fullmatch(base):
        name, options = "predict", [f"--stage-name {base}"]
    else:
        name = base
    if base != directory_name:
        options.append("--convention published")
    return " ".join([name, *options])


def known(directory_name: str) -> bool:
    """Whether a workspace directory is a stage's."""
    try:
        spec(base_stage(directory_name))
    except KeyError:
        return False
    return True


def order(directory_name: str) -> int:
    """Rank of a stage directory in the data flow (unknown directories last)."""
    try:
        return STAGES.index(spec(base_stage(directory_name)))
    except KeyError:
        return len(STAGES)


def is_model_stage(directory_name: str) -> bool:
    """Stages that run under a convention (docs/methods.md sec. 11)."""
    try:
        return spec(base_stage(directory_name)).conventioned
    except KeyError:
        return False
