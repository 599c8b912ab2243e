"""Shared fixtures: the published datasets and the real lab recordings (skipped cleanly when absent) and CLI
invocation."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def datasets_dir() -> Path | None:
    """``$COBOT_DATASETS`` or ``../shared/datasets`` beside the project, if present."""
    env = os.environ.get("COBOT_DATASETS")
    for cand in ([Path(env)] if env else []) + [ROOT.parent / "shared" / "datasets"]:
        if cand.is_dir():
            return cand
    return None


@pytest.fixture(autouse=True)
def _close_test_figures():
    """Close the figures a test drew itself (``result.figures()``, docstring examples: the caller owns them), so
    that they do not pile up over the session (pyplot warns past 20 open figures). A stage closes its own
    (``workspace.Stage``; tests/test_workspace.py checks it without this)."""
    yield
    plt = sys.modules.get("matplotlib.pyplot")
    if plt is not None:
        plt.close("all")


@pytest.fixture(scope="session")
def datasets() -> Path:
    path = datasets_dir()
    if path is None:
        pytest.skip("published datasets not found: set $COBOT_DATASETS or place them in ../shared/datasets")
    return path


@pytest.fixture
def cli(capsys):
    """Run the CLI in-process: ``code, out, err = cli("import", ...)``."""
    from cobot_analysis.cli import run

    def invoke(*args: str):
        capsys.readouterr()
        code = run([str(a) for a in args])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return invoke


@pytest.fixture
def dask_scheduler():
    """The address of a local Dask cluster (2 worker processes, 1 thread each) for one test, stopped after it
    (an idle cluster kept for the session costs more CPU, about 4 s a minute, than starting one per test). Its
    scheduler's HTTP server on a free port (":0"): .ci/run's two test runs may hold a cluster each at once."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        yield cluster.scheduler_address


def realdata_dir() -> Path | None:
    """``$COBOT_REALDATA`` or ``../shared/realdata`` beside the project, if present."""
    env = os.environ.get("COBOT_REALDATA")
    for cand in ([Path(env)] if env else []) + [ROOT.parent / "shared" / "realdata"]:
        if cand.is_dir():
            return cand
    return None


@pytest.fixture(scope="session")
def realdata() -> Path:
    """Real recordings of other labs (BTKData, pyomeca test files); never copied into the repository."""
    path = realdata_dir()
    if path is None:
        pytest.skip("real lab recordings not found: set $COBOT_REALDATA or place them in ../shared/realdata")
    return path


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items):
    """Tests on the published datasets (the ``datasets`` fixture or marker) are slow: they run in
    ``python -m pytest -m slow`` and ``.ci/run``, not in the default selection (before it is applied)."""
    for item in items:
        if "datasets" in getattr(item, "fixturenames", ()) or item.get_closest_marker("datasets"):
            item.add_marker(pytest.mark.slow)
    _record_ids("collected", items)


def pytest_collection_finish(session):
    _record_ids("selected", session.items)


def _record_ids(what: str, items) -> None:
    """For .ci/run's check that ``python -m pytest`` and ``python -m pytest -m slow`` together run every
    test, without collecting three more times: with ``$COBOT_TEST_IDS`` (a directory) each run writes the
    node ids it collected (before ``-m`` deselects) to ``collected-PID.txt`` and those it runs to
    ``selected-PID.txt``. Under pytest-xdist (``-n``) every worker collects the whole run and selects the same
    tests: the first worker writes the run's ids."""
    directory = os.environ.get("COBOT_TEST_IDS")
    if directory and os.environ.get("PYTEST_XDIST_WORKER", "gw0") == "gw0":
        Path(directory, f"{what}-{os.getpid()}.txt").write_text("".join(f"{item.nodeid}\n" for item in items))
