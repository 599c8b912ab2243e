"""`cobot-analysis import-published`: the published walking-2020 and pair-carriage-2022 data.

Counts are asserted against the datasets' READMEs (skipped when the data are absent); the
format handling and bad input are tested on small analytic datasets written here.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cobot_analysis.design import WALKING_CONDITIONS
from cobot_analysis.io.published import (DURATIONS, SUBJECT_WRT_TABLE, _pair_files, gamma_checks)
from cobot_analysis.schema import TRAJECTORIES, read_table

N = 500


# ---- analytic data --------------------------------------------------------------------------------
def straight_walk(gamma0=0.1, n=N):
    """Walk along +x from (-2, 0) to (0, 0): heading 0, so theta = gamma (consistent)."""
    x = np.linspace(-2.0, 0.0, n)
    y = np.zeros(n)
    gamma = np.full(n, gamma0)
    return x, y, gamma.copy(), gamma  # x, y, theta, gamma


def test_gamma_checks_analytic():
    ok = straight_walk(0.1)
    large = straight_walk(0.8)
    x, y, theta, gamma = straight_walk(0.1)
    inconsistent = (x, y, theta + 0.6, gamma)  # theta says one thing, gamma another
    stacked = [np.stack(v) for v in zip(ok, large, inconsistent)]
    too_large, mismatch = gamma_checks(*stacked)
    assert too_large.tolist() == [False, True, False]
    assert mismatch.tolist() == [False, False, True]
    # only the 20-80 % window counts: a large gamma at the very start is plausible (turning on the spot)
    x, y, theta, gamma = straight_walk(0.1)
    gamma[:90] = theta[:90] = 1.5
    assert gamma_checks(*(v[None] for v in (x, y, theta, gamma))) == (np.array([False]), np.array([False]))


def write_walking_dataset(directory: Path, missing=("O1500",)) -> dict[str, np.ndarray]:
    """40 files of 11 blocks: block k walks straight with gamma = 0.02 + 0.05 k (+ 2 pi for k = 3: unwrapped)."""
    directory.mkdir(parents=True, exist_ok=True)
    blocks = {}
    for c in WALKING_CONDITIONS:
        b = np.zeros((11, 6, N))
        for k in range(11):
            x, y, theta, gamma = straight_walk(0.02 + 0.05 * k)
            b[k, 0], b[k, 1] = x + 0.01 * k, y
            b[k, 2] = 1.0
            b[k, 4], b[k, 5] = gamma + (2 * np.pi if k == 3 else 0.0), theta
        if c in missing:
            b[[0, 2], 4:6] = 0.0  # the mean and subject 2 lost their orientation
        b[2, 4:6] = 0.0  # subject 2 never has orientation, as in the published data
        np.savetxt(directory / f"{c}.dat", b.reshape(66, N), fmt="%.9g")
        blocks[c] = b
    se = np.array([[b[0, 0, 0], b[0, 1, 0], b[0, 0, -1], b[0, 1, -1]] for b in blocks.values()])
    np.savetxt(directory / "StartAndEnd.dat", se)
    return blocks


@pytest.fixture(scope="module")
def walking_dir(tmp_path_factory):
    """An analytic walking-2020 dataset, written once; copy it before changing it."""
    d = tmp_path_factory.mktemp("walking") / "w"
    write_walking_dataset(d)
    return d


def test_walking_reader_on_analytic_data(walking_dir, tmp_path, cli):
    shutil.copytree(walking_dir, tmp_path / "w")
    ws = tmp_path / "ws"
    code, _, err = cli("import-published", "walking-2020", tmp_path / "w", "--out", ws)
    assert code == 0, err
    df = read_table(ws / "import-published" / "trajectories.parquet", TRAJECTORIES)
    assert df.groupby("trial").size().eq(N).all() and df["trial"].nunique() == 440
    s3 = df[df["trial"] == "E4015_S03"]
    np.testing.assert_allclose(s3["gamma"], 0.17)  # 0.17 + 2 pi published, wrapped here
    np.testing.assert_allclose(s3["theta"], 0.17)
    np.testing.assert_allclose(s3["travelled_distance"], 2.0)
    assert s3["phase"].iloc[0] == 0.0 and s3["phase"].iloc[-1] == 100.0
    assert s3["time"].isna().all() and s3["travel_time"].isna().all()
    assert (s3["subject"] == "S03").all() and (s3["kind"] == "trial").all() and (s3["n_trials"] == 1).all()
    s2 = df[df["subject"] == "S02"]
    assert s2["theta"].isna().all() and (s2["quality"] == "orientation_missing").all()
    means = df[df["kind"] == "mean"]
    assert means["trial"].nunique() == 40 and (means["n_trials"] == 10).all() and means["subject"].isna().all()
    assert set(means.loc[means["quality"] == "orientation_missing", "condition"]) == {"O1500"}
    flagged = df.loc[df["quality"].str.contains("implausible_gamma"), "subject"]
    assert set(flagged) == {"S10"}  # gamma 0.52 rad > 0.5 rad; S09 has 0.47
    code, _, _ = cli("import-published", "walking-2020", tmp_path / "w", "--out", ws, "--gamma-limit", "0.3")
    flagged = read_table(ws / "import-published" / "trajectories.parquet", TRAJECTORIES)
    got = flagged[flagged["quality"].str.contains("implausible_gamma")].groupby("subject")["trial"].nunique()
    assert dict(got) == {f"S{k:02d}": 40 for k in range(6, 11)}
    results = (ws / "import-published" / "results.md").read_text()
    assert "StartAndEnd.dat order" in results and "confirmed" in results


# ---- the published data ---------------------------------------------------------------------------
@pytest.mark.datasets
def test_walking_2020_counts(datasets, tmp_path, cli):
    ws = tmp_path / "ws"
    code, _, err = cli("import-published", "walking-2020", datasets / "walking-2020", "--out", ws)
    assert code == 0, err
    df = read_table(ws / "import-published" / "trajectories.parquet", TRAJECTORIES)
    per = df.groupby(["trial", "entity"]).agg(kind=("kind", "first"), q=("quality", "first"), n=("sample", "size"),
                                               subject=("subject", "first"), cond=("condition", "first"))
    assert (per["n"] == 500).all()
    assert (per["kind"] == "trial").sum() == 400 and (per["kind"] == "mean").sum() == 40
    missing = per["q"].str.contains("orientation_missing")
    assert (missing & (per["kind"] == "trial")).sum() == 125
    assert sorted(per.loc[missing & (per["kind"] == "mean"), "cond"]) == ["O1500", "O4000", "O4015"]
    assert missing[per["subject"] == "S02"].all()
    has = df[~df["quality"].str.contains("orientation_missing")]
    assert has["theta"].notna().all() and (has["gamma"] > -np.pi).all() and (has["gamma"] <= np.pi).all()
    assert df.loc[df["quality"].str.contains("orientation_missing"), ["theta", "gamma"]].isna().all().all()
    first = df[df["sample"] == 0].set_index("trial")
    last = df[df["sample"] == 499].set_index("trial")
    np.testing.assert_allclose(first["travelled_distance"], np.hypot(last["x"] - first["x"], last["y"] - first["y"]))
    results = (ws / "import-published" / "results.md").read_text()
    assert "| subject trajectories without orientation (rows 4-5 all zero) | 125 | 125 |" in results
    assert "StartAndEnd.dat order" in results and ": confirmed" in results
    flagged = per["q"].str.contains("implausible_gamma")
    assert 0 < flagged.sum() < 275 and not (flagged & missing).any()


@pytest.mark.datasets
def test_pair_carriage_2022_counts(datasets, tmp_path, cli):
    ws = tmp_path / "ws"
    code, _, err = cli("import-published", "pair-carriage-2022", datasets / "pair-carriage-2022", "--out", ws)
    assert code == 0, err
    df = read_table(ws / "import-published" / "trajectories.parquet", TRAJECTORIES)
    per = df.groupby(["trial", "entity"]).first()
    assert (df.groupby(["trial", "entity"]).size() == 500).all()
    assert (per["kind"] == "mean").all()
    table = per.xs("table", level="entity")
    fwd = table[table["direction"] == "forward"]
    counts = fwd.groupby("scenario")["n_trials"].sum()
    assert counts.to_dict() == {1: 179, 2: 180, 3: 180}
    assert fwd.loc[fwd["scenario"].isna(), "n_trials"].sum() == 539
    ret = table[table["direction"] == "return"]
    assert ret["n_trials"].sum() == 522 and (ret["scenario"] == 3).all() and len(ret) == 18
    assert (fwd["scenario"] == 3).sum() == 13
    assert set(per.index.get_level_values("entity")) == {"subject1", "subject2", "table"}
    assert "d3_p7_gris_forward_all_end+0" in set(per.index.get_level_values("trial")[per["quality"] == "plain_angle_mean"])
    d = read_table(ws / "import-published" / "durations.parquet", DURATIONS)
    assert d[d["direction"] == "forward"].groupby("scenario").size().to_dict() == {1: 180, 2: 180, 3: 180}
    assert (d["direction"] == "return").sum() == 172 and d["pair"].nunique() == 20
    rel = read_table(ws / "import-published" / "subject_wrt_table.parquet", SUBJECT_WRT_TABLE)
    assert len(rel) == 2 * 2 * 500
    raw = np.loadtxt(datasets / "pair-carriage-2022" / "subject2_wrt_table.dat")
    ret2 = rel[(rel["entity"] == "subject2") & (rel["direction"] == "return")]
    np.testing.assert_array_equal(ret2["y_rel"], raw[3])
    results = (ws / "import-published" / "results.md").read_text()
    assert "| 179 / 180 / 180 (total 539; All data 539) | 179 / 180 / 180 (539) |" in results
    assert "| return durations | 172 of 180 | 172 of 180 |" in results


# ---- bad input ------------------------------------------------------------------------------------
def assert_rejected(cli, ws, dataset, path, *fragments):
    code, _, err = cli("import-published", dataset, path, "--out", ws)
    assert code == 2, err
    message = " ".join(err.split())
    for f in fragments:
        assert f in message, message
    assert not (Path(ws) / "import-published").exists()
    assert not Path(ws).exists() or not list(Path(ws).iterdir())


def test_missing_dataset_folder_and_files(tmp_path, cli):
    assert_rejected(cli, tmp_path / "ws", "walking-2020", tmp_path / "nothere", "nothere: dataset folder not found")
    d = tmp_path / "w"
    d.mkdir()
    for c in WALKING_CONDITIONS[1:]:
        (d / f"{c}.dat").write_text("")
    (d / "StartAndEnd.dat").write_text("")
    assert_rejected(cli, tmp_path / "ws", "walking-2020", d, "N1500.dat: dataset incomplete: N1500.dat missing", "restore")


def test_damaged_walking_file(walking_dir, tmp_path, cli):
    d = tmp_path / "w"
    shutil.copytree(walking_dir, d)
    np.savetxt(d / "E4015.dat", np.zeros((60, N)))
    assert_rejected(cli, tmp_path / "ws", "walking-2020", d, "E4015.dat: has 60 x 500 values, 66 x 500 expected")
    (d / "E4015.dat").write_text("1 2 x\n")
    assert_rejected(cli, tmp_path / "ws", "walking-2020", d, "E4015.dat: not a whitespace-separated numeric matrix")


def test_walking_file_in_millimetres(walking_dir, tmp_path, cli):
    """Positions beyond the lab are not metres (before: imported, exit 0, and every later stage refused them)."""
    d = tmp_path / "w"
    shutil.copytree(walking_dir, d)
    np.savetxt(d / "E4015.dat", np.loadtxt(d / "E4015.dat") * 1000)
    assert_rejected(cli, tmp_path / "ws", "walking-2020", d, "E4015.dat: x, y (rows 1-2 of each block) reach", "beyond the lab",
                    "positions are in metres")


def test_corrupt_pair_json(tmp_path, cli):
    d = tmp_path / "p"
    d.mkdir()
    names = _pair_files() + ["time_and_vel_sub1_leader.json", "time_and_vel_sub2_leader.json",
                             "time_and_vel_sub1_2_leader.json", "start_and_end.json", "subject1_wrt_table.dat", "subject2_wrt_table.dat"]
    for n in names:
        (d / n).write_text("{}")
    (d / "d1_p4_gris_1_mean.json").write_text('{"Trajectoires_Moyennes": {"Table": ')  # truncated download
    assert_rejected(cli, tmp_path / "ws", "pair-carriage-2022", d, "d1_p4_gris_1_mean.json: not valid JSON")
    (d / "d1_p4_gris_1_mean.json").write_text(json.dumps({"Trajectoires_Moyennes": {"Table": {}}}))
    assert_rejected(cli, tmp_path / "ws", "pair-carriage-2022", d, "d1_p4_gris_1_mean.json: entities ['Table']")
    leaf = {"nb": 3, "x": [0.0] * 10, "y": [0.0] * N, "Orientation_Locale": [0.0] * N, "Orientation_Globale": [0.0] * N}
    doc = {"Trajectoires_Moyennes": {e: {"Sujet 1": {"Orientation_Table_End : 0.0": leaf}} for e in ("Sujet 1", "Sujet 2", "Table")}}
    (d / "d1_p4_gris_1_mean.json").write_text(json.dumps(doc))
    assert_rejected(cli, tmp_path / "ws", "pair-carriage-2022", d, "Sujet 1 / Sujet 1 / Orientation_Table_End : 0.0 / x: expected 500 finite numbers")
    leaf["x"] = [2000.0] * N  # millimetres
    (d / "d1_p4_gris_1_mean.json").write_text(json.dumps(doc))
    assert_rejected(cli, tmp_path / "ws", "pair-carriage-2022", d, "Sujet 1 / Sujet 1 / Orientation_Table_End : 0.0 / x, y reach 2000 m")
    (d / "time_and_vel_sub1_leader.json").unlink()
    assert_rejected(cli, tmp_path / "ws", "pair-carriage-2022", d, "time_and_vel_sub1_leader.json: dataset incomplete")


def test_unknown_dataset_is_a_usage_error(tmp_path, cli):
    code, _, _ = cli("import-published", "walking-1999", tmp_path, "--out", tmp_path / "ws")
    assert code == 2 and not (tmp_path / "ws").exists()


def test_reimport_is_skipped_when_unchanged(walking_dir, tmp_path, cli):
    shutil.copytree(walking_dir, tmp_path / "w")
    ws = tmp_path / "ws"
    assert cli("import-published", "walking-2020", tmp_path / "w", "--out", ws)[0] == 0
    code, _, err = cli("import-published", "walking-2020", tmp_path / "w", "--out", ws)
    assert code == 0 and "up to date" in err
    (tmp_path / "w" / "E4015.dat").write_text("1 2\n")  # a changed input is read again (and refused)
    code, _, err = cli("import-published", "walking-2020", tmp_path / "w", "--out", ws)
    assert code == 2 and "E4015.dat: has 1 x 2 values" in " ".join(err.split())
    assert read_table(ws / "import-published" / "trajectories.parquet", TRAJECTORIES)["trial"].nunique() == 440
