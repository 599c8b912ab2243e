"""`cobot-analysis import`: C3D, Vicon CSV and Qualisys TSV readers, label mapping, bad input.

Test files are written here (C3D with ezc3d, text exports by hand), never committed.
"""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cobot_analysis.errors import InputError
from cobot_analysis.io.c3d import read_c3d
from cobot_analysis.io.markers import ImportedTrial, detect_format, long_table
from cobot_analysis.io.protocol import save_protocol
from cobot_analysis.io.text_exports import read_qualisys_tsv, read_vicon_csv
from cobot_analysis.schema import MARKERS, TRIALS, read_table, table_metadata

RATE = 200.0
PELVIS_OFFSETS = {"LASI": (0.0, 0.12, 0.0), "RASI": (0.0, -0.12, 0.0), "LPSI": (-0.16, 0.045, 0.02), "RPSI": (-0.16, -0.045, 0.02)}
TABLE_OFFSETS = {"TAB1": (-0.61, 0.40, 0.0), "TAB2": (0.61, 0.40, 0.0), "TAB3": (-0.61, -0.40, 0.0)}


# ---- test data ------------------------------------------------------------------------------------
def person(n=100, x0=0.0, y0=0.0, speed=1.0, prefix="", extra=("LHEE",)):
    """Pelvis (and a heel) of a person walking along +x at ``speed`` m/s: label -> [n, 3] in m."""
    t = np.arange(n) / RATE
    centre = np.stack([x0 + speed * t, np.full(n, y0), 0.95 + 0.01 * np.sin(2 * np.pi * 1.8 * t)], axis=1)
    out = {f"{prefix}{k}": centre + np.array(v) for k, v in PELVIS_OFFSETS.items()}
    for k in extra:
        out[f"{prefix}{k}"] = centre + np.array([-0.05, 0.1, -0.9])
    return out


def table(n=100, prefix="Table:"):
    t = np.arange(n) / RATE
    centre = np.stack([0.5 * t, np.zeros(n), np.full(n, 0.77)], axis=1)
    return {f"{prefix}{k}": centre + np.array(v) for k, v in TABLE_OFFSETS.items()}


def write_c3d(path, markers, units="mm", scale=1000.0, rate=RATE):
    """C3D written with ezc3d; NaN samples become occluded points."""
    import ezc3d

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(markers)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = [units]
    xyz = np.stack(list(markers.values()), axis=1) * scale  # [frames, markers, 3]
    points = np.ones((4, xyz.shape[1], xyz.shape[0]))
    points[:3] = xyz.transpose(2, 1, 0)
    c3d["data"]["points"] = points
    c3d.write(str(path))
    return Path(path)


def write_vicon_csv(path, markers, scale=1000.0, units="mm", frames=None):
    """Vicon Nexus CSV export with a Devices section before the Trajectories section."""
    labels = list(markers)
    xyz = np.stack(list(markers.values()), axis=1) * scale
    n = xyz.shape[0]
    frames = np.arange(1, n + 1) if frames is None else frames
    lines = ["Devices", "1000", ",,Force Plate", "Frame,Sub Frame,Fx", ",,N", "1,0,0.5", "",
             "Trajectories", f"{RATE:g}", ",," + ",".join(f"Subj:{lab},," for lab in labels),
             "Frame,Sub Frame," + ",".join("X,Y,Z" for _ in labels), ",," + ",".join(f"{units},{units},{units}" for _ in labels)]
    for i in range(n):
        cells = ["" if np.isnan(v) else f"{v:.5f}" for v in xyz[i].ravel()]
        lines.append(f"{frames[i]},0," + ",".join(cells))
    Path(path).write_text("\n".join(lines) + "\n\n")
    return Path(path)


def write_qtm_tsv(path, markers, scale=1000.0, times=None):
    """Qualisys TSV export; occluded samples written as 0 0 0 as QTM does."""
    labels = list(markers)
    xyz = np.nan_to_num(np.stack(list(markers.values()), axis=1) * scale, nan=0.0)
    n = xyz.shape[0]
    times = np.arange(n) / RATE if times is None else times
    head = [f"NO_OF_FRAMES\t{n}", "NO_OF_CAMERAS\t20", f"NO_OF_MARKERS\t{len(labels)}", f"FREQUENCY\t{RATE:g}",
            "NO_OF_ANALOG\t0", "DESCRIPTION\t--", "DATA_INCLUDED\t3D", "MARKER_NAMES\t" + "\t".join(labels),
            "Frame\tTime\t" + "\t".join(f"{lab} {a}" for lab in labels for a in "XYZ")]
    rows = [f"{i + 1}\t{times[i]:.5f}\t" + "\t".join(f"{v:.5f}" for v in xyz[i].ravel()) for i in range(n)]
    Path(path).write_text("\n".join(head + rows) + "\n")
    return Path(path)


def protocol(tmp_path, files, study="test-walking", **cols):
    trials = pd.DataFrame({"trial": [f"t{i + 1}" for i in range(len(files))],
                           "file": [str(Path(f).relative_to(tmp_path)) for f in files], **cols})
    return save_protocol(tmp_path / "protocol.yaml", study, trials)


def assert_rejected(cli, ws, args, *fragments):
    """Exit code 2, one error line containing each fragment, and no output left in the workspace."""
    code, _, err = cli("import", *args, "--out", ws, "--jobs", "1")
    assert code == 2, err
    message = " ".join(err.split())
    for f in fragments:
        assert f in message, message
    assert not (Path(ws) / "import").exists()
    assert not list(Path(ws).glob(".import*")) if Path(ws).exists() else True
    return message


# ---- readers --------------------------------------------------------------------------------------
def test_read_c3d_converts_mm_to_metres_and_keeps_occlusions(tmp_path):
    m = person(50)
    m["LASI"][10:15] = np.nan
    labels, xyz, rate, units = read_c3d(write_c3d(tmp_path / "a.c3d", m))
    assert labels == list(m) and rate == RATE and units == "mm"
    assert xyz.shape == (50, 5, 3)
    assert np.isnan(xyz[10:15, 0]).all() and not np.isnan(xyz[15:, 0]).any()
    np.testing.assert_allclose(xyz[:, 1], m["RASI"], atol=1e-4)  # float32 storage of mm values


def test_text_exports_read_the_same_values_as_c3d(tmp_path):
    m = person(40)
    m["RPSI"][5:9] = np.nan
    ref = read_c3d(write_c3d(tmp_path / "a.c3d", m)).xyz
    for reader, writer, name in ((read_vicon_csv, write_vicon_csv, "a.csv"), (read_qualisys_tsv, write_qtm_tsv, "a.tsv")):
        labels, xyz, rate, units = reader(writer(tmp_path / name, m))
        assert [lab.split(":")[-1] for lab in labels] == list(m) and rate == RATE and units == "mm"
        np.testing.assert_allclose(xyz, ref, atol=1e-4)
        assert np.array_equal(np.isnan(xyz), np.isnan(ref))


def test_vicon_csv_missing_frames_become_occluded(tmp_path):
    m = person(10)
    frames = np.array([1, 2, 3, 5, 6, 7, 8, 9, 10, 11])  # frame 4 was not exported
    raw = read_vicon_csv(write_vicon_csv(tmp_path / "a.csv", m, frames=frames))
    assert raw.xyz.shape == (11, 5, 3)
    assert np.isnan(raw.xyz[3]).all() and not np.isnan(raw.xyz[4]).any()
    np.testing.assert_allclose(raw.xyz[4, 0], m["LASI"][3], atol=1e-6)


def test_qualisys_variants_without_header_row_or_time(tmp_path):
    m = person(12)
    full = write_qtm_tsv(tmp_path / "a.tsv", m).read_text().splitlines()
    header = [i for i, ln in enumerate(full) if ln.startswith("Frame")][0]
    ref = read_qualisys_tsv(tmp_path / "a.tsv").xyz
    old = full[:header] + full[header + 1:]  # old QTM exports: no column header row
    (tmp_path / "b.tsv").write_text("\n".join(old) + "\n")
    np.testing.assert_array_equal(read_qualisys_tsv(tmp_path / "b.tsv").xyz, ref)
    bare = full[:header] + ["\t".join(ln.split("\t")[2:]) for ln in full[header + 1:]]  # marker columns only
    (tmp_path / "c.tsv").write_text("\n".join(bare) + "\n")
    np.testing.assert_array_equal(read_qualisys_tsv(tmp_path / "c.tsv").xyz, ref)
    no_time = full[:header] + ["\t".join(c for j, c in enumerate(ln.split("\t")) if j != 1) for ln in full[header:]]
    (tmp_path / "d.tsv").write_text("\n".join(no_time) + "\n")
    np.testing.assert_array_equal(read_qualisys_tsv(tmp_path / "d.tsv").xyz, ref)


def test_format_is_detected_from_content_not_name(tmp_path):
    m = person(10)
    c3d = write_c3d(tmp_path / "trial.c3d", m).rename(tmp_path / "trial.dat")  # ezc3d only writes *.c3d
    assert detect_format(c3d) == "c3d"
    assert detect_format(write_vicon_csv(tmp_path / "trial.txt", m)) == "vicon-csv"
    assert detect_format(write_qtm_tsv(tmp_path / "trial.csv", m)) == "qualisys-tsv"
    (tmp_path / "x.c3d").write_text("Trajectories\n200\n")
    with pytest.raises(InputError, match="x.c3d: not a C3D file although named .c3d"):
        detect_format(tmp_path / "x.c3d")


@settings(max_examples=20, deadline=None)
@given(n=st.integers(1, 30), n_markers=st.integers(1, 4), seed=st.integers(0, 2**16))
def test_text_exports_round_trip(tmp_path_factory, n, n_markers, seed):
    """Any values (mm, 5 decimals) and occlusion pattern come back in metres, NaN where occluded."""
    rng = np.random.default_rng(seed)
    xyz = np.round(rng.uniform(-3.0, 3.0, size=(n, n_markers, 3)), 8)
    xyz[np.abs(xyz) < 1e-3] = 0.5  # QTM reads an exact 0 0 0 as occluded
    xyz[rng.random((n, n_markers)) < 0.3] = np.nan
    markers = {f"M{k}": xyz[:, k] for k in range(n_markers)}
    d = tmp_path_factory.mktemp("rt")
    for reader, writer in ((read_vicon_csv, write_vicon_csv), (read_qualisys_tsv, write_qtm_tsv)):
        raw = reader(writer(d / "t.txt", markers))
        assert raw.xyz.shape == xyz.shape
        np.testing.assert_allclose(raw.xyz, xyz, atol=1e-8)  # equal_nan: occlusions at the same samples


@settings(max_examples=25, deadline=None)
@given(shapes=st.lists(st.tuples(st.integers(1, 12), st.integers(1, 4)), min_size=1, max_size=4), seed=st.integers(0, 2**16))
def test_long_table_round_trips_every_sample(shapes, seed):
    rng = np.random.default_rng(seed)
    names = ["LASI", "RASI", "LPSI", "RPSI"]
    trials = []
    for i, (f, m) in enumerate(shapes):
        xyz = rng.normal(size=(f, m, 3))
        xyz[rng.random((f, m)) < 0.2] = np.nan
        trials.append(ImportedTrial(f"t{i}", ["walker"] * m, names[:m], xyz, 100.0, "mm", "c3d", ""))
    df = long_table(trials)
    assert len(df) == sum(f * m for f, m in shapes)
    for t in trials:
        sub = df[df["trial"] == t.trial]
        for k, name in enumerate(t.markers):
            rows = sub[sub["marker"] == name].sort_values("frame")
            assert rows["frame"].tolist() == list(range(t.xyz.shape[0]))
            np.testing.assert_array_equal(rows[["x", "y", "z"]].to_numpy(), t.xyz[:, k])
            assert (rows["occluded"].to_numpy() == np.isnan(t.xyz[:, k, 0])).all()
            np.testing.assert_allclose(rows["time"], rows["frame"] / 100.0)


# ---- the import command ---------------------------------------------------------------------------
def test_import_two_c3d_trials(tmp_path, cli):
    raw = tmp_path / "raw"
    raw.mkdir()
    m1, m2 = person(100), person(80, x0=1.0, speed=1.2)
    m1["LASI"][20:30] = np.nan
    files = [write_c3d(raw / "a.c3d", m1), write_c3d(raw / "b.c3d", m2)]
    proto = protocol(tmp_path, files, subject=["S01", "S02"], condition=["E4015", "N0615"], repetition=[1, 2])
    ws = tmp_path / "ws"
    code, _, err = cli("import", proto, "--out", ws, "--jobs", "1")
    assert code == 0, err
    df = read_table(ws / "import" / "markers.parquet", MARKERS)
    assert len(df) == 100 * 5 + 80 * 5  # 4 pelvis markers + LHEE each
    assert set(df["entity"]) == {"walker"} and set(df["marker"]) == {"LASI", "RASI", "LPSI", "RPSI", "LHEE"}
    first = df[df["trial"] == "t1"]
    assert first["marker"].astype(str).tolist() == [m for m in ("LASI", "LHEE", "LPSI", "RASI", "RPSI") for _ in range(100)]
    assert first["frame"].tolist() == list(range(100)) * 5
    lasi = df[(df["trial"] == "t1") & (df["marker"] == "LASI")].sort_values("frame")
    assert lasi["occluded"].tolist() == [False] * 20 + [True] * 10 + [False] * 70
    assert lasi[["x", "y", "z"]].iloc[20:30].isna().all().all()
    np.testing.assert_allclose(lasi[["x", "y", "z"]].iloc[:20], m1["LASI"][:20], atol=1e-4)
    np.testing.assert_allclose(lasi["time"].iloc[-1], 99 / RATE)
    meta = table_metadata(ws / "import" / "markers.parquet")
    assert meta["rate"] == RATE and meta["source_units"] == {"t1": "mm", "t2": "mm"}
    trials = read_table(ws / "import" / "trials.parquet", TRIALS)
    assert trials["trial"].tolist() == ["t1", "t2"] and trials["subject"].tolist() == ["S01", "S02"]
    assert trials["n_frames"].tolist() == [100, 80] and set(trials["source_format"]) == {"c3d"}
    assert trials["kind"].tolist() == ["trial"] * 2 and trials["study"].tolist() == ["test-walking"] * 2
    import hashlib
    assert trials["sha256"][0] == hashlib.sha256(files[0].read_bytes()).hexdigest()
    # unchanged inputs: skipped; other options: redone
    code, _, err = cli("import", proto, "--out", ws, "--jobs", "1")
    assert code == 0 and "up to date" in err
    code, _, _ = cli("import", proto, "--out", ws, "--jobs", "1", "--keep-all-markers")
    assert code == 0


def test_import_mixed_formats_in_parallel_equals_serial(tmp_path, cli):
    raw = tmp_path / "raw"
    raw.mkdir()
    m = person(60)
    m["RASI"][3:7] = np.nan
    files = [write_c3d(raw / "a.c3d", m), write_vicon_csv(raw / "b.csv", m), write_qtm_tsv(raw / "c.tsv", m)]
    proto = protocol(tmp_path, files)
    assert cli("import", proto, "--out", tmp_path / "w1", "--jobs", "1")[0] == 0
    assert cli("import", proto, "--out", tmp_path / "w2", "--jobs", "2")[0] == 0
    d1 = read_table(tmp_path / "w1" / "import" / "markers.parquet", MARKERS)
    d2 = read_table(tmp_path / "w2" / "import" / "markers.parquet", MARKERS)
    pd.testing.assert_frame_equal(d1, d2)
    per_trial = [d1[d1["trial"] == t].sort_values(["marker", "frame"])[["x", "y", "z"]].to_numpy() for t in ("t1", "t2", "t3")]
    np.testing.assert_allclose(per_trial[1], per_trial[0], atol=1e-4)
    np.testing.assert_allclose(per_trial[2], per_trial[0], atol=1e-4)
    trials = read_table(tmp_path / "w1" / "import" / "trials.parquet", TRIALS)
    assert trials["source_format"].tolist() == ["c3d", "vicon-csv", "qualisys-tsv"]


def test_pair_labels_resolve_to_entities(tmp_path, cli):
    m = {**person(50, prefix="S1:"), **person(50, x0=1.8, prefix="S2:", extra=()), **table(50), "Table:Extra": np.zeros((50, 3))}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "p.c3d", m)], study="test-pairs", pair=["P01"], condition=["d1_p4_gris"],
                     scenario=[3], configuration=["gris"], end_orientation=[np.pi])
    ws = tmp_path / "ws"
    assert cli("import", proto, "--out", ws, "--jobs", "1")[0] == 0
    df = read_table(ws / "import" / "markers.parquet", MARKERS)
    got = df.groupby(["entity", "marker"], observed=True).size()
    assert sorted(got.index) == sorted([("subject1", k) for k in (*PELVIS_OFFSETS, "LHEE")] + [("subject2", k) for k in PELVIS_OFFSETS]
                                       + [("table", k) for k in TABLE_OFFSETS])
    trials = read_table(ws / "import" / "trials.parquet", TRIALS)
    assert trials["scenario"].tolist() == [3] and trials["pair"].tolist() == ["P01"]
    assert cli("import", proto, "--out", ws, "--jobs", "1", "--keep-all-markers")[0] == 0
    kept = read_table(ws / "import" / "markers.parquet", MARKERS)
    assert len(kept) == len(df) + 50 and set(kept.loc[kept["marker"] == "Extra", "entity"]) == {"table"}


def test_marker_map_options(tmp_path, cli):
    lab = {"LASI": "L_ASIS", "RASI": "R_ASIS", "LPSI": "L_PSIS", "RPSI": "R_PSIS"}
    m = {lab.get(k, k): v for k, v in person(30).items()}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    ws = tmp_path / "ws"
    msg = assert_rejected(cli, ws, [proto], "a.c3d", "required markers missing: walker:LASI, walker:RASI, walker:LPSI, walker:RPSI", "labels found: L_ASIS", "--map LAB=CANON")
    assert "--marker-map" in msg
    args = [a for k, v in lab.items() for a in ("--map", f"{v}={k}")]
    assert cli("import", proto, "--out", ws, "--jobs", "1", *args)[0] == 0
    mapfile = tmp_path / "labmap.yaml"
    mapfile.write_text("".join(f"{v}: {k}\n" for k, v in lab.items()))
    assert cli("import", proto, "--out", tmp_path / "ws2", "--jobs", "1", "--marker-map", mapfile)[0] == 0
    df = read_table(tmp_path / "ws2" / "import" / "markers.parquet", MARKERS)
    assert set(df["marker"]) == {"LASI", "RASI", "LPSI", "RPSI", "LHEE"}


# ---- bad input: exit 2, one line naming the file and the remedy, no output ----------------------
def test_missing_protocol_and_missing_trial_file(tmp_path, cli):
    assert_rejected(cli, tmp_path / "ws", [tmp_path / "nope.yaml"], "nope.yaml: protocol file not found")
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", person(10))])
    (tmp_path / "a.c3d").unlink()
    assert_rejected(cli, tmp_path / "ws", [proto], "protocol.yaml", "names file a.c3d, which does not exist")


def test_non_c3d_file_with_c3d_name(tmp_path, cli):
    bad = tmp_path / "a.c3d"
    bad.write_bytes(b"PK\x03\x04 this is a zip archive" + bytes(600))
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [bad])], "a.c3d: not a C3D file although named .c3d")


def test_truncated_c3d(tmp_path, cli):
    good = write_c3d(tmp_path / "a.c3d", person(100))
    data = good.read_bytes()
    good.write_bytes(data[: len(data) - 3000])
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [good])], "a.c3d: truncated C3D file", "re-export")


def test_corrupt_c3d_parameter_section_is_refused_before_ezc3d(tmp_path):
    """These corruptions made ezc3d crash (segfault) or hang; the header walk refuses them."""
    data = write_c3d(tmp_path / "a.c3d", person(100, extra=("LHEE", "LTOE", "LMT5", "RHEE", "RTOE", "RMT5"))).read_bytes()
    rng = random.Random(1)
    for k in range(20):
        b = bytearray(data)
        for _ in range(50):
            b[rng.randrange(512, 1536)] = rng.randrange(256)
        path = tmp_path / f"c{k}.c3d"
        path.write_bytes(bytes(b))
        try:
            raw = read_c3d(path)
        except InputError as exc:
            assert f"c{k}.c3d: " in str(exc)
        else:  # a harmless corruption (e.g. in a description) must still give the full data
            assert raw.xyz.shape[0] == 100


def test_c3d_without_pelvis_markers(tmp_path, cli):
    m = person(30)
    del m["RPSI"]
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])],
                    "a.c3d: required markers missing: walker:RPSI", "labels found: LASI, RASI, LPSI, LHEE", "--map")


def test_pair_recording_without_table_markers(tmp_path, cli):
    m = {**person(30, prefix="S1:"), **person(30, x0=1.8, prefix="S2:")}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "p.c3d", m)], pair=["P01"])
    assert_rejected(cli, tmp_path / "ws", [proto], "p.c3d: required markers missing: table:TAB1, table:TAB2, table:TAB3")


def test_all_nan_pelvis_marker(tmp_path, cli):
    m = person(30)
    m["LPSI"][:] = np.nan
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])],
                    "a.c3d: marker LPSI of walker is never visible (all 30 samples missing)")


def test_never_visible_optional_marker_is_a_warning(tmp_path, cli):
    m = person(30)
    m["LHEE"][:] = np.nan
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0 and "a.c3d: marker LHEE of walker is never visible" in " ".join(err.split())
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    assert df.loc[df["marker"] == "LHEE", "occluded"].all() and len(df) == 5 * 30


def test_non_monotonic_and_duplicated_time(tmp_path, cli):
    m = person(10)
    csv = write_vicon_csv(tmp_path / "a.csv", m, frames=np.array([1, 2, 3, 4, 6, 5, 7, 8, 9, 10]))
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [csv])], "a.csv: non-monotonic frame numbers at data row 6 (6 then 5)")
    times = np.arange(10) / RATE
    times[4] = times[3]
    tsv = write_qtm_tsv(tmp_path / "a.tsv", m, times=times)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [tsv])], "a.tsv: duplicated Time values at data row 5")
    csv = write_vicon_csv(tmp_path / "b.csv", m, frames=np.array([1, 2, 3, 3, 4, 5, 6, 7, 8, 9]))
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [csv])], "b.csv: duplicated frame numbers at data row 4")


def test_non_numeric_cells(tmp_path, cli):
    lines = write_qtm_tsv(tmp_path / "a.tsv", person(5)).read_text().splitlines()
    (tmp_path / "a.tsv").write_text("\n".join(ln.replace(".", ",") if ln[:1].isdigit() else ln for ln in lines) + "\n")
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [tmp_path / "a.tsv"])], "a.tsv: non-numeric value '0,00000'",
                    "'.' as the decimal separator")


def test_mm_m_confusion_is_detected(tmp_path, cli):
    m = person(30)
    metres_as_mm = write_c3d(tmp_path / "a.c3d", m, units="mm", scale=1.0)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [metres_as_mm])], "a.c3d: marker distances look like metres labelled as mm",
                    "--units m")
    assert cli("import", tmp_path / "protocol.yaml", "--out", tmp_path / "ok", "--units", "m", "--jobs", "1")[0] == 0
    mm_as_m = write_vicon_csv(tmp_path / "b.csv", m, units="m")
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [mm_as_m])], "b.csv: marker distances look like millimetres labelled as metres",
                    "--units mm")
    tsv = write_qtm_tsv(tmp_path / "c.tsv", m, scale=1.0)  # QTM files are mm; these hold metres
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [tsv])], "c.tsv: marker distances look like metres labelled as mm")


def test_empty_trials(tmp_path, cli):
    m = {k: v[:0] for k, v in person(5).items()}
    csv = write_vicon_csv(tmp_path / "a.csv", m)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [csv])], "a.csv: empty trial", "remove the trial from the protocol")
    tsv = write_qtm_tsv(tmp_path / "b.tsv", m)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [tsv])], "b.tsv: empty trial")
    empty = tmp_path / "c.c3d"
    empty.write_bytes(b"")
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [empty])], "c.c3d: empty file")
    # ezc3d cannot write a C3D without frames: patch a 1-frame file's header to frames 1..0
    one = bytearray(write_c3d(tmp_path / "d.c3d", {k: v[:1] for k, v in person(1).items()}).read_bytes())
    one[6:10] = (1).to_bytes(2, "little") + (0).to_bytes(2, "little")
    (tmp_path / "d.c3d").write_bytes(bytes(one))
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [tmp_path / "d.c3d"])], "d.c3d: empty trial (the C3D file holds no frames)")


def test_failed_import_leaves_previous_output_unchanged(tmp_path, cli):
    f = write_c3d(tmp_path / "a.c3d", person(20))
    proto = protocol(tmp_path, [f])
    ws = tmp_path / "ws"
    assert cli("import", proto, "--out", ws, "--jobs", "1")[0] == 0
    before = {p.name: p.read_bytes() for p in (ws / "import").iterdir()}
    f.write_bytes(f.read_bytes()[:2000])
    code, _, err = cli("import", proto, "--out", ws, "--jobs", "2")
    assert code == 2 and "a.c3d: truncated C3D file" in " ".join(err.split())
    assert {p.name: p.read_bytes() for p in (ws / "import").iterdir()} == before
    assert sorted(p.name for p in ws.iterdir()) == ["import"]


def test_bad_map_option(tmp_path, cli):
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", person(10))])
    assert_rejected(cli, tmp_path / "ws", [proto, "--map", "LASI"], "--map 'LASI' is not LAB=CANON")
    assert_rejected(cli, tmp_path / "ws", [proto, "--marker-map", tmp_path / "none.yaml"], "none.yaml: marker map file not found")


# ---- a small synthetic study (cobot_analysis.synth) -----------------------------------------------
def _barycentre_error(markers: pd.DataFrame, truth: pd.DataFrame) -> float:
    """Largest horizontal distance between the imported pelvis barycentre and the true CoM (m)."""
    pelvis = markers[markers["marker"].isin(["LASI", "RASI", "LPSI", "RPSI"])]
    wide = pelvis.pivot_table(index=["trial", "entity", "frame"], columns="marker", values=["x", "y"], observed=True)
    full = wide.dropna()  # frames where the 4 pelvis markers are visible
    com = pd.DataFrame({"x": full["x"].mean(axis=1), "y": full["y"].mean(axis=1)})
    true = truth.set_index(["trial", "entity", "frame"])[["x", "y"]].rename(columns={"x": "x_true", "y": "y_true"})
    joined = com.join(true, how="inner")
    assert len(joined) == len(com)
    return float(np.hypot(joined["x"] - joined["x_true"], joined["y"] - joined["y_true"]).max())


def test_import_synthetic_walking_and_pair_studies(tmp_path, cli):
    walking = pytest.importorskip("cobot_analysis.synth.walking")
    pairs = pytest.importorskip("cobot_analysis.synth.pairs")
    for proto, n_trials, entities in (
        (walking.generate(tmp_path / "w", n_subjects=2, n_trials=1, conditions=["E4015", "N0615"]), 4, {"walker"}),
        (pairs.generate(tmp_path / "p", n_pairs=1, goals=["d1_p4_gris"], scenarios=[3]), 1, {"subject1", "subject2", "table"}),
    ):
        ws = tmp_path / f"ws_{proto.parent.name}"
        code, _, err = cli("import", proto, "--out", ws, "--jobs", "2")
        assert code == 0, err
        markers = read_table(ws / "import" / "markers.parquet", MARKERS)
        trials = read_table(ws / "import" / "trials.parquet", TRIALS)
        assert len(trials) == n_trials and set(markers["entity"]) == entities
        assert (trials["source_units"] == "mm").all() and (trials["rate"] == 200.0).all()
        assert markers.groupby("trial", observed=True)["frame"].max().add(1).tolist() == trials["n_frames"].tolist()
        truth = pd.read_parquet(proto.parent / "truth.parquet")
        truth = truth[truth["entity"] != "table"]
        assert _barycentre_error(markers, truth) < 0.005  # sensor noise ~1 mm
        occluded = markers[markers["marker"].isin(["LASI", "RASI", "LPSI", "RPSI"])].groupby(["trial", "entity", "frame"], observed=True)["occluded"].sum()
        lost = truth.set_index(["trial", "entity", "frame"])["pelvis_occluded"]
        assert (occluded.reindex(lost.index) == lost).all()
