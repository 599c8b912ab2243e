"""Issue 21: a bag without the default topics (/mocap/pose, /icp/pose): the refusal names --truth
and --icp, lists the pose topics by message type, and gives the command line when exactly one
pair is plausible (that command then runs)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from cobot_analysis.localisation import synth

sys.path.insert(0, str(Path(__file__).parent))
import damage  # noqa: E402

SHORT = synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)


def _edits(*edits):
    def edit(msgs, store):
        for e in edits:
            msgs = e(msgs, store)
        return msgs
    return edit


@pytest.fixture(scope="module")
def run():
    return synth.make_run(SHORT)


def _refusal(cli, out, bag, *args):
    code, _, err = cli("localisation", bag, *args, "--out", out, "--no-figures")
    assert code == 2, err
    lines = [ln for ln in err.strip().splitlines() if not ln.startswith("localisation runs")]  # the progress bar
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert not (out / "localisation").exists()
    return " ".join(lines[0].split())


@pytest.mark.parametrize("writer, name", [(synth.write_ros1, "a.bag"), (synth.write_mcap, "a.mcap"), (synth.write_ros2, "a_ros2")])
def test_one_plausible_pair_gives_the_command_line_that_works(cli, tmp_path, run, writer, name):
    edit = _edits(damage.drop_topic("/icp/odom"), damage.drop_topic("/icp/transform"),
                  damage.rename_topic("/mocap/pose", "/vicon/robot"), damage.rename_topic("/icp/pose", "/localization/pose"))
    bag = writer(run, tmp_path / name, edit=edit)
    line = _refusal(cli, tmp_path / "ws", bag)
    assert "no topic /mocap/pose for --truth; no topic /icp/pose for --icp" in line
    assert "pose topics in the bag: /goal (geometry_msgs/PoseStamped" in line and "/vicon/robot (geometry_msgs/PoseStamped" in line
    command = f"run `cobot-analysis localisation {bag} --truth /vicon/robot --icp /localization/pose`"
    assert command in line, line
    code, _, err = cli("localisation", bag, "--truth", "/vicon/robot", "--icp", "/localization/pose", "--out", tmp_path / "ws",
                       "--no-figures", "--jobs", "1")
    assert code == 0, err


def test_several_candidates_are_listed_without_a_guess(cli, tmp_path, run):
    edit = _edits(damage.rename_topic("/mocap/pose", "/vicon/robot"), damage.rename_topic("/icp/pose", "/localization/pose"))
    bag = synth.write_ros1(run, tmp_path / "a.bag", edit=edit)
    line = _refusal(cli, tmp_path / "ws", bag)
    assert "/icp/odom (nav_msgs/Odometry" in line and "/icp/transform (geometry_msgs/TransformStamped" in line
    assert "pass the streams with --truth TOPIC and --icp TOPIC" in line and "run `cobot-analysis" not in line
    assert "the bag has /tf and /tf_static: a frame pair is given as tf:PARENT->CHILD" in line


def test_only_the_missing_stream_is_named(cli, tmp_path, run):
    bag = synth.write_ros1(run, tmp_path / "a.bag", edit=damage.rename_topic("/icp/pose", "/robot/pose"))
    line = _refusal(cli, tmp_path / "ws", bag)
    assert "no topic /icp/pose for --icp" in line and "--truth" not in line.split(";")[0]
