"""Pose topics read through the bag's own index (localisation/indexed.py) give exactly what the
general reader (rosbags, mcap) gives, and anything unexpected goes to the general reader."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.localisation import bags, indexed, poses, synth
from cobot_analysis.localisation.bags import PoseSpec, read_streams

SPECS = {"truth": PoseSpec.parse("/mocap/pose"), "icp": PoseSpec.parse("/icp/pose"), "odom": PoseSpec.parse("/icp/odom"),
         "transform": PoseSpec.parse("/icp/transform"), "goals": PoseSpec.parse("/goal")}


@pytest.fixture(scope="module")
def run():
    return synth.make_run(synth.SynthParams(n_goals=2, stop=2.0))


def _general(path, specs, time="header"):
    """read_streams through rosbags / mcap only."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(bags, "_indexed_streams", lambda *a, **k: None)
        return read_streams(path, specs, time, optional=("goals",), sparse=("goals",))


def _assert_same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(a[k].t, b[k].t) and np.array_equal(a[k].xyz, b[k].xyz), k
        assert np.array_equal(a[k].quat, b[k].quat) and a[k].frame_id == b[k].frame_id and a[k].meta == b[k].meta, k


WRITERS = {
    "ros1": ("run.bag", lambda r, p: synth.write_ros1(r, p)),
    "ros1-bz2": ("run.bag", lambda r, p: synth.write_ros1(r, p, compression="bz2")),
    "ros1-lz4": ("run.bag", lambda r, p: synth.write_ros1(r, p, compression="lz4")),
    "mcap-cdr": ("run.mcap", lambda r, p: synth.write_mcap(r, p)),
    "mcap-ros1": ("run.mcap", lambda r, p: synth.write_mcap_ros1(r, p)),
}


@pytest.mark.parametrize("kind", sorted(WRITERS))
@pytest.mark.parametrize("time", ["header", "record"])
def test_indexed_read_equals_the_general_reader(run, tmp_path, kind, time):
    name, write = WRITERS[kind]
    path = write(run, tmp_path / name)
    fast = bags._indexed_streams(path, SPECS, time, ("goals",), ("goals",))
    assert fast is not None  # these bags are read through their index
    _assert_same(fast, _general(path, SPECS, time))
    _assert_same(read_streams(path, SPECS, time, optional=("goals",), sparse=("goals",)), fast)
    assert len(fast["truth"]) == len(run.t_mocap) and fast["truth"].frame_id == "mocap"


def test_varying_layouts_tf_and_missing_topics_go_to_the_general_reader(run, tmp_path):
    def rename(msgs, store):  # the ICP frame id changes length half way: two layouts on one topic
        out = []
        for k, (ts, topic, msgtype, msg) in enumerate(msgs):
            if topic == "/icp/pose" and k % 2:
                msg.header.frame_id = "map_long_name"
            out.append((ts, topic, msgtype, msg))
        return out

    path = synth.write_ros1(run, tmp_path / "run.bag", edit=rename)
    assert bags._indexed_streams(path, SPECS, "header", ("goals",), ("goals",)) is None
    _assert_same(read_streams(path, SPECS, optional=("goals",), sparse=("goals",)), _general(path, SPECS))
    good = synth.write_ros1(run, tmp_path / "good.bag")
    tf = {"truth": PoseSpec.parse("/mocap/pose"), "icp": PoseSpec.parse("tf:map->base_link")}
    assert bags._indexed_streams(good, tf, "header", (), ()) is None
    with pytest.raises(InputError, match="no topic /nothing"):  # the general reader's error, unchanged
        read_streams(good, {"truth": PoseSpec.parse("/nothing")})


def test_damaged_index_or_summary_is_left_to_the_general_reader(run, tmp_path):
    bag = synth.write_ros1(run, tmp_path / "run.bag")
    data = bag.read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) - 100])  # the index at the end is truncated
    assert indexed.open_indexed(cut) is None
    mcap = synth.write_mcap_ros1(run, tmp_path / "run.mcap")
    assert indexed.open_indexed(mcap) is not None
    raw = bytearray(mcap.read_bytes())
    end = len(raw) - len(indexed.MCAP_MAGIC)
    crc = int.from_bytes(raw[end - 4:end], "little")
    assert crc == zlib.crc32(raw[int.from_bytes(raw[end - 20:end - 12], "little"):end - 4])  # the summary CRC is checked
    raw[end - 4:end] = (crc ^ 1).to_bytes(4, "little")
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(raw))
    assert indexed.open_indexed(bad) is None


def test_quaternion_maths_against_definitions():
    rng = np.random.default_rng(3)
    q, r = poses.normalise(rng.normal(size=(50, 4))), poses.normalise(rng.normal(size=(50, 4)))
    m = poses.to_matrix(q)
    assert np.allclose(m @ np.swapaxes(m, 1, 2), np.eye(3), atol=1e-12) and np.allclose(np.linalg.det(m), 1.0)
    assert np.allclose(poses.to_matrix(poses.multiply(q, r)), m @ poses.to_matrix(r), atol=1e-12)
    back = poses.from_matrix(m)
    assert np.allclose(np.abs(np.sum(back * q, axis=1)), 1.0, atol=1e-12)  # the same rotation (q or -q)
    v = rng.normal(size=(50, 3))
    assert np.allclose(poses.rotate(q, v), np.einsum("nij,nj->ni", m, v), atol=1e-12)
    yaw = rng.uniform(-3, 3, 50)
    assert np.allclose(poses.yaw_of(poses.from_yaw(yaw, 0.2, -0.1)), yaw, atol=1e-12)
    half = poses.slerp(q, r, np.full(50, 0.5))  # halfway: the same angle to both ends
    ang = lambda a, b: 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0, 1))  # noqa: E731
    assert np.allclose(ang(half, q), ang(half, r), atol=1e-9) and np.allclose(ang(half, q), ang(q, r) / 2, atol=1e-9)
    p, qq = poses.compose(v, q, *poses.invert(v, q))
    assert np.allclose(p, 0, atol=1e-12) and np.allclose(np.abs(qq[:, 3]), 1.0, atol=1e-12)
