"""Bad input to `localisation` / `bag-info`: one clear line, exit code 2, no partial output."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from cobot_analysis.localisation import synth
from cobot_analysis.localisation.tables import RUNS
from cobot_analysis.schema import read_table

sys.path.insert(0, str(Path(__file__).parent))
import damage  # noqa: E402

SHORT = synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)  # a 1-goal run of about 14 s


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    d = tmp_path_factory.mktemp("bags")
    run = synth.make_run(SHORT)
    synth.write_ros1(run, d / "short.bag")
    synth.write_mcap(run, d / "short.mcap")
    synth.write_ros2(run, d / "short_ros2")
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
    cut = damage.truncate(d / name, (d / name).stat().st_size * 6 // 10, tmp_path / name)
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
    island = tmp_path / "island.bag"
    synth.write_ros1(run, island, edit=damage.add_static_tf("world", "camera", synth.T0))
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
    pairs = [(a, a + 1) for a in range(10, 60, 2)]  # messages swapped, record times kept
    bag = synth.write_ros1(run, tmp_path / "shuffled.bag", edit=damage.swap_messages("/icp/pose", pairs))
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
    # The same stream twice (a typo): it was compared with itself, RMSE 0.0 mm beside a delay-edge warning.
    _fails(cli, tmp_path / "ws", d / "short.bag", "--truth", "/icp/pose", "--icp", "/icp/pose",
           match=["--truth and --icp are the same stream /icp/pose", "bag-info"])
    _fails(cli, tmp_path / "ws", d / "short.bag", "--truth", "tf:map->base_link", "--icp", " tf:/map->base_link",
           match=["--truth and --icp are the same stream tf:map->base_link"])


# ---- damaged bags (what `benchmarks/fuzz_inputs.py` found) -------------------------------------------
FORMATS = ["short.bag", "short.mcap", "short_ros2"]


def _copy(d, name, tmp_path):
    """A copy of a seed bag, and the file holding its messages (the .db3 of a ROS2 directory)."""
    if (d / name).is_dir():
        bag = shutil.copytree(d / name, tmp_path / name)
        return bag, next(bag.glob("*.db3"))
    bag = shutil.copy(d / name, tmp_path / name)
    return bag, bag


@pytest.mark.parametrize("name", FORMATS)
@pytest.mark.parametrize("topic, index, field, change, what", [
    ("/mocap/pose", 1000, "y", lambda v: v + 5.0, "a position spike (to and from its neighbours faster than 10 m/s)"),
    ("/mocap/pose", 1000, "qz", lambda v: -v, "an orientation spike (to and from its neighbours faster than 10 rad/s)"),
    ("/icp/pose", 60, "z", lambda v: 1e35, "a position beyond 1000 m from the frame origin (1e+35 m)"),
    ("/goal", 0, "x", lambda v: v + 1000.0, "a position beyond 1000 m from the frame origin (1e+03 m)"),
    ("/mocap/pose", 1000, "nanosec", lambda v: v + 10**9, "a stamp whose nanosec is not below 1e9"),
    ("/mocap/pose", 1000, "sec", lambda v: v + 1, "a stamp out of place (more than 0.5 s from the stamps of the messages "
                                                  "before and after it)"),
    ("/mocap/pose", 1000, "sec", lambda v: v - 3600, "a stamp that jumps by more than 10 s against the bag's record times"),
])
def test_implausible_pose_value_names_the_message(cli, tmp_path, short, name, topic, index, field, change, what):
    d, run = short
    bag, data = _copy(d, name, tmp_path)
    before = damage.pose_of(data, topic, index)
    damage.set_pose_field(data, topic, index, field, change(before[field]))
    n = {"/mocap/pose": len(run.t_mocap), "/icp/pose": len(run.t_icp), "/goal": len(run.goals)}[topic]
    t = before["t"] + (change(before["sec"]) - before["sec"] if field == "sec" else 0)
    stamp = "" if field == "nanosec" else f" (stamp {t:.3f} s)"
    line = _fails(cli, tmp_path / "ws", bag, match=[str(bag), f"{topic}: {what} in message {index + 1} of {n}{stamp}",
                                                     "a damaged bag: re-export it or record it again"])
    assert ("--time record" in line) == ("record times" in what)


def test_damaged_sqlite_record_is_one_line(cli, tmp_path, short):
    bag, db3 = _copy(short[0], "short_ros2", tmp_path)
    damage.db3_set(db3, "/mocap/pose", 10, "timestamp", bytes(10))  # a record's type byte flipped: the time read as a blob
    line = _fails(cli, tmp_path / "ws", bag, match=[str(bag), "cannot read the messages (a damaged record of /mocap/pose: "
                                                    "its time is bytes, its data bytes)", "re-export it (ros2 bag convert)"])
    code, _, err = cli("bag-info", bag)
    assert code == 2 and err.strip().splitlines()[-1] == line


def test_damaged_metadata_is_one_line(cli, tmp_path, short):
    bag, _ = _copy(short[0], "short_ros2", tmp_path)
    damage.replace_bytes(bag / "metadata.yaml", b"type: geometry_msgs/msg/PoseStamped", b"type: []")
    line = _fails(cli, tmp_path / "ws", bag, match=[str(bag), "not a readable ROS bag (ValueError: the topic", "has the message "
                                                    "type [], not a name)"])
    code, _, err = cli("bag-info", bag)
    assert code == 2 and err.strip().splitlines()[-1] == line


def test_tf_topic_of_another_type_is_one_line(cli, tmp_path, short):
    bag = synth.write_mcap_ros1(short[1], tmp_path / "ros1.mcap")
    damage.replace_bytes(bag, b"tf2_msgs/TFMessage", b"tf2_msgs/TF1essage")  # the schema of /tf_static, recorded first
    _fails(cli, tmp_path / "ws", bag, "--icp", "tf:map->base_link",
           match=[str(bag), "topic /tf_static has message type tf2_msgs/TF1essage, not tf2_msgs/TFMessage", "pass a pose topic"])


def test_namespaced_tf_topic_is_read_as_topic_frame_pair(cli, tmp_path, short):
    """A robot whose tf is recorded on /robot1/tf (a namespace, multi-robot setups): `--icp /robot1/tf` was told
    to 'ask for a frame pair: tf:PARENT->CHILD', which reads /tf only and then found no 'map' in the bag.
    The pair on that topic is written /robot1/tf:PARENT->CHILD and gives the numbers of tf:map->base_link."""
    d, run = short
    bag = synth.write_ros1(run, tmp_path / "ns.bag", edit=damage.rename_topic("/tf", "/robot1/tf"))
    _fails(cli, tmp_path / "ws", bag, "--icp", "/robot1/tf", match=["topic /robot1/tf is a tf topic",
                                                                     "/robot1/tf:PARENT->CHILD"])
    _fails(cli, tmp_path / "ws", bag, "--icp", "tf:map->base_link",
           match=["no topic /tf for tf:map->base_link", "tf topics in the bag: /robot1/tf:",
                  "TOPIC:PARENT->CHILD (e.g. /robot1/tf:map->base_link)"])
    code, _, err = cli("localisation", bag, "--icp", "/robot1/tf:map->base_link", "--out", tmp_path / "ns", "--no-figures")
    assert code == 0, err
    code, _, err = cli("localisation", d / "short.bag", "--icp", "tf:map->base_link", "--out", tmp_path / "tf", "--no-figures")
    assert code == 0, err
    ns, tf = (read_table(tmp_path / w / "localisation" / "localisation.parquet", RUNS).iloc[0] for w in ("ns", "tf"))
    assert ns["icp"] == "/robot1/tf:map->base_link"
    for col in ("delay", "ape_rmse", "offset_x", "n"):
        assert ns[col] == tf[col], col
