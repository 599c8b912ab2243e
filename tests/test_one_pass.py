"""``import --preprocess``: the import and preprocess stages in one pass (each trial preprocessed by the
worker that has just read it) leave exactly what ``import`` then ``preprocess`` leave (issue 22)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.stages import data
from cobot_analysis.synth import pairs, walking


def _same_workspaces(a: Path, b: Path) -> None:
    """Every table (values, types, stage metadata), results.md, metrics.json and the manifests' refusals equal."""
    import pyarrow.parquet as pq

    for stage in ("import", "preprocess"):
        tables = sorted(p.name for p in (a / stage).glob("*.parquet"))
        assert tables and tables == sorted(p.name for p in (b / stage).glob("*.parquet"))
        for name in tables:
            x, y = pd.read_parquet(a / stage / name), pd.read_parquet(b / stage / name)
            pd.testing.assert_frame_equal(x, y, check_exact=True)
            assert pq.read_schema(a / stage / name).metadata == pq.read_schema(b / stage / name).metadata
        for name in ("results.md", "metrics.json"):
            assert (a / stage / name).read_text() == (b / stage / name).read_text(), (stage, name)
        ma, mb = (json.loads((w / stage / "manifest.json").read_text()) for w in (a, b))
        assert ma.get("refused") == mb.get("refused") and ma["params"] == mb["params"]


@pytest.fixture(scope="module")
def walking_study(tmp_path_factory):
    return walking.generate(tmp_path_factory.mktemp("one-pass") / "study", n_subjects=2, n_trials=1,
                            conditions=["E4015", "N1500"])


@pytest.mark.parametrize("jobs", [1, 2])
def test_one_pass_equals_import_then_preprocess(walking_study, tmp_path, jobs):
    data.import_markers(tmp_path / "two", walking_study, jobs=jobs)
    data.preprocess(tmp_path / "two", jobs=jobs)
    imported, pre = data.import_and_preprocess(tmp_path / "one", walking_study, jobs=jobs)
    assert imported.result.preprocessed is not None and len(pre.result.trajectories) == 4 * 500
    _same_workspaces(tmp_path / "two", tmp_path / "one")
    # run again: both stages are up to date, as after the two commands
    again = data.import_and_preprocess(tmp_path / "one", walking_study, jobs=jobs)
    assert again[0].skipped and again[1].skipped


@pytest.mark.slow
def test_one_pass_of_a_pair_study_with_options(tmp_path):
    """Pair recordings (segmentation into forward and return, scenario 3, the table's end orientation) and
    preprocess options (the approach walks kept, 50 samples) come out as with the two stages."""
    protocol = pairs.generate(tmp_path / "study", n_pairs=1, goals=["d1_p4_gris"], scenarios=[1])
    options = {"keep_approach": True, "n_samples": 50}
    data.import_markers(tmp_path / "two", protocol, jobs=2)
    data.preprocess(tmp_path / "two", jobs=2, **options)
    data.import_and_preprocess(tmp_path / "one", protocol, preprocess_options=options, jobs=2)
    _same_workspaces(tmp_path / "two", tmp_path / "one")
    traj = pd.read_parquet(tmp_path / "one" / "preprocess" / "trajectories.parquet")
    assert {"forward", "return", "approach"} <= set(traj["direction"]) and traj.groupby(["trial", "entity"]).size().eq(50).all()


def test_one_pass_refusals_are_those_of_the_two_stages(walking_study, tmp_path, cli):
    """A truncated file: skipped and listed by both (exit 3); with --strict the run is refused (exit 2) and
    nothing is written, the preprocess stage included."""
    import shutil

    study = tmp_path / "study"
    shutil.copytree(walking_study.parent, study)
    bad = sorted((study / "raw").glob("*.c3d"))[0]
    bad.write_bytes(bad.read_bytes()[:600])
    protocol = study / walking_study.name
    assert cli("import", protocol, "--out", tmp_path / "two", "--jobs", "1")[0] == 3
    assert cli("preprocess", "--out", tmp_path / "two", "--jobs", "1")[0] == 0
    assert cli("import", protocol, "--out", tmp_path / "one", "--jobs", "2", "--preprocess")[0] == 3
    _same_workspaces(tmp_path / "two", tmp_path / "one")
    code, _, err = cli("import", protocol, "--out", tmp_path / "strict", "--jobs", "2", "--preprocess", "--strict")
    assert code == 2 and bad.name in err
    assert not (tmp_path / "strict" / "import").exists() and not (tmp_path / "strict" / "preprocess").exists()


def test_a_filter_that_does_not_fit_the_rate_is_refused_as_preprocess_refuses_it(walking_study, tmp_path):
    """The cut-off above the Nyquist frequency (the synthetic files are 200 Hz): the same one-line error,
    naming trials.parquet; the import stage (done first, as with the two commands) is kept."""
    data.import_markers(tmp_path / "two", walking_study, jobs=1)
    with pytest.raises(InputError) as two:
        data.preprocess(tmp_path / "two", jobs=1, cutoff=150.0)
    with pytest.raises(InputError) as one:
        data.import_and_preprocess(tmp_path / "one", walking_study, preprocess_options={"cutoff": 150.0}, jobs=2)
    assert str(one.value) == str(two.value).replace(str(tmp_path / "two"), str(tmp_path / "one"))
    assert "trials.parquet" in str(one.value) and "Nyquist" in str(one.value)
    assert (tmp_path / "one" / "import" / "trials.parquet").is_file() and not (tmp_path / "one" / "preprocess").exists()


def test_one_pass_of_real_lab_files_equals_the_two_stages(realdata, tmp_path, cli):
    """Five real recordings of three labs (C3D Intel and DEC, a CSV export, a marker map): the same tables,
    and the same recordings refused by preprocess (the two static ones: nobody walks), exit 3."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("realdata_study", Path(__file__).with_name("test_realdata_study.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    (tmp_path / "protocol.yaml").write_text(module.PROTOCOL.format(d=realdata))
    assert cli("import", tmp_path / "protocol.yaml", "--out", tmp_path / "two", "--jobs", "1")[0] == 0
    assert cli("preprocess", "--out", tmp_path / "two", "--jobs", "1")[0] == 3
    assert cli("import", tmp_path / "protocol.yaml", "--out", tmp_path / "one", "--jobs", "2", "--preprocess")[0] == 3
    _same_workspaces(tmp_path / "two", tmp_path / "one")
    refused = json.loads((tmp_path / "one" / "preprocess" / "manifest.json").read_text())["refused"]
    assert sorted(r["trial"] for r in refused) == ["pyomeca_c3d", "pyomeca_csv"]


@pytest.mark.slow
def test_one_pass_on_a_dask_cluster(walking_study, tmp_path, dask_scheduler):
    """The workers of a Dask cluster import and preprocess the trials too (the tasks carry everything they need)."""
    data.import_markers(tmp_path / "two", walking_study, jobs=1)
    data.preprocess(tmp_path / "two", jobs=1)
    data.import_and_preprocess(tmp_path / "one", walking_study, scheduler=dask_scheduler)
    _same_workspaces(tmp_path / "two", tmp_path / "one")
