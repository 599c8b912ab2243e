"""A synthetic humanoid robot run with motion capture and ICP localisation, written as real bags.

The robot walks forward along cubic Hermite curves through a start pose and 6 goal poses (about
10 m per lap), stops ``stop`` seconds on each goal, and sways like a humanoid: lateral torso sway
of one cycle per two steps, vertical bob once per step, small yaw and roll oscillations, all
scaled by the walking speed. Everything is generated in the map frame (the frame of the ICP
localisation and of the commanded goals):

- motion capture (ground truth, ``/mocap/pose``, 200 Hz): ``p_mocap(t) = p_map(t) - offset_xyz``,
  ``yaw_mocap = yaw_map - offset_yaw`` (the structural offset of docs/methods.md sec. 9, per axis), plus
  a small measurement noise;
- ICP (``/icp/pose`` PoseStamped, ``/icp/odom`` Odometry, ``/icp/transform`` TransformStamped and
  the tf chain map -> odom -> base_link, 10 Hz): ``p_icp(t) = p_map(t - delay) + noise``;
- commanded goals (``/goal``, PoseStamped in the map frame) and velocity commands
  (``/walking_controller/cmd_vel``, Twist, 10 Hz). The robot stops at ``goal + stop_error`` (a
  planted error within the controller's tolerances) so goal accuracy has a known answer.

The run is written as a ROS1 bag, a ROS2 bag (sqlite3 storage) and a standalone MCAP file with the
rosbags writers; ``truth.json`` and ``goals.csv`` beside them hold the planted values. Every writer
takes an ``edit`` of the message list (tests and ``benchmarks/fuzz_inputs.py`` make defective bags
with it, see ``tests/damage.py``); ``write_mcap_ros1`` writes MCAP with ROS1-encoded channels.
"""

from __future__ import annotations

import json
import shutil
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from cobot_analysis.collector import paused
from cobot_analysis.localisation.poses import compose, from_yaw, invert

T0 = 1_634_300_000.0  # ROS epoch of the synthetic run (October 2021), s
GOALS_MAP = np.array([  # x, y, yaw of the 6 commanded goals (map frame); start pose is (0, 0, 0)
    [1.6, 0.4, 0.5], [2.6, 1.9, 1.7], [1.5, 3.1, 3.0], [0.1, 2.6, -2.3], [-0.3, 1.2, -1.2], [0.2, 0.1, 0.0],
])
TOPICS = {
    "truth": "/mocap/pose", "icp": "/icp/pose", "icp_odom": "/icp/odom", "icp_transform": "/icp/transform",
    "goal": "/goal", "cmd_vel": "/walking_controller/cmd_vel", "tf": "/tf", "tf_static": "/tf_static",
}
TF_MSGDEF = "geometry_msgs/TransformStamped[] transforms\n"


@dataclass
class SynthParams:
    """Planted values of a synthetic run (lengths m, angles rad, times s, rates Hz)."""

    seed: int = 0
    laps: int = 1
    n_goals: int = 6  # goals per lap (the first n of the 6); fewer makes a short run for tests
    speed: float = 0.12
    stop: float = 8.0
    delay: float = 0.55
    offset: tuple[float, float, float, float] = (0.120, -0.085, 0.045, 0.030)  # x, y, z, yaw
    noise: tuple[float, float, float, float] = (0.006, 0.006, 0.003, 0.004)  # ICP sd per axis
    mocap_noise: tuple[float, float] = (0.0002, 0.0002)  # position (m), yaw (rad)
    stop_error: tuple[float, float] = (0.04, 0.035)  # max planted |error| at goals: position, yaw
    mocap_rate: float = 200.0
    icp_rate: float = 10.0
    step_period: float = 0.9
    sway: tuple[float, float, float, float] = (0.03, 0.008, 0.02, 0.01)  # lateral, vertical, yaw, roll
    torso_height: float = 1.05


@dataclass
class SynthRun:
    params: SynthParams
    t_mocap: np.ndarray
    mocap_xyz: np.ndarray
    mocap_quat: np.ndarray
    t_icp: np.ndarray
    icp_xyz: np.ndarray
    icp_quat: np.ndarray
    icp_noise: np.ndarray  # (n, 4) planted ICP noise x, y, z, yaw
    t_cmd: np.ndarray
    cmd: np.ndarray  # (n, 2) forward speed, yaw rate
    goals: np.ndarray  # (k, 3) commanded goals x, y, yaw (map frame)
    goal_times: np.ndarray  # when each goal was commanded
    stop_errors: np.ndarray  # (k, 3) reached - commanded, map frame
    stops: np.ndarray  # (k, 2) start and end of each stop
    distance: float  # nominal travelled distance (path without sway)
    odom_drift: np.ndarray = field(default=None)  # (n, 4) map->odom x, y, z, yaw at t_icp


def _hermite(p0, h0, p1, h1, n=4000):
    """Cubic Hermite curve between two poses with tangents along the headings (|m| = chord)."""
    u = np.linspace(0.0, 1.0, n)[:, None]
    chord = np.linalg.norm(p1 - p0)
    m0 = chord * np.array([np.cos(h0), np.sin(h0)])
    m1 = chord * np.array([np.cos(h1), np.sin(h1)])
    h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
    pts = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    d = (6 * u**2 - 6 * u) * p0 + (3 * u**2 - 4 * u + 1) * m0 + (-6 * u**2 + 6 * u) * p1 + (3 * u**2 - 2 * u) * m1
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    return pts, np.unwrap(np.arctan2(d[:, 1], d[:, 0])), s


def make_run(params: SynthParams | None = None) -> SynthRun:
    """Generate the run (deterministic for ``params.seed``)."""
    p = params or SynthParams()
    rng = np.random.default_rng(p.seed)
    dt = 1.0 / p.mocap_rate
    ramp = 1.5  # s, cosine speed ramps at both ends of a leg
    goals = np.tile(GOALS_MAP[: p.n_goals], (p.laps, 1))
    k = len(goals)
    stop_err = np.column_stack([rng.uniform(-1, 1, (k, 2)) * p.stop_error[0] / np.sqrt(2),
                                rng.uniform(-1, 1, k) * p.stop_error[1]])
    targets = goals + stop_err

    # Timeline on the motion-capture grid: stand 2 s, then (walk, stop) per goal.
    xs, ys, hs, rs, goal_times, stops = [], [], [], [], [], []
    pose = np.array([0.0, 0.0, 0.0])
    t = 0.0
    stand = int(round(2.0 / dt))
    xs.append(np.full(stand, pose[0])), ys.append(np.full(stand, pose[1])), hs.append(np.full(stand, pose[2]))
    rs.append(np.zeros(stand))
    t += stand * dt
    distance = 0.0
    for target in targets:
        goal_times.append(t)
        heading0 = pose[2]
        pts, head, s = _hermite(pose[:2], pose[2], target[:2], target[2])
        head = head - head[0] + heading0  # keep the heading continuous across legs
        length = s[-1]
        distance += length
        n = int(np.ceil((length / p.speed + ramp) / dt))
        tau = np.arange(1, n + 1) * dt
        dur = n * dt
        r = np.minimum(1.0, np.minimum(tau / ramp, (dur - tau) / ramp).clip(0, None))
        r = 0.5 - 0.5 * np.cos(np.pi * r)
        sv = np.cumsum(r) * dt
        sv *= length / sv[-1]
        xs.append(np.interp(sv, s, pts[:, 0])), ys.append(np.interp(sv, s, pts[:, 1]))
        hs.append(np.interp(sv, s, head)), rs.append(r)
        t += dur
        end_heading = hs[-1][-1]
        pose = np.array([target[0], target[1], end_heading])
        m = int(round(p.stop / dt))
        stops.append((t, t + m * dt))
        xs.append(np.full(m, pose[0])), ys.append(np.full(m, pose[1])), hs.append(np.full(m, pose[2]))
        rs.append(np.zeros(m))
        t += m * dt
    tail = int(round(2.0 / dt))  # stand still after the last goal
    xs.append(np.full(tail, pose[0])), ys.append(np.full(tail, pose[1])), hs.append(np.full(tail, pose[2]))
    rs.append(np.zeros(tail))
    x, y, h, r = (np.concatenate(v) for v in (xs, ys, hs, rs))
    tt = np.arange(len(x)) * dt

    # Humanoid sway: gait phase advances only while walking.
    phase = 2 * np.pi * np.cumsum(r) * dt / p.step_period
    lat, vert, dyaw, roll = p.sway
    lateral = lat * r * np.sin(phase / 2)
    px = x - np.sin(h) * lateral
    py = y + np.cos(h) * lateral
    pz = p.torso_height + vert * r * np.sin(phase)
    yaw = h + dyaw * r * np.sin(phase / 2 + 0.7)
    rollv = roll * r * np.sin(phase / 2)

    def map_pose(tq):
        """Map-frame torso pose at times ``tq`` (linear interpolation of the 200 Hz grid)."""
        xyz = np.column_stack([np.interp(tq, tt, px), np.interp(tq, tt, py), np.interp(tq, tt, pz)])
        return xyz, np.interp(tq, tt, yaw), np.interp(tq, tt, rollv)

    off = np.asarray(p.offset)
    mn = rng.normal(0.0, 1.0, (len(tt), 4)) * np.array([p.mocap_noise[0]] * 3 + [p.mocap_noise[1]])
    mocap_xyz = np.column_stack([px, py, pz]) - off[:3] + mn[:, :3]
    mocap_quat = from_yaw(yaw - off[3] + mn[:, 3], 0.0, rollv)

    t_icp = np.arange(p.delay + 0.0137, tt[-1], 1.0 / p.icp_rate)
    noise = rng.normal(0.0, 1.0, (len(t_icp), 4)) * np.asarray(p.noise)
    ixyz, iyaw, iroll = map_pose(t_icp - p.delay)
    icp_xyz = ixyz + noise[:, :3]
    icp_quat = from_yaw(iyaw + noise[:, 3], 0.0, iroll)

    # Odometry frame drifting slowly from the map (the tf chain map -> odom -> base_link).
    rel = t_icp - t_icp[0]
    drift = np.column_stack([0.02 * rel / 60, -0.01 * rel / 60, np.zeros_like(rel), 0.004 * rel / 60])

    # Velocity commands: nominal forward speed and heading rate, 10 Hz.
    t_cmd = np.arange(0.0, tt[-1], 0.1)
    vfwd = np.hypot(np.gradient(x, dt), np.gradient(y, dt))
    wz = np.gradient(h, dt)
    cmd = np.column_stack([np.interp(t_cmd, tt, vfwd), np.interp(t_cmd, tt, wz)])
    return SynthRun(p, tt, mocap_xyz, mocap_quat, t_icp, icp_xyz, icp_quat, noise, t_cmd, cmd, goals,
                    np.asarray(goal_times), stop_err, np.asarray(stops), float(distance), drift)


def truth_summary(run: SynthRun) -> dict:
    """The planted values, as written to ``truth.json``."""
    n = run.icp_noise
    p = run.params
    return {
        "params": asdict(p),
        "t0": T0,
        "delay": p.delay,
        "offset": dict(zip(("x", "y", "z", "yaw"), p.offset)),
        "noise_sd": dict(zip(("x", "y", "z", "yaw"), p.noise)),
        "noise_realised": {a: {"mean_abs": float(np.mean(np.abs(n[:, i]))), "sd_abs": float(np.std(np.abs(n[:, i]), ddof=1)),
                               "rmse": float(np.sqrt(np.mean(n[:, i] ** 2)))} for i, a in enumerate(("x", "y", "z", "yaw"))},
        "distance": run.distance,
        "goals": run.goals.tolist(),
        "stop_errors": run.stop_errors.tolist(),
        "stops": (run.stops + T0).tolist(),
        "duration": float(run.t_mocap[-1]),
        "n_mocap": int(len(run.t_mocap)),
        "n_icp": int(len(run.t_icp)),
        "topics": TOPICS,
    }


# ---- writers ----------------------------------------------------------------------------------
def _typestore(ros1: bool):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:
        store.register(get_types_from_msg(TF_MSGDEF, "tf2_msgs/msg/TFMessage"))
    return store


def _messages(run: SynthRun, store, ros1: bool):
    """``(record time ns, topic, msgtype, message)`` of the whole run, in record-time order. A 10-minute run's
    are about a million small objects, without reference cycles: the writers make and write them with the
    garbage collector paused (``collector.paused``: its full collections took 3.6 of the 9.0 s of CPU of
    ``synth localisation``)."""
    T = store.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Point, Quat, Vec3 = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Vector3"]
    Pose, PoseStamped = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/PoseStamped"]
    Transform, TransformStamped = T["geometry_msgs/msg/Transform"], T["geometry_msgs/msg/TransformStamped"]
    Twist = T["geometry_msgs/msg/Twist"]
    Odom, PWC, TWC = T["nav_msgs/msg/Odometry"], T["geometry_msgs/msg/PoseWithCovariance"], T["geometry_msgs/msg/TwistWithCovariance"]
    TF = T["tf2_msgs/msg/TFMessage"]
    seq = [0]

    def header(t, frame):
        ns = int(round((t + T0) * 1e9))
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        if ros1:
            seq[0] += 1
            return Header(seq=seq[0], stamp=stamp, frame_id=frame)
        return Header(stamp=stamp, frame_id=frame)

    def pose(xyz, q):
        return Pose(position=Point(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                    orientation=Quat(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])))

    def transform(xyz, q):
        return Transform(translation=Vec3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                         rotation=Quat(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])))

    def rec(t, latency):
        return int(round((t + T0 + latency) * 1e9))

    out = []
    for t, xyz, q in zip(run.t_mocap, run.mocap_xyz, run.mocap_quat):
        out.append((rec(t, 0.002), TOPICS["truth"], "geometry_msgs/msg/PoseStamped",
                    PoseStamped(header=header(t, "mocap"), pose=pose(xyz, q))))
    zero = Vec3(x=0.0, y=0.0, z=0.0)
    cov = np.zeros(36)
    odom_xyz = np.column_stack([run.odom_drift[:, :3]])
    odom_q = from_yaw(run.odom_drift[:, 3])
    base_xyz, base_q = compose(*invert(odom_xyz, odom_q), run.icp_xyz, run.icp_quat)  # odom -> base_link
    for i, (t, xyz, q) in enumerate(zip(run.t_icp, run.icp_xyz, run.icp_quat)):
        r = rec(t, 0.001)
        out.append((r, TOPICS["icp"], "geometry_msgs/msg/PoseStamped", PoseStamped(header=header(t, "map"), pose=pose(xyz, q))))
        out.append((r, TOPICS["icp_odom"], "nav_msgs/msg/Odometry",
                    Odom(header=header(t, "map"), child_frame_id="base_link", pose=PWC(pose=pose(xyz, q), covariance=cov),
                         twist=TWC(twist=Twist(linear=zero, angular=zero), covariance=cov))))
        out.append((r, TOPICS["icp_transform"], "geometry_msgs/msg/TransformStamped",
                    TransformStamped(header=header(t, "map"), child_frame_id="base_link", transform=transform(xyz, q))))
        out.append((r, TOPICS["tf"], "tf2_msgs/msg/TFMessage", TF(transforms=[
            TransformStamped(header=header(t, "map"), child_frame_id="odom", transform=transform(odom_xyz[i], odom_q[i])),
            TransformStamped(header=header(t, "odom"), child_frame_id="base_link", transform=transform(base_xyz[i], base_q[i])),
        ])))
    static = TF(transforms=[TransformStamped(header=header(0.0, "base_link"), child_frame_id="os_sensor",
                                             transform=transform([0.02, 0.0, 0.6], from_yaw(np.pi / 2)))])
    out.append((rec(0.0, 0.0), TOPICS["tf_static"], "tf2_msgs/msg/TFMessage", static))
    for t, g in zip(run.goal_times, run.goals):
        out.append((rec(t, 0.0), TOPICS["goal"], "geometry_msgs/msg/PoseStamped",
                    PoseStamped(header=header(t, "map"), pose=pose([g[0], g[1], 0.0], from_yaw(g[2])))))
    for t, (v, w) in zip(run.t_cmd, run.cmd):
        out.append((rec(t, 0.0), TOPICS["cmd_vel"], "geometry_msgs/msg/Twist",
                    Twist(linear=Vec3(x=float(v), y=0.0, z=0.0), angular=Vec3(x=0.0, y=0.0, z=float(w)))))
    out.sort(key=lambda m: m[0])
    return out


@paused()
def write_ros1(run: SynthRun, path: Path, edit=None, compression: str | None = None) -> Path:
    """ROS1 bag (format 2.0), uncompressed or with ``compression`` 'bz2' / 'lz4' chunks.
    ``edit(messages, typestore)`` may alter the list of ``(record ns, topic, msgtype, message)``
    first (tests use it to make defective bags)."""
    from rosbags.rosbag1 import Writer

    store = _typestore(ros1=True)
    msgs = _messages(run, store, ros1=True)
    if edit is not None:
        msgs = edit(msgs, store)
    writer = Writer(path)
    if compression:
        writer.set_compression(Writer.CompressionFormat[compression.upper()])
    with writer:
        conns = {}
        for ts, topic, msgtype, msg in msgs:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store,
                                                     latching=1 if topic == TOPICS["tf_static"] else None)
            writer.write(conns[topic], ts, store.serialize_ros1(msg, msgtype))
    return path


@paused()
def write_ros2(run: SynthRun, path: Path, storage: str = "sqlite3", edit=None) -> Path:
    """ROS2 bag directory (rosbag2 format 9), sqlite3 or mcap storage; ``edit`` as for ``write_ros1``."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = _typestore(ros1=False)
    msgs = _messages(run, store, ros1=False)
    if edit is not None:
        msgs = edit(msgs, store)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        conns = {}
        for ts, topic, msgtype, msg in msgs:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            writer.write(conns[topic], ts, store.serialize_cdr(msg, msgtype))
    return path


def write_mcap(run: SynthRun, path: Path, edit=None) -> Path:
    """A standalone MCAP file (ros2msg schemas, CDR messages), as ``ros2 bag record -s mcap`` makes;
    ``edit`` as for ``write_ros1``."""
    tmp = Path(tempfile.mkdtemp(prefix=".mcap-", dir=path.parent))
    try:
        write_ros2(run, tmp / "bag", storage="mcap", edit=edit)
        (mcap,) = (tmp / "bag").glob("*.mcap")
        shutil.move(mcap, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path


@paused()
def write_mcap_ros1(run: SynthRun, path: Path, edit=None) -> Path:
    """A standalone MCAP file with ROS1-encoded channels (ros1msg schemas), as ``mcap-ros1-support``
    writes it; ``edit`` as for ``write_ros1``."""
    from mcap.writer import Writer

    store = _typestore(ros1=True)
    msgs = _messages(run, store, ros1=True)
    if edit is not None:
        msgs = edit(msgs, store)
    with open(path, "wb") as fh:
        writer = Writer(fh)
        writer.start(profile="ros1", library="cobot-analysis synth")
        channels = {}
        for ts, topic, msgtype, msg in msgs:
            if topic not in channels:
                schema = writer.register_schema(msgtype.replace("/msg/", "/"), "ros1msg",
                                                store.generate_msgdef(msgtype, ros_version=1)[0].encode())
                channels[topic] = writer.register_channel(topic, "ros1", schema)
            writer.add_message(channels[topic], log_time=ts, data=bytes(store.serialize_ros1(msg, msgtype)), publish_time=ts)
        writer.finish()
    return path


def write_goals_csv(run: SynthRun, path: Path) -> Path:
    """Commanded goals: ``goal, x, y, yaw`` (map frame, m and rad)."""
    lines = ["goal,x,y,yaw"] + [f"{i + 1},{g[0]:.6f},{g[1]:.6f},{g[2]:.6f}" for i, g in enumerate(run.goals)]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_truth(run: SynthRun, path: Path) -> Path:
    path.write_text(json.dumps(truth_summary(run), indent=2) + "\n")
    return path
