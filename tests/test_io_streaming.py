"""Import written trial by trial (one Parquet row group per trial, by workers' rows) and preprocess
reading each trial's row groups where it is processed: same tables as the in-memory path (issue 22)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

from cobot_analysis import api
from cobot_analysis.preprocess.stage import Params, _trial_row_groups, load_recordings, process
from cobot_analysis.schema import MARKERS, TRIALS, read_table, table_metadata, write_table
from cobot_analysis.synth import walking


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("streaming")
    protocol = walking.generate(tmp / "study", n_subjects=2, n_trials=1, conditions=["E4015", "N1500"])
    memory = api.import_markers(protocol, jobs=1)
    write_table(memory.markers, tmp / "whole" / "markers.parquet", MARKERS, **memory.meta)
    write_table(memory.trials, tmp / "whole" / "trials.parquet", TRIALS, study=memory.plan.protocol.study)
    streamed = api.import_markers(protocol, jobs=2, markers_path=tmp / "streamed.parquet")
    write_table(streamed.trials, tmp / "trials.parquet", TRIALS, study=streamed.plan.protocol.study)
    return tmp, memory, streamed


def _labels_as_text(df: pd.DataFrame) -> pd.DataFrame:
    return df.astype({c: str for c in ("trial", "entity", "marker")})


def test_streamed_markers_equal_the_in_memory_table(imported):
    tmp, memory, streamed = imported
    assert streamed.markers is None and streamed.markers_path == tmp / "streamed.parquet"
    whole, parts = read_table(tmp / "whole" / "markers.parquet", MARKERS), read_table(tmp / "streamed.parquet", MARKERS)
    pd.testing.assert_frame_equal(_labels_as_text(whole), _labels_as_text(parts), check_exact=True)
    assert table_metadata(tmp / "streamed.parquet") == table_metadata(tmp / "whole" / "markers.parquet")
    # what pyarrow reads (the Arrow schema stored in the file) carries the stage metadata too
    assert pq.read_schema(tmp / "streamed.parquet").metadata[b"cobot_analysis"] == pq.read_schema(
        tmp / "whole" / "markers.parquet").metadata[b"cobot_analysis"]
    pd.testing.assert_frame_equal(memory.trials, streamed.trials)
    assert (streamed.n_samples, streamed.n_occluded) == (len(whole), int(whole["occluded"].sum())) and streamed.summary() == memory.summary()


def test_each_trial_is_one_row_group_and_read_there(imported):
    tmp, memory, _ = imported
    index = _trial_row_groups(tmp / "streamed.parquet")
    assert index == {t: [i] for i, t in enumerate(memory.trials["trial"])}
    assert _trial_row_groups(tmp / "whole" / "markers.parquet") is None  # one row group for all: read up front
    lazy = load_recordings(tmp / "streamed.parquet", tmp / "trials.parquet", lazy=True)
    assert [r.row_groups for r in lazy] == [(i,) for i in range(len(lazy))] and all(not r.markers for r in lazy)


@pytest.mark.parametrize("jobs", [1, 2])
def test_preprocess_of_the_streamed_file_equals_the_whole_file(imported, jobs):
    tmp, _, _ = imported
    a = process(tmp / "whole" / "markers.parquet", tmp / "whole" / "trials.parquet", Params(), jobs=jobs)
    b = process(tmp / "streamed.parquet", tmp / "trials.parquet", Params(), jobs=jobs)
    pd.testing.assert_frame_equal(a[0], b[0], check_exact=True)
    pd.testing.assert_frame_equal(a[1], b[1], check_exact=True)
    assert a[2] == b[2] == 4 and not a[3] and not b[3]


def test_a_trial_listed_nowhere_in_the_row_groups_is_refused(imported, tmp_path):
    from cobot_analysis.errors import InputError

    tmp, memory, _ = imported
    trials = memory.trials.copy()
    extra = trials.iloc[[0]].assign(trial="ghost")
    write_table(pd.concat([trials, extra], ignore_index=True), tmp_path / "trials.parquet", TRIALS, study="s")
    with pytest.raises(InputError, match="trial ghost has no pelvis or table marker samples"):
        load_recordings(Path(tmp / "streamed.parquet"), tmp_path / "trials.parquet", lazy=True)
    write_table(trials.iloc[1:], tmp_path / "trials.parquet", TRIALS, study="s")
    with pytest.raises(InputError, match=f"marker rows of trials \\['{trials['trial'][0]}'\\]"):
        load_recordings(Path(tmp / "streamed.parquet"), tmp_path / "trials.parquet", lazy=True)


def test_a_refused_streamed_import_leaves_no_file(tmp_path):
    from cobot_analysis.errors import InputError

    protocol = walking.generate(tmp_path / "study", n_subjects=2, n_trials=1, conditions=["E4015"])
    bad = sorted((protocol.parent / "raw").glob("*.c3d"))[0]
    bad.write_bytes(bad.read_bytes()[:600])  # truncated: refused
    with pytest.raises(InputError, match="1 of 2 trials refused|refused"):
        api.import_markers(protocol, jobs=1, skip_bad=False, markers_path=tmp_path / "m.parquet")
    assert not (tmp_path / "m.parquet").exists()
    kept = api.import_markers(protocol, jobs=1, markers_path=tmp_path / "m.parquet")  # skip_bad: the good trial kept
    assert [t.trial for t in kept.imported] == ["S02_E4015_1"] and len(kept.refused) == 1
    assert table_metadata(tmp_path / "m.parquet")["skipped"].keys() == {"S01_E4015_1"}


def test_each_raw_file_is_hashed_once_and_its_hash_recorded_twice(tmp_path, monkeypatch):
    """In a new workspace each raw file is hashed once, by the worker that reads it; the manifest and the trials
    table's sha256 both record that hash, and it is the file's SHA-256."""
    import hashlib
    import json

    from cobot_analysis import provenance
    from cobot_analysis.stages import data

    protocol = walking.generate(tmp_path / "study", n_subjects=1, n_trials=2, conditions=["E4015"])
    hashed = []
    real = provenance.file_sha256
    monkeypatch.setattr(provenance, "file_sha256", lambda p, *a: hashed.append(Path(p).name) or real(p, *a))
    data.import_markers(tmp_path / "ws", protocol, jobs=1)  # in-process: the worker's calls are seen here
    assert sorted(n for n in hashed if n.endswith(".c3d")) == ["S01_E4015_1.c3d", "S01_E4015_2.c3d"]  # once each
    trials = read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)
    manifest = {Path(i["path"]).name: i["sha256"] for i in json.loads((tmp_path / "ws" / "import" / "manifest.json").read_text())["inputs"]}
    raw = sorted((protocol.parent / "raw").glob("*.c3d"))
    assert len(trials) == len(raw) == 2
    for f, sha in zip(trials["file"], trials["sha256"]):
        name = Path(f).name
        assert sha == manifest[name] == hashlib.sha256((protocol.parent / "raw" / name).read_bytes()).hexdigest()


def test_a_jump_is_named_whether_or_not_the_marker_is_always_visible():
    """``check_positions`` checks the always-visible markers together and the others one by one: the
    earliest jump of either kind is named, and all of them counted."""
    import numpy as np

    from cobot_analysis.errors import InputError
    from cobot_analysis.io.plausibility import check_positions

    xyz = np.zeros((50, 2, 3))
    xyz[:, :, 0] = np.linspace(0, 0.5, 50)[:, None]  # 1 m/s at 100 Hz
    xyz[20:, 0, 1] += 0.3  # A (always visible): 0.3 m between frames 19 and 20
    xyz[5:8, 1] = np.nan  # B occluded in frames 5-7, then 1.2 m away (30 m/s): a jump between frames 4 and 8
    xyz[8:, 1, 2] += 1.2
    with pytest.raises(InputError, match=r"jump of marker B: 1\.2 m between frames 4 and 8 .*2 jumps over the limit in 2 marker"):
        check_positions(xyz, ["A", "B"], 100.0, "x.c3d", max_spike=10.0)
    xyz[8:, 1, 2] -= 1.2
    with pytest.raises(InputError, match=r"jump of marker A: 0\.3 m between frames 19 and 20 \(t = 0\.190 s\), 30 m/s"):
        check_positions(xyz, ["A", "B"], 100.0, "x.c3d", max_spike=10.0)


def test_jumps_found_in_one_pass_are_those_of_each_marker_over_its_visible_frames():
    """The vectorised jump check (every marker at once, each visible frame against the marker's previous
    visible one) against the rule written marker by marker: same first jump named, same count, on random
    recordings with gaps."""
    import re

    import numpy as np

    from cobot_analysis.errors import InputError
    from cobot_analysis.io.plausibility import check_positions

    rng = np.random.default_rng(7)
    seen = 0
    for _ in range(300):
        n, m, rate = int(rng.integers(2, 40)), int(rng.integers(1, 5)), 100.0
        xyz = np.cumsum(rng.normal(0, 0.02, (n, m, 3)), axis=0)
        xyz[rng.random((n, m)) < rng.uniform(0, 0.5)] = np.nan
        for _ in range(int(rng.integers(0, 3))):
            xyz[rng.integers(0, n):, rng.integers(0, m), 0] += 0.5  # a step: one jump where it starts
        expected = []  # (first frame, marker, next frame) of each marker's first jump, and its number of jumps
        for k in range(m):
            idx = np.flatnonzero(~np.isnan(xyz[:, k]).any(axis=1))
            speed = np.linalg.norm(np.diff(xyz[idx, k], axis=0), axis=1) * rate / np.diff(idx)
            fast = np.flatnonzero(speed > 20.0)
            if fast.size:
                expected.append(((int(idx[fast[0]]), k, int(idx[fast[0] + 1])), fast.size))
        try:
            check_positions(xyz, [f"M{k}" for k in range(m)], rate, "x.c3d", max_spike=100.0)
            assert not expected
        except InputError as exc:
            (a, k, b), _ = min(expected)
            total = sum(c for _, c in expected)
            found = re.search(r"jump of marker M(\d+): .* between frames (\d+) and (\d+)", str(exc))
            assert found and tuple(map(int, found.groups())) == (k, a, b)
            assert (f"{total} jumps over the limit in {len(expected)} marker(s)" in str(exc)) == (total > 1)
            seen += 1
    assert seen > 50  # the case is exercised


def _cube(x: int) -> int:
    if x == 7:
        raise ValueError("seven")
    return x ** 3


@pytest.mark.parametrize("jobs,chunk", [(1, 3), (2, 1), (2, 3), (2, 20)])
def test_imap_tasks_in_chunks_yields_every_result_in_order(jobs, chunk):
    """Items sent to the workers a few at a time (``chunk``) still come back one by one, in order, and an
    exception in any item of a chunk is re-raised."""
    from cobot_analysis.parallel import imap_tasks

    items = [0, 1, 2, 3, 4, 5, 6, 8, 9, 10, 11]
    assert list(imap_tasks(_cube, items, jobs=jobs, chunk=chunk, window=2)) == [x ** 3 for x in items]
    with pytest.raises(ValueError, match="seven"):
        list(imap_tasks(_cube, list(range(12)), jobs=jobs, chunk=chunk))


def test_a_file_is_hashed_once_per_version(tmp_path, monkeypatch):
    """``workspace.content_sha256`` reads a file hashed before only when it may have changed: a rewrite of the
    same size with its modification time put back is seen (the status-change time moved), and a file modified
    just before it was hashed is not remembered (file times are kernel ticks)."""
    import hashlib
    import os
    import time

    from cobot_analysis import workspace

    reads = []
    real = workspace.file_sha256
    monkeypatch.setattr(workspace, "file_sha256", lambda p, *a: reads.append(p) or real(p, *a))
    f = tmp_path / "a.bin"
    f.write_bytes(b"x" * 5000)
    monkeypatch.setattr(workspace, "RACY_NS", 10**12)  # modified "just before" (within 1000 s): not remembered
    assert workspace.content_sha256(f) == hashlib.sha256(b"x" * 5000).hexdigest()
    workspace.content_sha256(f)
    assert len(reads) == 2
    monkeypatch.setattr(workspace, "RACY_NS", 0)
    workspace.content_sha256(f)  # remembered from now on
    assert workspace.content_sha256(f) == hashlib.sha256(b"x" * 5000).hexdigest() and len(reads) == 3
    time.sleep(0.1)  # more than a kernel tick: the rewrite gets another status-change time
    st = f.stat()
    with open(f, "r+b") as fh:
        fh.write(b"y")
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns))  # same size, same modification time
    assert f.stat().st_mtime_ns == st.st_mtime_ns and f.stat().st_size == st.st_size
    assert workspace.content_sha256(f) == hashlib.sha256(b"y" + b"x" * 4999).hexdigest() and len(reads) == 4


def test_markers_are_hashed_once_by_import_preprocess(tmp_path, monkeypatch):
    """``import --preprocess``: markers.parquet, hashed for the import's manifest, is the preprocess stage's input
    with that hash, without being read again; both manifests hold its SHA-256."""
    import hashlib
    import json

    from cobot_analysis import workspace
    from cobot_analysis.stages import data

    protocol = walking.generate(tmp_path / "study", n_subjects=1, n_trials=2, conditions=["E4015"])
    reads = []
    real = workspace.file_sha256
    monkeypatch.setattr(workspace, "file_sha256", lambda p, *a: reads.append(Path(p).name) or real(p, *a))
    monkeypatch.setattr(workspace, "RACY_NS", 0)  # a small study is hashed within a tick of its writing
    data.import_and_preprocess(tmp_path / "ws", protocol, jobs=1)
    assert reads.count("markers.parquet") == 1
    sha = hashlib.sha256((tmp_path / "ws" / "import" / "markers.parquet").read_bytes()).hexdigest()
    imported = json.loads((tmp_path / "ws" / "import" / "manifest.json").read_text())
    pre = json.loads((tmp_path / "ws" / "preprocess" / "manifest.json").read_text())
    assert [o["sha256"] for o in imported["outputs"] if o["path"] == "markers.parquet"] == [sha]
    assert [i["sha256"] for i in pre["inputs"] if i["path"].endswith("markers.parquet")] == [sha]
