"""Split recordings: `rosbag record --split` writes one run as run_0.bag, run_1.bag, ...; `--join` reads
the pieces as one run, with the numbers of the unsplit recording; without it they are refused (one
line), `--no-join` analyses each alone. A ROS2 bag directory split into several files is one bag."""

from __future__ import annotations

import numpy as np
import pytest

from cobot_analysis.api import localise
from cobot_analysis.errors import InputError
from cobot_analysis.localisation import bags, synth

RUN = synth.SynthParams(n_goals=3, stop=3.0, speed=0.3)  # about 35 s through 3 goals
CUTS = (6.0, 22.0)  # s into the run: a 6 s first piece, the second cut inside the stop at the second goal


def _pieces(run, d, cuts, stem="run", drop=()):
    """The run written as rosbag record --split does: each message in the piece of its record time."""
    edges = [0, *(int((synth.T0 + c) * 1e9) for c in cuts), 1 << 62]
    return [synth.write_ros1(run, d / f"{stem}_{i}.bag", edit=lambda m, s, lo=lo, hi=hi: [
        x for x in m if lo <= x[0] < hi and x[1] not in drop]) for i, (lo, hi) in enumerate(zip(edges, edges[1:]))]


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    d = tmp_path_factory.mktemp("split")
    run = synth.make_run(RUN)
    return d, run, synth.write_ros1(run, d / "whole.bag"), _pieces(run, d, CUTS)


def _same(a, b):
    """The two results' tables agree in every column but the run's name and file."""
    for name in ("runs", "errors", "goals", "poses"):
        x, y = (getattr(r, name).drop(columns=["run", "file", "warnings"], errors="ignore") for r in (a, b))
        assert x.columns.tolist() == y.columns.tolist()
        for col in x.columns:
            assert np.array_equal(x[col].to_numpy(), y[col].to_numpy()) or np.allclose(x[col], y[col], rtol=1e-12, atol=0), (name, col)


def test_pieces_of_a_split_recording_are_refused_without_join(cli, tmp_path, split):
    d, _, _, pieces = split
    code, _, err = cli("localisation", *pieces[:2], "--out", tmp_path / "out", "--no-figures")
    line = err.strip().splitlines()[-1]
    assert code == 2 and "run_0.bag and run_1.bag are pieces of one split recording" in line, err
    assert "--join" in line and "--no-join" in line
    assert not (tmp_path / "out" / "localisation").exists()


@pytest.mark.parametrize("icp", ["/icp/pose", "tf:map->base_link"])
def test_joined_pieces_give_the_numbers_of_the_whole_recording(split, icp):
    """Analysed alone, the pieces gave delays 0.558, 0.550 and 0.545 s (the whole: 0.5495 s) and 1 of the 3
    goals; joined (given in any order) they give the whole's numbers."""
    d, _, whole, pieces = split
    ref = localise(whole, icp=icp)
    joined = localise([pieces[2], pieces[0], pieces[1]], icp=icp, join=True)
    assert joined.runs["run"].tolist() == ["run"]
    assert joined.runs.loc[0, "file"] == str(d / "run_0.bag+run_1.bag+run_2.bag")
    assert abs(joined.runs.loc[0, "delay"] - 0.55) < 0.003 and joined.runs.loc[0, "goals_found"] == 3
    _same(ref, joined)


def test_no_join_analyses_each_piece_alone(split):
    _, _, _, pieces = split
    r = localise(pieces[1:], join=False)
    assert r.runs["run"].tolist() == ["run_1", "run_2"]
    assert r.runs["goals_found"].sum() == 1  # the cut in the stop at the second goal loses it in both pieces


def test_pieces_read_through_the_index_equal_the_general_reader(split, tmp_path, monkeypatch):
    """Pieces that hold every stream are read through their index, one after the other, as the whole is."""
    _, run, _, _ = split
    pieces = _pieces(run, tmp_path, CUTS, drop=("/goal",))
    specs = {"truth": bags.PoseSpec.parse("/mocap/pose"), "icp": bags.PoseSpec.parse("/icp/pose")}
    fast = bags._indexed_streams(pieces, specs, "header", (), ())
    assert fast is not None
    monkeypatch.setattr(bags, "_indexed_streams", lambda *a, **k: None)
    slow = bags.read_streams(pieces, specs)
    for name in specs:
        assert len(fast[name]) == len(slow[name]) > 0
        assert np.array_equal(fast[name].t, slow[name].t) and np.array_equal(fast[name].xyz, slow[name].xyz)


def test_join_refuses_a_missing_piece_and_files_that_do_not_continue(split, tmp_path):
    d, run, _, pieces = split
    with pytest.raises(InputError, match="run_1.bag is missing between run_0.bag and run_2.bag; give every piece"):
        localise([pieces[0], pieces[2]], join=True)
    other = _pieces(run, tmp_path, (), stem="lap") + [synth.write_ros1(run, tmp_path / "lap_1.bag")]  # two recordings
    with pytest.raises(InputError, match=r"--join: lap_0.bag and lap_1.bag are not pieces of one recording \(lap_1.bag "
                                         r"starts 3\d.\d s before lap_0.bag ends\)"):
        localise(other, join=True)
    assert localise(other, delay=0.55).runs["run"].tolist() == ["lap_0", "lap_1"]  # without --join: two runs


def test_ros2_bag_split_into_files_is_one_bag(split, tmp_path):
    """ros2 bag record --max-bag-size writes one directory with several files and one metadata.yaml: rosbags
    reads it as one bag (already so; this keeps it)."""
    import shutil

    import yaml

    _, run, whole, _ = split
    cut = int((synth.T0 + CUTS[1]) * 1e9)
    parts = [synth.write_ros2(run, tmp_path / f"p{i}", edit=lambda m, s, i=i: [x for x in m if (x[0] < cut) == (i == 0)])
             for i in (0, 1)]
    meta = [yaml.safe_load((p / "metadata.yaml").read_text())["rosbag2_bagfile_information"] for p in parts]
    bag = tmp_path / "run_ros2"
    bag.mkdir()
    files = []
    for i, p in enumerate(parts):
        files.append(f"run_ros2_{i}.db3")
        shutil.copy(next(p.glob("*.db3")), bag / files[-1])
    info = dict(meta[0], relative_file_paths=files, files=[dict(m["files"][0], path=f) for m, f in zip(meta, files)],
                message_count=sum(m["message_count"] for m in meta))
    counts = {}
    for m in meta:
        for t in m["topics_with_message_count"]:
            counts.setdefault(t["topic_metadata"]["name"], dict(t, message_count=0))["message_count"] += t["message_count"]
    info["topics_with_message_count"] = list(counts.values())
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": info}))
    _same(localise(whole), localise(bag))


@pytest.mark.parametrize("write", [synth.write_mcap, synth.write_mcap_ros1])
def test_mcap_pieces_are_joined_or_refused_naming_mcap_merge(split, tmp_path, write):
    """Standalone MCAP pieces join like ROS1 bags (rosbags reads CDR ones; the pose topics of ROS1-encoded ones
    through their index); ROS1-encoded pieces that need the general reader (tf) are refused, naming mcap merge."""
    _, run, _, _ = split
    cut = int((synth.T0 + CUTS[1]) * 1e9)
    pieces = [write(run, tmp_path / f"run_{i}.mcap", edit=lambda m, s, i=i: [x for x in m if (x[0] < cut) == (i == 0)])
              for i in (0, 1)]
    whole = write(run, tmp_path / "whole.mcap")
    _same(localise(whole), localise(pieces, join=True))
    if write is synth.write_mcap:
        _same(localise(whole, icp="tf:map->base_link"), localise(pieces, join=True, icp="tf:map->base_link"))
    else:
        with pytest.raises(InputError, match="run_0.mcap: pieces of an MCAP recording with ROS1-encoded channels cannot be "
                                             r"read as one run; merge them into one file first \(mcap merge run_0.mcap "
                                             r"run_1.mcap -o ONE.mcap\)"):
            localise(pieces, join=True, icp="tf:map->base_link")


@pytest.mark.parametrize("damage, what", [("records", "cannot read the messages"), ("string", "cannot decode a geometry_msgs/PoseStamped")])
def test_a_damaged_piece_of_a_joined_run_is_the_file_named(split, tmp_path, damage, what):
    """Damage inside the second piece (its records, or a frame name's length in a pose message): the one line
    names that piece, whose repair its remedy gives, not the joined run (which no tool can reindex)."""
    d, _, _, pieces = split
    copies = [tmp_path / p.name for p in pieces]
    for p, c in zip(pieces, copies):
        c.write_bytes(p.read_bytes())
    b = bytearray(copies[1].read_bytes())
    if damage == "records":
        for i in range(len(b) // 2, len(b) // 2 + 400, 7):
            b[i] ^= 0xFF
    else:
        i = b.find(b"\x03\x00\x00\x00map", len(b) // 2)
        b[i:i + 4] = b"\xf0\xff\xff\x7f"
    copies[1].write_bytes(bytes(b))
    with pytest.raises(InputError, match=what) as joined:
        localise(copies, join=True)
    assert str(joined.value).startswith(f"{copies[1]}: ") and "reindex it" in str(joined.value)
