"""The public API's documentation: every example in the docstrings of ``cobot_analysis.api`` runs and
gives what it shows, every public function has one, and docs/api.md documents every exported name."""

from __future__ import annotations

import doctest
import importlib
import inspect
import re
from pathlib import Path

import pytest

from cobot_analysis import api

DOC = Path(__file__).resolve().parents[1] / "docs" / "api.md"
MODULES = ["cobot_analysis.api", *sorted({f"cobot_analysis.api.{m}" for m in api.EXPORTS.values()})]


def public_functions(module) -> list[str]:
    """Functions defined in ``module`` whose name does not start with an underscore."""
    return [name for name, obj in vars(module).items()
            if inspect.isfunction(obj) and obj.__module__ == module.__name__ and not name.startswith("_")]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)  # an example that wrote beside it would write here
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS, report=True, verbose=False)
    assert result.attempted > 0, f"{name} has no doctest example"
    assert result.failed == 0, f"{result.failed} of {result.attempted} doctest examples of {name} failed (see the output above)"


@pytest.mark.parametrize("name", MODULES[1:])
def test_every_public_function_has_an_example(name):
    module = importlib.import_module(name)
    missing = [f for f in public_functions(module) if ">>>" not in (getattr(module, f).__doc__ or "")]
    assert public_functions(module) and not missing, f"{name}: no >>> example in {missing}"


def test_every_export_is_documented():
    text = DOC.read_text()
    missing = [n for n in api.EXPORTS if not re.search(rf"`{n}\b", text)]
    assert not missing, f"docs/api.md does not document {missing}"
    for name in api.EXPORTS:  # each exported function with its signature: `name(` starts a code line or span
        obj = getattr(api, name)
        if inspect.isfunction(obj):
            assert re.search(rf"(^|`){name}\(", text, re.M), f"docs/api.md gives no signature for {name}"


def documented_defaults(name: str, text: str) -> dict[str, object]:
    """``option=default`` pairs of the signature docs/api.md gives for ``name`` (its code block line)."""
    import ast

    block = re.search(rf"^{name}\((.*?)\)(?:\s*->|\n```)", text, re.M | re.S)
    assert block, f"docs/api.md gives no signature for {name}"
    pairs = {}
    for key, value in re.findall(r"(\w+)=((?:\"[^\"]*\"|\([^)]*\)|[^,\s)])+)", block.group(1)):
        pairs[key] = ast.literal_eval(value)
    return pairs


def test_documented_defaults_are_the_functions():
    """The signatures docs/api.md shows name every parameter of the functions, with their defaults
    (localise: the options it checks with localisation_options)."""
    text = DOC.read_text()
    for name in api.EXPORTS:
        obj = getattr(api, name)
        if not inspect.isfunction(obj):
            continue
        params = dict(inspect.signature(obj).parameters)
        block = re.search(rf"^{name}\((.*?)\)(?:\s*->|\n```)", text, re.M | re.S).group(1)
        missing = [p for p, v in params.items() if v.kind is not v.VAR_KEYWORD and not re.search(rf"\b{p}\b", block)]
        assert not missing, f"docs/api.md: the signature of {name} lacks {missing}"
        if name == "localise":
            from cobot_analysis.api.localisation import localisation_options

            params.update(inspect.signature(localisation_options).parameters)
        for key, value in documented_defaults(name, text).items():
            assert key in params, f"docs/api.md: {name} has no option {key}"
            assert params[key].default == value, f"docs/api.md: {name}({key}={value!r}), the function's default is {params[key].default!r}"


def test_code_examples_of_the_page_are_python():
    """The example blocks of docs/api.md (not the signature blocks) are valid Python."""
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)
    examples = [b for b in blocks if not re.match(r"\w+\(", b)]
    assert len(examples) >= 14
    for block in examples:
        compile(block, "docs/api.md", "exec")


@pytest.mark.slow
def test_the_pages_examples_run_in_order(datasets, tmp_path, monkeypatch):
    """The example blocks of docs/api.md run as written, top to bottom in one namespace, beside the files they
    name: a protocol (study/protocol.yaml), the published datasets (../shared/datasets), a robot run (run.bag,
    goals.csv) and a workspace (ws). An example that used a name defined further down, or an undefined table,
    failed here."""
    import shutil

    import matplotlib

    from cobot_analysis.stages import data
    from cobot_analysis.stages.localisation import synth_localisation
    from cobot_analysis.synth import walking

    matplotlib.use("Agg")
    repo = tmp_path / "repo"
    (tmp_path / "shared").mkdir()
    (tmp_path / "shared" / "datasets").symlink_to(datasets, target_is_directory=True)
    repo.mkdir()
    monkeypatch.chdir(repo)
    walking.generate(Path("study"), n_subjects=2, n_trials=1, conditions=["E4015", "N1500"])
    synth_localisation(tmp_path / "robot", goals_per_lap=1, stop=3.0, speed=0.3, formats="ros1")
    for name in ("run.bag", "goals.csv"):
        shutil.copy(tmp_path / "robot" / "synth-localisation" / name, name)
    data.synth_walking("ws", subjects=3, repetitions=2, conditions=["N1500", "E4015"], jobs=1)
    data.import_markers("ws", "ws/synth-walking/protocol.yaml", jobs=1)
    data.preprocess("ws", jobs=1)
    blocks = [b for b in re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S) if not re.match(r"\w+\(", b)]
    namespace: dict = {}
    for n, block in enumerate(blocks):
        exec(compile(block, f"docs/api.md, example {n + 1}", "exec"), namespace)  # noqa: S102 - the page's own examples
    assert namespace["r"].run_lines() == ["run: delay 0.547 ± 0.003 s, RMSE 9.0 mm, goals 1/1"]   # as the page shows
    assert set(namespace["model"]["comparison"]) == {"individual-mean", "model"}
