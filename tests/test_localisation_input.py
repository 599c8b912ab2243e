"""What real lab recordings do to `localisation` / `bag-info`: frames that are not z-up, a delay on
the edge of its window, truth streams sampled more coarsely than 20 Hz, bad option values, damaged
bags. Each gives the right numbers with a warning, or one error line (exit code 2, no output)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cobot_analysis.localisation import synth
from cobot_analysis.localisation.tables import RUNS
from cobot_analysis.schema import read_table

sys.path.insert(0, str(Path(__file__).parent))
import damage  # noqa: E402

SHORT = synth.SynthParams(n_goals=2, stop=3.0, speed=0.3)  # a 2-goal run of about 30 s
# Level frame (x forward, y left, z up) -> camera optical frame (x right, y down, z forward).
CAMERA = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def _one_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _fails(cli, out, *args, match):
    code, _, err = cli("localisation", *args, "--out", out, "--no-figures")
    line = _one_line(err)
    assert code == 2 and all(m in line for m in match), line
    assert not out.exists() or not list(out.iterdir())
    return line


def _runs(out):
    return read_table(out / "localisation" / "localisation.parquet", RUNS).set_index("run")


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    d = tmp_path_factory.mktemp("bags")
    run = synth.make_run(SHORT)
    synth.write_ros1(run, d / "level.bag")
    synth.write_mcap(run, d / "level.mcap")
    return d, run


@pytest.fixture(scope="module")
def level(short, tmp_path_factory):
    """The z-up run analysed once (the reference of the rotated ones)."""
    from cobot_analysis.cli import run as cli_run

    out = tmp_path_factory.mktemp("level")
    assert cli_run(["-q", "localisation", str(short[0] / "level.bag"), "--out", str(out), "--no-figures"]) == 0
    return _runs(out).iloc[0]


# ---- 1. vertical axis --------------------------------------------------------------------------------
def test_camera_frame_run_is_levelled_with_a_warning(cli, tmp_path, short, level):
    d, run = short
    rot = Rotation.from_matrix(CAMERA)
    bag = synth.write_ros1(run, tmp_path / "camera.bag", edit=damage.edit_poses(
        lambda topic, i, xyz, q: (CAMERA @ xyz, (rot * Rotation.from_quat(q) * rot.inv()).as_quat())))
    code, _, err = cli("localisation", bag, "--out", tmp_path / "auto", "--no-figures")
    assert code == 0, err
    flat = " ".join(err.split())
    assert "the motion-capture frame is not z-up: its vertical axis is y (detected" in flat
    assert "the ICP frame is not z-up: its vertical axis is y (detected" in flat
    auto = _runs(tmp_path / "auto").iloc[0]
    assert auto["up_truth"] == "y (detected)" and auto["up_icp"] == "y (detected)"
    # +y is the axis, -y the true up: the levelled frame is the level one turned upside down (about x)
    for col in ("distance", "drift", "delay", "ape_rmse", "err_x_mean", "err_y_mean", "err_yaw_mean", "goal_err_xy_mean", "offset_x"):
        assert auto[col] == pytest.approx(level[col], rel=1e-6, abs=1e-9), col
    for col in ("offset_y", "offset_z", "offset_yaw"):
        assert auto[col] == pytest.approx(-level[col], abs=1e-9), col
    assert auto["distance"] == pytest.approx(run.distance, rel=0.05)
    md = (tmp_path / "auto" / "localisation" / "results.md").read_text()
    assert "Warnings:" in md and "camera: the motion-capture frame is not z-up" in md and "Frames not z-up" in md
    # the sign given: the very numbers of the level run
    code, _, err = cli("-q", "localisation", bag, "--out", tmp_path / "given", "--no-figures", "--up", "-y")
    assert code == 0, err
    given = _runs(tmp_path / "given").iloc[0]
    assert given["up_truth"] == "-y (given)"
    for col in ("distance", "drift", "delay", "offset_x", "offset_y", "offset_z", "offset_yaw", "err_yaw_mean", "goal_err_xy_mean"):
        assert given[col] == pytest.approx(level[col], rel=1e-6, abs=1e-9), col


def test_straight_run_in_a_camera_frame_is_not_guessed_silently(cli, tmp_path):
    from cobot_analysis.localisation.poses import PoseStream, from_yaw
    from cobot_analysis.localisation.vertical import find, warning

    t = np.arange(0, 20, 0.005)
    level = np.column_stack([0.3 * t, 0.03 * np.sin(t * 3.5), 1.0 + 0.008 * np.sin(t * 7)])  # straight, sway, bob
    stream = PoseStream(t, level @ CAMERA.T, from_yaw(np.zeros_like(t)))
    v = find(stream)
    assert (v.axis, v.how) == ("z", "assumed")
    assert "cannot tell the vertical axis of the ICP frame from the motion" in warning("ICP", v)
    assert warning("ICP", find(PoseStream(t, level, stream.quat))) is None  # z-up: nothing to say


# ---- 2. delay on the edge of its window --------------------------------------------------------------
def test_delay_at_the_window_edge_is_warned_with_the_window_to_try(cli, tmp_path, short):
    bag = short[0] / "level.bag"
    code, _, err = cli("localisation", bag, "--out", tmp_path / "narrow", "--no-figures", "--delay-window", "0,0.3")
    assert code == 0, err
    flat = " ".join(err.split())
    assert ("the delay estimate 0.300 s is at the upper end of its search window 0..0.3 s, so it is not a minimum of "
            "the cost: widen the window (e.g. --delay-window 0,0.6)") in flat
    assert "delay 0.300 s (at the edge of the search window: see the warning)" in flat
    r = _runs(tmp_path / "narrow").iloc[0]
    assert r["delay_at_edge"] and np.isnan(r["delay_sd"])
    md = (tmp_path / "narrow" / "localisation" / "results.md").read_text()
    assert "0.300 (at the window edge: see the warnings)" in md and "--delay-window 0,0.6" in md
    code, _, err = cli("localisation", bag, "--out", tmp_path / "wide", "--no-figures", "--delay-window", "0,0.6")
    assert code == 0 and "warning" not in err
    r = _runs(tmp_path / "wide").iloc[0]
    assert not r["delay_at_edge"] and abs(r["delay"] - SHORT.delay) < 0.01 and 0 < r["delay_sd"] < 0.01


# ---- 3. truth sampled every 60 ms ------------------------------------------------------------------------
def test_max_gap_follows_the_truth_sample_spacing(cli, tmp_path):
    run = synth.make_run(synth.SynthParams(n_goals=2, stop=3.0, speed=0.3, mocap_rate=1 / 0.06))
    bag = synth.write_ros1(run, tmp_path / "slow.bag")
    code, _, err = cli("-q", "localisation", bag, "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    r = _runs(tmp_path / "ws").iloc[0]
    assert r["max_gap"] == pytest.approx(0.12, rel=1e-6) and r["n"] == r["n_icp"]
    assert abs(r["delay"] - 0.55) < 0.01
    line = _fails(cli, tmp_path / "ws2", bag, "--max-gap", "0.05",
                  match=["slow.bag: too few associated samples:", "ICP poses inside the motion capture fall in truth gaps "
                         "longer than --max-gap 0.05 s (truth sample spacing: median 0.06 s", "raise --max-gap (e.g. --max-gap 0.12)"])
    assert "cover the same time" not in line


# ---- 4. option values ----------------------------------------------------------------------------------
@pytest.mark.parametrize("args, message", [
    (["--delay-window", "2,1"], "--delay-window MIN,MAX needs MIN < MAX, got '2,1'; e.g. --delay-window 0,1.5"),
    (["--max-gap", "-1"], "--max-gap must be > 0, got -1"),
    (["--tol-xy", "-1"], "--tol-xy must be >= 0, got -1"),
    (["--min-stop", "-5"], "--min-stop must be >= 0, got -5"),
    (["--max-diff", "0"], "--max-diff must be > 0, got 0"),
    (["--delay-weights", "0,0,0,0"], "--delay-weights must be >= 0 with at least one > 0"),
    (["--up", "w"], "--up must be auto, x, y, z, -x, -y, -z or TRUTH,ICP, got 'w'"),
])
def test_option_values_are_checked_before_any_work(cli, tmp_path, short, args, message):
    line = _fails(cli, tmp_path / "ws", short[0] / "level.bag", *args, match=[message])
    assert line.startswith("error: --")


# ---- 10. damaged bags ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["level.bag", "level.mcap"])
def test_overwritten_block_is_one_line(cli, tmp_path, short, name):
    src = short[0] / name
    noise = np.random.default_rng(3).integers(0, 256, 4096, dtype=np.uint8).tobytes()
    bad = damage.overwrite(src, src.stat().st_size // 3, noise, tmp_path / name)
    line = _fails(cli, tmp_path / "ws", bad, match=[str(bad), "truncated or damaged"])
    assert ("rosbag reindex" if name.endswith(".bag") else "mcap recover") in line
    code, _, err = cli("bag-info", bad)
    assert code == 2 and str(bad) in _one_line(err)


@pytest.mark.parametrize("name", ["level.bag", "level.mcap"])
def test_overwritten_quaternion_is_dropped_with_a_warning(cli, tmp_path, short, name):
    d, run = short
    bad, before = damage.set_pose_field(d / name, "/mocap/pose", 1000, "qx", 0.5, tmp_path / name)  # no longer a rotation
    assert [before[f] for f in ("qx", "qy", "qz", "qw")] == pytest.approx(run.mocap_quat[1000], abs=1e-12)
    code, _, err = cli("localisation", bad, "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    n = len(run.t_mocap)
    assert f"/mocap/pose: 1 of {n} message(s) dropped: 1 with an orientation quaternion of norm far from 1" in " ".join(err.split())
    r = _runs(tmp_path / "ws").iloc[0]
    assert r["n_truth"] == n - 1 and "norm far from 1" in r["warnings"]


def test_nan_and_zero_poses_name_the_topic_and_the_cause(cli, tmp_path):
    run = synth.make_run(SHORT)
    n_truth, n_icp = len(run.t_mocap), len(run.t_icp)
    run.mocap_xyz = np.full_like(run.mocap_xyz, np.nan)
    bag = synth.write_ros1(run, tmp_path / "nan.bag")
    _fails(cli, tmp_path / "ws", bag, match=[f"nan.bag: /mocap/pose: no usable pose in {n_truth} message(s) "
                                             f"({n_truth} with NaN/inf values)"])
    zero = synth.write_ros1(synth.make_run(SHORT), tmp_path / "zero.bag", edit=damage.edit_poses(
        lambda topic, i, xyz, q: (xyz, np.zeros(4) if topic == "/icp/pose" else q)))
    _fails(cli, tmp_path / "ws", zero, match=[f"zero.bag: /icp/pose: no usable pose in {n_icp} message(s) ({n_icp} with a "
                                              "zero orientation quaternion (orientation unset))"])


@pytest.mark.parametrize("topic, scale", [("/mocap/pose", 2.0), ("/icp/pose", 0.5)])
def test_quaternions_of_one_constant_norm_are_normalised_with_a_warning(cli, tmp_path, short, level, topic, scale):
    """A publisher that never normalises (every quaternion of norm 2, or 0.5, within 0.2 %) was refused: "no usable
    pose in 4963 message(s) (4963 with an orientation quaternion of norm far from 1 (2..2: damaged))". Its
    orientations are those of the unit quaternions: the numbers of the run as recorded, with one warning."""
    rng = np.random.default_rng(0)
    bag = synth.write_ros1(short[1], tmp_path / "scaled.bag", edit=damage.edit_poses(
        lambda t, i, xyz, q: (xyz, q * scale * (1 + rng.uniform(-0.002, 0.002)) if t == topic else q)))
    code, _, err = cli("localisation", bag, "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    assert f"{topic}: every orientation quaternion has the norm {scale:g}, not 1" in " ".join(err.split())
    r = _runs(tmp_path / "ws").iloc[0]
    assert f"{topic}: every orientation quaternion has the norm" in r["warnings"]
    for col in ("delay", "ape_rmse", "err_yaw_rmse", "offset_yaw", "n_truth", "n_icp"):
        assert r[col] == pytest.approx(level[col], rel=1e-9), col


def test_a_few_damaged_quaternions_among_those_of_one_norm_are_dropped_the_others_normalised(cli, tmp_path, short, level):
    """A publisher that never normalises (norm 2) and a few damaged messages (1 in 25, norms 0.5..1.5): before, the
    whole stream was refused as damaged (no norm shared by all); now the 96 % of one norm are normalised with one
    warning and the others dropped, named in another: the run's numbers those of its recording less 4 % of poses."""
    rng = np.random.default_rng(0)
    bag = synth.write_ros1(short[1], tmp_path / "mostly.bag", edit=damage.edit_poses(
        lambda t, i, xyz, q: (xyz, q * (rng.uniform(0.5, 1.5) if i % 25 == 7 else 2.0) if t == "/icp/pose" else q)))
    code, _, err = cli("localisation", bag, "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    err = " ".join(err.split())
    assert "/icp/pose: every orientation quaternion has the norm 2, not 1" in err
    assert "message(s) dropped: " in err and "with an orientation quaternion of norm far from 1" in err
    r = _runs(tmp_path / "ws").iloc[0]
    assert r["delay"] == pytest.approx(level["delay"], abs=0.01) and r["ape_rmse"] == pytest.approx(level["ape_rmse"], rel=0.1)
    assert r["n_icp"] < level["n_icp"]


def test_quaternions_of_varying_norms_are_damage(cli, tmp_path):
    """Norms spread over 1.5..3 share no constant: damage, as before."""
    rng = np.random.default_rng(0)
    n_icp = len(synth.make_run(SHORT).t_icp)
    bag = synth.write_ros1(synth.make_run(SHORT), tmp_path / "spread.bag", edit=damage.edit_poses(
        lambda t, i, xyz, q: (xyz, q * rng.uniform(1.5, 3.0) if t == "/icp/pose" else q)))
    _fails(cli, tmp_path / "ws", bag, match=[f"spread.bag: /icp/pose: no usable pose in {n_icp} message(s) ({n_icp} with an "
                                             "orientation quaternion of norm far from 1 (1.5"])


def test_too_few_samples_after_damaged_poses_were_dropped_says_so_in_its_line(cli, tmp_path):
    """Norms spread over 0.5..2 leave 2 ICP poses of their stream: before, the one line said 'too few overlapping
    samples' and the cause (the dropped poses) was only in a warning above it; now the line says it."""
    rng = np.random.default_rng(0)
    n_icp = len(synth.make_run(SHORT).t_icp)
    bag = synth.write_ros1(synth.make_run(SHORT), tmp_path / "most.bag", edit=damage.edit_poses(
        lambda t, i, xyz, q: (xyz, q * rng.uniform(0.5, 2.0) if t == "/icp/pose" else q)))
    line = _fails(cli, tmp_path / "ws", bag, match=["most.bag: too few overlapping samples", "; on reading, /icp/pose: ",
                                                   f"of {n_icp} message(s) dropped: "])
    assert "orientation quaternion of norm far from 1" in line and line.endswith("check the topics with `cobot-analysis "
                                                                                 "bag-info` and the recording")


def test_bag_info_prints_long_topic_names_whole(cli, tmp_path):
    long = "/robot/localization/lidar_icp_node_with_a_really_long_name/pose_in_map_frame_estimated"
    bag = synth.write_ros1(synth.make_run(SHORT), tmp_path / "long.bag", edit=damage.rename_topic("/icp/pose", long))
    code, out, err = cli("bag-info", bag)
    assert code == 0
    assert any(long in line for line in err.splitlines())  # the table, wider than 80 columns
    assert f"{long}\tgeometry_msgs/PoseStamped" in out


def test_the_command_as_a_process_flushes_its_lines_and_exit_code(tmp_path, short, level):
    """``cobot-analysis`` ends a finished command with ``os._exit`` (no interpreter teardown): what it printed
    still reaches a pipe whole, its exit code is kept, and the tables are the in-process run's."""
    import os
    import subprocess

    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}
    cmd = [sys.executable, "-m", "cobot_analysis", "localisation", str(short[0] / "level.bag"), "--no-figures"]
    ok = subprocess.run([*cmd, "--out", str(tmp_path / "ok")], capture_output=True, text=True, env=env, timeout=120)
    assert ok.returncode == 0, ok.stderr
    printed = ok.stdout + ok.stderr  # the console writes to stderr
    assert printed.rstrip().endswith(f"localisation: 1 run(s) -> {tmp_path / 'ok' / 'localisation'}"), printed
    assert f"level: delay {level['delay']:.3f} ± {level['delay_sd']:.3f} s" in printed
    assert _runs(tmp_path / "ok").iloc[0].equals(level)
    info = subprocess.run([sys.executable, "-m", "cobot_analysis", "bag-info", str(short[0] / "level.bag")], capture_output=True,
                          text=True, env=env, timeout=120)  # a table on stdout: block-buffered in a pipe
    assert info.returncode == 0 and info.stdout.endswith("\tdynamic\n"), info.stdout[-300:]
    assert [ln.split("\t")[0] for ln in info.stdout.splitlines()[-3:]] == ["tf:base_link->os_sensor", "tf:map->odom", "tf:odom->base_link"]
    bad = subprocess.run([*cmd, "--out", str(tmp_path / "bad"), "--tol-xy", "-1"], capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode == 2 and "--tol-xy must be >= 0" in _one_line(bad.stdout + bad.stderr)


# ---- 11. two runs under one label, goals beyond the lab -----------------------------------------------
def test_two_bags_with_one_label_are_refused(cli, tmp_path, short):
    """A run's label names its rows and metrics (before: exit 0, metrics.json holding an error instead
    of the metrics, and two runs under one name in the tables)."""
    other = tmp_path / "day2" / "level.mcap"
    other.parent.mkdir()
    other.write_bytes((short[0] / "level.mcap").read_bytes())
    _fails(cli, tmp_path / "ws", short[0] / "level.mcap", short[0] / "level.mcap", match=["level.mcap: bag given twice; give each bag once"])
    _fails(cli, tmp_path / "ws", short[0] / "level.mcap", other,
           match=[f"{other}: run label 'level.mcap' given to two bags", "give each bag its own --label"])
    _fails(cli, tmp_path / "ws", short[0] / "level.mcap", other, "--label", "a", "--label", "a",
           match=["run label 'a' given to two bags"])


def test_goals_in_millimetres_are_refused(cli, tmp_path, short):
    goals = tmp_path / "goals.csv"
    goals.write_text("goal,x,y,yaw\n1,1500,-800,0\n")
    _fails(cli, tmp_path / "ws", short[0] / "level.mcap", "--goals-csv", goals,
           match=[f"{goals}: goal 1 (1500, -800) lies beyond the lab (|x|, |y| <= 100 m); give x and y in metres"])


def test_unset_header_stamps_ask_for_the_record_time(cli, tmp_path, short):
    """A node that publishes its poses without stamping them (header.stamp 0): all but one message were
    dropped as repeated stamps and the run refused as '1 pose(s), too few to compare', a remedy that
    does not work. The record times do."""
    from dataclasses import replace

    def unstamped(msgs, store):
        zero = store.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
        return [(ts, tp, mt, replace(m, header=replace(m.header, stamp=zero)) if tp == "/icp/pose" else m)
                for ts, tp, mt, m in msgs]

    bag = synth.write_ros1(short[1], tmp_path / "unstamped.bag", edit=unstamped)
    _fails(cli, tmp_path / "ws", bag, match=[f"unstamped.bag: /icp/pose: {len(short[1].t_icp)} of {len(short[1].t_icp)} "
                                             "messages share the header stamp 0.000 s (unset)", "--time record"])
    code, _, err = cli("localisation", bag, "--time", "record", "--out", tmp_path / "ok", "--no-figures")
    assert code == 0, err
    assert abs(_runs(tmp_path / "ok").iloc[0]["delay"] - SHORT.delay) < 0.01


def test_truth_in_millimetres_is_refused_and_read_with_units(cli, tmp_path, short):
    """Some motion-capture bridges publish millimetres. A lab beyond 1 m from the origin was refused as
    'a damaged bag'; a small one (a rigid body within 1 m of the origin) was compared as metres (the
    delay and the errors of a 1000-times larger motion). Both are refused naming --units, and
    --units mm,m reads the run as the same run in metres."""
    run = synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3, mocap_noise=(1e-6, 0.0)))  # within 1 m of `centre`
    centre = np.array([0.8, 0.2, 1.0])

    def shifted(scale):
        return damage.edit_poses(lambda topic, i, xyz, q: ((scale if topic == "/mocap/pose" else 1) * (xyz - centre), q))

    metres = synth.write_ros1(run, tmp_path / "m.bag", edit=shifted(1))
    mm = synth.write_ros1(run, tmp_path / "mm.bag", edit=shifted(1000))
    _fails(cli, tmp_path / "ws", mm, match=["mm.bag: the positions of /mocap/pose spread 972 times as far as those of "
                                            "/icp/pose", "not the same units", "read it with --units mm,m"])
    for bag, units in ((metres, "m"), (mm, "mm,m")):
        code, _, err = cli("localisation", bag, "--units", units, "--out", tmp_path / units, "--no-figures")
        assert code == 0, err
    r, m = _runs(tmp_path / "mm,m").iloc[0], _runs(tmp_path / "m").iloc[0]
    for col in ("delay", "ape_rmse", "err_x_mean", "offset_x", "distance", "goal_err_xy_mean"):
        assert r[col] == pytest.approx(m[col], rel=1e-6), col
    far = synth.write_ros1(short[1], tmp_path / "far.bag", edit=damage.edit_poses(
        lambda topic, i, xyz, q: (1000 * xyz if topic == "/mocap/pose" else xyz, q)))
    _fails(cli, tmp_path / "ws", far, match=["far.bag: /mocap/pose: a position beyond 1000 m", "in millimetres: --units"])
    noisy = synth.write_ros1(synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)), tmp_path / "noisy.bag",
                             edit=shifted(1000))  # 0.2 mm marker noise read as metres: 40 m/s back and forth at 200 Hz
    _fails(cli, tmp_path / "ws", noisy, match=["noisy.bag: /mocap/pose: a position spike", "in millimetres: --units"])
    assert cli("-q", "localisation", noisy, "--units", "mm,m", "--out", tmp_path / "noisy", "--no-figures")[0] == 0


def test_metres_read_as_millimetres_are_warned_about(cli, tmp_path, short):
    """Both streams in metres read with --units mm: the same motion 1000 times smaller, so the units check that
    compares the two streams cannot see it, and the run reads as a robot standing still (RMSE 0.0 mm). The run goes
    on (a robot may stand still), with a warning in its line and its row that gives the spread in metres."""
    bag = short[0] / "level.bag"
    code, _, err = cli("localisation", bag, "--units", "mm", "--out", tmp_path / "mm", "--no-figures")
    text = " ".join(err.split())
    assert code == 0 and "read with --units mm,mm the poses spread" in text and "as a robot standing still; read in " \
        "metres they spread" in text and "if the robot moved, its positions are in metres (--units m)" in text, err
    assert "read with --units mm,mm" in _runs(tmp_path / "mm").iloc[0]["warnings"]
    code, _, err = cli("localisation", bag, "--out", tmp_path / "m", "--no-figures")
    assert code == 0 and "read with --units" not in err and "read with --units" not in _runs(tmp_path / "m").iloc[0]["warnings"]


def test_truth_frozen_on_its_last_pose_is_a_gap(cli, tmp_path, short, level):
    """A motion-capture bridge that repeats the last pose of a lost rigid body (5 s while the robot walks):
    the ICP was compared with a truth standing still (RMSE 0.2 m instead of 9 mm). The repeats are now
    dropped with a warning, so the comparison leaves that time out like any truth gap."""
    frozen = {}

    def freeze(topic, i, xyz, q):
        if topic == "/mocap/pose" and i == 999:
            frozen["pose"] = (xyz, q)
        return frozen["pose"] if topic == "/mocap/pose" and 1000 <= i < 2000 else (xyz, q)

    bag = synth.write_ros1(short[1], tmp_path / "frozen.bag", edit=damage.edit_poses(freeze))
    code, _, err = cli("localisation", bag, "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    flat = " ".join(err.split())
    assert ("1000 motion-capture poses repeating the pose before them exactly dropped (a lost rigid body whose last pose "
            "the bridge repeats; the longest stretch 5 s from 5.0 s into the stream)") in flat
    r = _runs(tmp_path / "ws").iloc[0]
    assert r["ape_rmse"] == pytest.approx(level["ape_rmse"], rel=0.1) and r["n"] < level["n"] - 40


def test_header_stamps_in_clocks_seconds_apart_are_said(cli, tmp_path, short):
    """The motion-capture PC's clock 3 s ahead of the robot's: with a window wide enough the delay found is
    the 3 s offset minus the robot's 0.55 s, reported as 'the delay' without a word. The run now says that
    the two streams' header stamps stand 3 s apart against the bag's record times."""
    from dataclasses import replace

    def ahead(msgs, store):
        Time = store.types["builtin_interfaces/msg/Time"]

        def shifted(m):
            ns = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec + 3_000_000_000
            return replace(m, header=replace(m.header, stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
        return [(ts, tp, mt, shifted(m) if tp == "/mocap/pose" else m) for ts, tp, mt, m in msgs]

    bag = synth.write_ros1(short[1], tmp_path / "ahead.bag", edit=ahead)
    code, _, err = cli("localisation", bag, "--delay-window=-4,1", "--out", tmp_path / "ws", "--no-figures")
    assert code == 0, err
    flat = " ".join(err.split())
    assert ("the header stamps of /mocap/pose are +3 s from the bag's record times, those of /icp/pose -0.001 s: their "
            "clocks differ by about 3 s, which the delay includes (--time record compares them on the bag's clock)") in flat
    assert _runs(tmp_path / "ws").iloc[0]["delay"] == pytest.approx(SHORT.delay - 3.0, abs=0.01)
