"""The garbage collector's pause and freeze (cobot_analysis.collector) and the code that makes many objects under
them: they put the collector back as they found it, and no full collection runs where they hold."""

from __future__ import annotations

import doctest
import gc

import pytest

from cobot_analysis import collector
from cobot_analysis.localisation import synth


@pytest.fixture
def full_collections():
    """The number of full (generation 2) collections started while the test runs (explicit ones too)."""
    seen = [0]

    def count(phase, info):
        seen[0] += phase == "start" and info["generation"] == 2

    gc.callbacks.append(count)
    yield seen
    gc.callbacks.remove(count)


def test_the_module_example_runs():
    result = doctest.testmod(collector, report=True, verbose=False)
    assert result.attempted > 0 and result.failed == 0


def test_paused_restores_the_collector_also_when_the_block_raises():
    assert gc.isenabled()
    with pytest.raises(RuntimeError), collector.paused():
        assert not gc.isenabled()
        raise RuntimeError("boom")
    assert gc.isenabled()
    with collector.paused():  # nested: the inner one leaves it off, the outer one turns it back on
        with collector.paused():
            pass
        assert not gc.isenabled()
    assert gc.isenabled()
    gc.disable()
    try:
        with collector.paused():
            pass
        assert not gc.isenabled()  # it was off before: it stays off
    finally:
        gc.enable()


def test_frozen_leaves_out_the_objects_from_before_and_hands_them_back():
    assert gc.get_freeze_count() == 0
    before = [{"i": i} for i in range(2000)]
    with pytest.raises(RuntimeError), collector.frozen():
        assert gc.get_freeze_count() >= len(before)
        raise RuntimeError("boom")
    assert gc.get_freeze_count() == 0
    gc.freeze()  # the caller's freeze is the caller's to undo: frozen() leaves it as it is
    try:
        held = gc.get_freeze_count()
        with collector.frozen():
            made = [{"i": i} for i in range(100)]
        assert gc.get_freeze_count() == held > 0 and made
    finally:
        gc.unfreeze()


def test_writing_a_synthetic_run_runs_no_full_collection(tmp_path, full_collections):
    run = synth.make_run(synth.SynthParams(laps=1, n_goals=2, stop=2.0, speed=0.3, seed=3))
    synth.write_ros1(run, tmp_path / "run.bag")
    synth.write_mcap(run, tmp_path / "run.mcap")
    synth.write_mcap_ros1(run, tmp_path / "ros1.mcap")
    assert full_collections[0] == 0 and gc.isenabled()
    gc.collect()  # the counter counts
    assert full_collections[0] == 1
