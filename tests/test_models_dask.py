"""``generate`` runs unchanged on a Dask cluster (``--scheduler``) and gives the local run's paths."""

from __future__ import annotations

import pandas as pd
import pytest


@pytest.mark.slow
def test_generate_study_on_dask_equals_local_run(cli, tmp_path, dask_scheduler):
    args = ("generate", "--study", "walking-2020", "--convention", "continuous", "--intervals", "20", "--samples", "40")
    code, _, err = cli(*args, "--out", tmp_path / "local", "--jobs", "2")
    assert code == 0, err
    code, _, err = cli(*args, "--out", tmp_path / "dask", "--scheduler", dask_scheduler)
    assert code == 0, err
    local = pd.read_parquet(tmp_path / "local" / "generate" / "generated.parquet")
    dask = pd.read_parquet(tmp_path / "dask" / "generate" / "generated.parquet")
    assert local["condition"].nunique() == 40  # every start condition of the walking design
    pd.testing.assert_frame_equal(local, dask)
