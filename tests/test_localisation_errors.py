"""Bad input to `localisation` / `bag-info`: one clear line, exit code 2, no partial output."""

from __future__ import annotations

import numpy as np
import pytest

from cobot_analysis.localisation import synth
from cobot_analysis.localisation.report import RUNS
from cobot_analysis.schema import read_table

SHORT = synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)  # a 1-goal run of about 14 s


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    d = tmp_path_factory.mktemp("bags")
    run = synth.make_run(SHORT)
    synth.write_ros1(run, d / "short.bag")
    synth.write_mcap(run, d / "short.mcap")
    return d, run


def _no_output(out):
    assert not (out / "localisation").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")] if out.exists() else True


def _fails(cli, out, *args, match):
    code, _, err = cli("localisation", *args, "--out", out, "--no-figures")
    assert code == 2, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("error:") and all(m in line for m in match), line
    _no_output(out)
    return line


def test_not_a_bag(cli, tmp_path):
    fake = tmp_path / "notes.bag"
    fake.write_text("this is not a bag\n")
    _fails(cli, tmp_path / "ws", fake, match=["notes.bag", "not a readable ROS bag"])
    other = tmp_path / "run.csv"
    other.write_text("t,x\n")
    _fails(cli, tmp_path / "ws", other, match=["run.csv", "unknown extension", ".mcap"])
    empty_dir = tmp_path / "ros2"
    empty_dir.mkdir()
    _fails(cli, tmp_path / "ws", empty_dir, match=["no metadata.yaml"])
    code, _, err = cli("bag-info", fake)
    assert code == 2 and "not a readable ROS bag" in err


@pytest.mark.parametrize("name", ["short.bag", "short.mcap"])
def test_truncated_bag(cli, tmp_path, short, name):
    d, _ = short
    data = (d / name).read_bytes()
    cut = tmp_path / name
    cut.write_bytes(data[: len(data) * 6 // 10])
    line = _fails(cli, tmp_path / "ws", cut, match=[name])
    assert "truncated" in line or "not a readable" in line or "cannot read" in line


def test_missing_topic_lists_the_topics(cli, tmp_path, short):
    d, _ = short
    _fails(cli, tmp_path / "ws", d / "short.bag", "--truth", "/vicon/pose",
           match=["no topic /vicon/pose", "/mocap/pose (geometry_msgs/PoseStamped", "/icp/odom"])


def test_topic_without_pose(cli, tmp_path, short):
    d, _ = short
    _fails(cli, tmp_path / "ws", d / "short.mcap", "--icp", "/walking_controller/cmd_vel",
           match=["geometry_msgs/Twist", "holds no pose"])


def test_tf_frames_missing_or_not_connected(cli, tmp_path, short):
    d, run = short
    _fails(cli, tmp_path / "ws", d / "short.bag", "--icp", "tf:map->camera",
           match=["camera not in the bag", "base_link, map, odom, os_sensor"])

    def add_island(msgs, store):
        T = store.types
        tr = T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](seq=0, stamp=T["builtin_interfaces/msg/Time"](sec=int(synth.T0), nanosec=0), frame_id="world"),
            child_frame_id="camera", transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
        return [(int(synth.T0 * 1e9), "/tf_static", "tf2_msgs/msg/TFMessage", T["tf2_msgs/msg/TFMessage"](transforms=[tr]))] + msgs

    island = tmp_path / "island.bag"
    synth.write_ros1(run, island, edit=add_island)
    _fails(cli, tmp_path / "ws", island, "--icp", "tf:map->camera",
           match=["map and camera are not connected", "world->camera", "map->odom"])


def test_too_few_overlapping_samples(cli, tmp_path):
    run = synth.make_run(SHORT)
    run.t_icp = run.t_icp + 1000.0  # ICP recorded long after the motion capture
    bag = synth.write_ros1(run, tmp_path / "apart.bag")
    _fails(cli, tmp_path / "ws", bag, match=["apart.bag", "too few overlapping samples"])
    _fails(cli, tmp_path / "ws", bag, "--delay", "0.5", match=["too few overlapping samples: 0 ICP poses"])


def test_non_monotonic_stamps_are_sorted_with_a_warning(cli, tmp_path, short):
    d, run = short

    def shuffle(msgs, store):
        icp = [i for i, m in enumerate(msgs) if m[1] == "/icp/pose"]
        msgs = list(msgs)
        for a, b in zip(icp[10:60:2], icp[11:60:2]):  # swap the messages, keep the record times
            msgs[a], msgs[b] = (msgs[a][0], *msgs[b][1:]), (msgs[b][0], *msgs[a][1:])
        return msgs

    bag = synth.write_ros1(run, tmp_path / "shuffled.bag", edit=shuffle)
    code, _, err = cli("localisation", bag, "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    assert "stamps are not monotonic; sorted" in err
    code, _, _ = cli("-q", "localisation", d / "short.bag", "--out", tmp_path / "ws2", "--no-figures")
    assert code == 0
    a = read_table(tmp_path / "ws" / "localisation" / "localisation.parquet", RUNS).iloc[0]
    b = read_table(tmp_path / "ws2" / "localisation" / "localisation.parquet", RUNS).iloc[0]
    assert np.isclose(a["delay"], b["delay"], atol=1e-9) and np.isclose(a["ape_rmse"], b["ape_rmse"], atol=1e-12)


def test_bad_options(cli, tmp_path, short):
    d, _ = short
    _fails(cli, tmp_path / "ws", d / "short.bag", "--icp", "tf:map", match=["bad tf pose spec"])
    _fails(cli, tmp_path / "ws", d / "short.bag", "--delay-window", "0.5", match=["--delay-window needs 2"])
    _fails(cli, tmp_path / "ws", d / "short.bag", "--label", "a", "--label", "b", match=["2 --label for 1 bags"])
    goals = tmp_path / "goals.csv"
    goals.write_text("x,y\n1,2\n")
    _fails(cli, tmp_path / "ws", d / "short.bag", "--goals-csv", goals, match=["goals.csv", "lacks columns ['yaw']"])
    _fails(cli, tmp_path / "ws", match=["no bag given and no synthetic runs"])
