"""The two worked examples of docs/examples/ run as written and find what was planted."""

from __future__ import annotations

import runpy
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "docs" / "examples"


def run_example(name: str, out: Path) -> dict:
    """``main(out)`` of docs/examples/NAME.py (the script as a user runs it, minus the command line)."""
    return runpy.run_path(str(EXAMPLES / name), run_name="example")["main"](out)


def test_walking_study_from_c3d_to_statistics(tmp_path, capsys):
    found = run_example("walking_study.py", tmp_path)
    printed = capsys.readouterr().out
    # 4 subjects x 4 conditions x 2 repetitions: every trial imported, one walk each, one mean per condition
    assert found["trials"] == 32 and found["trajectories"] == 32 and found["means"] == 4
    assert "import: 32 trials" in printed and "preprocess: 32 trajectories of 500 samples" in printed
    d = found["distances"]
    assert (d["comparison"] == "individual-mean").sum() == 32
    assert d["d_xy"].between(0.01, 0.3).all()  # m: walks of one condition stay within a stride or so of its mean
    stats = found["stats"].set_index("id")
    assert list(stats.index) == ["subjects", "orientation", "distance"]
    assert (stats["status"] == "ok").all() and (stats["n"] == 32).all()
    assert stats["p"].between(0, 1).all() and (stats["p_holm"] >= stats["p"]).all()
    assert stats.loc["subjects", "test"] == "kruskal" and stats.loc["distance", "test"] == "pearson"
    figure = found["figure"]
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and figure.stat().st_size > 10_000
    ind = d[d["comparison"] == "individual-mean"]["d_xy"]
    numbers = found["metrics"]  # the compare result's headline numbers are the distances' own
    assert numbers["compare.individual-mean.walker.n"] == 32
    # numpy's mean and sample sd of the same distances, bit for bit (pandas' own may differ in the last bit:
    # it sums through bottleneck when that is installed)
    assert numbers["compare.individual-mean.walker.d_xy.mean"] == ind.to_numpy().mean()
    assert numbers["compare.individual-mean.walker.d_xy.sd"] == ind.to_numpy().std(ddof=1)
    assert [p.name for p in found["figures"]] == ["means.png", "d_xy.png", "d_theta.png", "d_gamma.png"]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in found["figures"])


def test_robot_run_from_bag_to_localisation_errors(tmp_path, capsys):
    found = run_example("robot_localisation.py", tmp_path)
    printed = capsys.readouterr().out
    planted, run = found["planted"], found["run"]
    assert abs(run["delay"] - planted["delay"]) < 0.005  # s: the planted 0.55 s delay recovered within 5 ms
    for axis in ("x", "y", "z"):
        assert abs(run[f"offset_{axis}"] - planted["offset"][axis]) < 0.003  # m
        # the per-axis error left after the offset is the planted ICP noise (its realised RMSE)
        assert run[f"err_{axis}_rmse"] == pytest.approx(planted["noise_realised"][axis]["rmse"], rel=0.1)
    assert abs(run["offset_yaw"] - planted["offset"]["yaw"]) < 0.002  # rad
    assert run["goals_found"] == run["goals_commanded"] == 1
    assert run["n"] == planted["n_icp"] == len(found["errors"])
    assert np.isfinite(found["errors"][["err_x", "err_y", "err_z", "err_yaw"]].to_numpy()).all()
    assert "/mocap/pose" in printed and "/icp/pose" in printed and f"delay {run['delay']:.4f}" in printed
    assert found["figure"].stat().st_size > 10_000
    numbers = found["metrics"]  # the result's headline numbers are the run's own
    assert numbers["localisation.runs"] == 1 and numbers["localisation.run.delay"] == run["delay"]
    assert numbers["localisation.run.associated"] == run["n"] and numbers["localisation.run.ape_rmse"] == run["ape_rmse"]
    assert sorted(p.stem for p in found["figures"]) == ["delay_cost", "error_distribution", "error_time", "paths", "timeseries_run"]
    assert all(p.stat().st_size > 10_000 for p in found["figures"])
