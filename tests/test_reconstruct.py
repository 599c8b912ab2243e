"""Reconstruction of the subjects from the table (docs/methods.md sec. 8)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from cobot_analysis.compare import pivot
from cobot_analysis.errors import InputError
from cobot_analysis.reconstruct import accuracy, read_wrt_table, reconstruct, relative_pose

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import pair_table  # noqa: E402


def test_reconstruct_is_the_rigid_transform_of_the_relative_pose():
    th = np.array([0.0, math.pi / 2, math.pi])
    x, y, t = reconstruct(np.array([1.0, 1.0, 1.0]), np.zeros(3), th, np.full(3, 0.9), np.zeros(3), np.full(3, math.pi))
    np.testing.assert_allclose(x, [1.9, 1.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(y, [0.0, 0.9, 0.0], atol=1e-12)
    np.testing.assert_allclose(t, th + math.pi)


def test_relative_pose_round_trip_is_exact_for_rigid_carriers():
    # no individual noise: subjects are rigidly attached to the table -> reconstruction is exact
    ts = pivot(pair_table(seed=3, n_pairs=3, goals=2, subject_sd=0.0, table_sd=0.05, n=30))
    rel = relative_pose(ts)
    assert set(rel) == {(e, d) for e in ("subject1", "subject2") for d in ("forward", "return")}
    np.testing.assert_allclose(rel[("subject1", "forward")][0], 0.9, atol=1e-12)  # 0.9 m ahead along the long axis
    np.testing.assert_allclose(rel[("subject2", "forward")][0], -0.9, atol=1e-12)
    np.testing.assert_allclose(np.abs(rel[("subject1", "forward")][2]), math.pi, atol=1e-12)  # facing the table
    acc = accuracy(ts, rel, "trials")
    assert len(acc) == 3 * 2 * (1 + 3) * 2  # pairs x goals x (scenario-3 forward + 3 returns) x subjects
    assert acc["d_xy"].max() < 1e-9 and acc["d_theta"].max() < 1e-9


def test_reconstruction_error_grows_with_individual_deviation():
    small = accuracy(ts := pivot(pair_table(seed=4, n_pairs=3, goals=2, subject_sd=0.02, n=30)), relative_pose(ts), "trials")
    large = accuracy(ts := pivot(pair_table(seed=4, n_pairs=3, goals=2, subject_sd=0.2, n=30)), relative_pose(ts), "trials")
    assert 0 < small["d_xy"].mean() < large["d_xy"].mean()


def test_published_relative_pose(datasets):
    rel = read_wrt_table(datasets / "pair-carriage-2022")
    x_fwd, y_fwd, _ = rel[("subject1", "forward")]
    assert len(x_fwd) == 500
    # Subject 1 and Subject 2 hold opposite sides: about 0.9 m from the centre, on opposite sides
    d1 = np.hypot(x_fwd, y_fwd)
    d2 = np.hypot(*rel[("subject2", "forward")][:2])
    assert 0.5 < np.median(d1) < 1.5 and 0.5 < np.median(d2) < 1.5
    assert np.median(x_fwd * rel[("subject2", "forward")][0]) < 0


def test_bad_relative_pose_file(tmp_path):
    (tmp_path / "subject1_wrt_table.dat").write_text("1 2 3\n4 5 6\n")
    with pytest.raises(InputError, match="subject1_wrt_table.dat: expected 6 finite rows"):
        read_wrt_table(tmp_path)
    (tmp_path / "subject1_wrt_table.dat").write_text("\n".join(" ".join(["0.1"] * 5) for _ in range(6)))
    with pytest.raises(InputError, match="subject2_wrt_table.dat: cannot read"):
        read_wrt_table(tmp_path)
