"""`synth localisation` + `localisation` end to end on the ROS1, ROS2 and MCAP versions of the same
run: the planted delay, offset, noise and goal errors are recovered (issue 5 acceptance)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.cli import run as cli_run
from cobot_analysis.localisation.poses import POSES
from cobot_analysis.localisation.tables import ERRORS, GOALS, RUNS
from cobot_analysis.schema import read_table

AXES = ("x", "y", "z", "yaw")


@pytest.fixture(scope="module")
def ws(tmp_path_factory):
    """One full synthetic run (6 goals, about 10 m) in three formats, analysed once without figures."""
    out = tmp_path_factory.mktemp("loc")
    assert cli_run(["-q", "synth", "localisation", "--out", str(out)]) == 0
    assert cli_run(["-q", "localisation", "--out", str(out), "--no-figures", "--map-name", "synthetic"]) == 0
    return out


@pytest.fixture(scope="module")
def truth(ws):
    return json.loads((ws / "synth-localisation" / "truth.json").read_text())


@pytest.fixture(scope="module")
def runs(ws):
    return read_table(ws / "localisation" / "localisation.parquet", RUNS).set_index("run")


def test_synthetic_run_is_written_in_three_formats(ws, truth):
    d = ws / "synth-localisation"
    assert (d / "run.bag").is_file() and (d / "run.mcap").is_file() and (d / "run_ros2" / "metadata.yaml").is_file()
    assert 9.0 < truth["distance"] < 11.0 and len(truth["goals"]) == 6
    goals = pd.read_csv(d / "goals.csv")
    assert np.allclose(goals[["x", "y", "yaw"]].to_numpy(), truth["goals"])
    assert truth["n_mocap"] / truth["duration"] == pytest.approx(200.0, rel=0.01)
    assert truth["n_icp"] / truth["duration"] == pytest.approx(10.0, rel=0.02)


def test_bag_info_lists_topics_rates_and_tf_pairs(ws, cli):
    code, out, _ = cli("bag-info", ws / "synth-localisation" / "run.mcap")
    assert code == 0
    lines = {ln.split("\t")[0]: ln.split("\t") for ln in out.splitlines()}
    assert lines["/mocap/pose"][1] == "geometry_msgs/PoseStamped" and float(lines["/mocap/pose"][3]) == pytest.approx(200.0, rel=1e-3)
    assert lines["/icp/odom"][1] == "nav_msgs/Odometry" and float(lines["/icp/odom"][3]) == pytest.approx(10.0, rel=1e-3)
    assert lines["/walking_controller/cmd_vel"][1] == "geometry_msgs/Twist"
    assert lines["tf:map->odom"][2] == "dynamic" and lines["tf:base_link->os_sensor"][2] == "static"


@pytest.mark.parametrize("run", ["run.bag", "run_ros2", "run.mcap"])
def test_planted_values_are_recovered(runs, truth, run):
    r = runs.loc[run]
    assert r["map"] == "synthetic"
    assert abs(r["delay"] - truth["delay"]) < 0.005
    assert 0 < r["delay_sd"] < 0.005
    for a in ("x", "y", "z"):
        assert abs(r[f"offset_{a}"] - truth["offset"][a]) < 0.001
    assert abs(r["offset_yaw"] - truth["offset"]["yaw"]) < 0.001
    for a in AXES:
        realised = truth["noise_realised"][a]
        assert r[f"err_{a}_mean"] == pytest.approx(realised["mean_abs"], rel=0.1)
        assert r[f"err_{a}_sd"] == pytest.approx(realised["sd_abs"], rel=0.1)
        assert r[f"err_{a}_mean"] == pytest.approx(truth["noise_sd"][a] * np.sqrt(2 / np.pi), rel=0.1)
    assert r["distance"] == pytest.approx(truth["distance"], rel=0.02)
    assert abs(r["drift"]) < 3 * r["drift_sd"] + 1e-4  # no drift planted
    assert r["goals_commanded"] == 6 and r["goals_found"] == 6 and r["goals_within_tolerance"] == 6


def test_three_formats_give_the_same_numbers(runs):
    cols = ["delay", "offset_x", "offset_yaw", "err_x_mean", "ape_rmse", "goal_err_xy_mean"]
    assert np.allclose(runs.loc["run.bag", cols].astype(float), runs.loc["run_ros2", cols].astype(float), rtol=0, atol=1e-9)
    assert np.allclose(runs.loc["run.bag", cols].astype(float), runs.loc["run.mcap", cols].astype(float), rtol=0, atol=1e-9)


def test_goal_errors_match_the_planted_stop_errors(ws, truth):
    g = read_table(ws / "localisation" / "goals.parquet", GOALS)
    planted = np.asarray(truth["stop_errors"])
    for run, gr in g.groupby("run"):
        gr = gr.sort_values("goal")
        assert gr["found"].all()
        assert np.allclose(gr[["dx", "dy"]].to_numpy(), planted[:, :2], atol=0.001)
        assert np.allclose(gr["dyaw"].to_numpy(), planted[:, 2], atol=0.001)
        assert (gr["duration"] > 7.0).all() and (gr["loc_err_xy"] < 0.01).all()


def test_tables_are_consistent(ws, runs):
    poses = read_table(ws / "localisation" / "poses.parquet", POSES)
    err = read_table(ws / "localisation" / "errors.parquet", ERRORS)
    assert set(poses["source"]) == {"truth", "icp"}
    n = err.groupby("run").size()
    assert n.to_dict() == runs["n"].to_dict()
    e = err[err["run"] == "run.bag"]
    assert np.sqrt(np.mean(e["err_xyz"] ** 2)) == pytest.approx(runs.loc["run.bag", "ape_rmse"], rel=1e-12)
    assert np.allclose(e["aligned_x"] - e["truth_x"], e["err_x"])
    md = (ws / "localisation" / "results.md").read_text()
    assert md.startswith("## Localisation accuracy") and "| run.bag | synthetic |" in md and "6/6" in md


def test_other_streams_tf_chain_record_time_and_alignments(ws, cli, truth):
    """Odometry topic and the tf chain give the same answer; record time shifts the delay by the
    planted latencies; Umeyama alignments run and report their method."""
    bag = ws / "synth-localisation" / "run_ros2"
    out = ws / "variants"
    code, _, err = cli("-q", "localisation", bag, "--out", out, "--no-figures", "--icp", "tf:map->base_link", "--alignment", "yaw",
                       "--goals-csv", ws / "synth-localisation" / "goals.csv")
    assert code == 0, err
    r = read_table(out / "localisation" / "localisation.parquet", RUNS).iloc[0]
    assert r["alignment"] == "yaw" and abs(r["delay"] - truth["delay"]) < 0.005 and r["goals_found"] == 6
    code, _, err = cli("-q", "localisation", bag, "--out", out, "--no-figures", "--icp", "/icp/odom", "--time", "record")
    assert code == 0, err
    r = read_table(out / "localisation" / "localisation.parquet", RUNS).iloc[0]
    # record = stamp + 2 ms (mocap) and + 1 ms (ICP): the apparent delay is 1 ms shorter.
    assert abs(r["delay"] - (truth["delay"] - 0.001)) < 0.005 and r["time_base"] == "record"


@pytest.mark.slow
def test_figures_and_manifest(tmp_path, cli):
    """The same run as ``ws`` written as MCAP only, analysed with its figures (not through ``ws``: .ci/run's slow
    selection would analyse the three formats without figures first, for nothing)."""
    assert cli("-q", "synth", "localisation", "--out", tmp_path, "--formats", "mcap")[0] == 0
    out = tmp_path / "figs"
    code, _, err = cli("-q", "localisation", tmp_path / "synth-localisation" / "run.mcap", "--out", out)
    assert code == 0, err
    d = out / "localisation"
    for stem in ("paths", "error_time", "error_distribution", "delay_cost", "timeseries_run"):
        assert (d / f"{stem}.png").stat().st_size > 5000 and (d / f"{stem}.pdf").is_file()
    manifest = json.loads((d / "manifest.json").read_text())
    assert manifest["stage"] == "localisation" and any(i["path"].endswith("run.mcap") for i in manifest["inputs"])
    code, _, err = cli("localisation", tmp_path / "synth-localisation" / "run.mcap", "--out", out)
    assert code == 0 and "up to date" in err


def test_repeated_goals_are_matched_in_command_order(tmp_path):
    """Two laps over the same goals: each stop goes to its own lap's goal (planted errors differ)."""
    from cobot_analysis.localisation import synth
    from cobot_analysis.localisation.analysis import Options, analyse_run

    run = synth.make_run(synth.SynthParams(laps=2, n_goals=2, stop=4.0, speed=0.3, seed=7))
    bag = synth.write_mcap(run, tmp_path / "laps.mcap")
    g = analyse_run((str(bag), "laps", "", Options()))["goals"].sort_values("goal")
    assert len(g) == 4 and g["found"].all()
    assert np.allclose(g[["dx", "dy", "dyaw"]].to_numpy(), run.stop_errors, atol=0.001)
    assert (np.diff(g["t_start"].to_numpy()) > 0).all()
