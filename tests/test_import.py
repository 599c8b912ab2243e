"""`cobot-analysis import`: C3D, Vicon CSV and Qualisys TSV readers, label mapping, bad input.

Test files are written here (C3D with ezc3d, text exports by hand), never committed.
"""

from __future__ import annotations

import random
import re
import sys
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

sys.path.insert(0, str(Path(__file__).parent))
import damage  # noqa: E402

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


def write_c3d(path, markers, units="mm", scale=1000.0, rate=RATE, extra_params=None):
    """C3D written with ezc3d; NaN samples become occluded points; ``extra_params``: {(GROUP, NAME): values}."""
    import ezc3d

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [rate]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(markers)
    c3d["parameters"]["POINT"]["UNITS"]["value"] = [units]
    for (group, name), values in (extra_params or {}).items():
        c3d.add_parameter(group, name, values)
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
    labels, xyz, rate, units, notes = read_c3d(write_c3d(tmp_path / "a.c3d", m))
    assert labels == list(m) and rate == RATE and units == "mm" and notes == ()
    assert xyz.shape == (50, 5, 3)
    assert np.isnan(xyz[10:15, 0]).all() and not np.isnan(xyz[15:, 0]).any()
    np.testing.assert_allclose(xyz[:, 1], m["RASI"], atol=1e-4)  # float32 storage of mm values


def test_text_exports_read_the_same_values_as_c3d(tmp_path):
    m = person(40)
    m["RPSI"][5:9] = np.nan
    ref = read_c3d(write_c3d(tmp_path / "a.c3d", m)).xyz
    for reader, writer, name in ((read_vicon_csv, write_vicon_csv, "a.csv"), (read_qualisys_tsv, write_qtm_tsv, "a.tsv")):
        labels, xyz, rate, units, _ = reader(writer(tmp_path / name, m))
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
    msg = assert_rejected(cli, ws, [proto], "a.c3d", "required markers missing: walker:LASI, walker:RASI, walker:LPSI, walker:RPSI",
                          "labels found: L_ASIS", "--map L_ASIS=LASI --map L_PSIS=LPSI --map R_ASIS=RASI --map R_PSIS=RPSI")
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


# ---- issue #11: real lab files and hostile input ------------------------------------------------
REAL_C3D = "c3d/{}.c3d"


def real_protocol(tmp_path, realdata, name):
    """A one-trial protocol naming a file of ../shared/realdata in place (never copied)."""
    f = realdata / name
    proto = tmp_path / f"{f.stem}.yaml"
    proto.write_text(f"study: realdata\nallow_outside: true\ntrials:\n  - {{trial: t1, file: {f}, condition: c1}}\n")
    return proto


def ezc3d_marker(path, label):
    """A marker straight from ezc3d (m, NaN where the residual is negative), for comparison."""
    import ezc3d

    c = ezc3d.c3d(str(path))
    j = list(c["parameters"]["POINT"]["LABELS"]["value"]).index(label)
    xyz = c["data"]["points"][:3, j].T / 1000.0
    xyz[c["data"]["meta_points"]["residuals"][0, j] < 0] = np.nan
    return xyz


def test_vicon_parameter_names_with_spaces_are_read(realdata, tmp_path, cli):
    """FunctionalWalk.c3d (Vicon Nexus) has PROCESSING:'Marker Diameter': ezc3d reads it, so do we."""
    f = realdata / REAL_C3D.format("FunctionalWalk")
    assert b"Marker Diameter" in f.read_bytes()
    code, _, err = cli("import", real_protocol(tmp_path, realdata, REAL_C3D.format("FunctionalWalk")), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    trials = read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)
    assert trials["rate"].tolist() == [120.0] and trials["n_frames"].tolist() == [438]
    assert trials["pelvis_markers"].tolist() == ["LASI,RASI,LPSI,RPSI"]  # SACR is never visible in this file
    lasi = df[df["marker"] == "LASI"].sort_values("frame")[["x", "y", "z"]].to_numpy()
    np.testing.assert_allclose(lasi, ezc3d_marker(f, "LASI"), atol=1e-9)


def test_model_outputs_are_never_markers(tmp_path, cli):
    """POINT channels listed under POINT:ANGLES / MOMENTS / POWERS / FORCES are left out, even with --keep-all-markers."""
    m = person(40)
    m["LHipAngles"] = np.full((40, 3), 0.012)  # 12 deg written as if mm
    m["LKneeMoment"] = np.full((40, 3), 250.0)  # 250,000 N.mm
    m["RHJC"] = m["RASI"] + 0.05  # a virtual marker (a position): kept with --keep-all-markers
    f = write_c3d(tmp_path / "a.c3d", m, extra_params={("POINT", "ANGLES"): ["LHipAngles"], ("POINT", "ANGLE_UNITS"): ["deg"],
                                                        ("POINT", "MOMENTS"): ["LKneeMoment"], ("POINT", "MOMENT_UNITS"): ["Nmm"]})
    raw = read_c3d(f)
    assert raw.labels == ["LASI", "RASI", "LPSI", "RPSI", "LHEE", "RHJC"]
    assert "2 model outputs stored as POINT channels left out (not markers: angles (deg), moments (Nmm))" in raw.notes[0]
    code, _, err = cli("import", protocol(tmp_path, [f]), "--out", tmp_path / "ws", "--jobs", "1", "--keep-all-markers")
    assert code == 0, err
    assert "2 model outputs stored as POINT channels left out" in " ".join(err.split())
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    assert set(df["marker"]) == {"LASI", "RASI", "LPSI", "RPSI", "LHEE", "RHJC"}
    assert "model outputs stored as POINT channels left out" in (tmp_path / "ws" / "import" / "results.md").read_text()


def test_plug_in_gait_file_with_keep_all_markers(realdata, tmp_path, cli):
    f = realdata / REAL_C3D.format("PiG_Motion-FlatFoot-Full")
    code, _, err = cli("import", real_protocol(tmp_path, realdata, REAL_C3D.format("PiG_Motion-FlatFoot-Full")), "--out", tmp_path / "ws",
                       "--jobs", "1", "--keep-all-markers")
    assert code == 0, err
    import ezc3d

    point = ezc3d.c3d(str(f))["parameters"]["POINT"]
    outputs = {lab for g in ("ANGLES", "MOMENTS", "POWERS", "FORCES") for lab in point[g]["value"]}
    assert len(outputs) == 80
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    kept = set(df["marker"].astype(str))
    assert not kept & outputs and {"LHipAngles", "LKneeMoment", "LAnklePower", "LHipForce"} <= outputs
    assert len(kept) == len(point["LABELS"]["value"]) - 80
    assert df[["x", "y", "z"]].abs().max().max() < 3.0  # positions in metres; a moment / 1000 would be far larger


@pytest.mark.parametrize("mm, expected, remedy", [
    (1.2e38, "implausible marker positions, up to 1.2e+35 m from the lab origin (limit 100 m): RASI (frame 30, from t = 0.150 s)",
     "origin inside the capture volume"),
    (float("inf"), "infinite marker coordinates: RASI (frame 30, from t = 0.150 s)", "re-export"),
    (-120.0 - 120.0, "implausible jump of marker RASI: 0.12 m between frames 29 and 30 (t = 0.145 s), 24 m/s (limit 20 m/s)",
     "--max-speed"),  # y of RASI is -120 mm: moved by 120 mm in one frame
    (-120.0 + 70.0, "implausible spike of marker RASI at frame 30 (t = 0.150 s): 0.07 m from the midpoint of its neighbours "
     "(limit 0.05 m)", "--max-spike"),  # 70 mm for one frame: 14 m/s, below the speed limit
])
def test_corrupt_values_in_the_data_block_are_refused(tmp_path, cli, mm, expected, remedy):
    """One C3D float overwritten in place (y of RASI, mm): refused with the marker and frame, nothing written."""
    f = write_c3d(tmp_path / "a.c3d", person(60))
    damage.c3d_set_float(f, frame=30, point=1, axis=1, value=mm)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.c3d: " + expected, remedy)


def test_plausibility_limits_are_options(tmp_path, cli):
    m = person(60)
    m["RASI"][30:, 1] -= 0.12  # a step of 12 cm in one frame (24 m/s), then steady: fast, but asked for
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    assert_rejected(cli, tmp_path / "ws", [proto], "implausible jump of marker RASI")
    assert_rejected(cli, tmp_path / "ws", [proto, "--max-speed", "30"],  # half the step off the midpoint of its neighbours
                    "a.c3d: implausible spike of marker RASI at frame 29 (t = 0.145 s): 0.06 m from the midpoint of its "
                    "neighbours (limit 0.05 m); 2 such samples in 1 marker(s)", "--max-spike")
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1", "--max-speed", "30", "--max-spike", "0.07")
    assert code == 0, err
    meta = table_metadata(tmp_path / "ws" / "import" / "markers.parquet")
    assert meta["max_speed"] == 30.0 and meta["max_spike"] == 0.07 and meta["lab_extent"] == 100.0
    far = {k: v + np.array([150.0, 0, 0]) for k, v in person(20).items()}  # a lab whose origin is 150 m away
    proto = protocol(tmp_path, [write_c3d(tmp_path / "b.c3d", far)])
    assert_rejected(cli, tmp_path / "ws2", [proto], "b.c3d: implausible marker positions, up to 150 m", "origin inside the capture volume")
    # every later stage refuses trajectories beyond 100 m of the origin (schema.LAB_EXTENT): a wider lab is refused at once
    assert_rejected(cli, tmp_path / "ws2", [proto, "--lab-extent", "200"], "--lab-extent 200 m is beyond the 100 m", "at most 100")
    near = {k: v + np.array([60.0, 0, 0]) for k, v in person(20).items()}  # 60 m away: inside a --lab-extent of 100 m
    small = protocol(tmp_path, [write_c3d(tmp_path / "c.c3d", near)])
    assert_rejected(cli, tmp_path / "ws3", [small, "--lab-extent", "50"], "c.c3d: implausible marker positions, up to 60",
                    "--lab-extent up to 100")
    assert cli("import", small, "--out", tmp_path / "ws3", "--jobs", "1")[0] == 0


def test_sacrum_pelvis_is_imported_and_named(tmp_path, cli):
    """LASI RASI + one sacrum marker (VSAC read as SACR): the pelvis markers used are recorded."""
    m = person(40)
    sacrum = (m.pop("LPSI") + m.pop("RPSI")) / 2
    m["VSAC"] = sacrum
    f = write_c3d(tmp_path / "a.c3d", m)
    g = write_c3d(tmp_path / "b.c3d", person(40))
    code, _, err = cli("import", protocol(tmp_path, [f, g]), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    trials = read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)
    assert trials["pelvis_markers"].tolist() == ["LASI,RASI,SACR", "LASI,RASI,LPSI,RPSI"]
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    sacr = df[(df["trial"] == "t1") & (df["marker"] == "SACR")].sort_values("frame")[["x", "y", "z"]].to_numpy()
    np.testing.assert_allclose(sacr, sacrum, atol=1e-4)
    assert table_metadata(tmp_path / "ws" / "import" / "markers.parquet")["pelvis_markers"]["t1"] == {"walker": ["LASI", "RASI", "SACR"]}
    results = (tmp_path / "ws" / "import" / "results.md").read_text()
    assert "| LASI RASI SACR | 1 |" in results and "| LASI RASI LPSI RPSI | 1 |" in results
    del m["VSAC"]
    assert_rejected(cli, tmp_path / "ws3", [protocol(tmp_path, [write_c3d(tmp_path / "c.c3d", m)])],
                    "c.c3d: required markers missing: walker:LPSI, walker:RPSI (or walker:SACR instead of walker:LPSI and walker:RPSI)")


def test_realdata_sacrum_pelvis(realdata, tmp_path, cli):
    """Gait.c3d: LASI RASI VSAC, visible in frames 133-326 only, duplicated labels (RKNE, ...)."""
    proto = real_protocol(tmp_path, realdata, REAL_C3D.format("Gait"))
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1", "--keep-all-markers")
    assert code == 0, err
    trials = read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)
    assert trials["pelvis_markers"].tolist() == ["LASI,RASI,SACR"]
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    sacr = df[df["marker"] == "SACR"].sort_values("frame")[["x", "y", "z"]].to_numpy()
    np.testing.assert_allclose(sacr, ezc3d_marker(realdata / REAL_C3D.format("Gait"), "VSAC"), atol=1e-9)
    assert {"RKNE", "RKNE#2"} <= set(df["marker"].astype(str))
    assert "duplicated label 'RKNE' kept as RKNE#2" in " ".join(err.split())


def test_one_label_mapped_to_two_markers_is_refused(tmp_path, cli):
    m = person(20)
    m["SACR"] = (m.pop("LPSI") + m.pop("RPSI")) / 2
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    assert_rejected(cli, tmp_path / "ws", [proto, "--map", "SACR=LPSI", "--map", "SACR=RPSI"],
                    "--map gives label 'SACR' two markers (SACR=LPSI and SACR=RPSI)", "map it once, --map SACR=SACR")
    assert cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1", "--map", "L=LASI", "--map", "L=LASI")[0] == 0  # same twice: fine


def test_map_accepts_labels_with_their_subject_prefix(tmp_path, cli):
    lab = {"LASI": "Daphnee:ASISl", "RASI": "Daphnee:ASISr", "LPSI": "Daphnee:PSISl", "RPSI": "Daphnee:PSISr"}
    m = {lab.get(k, f"Daphnee:{k}"): v for k, v in person(30).items()}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    args = [a for k, v in lab.items() for a in ("--map", f"{v}={k}")]
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1", *args)
    assert code == 0, err
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    assert set(zip(df["entity"], df["marker"])) == {("walker", k) for k in ("LASI", "RASI", "LPSI", "RPSI", "LHEE")}
    rasi = df[df["marker"] == "RASI"].sort_values("frame")[["x", "y", "z"]].to_numpy()
    np.testing.assert_allclose(rasi, person(30)["RASI"], atol=1e-4)


def test_realdata_prefixed_labels_and_vicon_csv(realdata, tmp_path, cli):
    """pyomeca_markers_analogs.c3d and its Vicon CSV export: Daphnee:ASISr ... mapped as the tool lists them."""
    maps = [a for pair in (("Daphnee:ASISr", "RASI"), ("Daphnee:ASISl", "LASI"), ("Daphnee:PSISr", "RPSI"), ("Daphnee:PSISl", "LPSI"))
            for a in ("--map", "=".join(pair))]
    out = {}
    for name in ("c3d/pyomeca_markers_analogs.c3d", "csv/pyomeca_markers.csv"):
        ws = tmp_path / Path(name).stem
        code, _, err = cli("import", real_protocol(tmp_path, realdata, name), "--out", ws, "--jobs", "1", *maps)
        assert code == 0, err
        df = read_table(ws / "import" / "markers.parquet", MARKERS)
        out[name] = df[df["marker"] == "RASI"].sort_values("frame")[["x", "y", "z"]].to_numpy()
    np.testing.assert_allclose(out["c3d/pyomeca_markers_analogs.c3d"], ezc3d_marker(realdata / "c3d/pyomeca_markers_analogs.c3d", "Daphnee:ASISr"),
                               atol=1e-9)
    np.testing.assert_allclose(out["csv/pyomeca_markers.csv"], out["c3d/pyomeca_markers_analogs.c3d"], atol=1e-5)


def test_bad_files_are_skipped_and_listed_or_named_in_one_error_with_strict(tmp_path, cli):
    good = write_c3d(tmp_path / "good.c3d", person(40))
    short = damage.truncate(write_c3d(tmp_path / "short.c3d", person(40)), -1500)
    (tmp_path / "notc3d.c3d").write_bytes(b"PK\x03\x04" + bytes(600))
    nopelvis = {k: v for k, v in person(40).items() if k != "RPSI"}
    files = [good, short, tmp_path / "notc3d.c3d", write_c3d(tmp_path / "nopelvis.c3d", nopelvis)]
    proto = protocol(tmp_path, files)
    msg = assert_rejected(cli, tmp_path / "ws", [proto, "--strict"], "3 of 4 trials refused (--strict), nothing written:",
                          "t2 (short.c3d): truncated C3D file", "t3 (notc3d.c3d): not a C3D file",
                          "t4 (nopelvis.c3d): required markers missing: walker:RPSI")
    assert "t1 (" not in msg
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "2")  # default: the good trial goes on
    assert code == 3, err
    text = " ".join(err.split())
    assert "import: 3 of 4 trials refused and left out, the other 1 went on (exit code 3" in text
    assert all(f"{t} ({f}): " in text for t, f in (("t2", "short.c3d"), ("t3", "notc3d.c3d"), ("t4", "nopelvis.c3d")))
    assert err.splitlines()[-1].startswith(f"import: 1 trials, 3 refused (listed above and in {tmp_path / 'ws' / 'import' / 'results.md'}), ")
    trials = read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)
    assert trials["trial"].tolist() == ["t1"]
    assert set(read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)["trial"]) == {"t1"}
    results = (tmp_path / "ws" / "import" / "results.md").read_text()
    assert "1 of 4 trials" in results and "Refused and left out: 3 of 4 trials" in results
    assert "| t2 | `short.c3d` | truncated C3D file" in results
    import json

    manifest = json.loads((tmp_path / "ws" / "import" / "manifest.json").read_text())
    assert [r["trial"] for r in manifest["refused"]] == ["t2", "t3", "t4"] and manifest["refused"][0]["file"] == str(short)
    code, _, _ = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "2")  # skipped as up to date: still exit 3
    assert code == 3
    bad_only = protocol(tmp_path, files[1:])
    assert_rejected(cli, tmp_path / "ws2", [bad_only], "every trial refused, nothing written")  # nothing left to import


def test_c3d_without_frame_data_is_an_empty_trial(tmp_path, cli):
    f = write_c3d(tmp_path / "a.c3d", person(30))
    damage.truncate(f, damage.c3d_data_offset(f))  # the file ends where the data section starts
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.c3d: empty trial (the C3D file holds no frames: "
                    "it ends where its data section starts, although its header announces 30)", "remove the trial")


@pytest.mark.parametrize("edit, expected", [
    ("rate: 200Hz\n", "'rate' must be a positive number of Hz, not '200Hz'"),
    ("entities: [S1, S2]\n", "'entities' must map labels to names"),
    ("entities: {S1: person1}\n", "'entities' names unknown entities ['person1']"),
    ("marker_map: LASI\n", "'marker_map' must map labels to names, not 'LASI'"),
    ("subjetcs: subjects.csv\n", "unknown protocol key(s) ['subjetcs']; use only study, rate, invalid_rate, allow_outside, entities, marker_map, subjects, pairs, trials"),
])
def test_bad_protocol_entries(tmp_path, cli, edit, expected):
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", person(10))])
    proto.write_text(proto.read_text() + edit)
    assert_rejected(cli, tmp_path / "ws", [proto], "protocol.yaml: " + expected)


@pytest.mark.parametrize("trial_cols, pairs, expected", [
    ({"subject": ["S99"]}, None, "trial t1 names subject S99, which is not an id of the subjects table (S01, S02); correct the "
                                 "'subject' column of the trials table, or add S99 to the subjects table"),
    ({"pair": ["P99"]}, {"id": ["P01"], "subject1": ["S01"], "subject2": ["S02"]},
     "trial t1 names pair P99, which is not an id of the pairs table (P01)"),
    ({"pair": ["P01"]}, {"id": ["P01"], "subject1": ["S01"], "subject2": ["S03"]},
     "pair P01 names subject2 S03, which is not an id of the subjects table (S01, S02); correct the 'subject2' column of "
     "the pairs table, or add S03 to the subjects table"),
])
def test_a_subject_or_pair_the_protocol_does_not_list_is_refused(tmp_path, cli, trial_cols, pairs, expected):
    """A typo in the trials table (S99 for S09) would make a subject or pair of its own in every per-subject question:
    refused when the protocol gives the table of subjects (pairs) it should name."""
    f = write_c3d(tmp_path / "a.c3d", person(10))
    trials = pd.DataFrame({"trial": ["t1"], "file": ["a.c3d"], **trial_cols})
    subjects = pd.DataFrame({"id": ["S01", "S02"], "sex": ["F", "M"], "weight": [60.0, 70.0], "height": [1.6, 1.7]})
    proto = save_protocol(tmp_path / "protocol.yaml", "test", trials, subjects=subjects,
                          pairs=pd.DataFrame(pairs) if pairs else None)
    assert_rejected(cli, tmp_path / "ws", [proto], "protocol.yaml: " + expected)
    assert f.is_file() and not (tmp_path / "ws").exists()


def test_an_id_listed_twice_and_a_pair_of_one_subject_are_refused(tmp_path, cli):
    """Two rows of the subjects table with one id (two weights for S01: which one the statistics of the pairs' weight
    differences took was left to chance), and a pair whose subject1 is its subject2."""
    write_c3d(tmp_path / "a.c3d", person(10))
    trials = pd.DataFrame({"trial": ["t1"], "file": ["a.c3d"], "pair": ["P01"]})
    subjects = pd.DataFrame({"id": ["S01", "S02", "S01"], "weight": [60.0, 70.0, 80.0]})
    pairs = pd.DataFrame({"id": ["P01"], "subject1": ["S01"], "subject2": ["S02"]})
    proto = save_protocol(tmp_path / "protocol.yaml", "test", trials, subjects=subjects, pairs=pairs)
    assert_rejected(cli, tmp_path / "ws", [proto], "protocol.yaml: the subjects table lists S01 twice; give each row of "
                                                   "the subjects table its own id")
    proto = save_protocol(tmp_path / "protocol.yaml", "test", trials, subjects=subjects.iloc[:2],
                          pairs=pairs.assign(subject2=["S01"]))
    assert_rejected(cli, tmp_path / "ws", [proto], "protocol.yaml: pair P01 has S01 as both subject1 and subject2")


def test_numeric_subject_ids_match_across_a_blank_cell(tmp_path):
    """Subject ids 1 and 2 in the subjects table; in the trials table a blank cell makes pandas read the column as
    1.0, 2.0, NaN: the same ids, not a refusal."""
    from cobot_analysis.io.protocol import load_protocol

    for name in ("a", "b", "c"):
        write_c3d(tmp_path / f"{name}.c3d", person(10))
    (tmp_path / "trials.csv").write_text("trial,file,subject\nt1,a.c3d,1\nt2,b.c3d,2\nt3,c.c3d,\n")
    (tmp_path / "subjects.csv").write_text("id,sex\n1,F\n2,M\n")
    (tmp_path / "protocol.yaml").write_text("study: s\nsubjects: subjects.csv\ntrials: trials.csv\n")
    assert list(load_protocol(tmp_path / "protocol.yaml").trials["trial"]) == ["t1", "t2", "t3"]
    (tmp_path / "trials.csv").write_text("trial,file,subject\nt1,a.c3d,1\nt2,b.c3d,3\nt3,c.c3d,\n")
    with pytest.raises(InputError, match="trial t2 names subject 3, which is not an id of the subjects table \\(1, 2\\)"):
        load_protocol(tmp_path / "protocol.yaml")


def test_binary_trials_csv(tmp_path, cli):
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", person(10))])
    (tmp_path / "trials.csv").write_bytes(bytes(range(256)) * 4)
    assert_rejected(cli, tmp_path / "ws", [proto], "trials.csv: not a readable CSV table", "UTF-8 CSV")


# ---- found by benchmarks/fuzz_inputs.py -------------------------------------------------------------
def test_nan_coordinate_with_a_valid_residual_is_an_occluded_sample(tmp_path, cli):
    f = write_c3d(tmp_path / "a.c3d", person(40))
    damage.c3d_set_float(f, frame=12, point=0, axis=2, value=float("nan"))
    raw = read_c3d(f)
    assert np.isnan(raw.xyz[12, 0]).all() and not np.isnan(raw.xyz[13, 0]).any()
    assert "a.c3d: 1 samples with a NaN coordinate counted as occluded" in raw.notes
    code, _, err = cli("import", protocol(tmp_path, [f]), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    df = read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)
    lasi = df[df["marker"] == "LASI"].sort_values("frame")
    assert lasi["occluded"].tolist() == [False] * 12 + [True] + [False] * 27 and lasi[["x", "y", "z"]].iloc[12].isna().all()


@pytest.mark.parametrize("axis", ["X", "Y"])
@pytest.mark.parametrize("fmt", ["c3d", "csv", "tsv"])
def test_a_sample_missing_one_coordinate_is_occluded_in_every_format(tmp_path, cli, fmt, axis):
    """LASI's x (or y) missing in every frame, the other coordinates given (a NaN with a valid residual, an empty
    CSV cell, a NaN TSV cell): each sample is occluded as a whole by the reader, so the trial is refused because
    LASI is never visible. The import's later checks look at x alone: a y missing with x given relies on it."""
    m = person(40)
    m["LASI"][:, "XYZ".index(axis)] = np.nan
    if fmt == "tsv":  # the writer fills NaN with QTM's 0 0 0: write the cells as NaN text instead
        f = write_qtm_tsv(tmp_path / "a.tsv", person(40))
        lines = f.read_text().splitlines()
        column = lines[8].split("\t").index(f"LASI {axis}")
        lines[9:] = ["\t".join(c[:column] + ["NaN"] + c[column + 1:]) for c in (ln.split("\t") for ln in lines[9:])]
        f.write_text("\n".join(lines) + "\n")
    else:
        f = (write_c3d if fmt == "c3d" else write_vicon_csv)(tmp_path / f"a.{fmt}", m)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])],
                    f"a.{fmt}: marker LASI of walker is never visible (all 40 samples missing)")


def test_a_failed_import_prints_its_error_line_alone(tmp_path, cli):
    """Without -q, the progress lines of the work that then failed came first ('import: 0/1 (0 %)', 'import: 1/1
    (100 %)'): the error is the one line now."""
    m = person(40)
    m["LASI"][:] = np.nan
    f = write_c3d(tmp_path / "a.c3d", m)
    code, _, err = cli("import", protocol(tmp_path, [f]), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 2 and err.splitlines() == [f"error: {f}: marker LASI of walker is never visible (all 40 samples missing); check "
                                              "the labelling of the trial in the capture software, or leave the trial out of the protocol"]


def test_label_bytes_that_are_not_utf8(tmp_path, cli):
    m = person(30)
    m["XHEE"] = m.pop("LHEE")
    f = write_c3d(tmp_path / "a.c3d", m)
    data = f.read_bytes()
    damage.overwrite(f, data.index(b"XHEE"), b"\xe9")
    raw = read_c3d(f)
    assert raw.labels[-1] == "\ufffdHEE"
    code, _, err = cli("import", protocol(tmp_path, [f]), "--out", tmp_path / "ws", "--jobs", "1", "--keep-all-markers")
    assert code == 0, err
    assert "\ufffdHEE" in set(read_table(tmp_path / "ws" / "import" / "markers.parquet", MARKERS)["marker"])


@pytest.mark.parametrize("cell, shown", [("12\t34", "'12 34'"), ('"12.5', "'\"12.5'")])
def test_vicon_csv_damaged_cells(tmp_path, cli, cell, shown):
    """A tab inside a cell (it split the row into one field too many) and an unclosed quote (it swallowed the
    rest of the file into one field): a non-numeric value, refused."""
    f = write_vicon_csv(tmp_path / "a.csv", person(30))
    lines = f.read_text().splitlines()
    row = next(i for i, ln in enumerate(lines) if ln.startswith("5,0,"))
    cells = lines[row].split(",")
    cells[4] = cell
    lines[row] = ",".join(cells)
    f.write_text("\n".join(lines) + "\n")
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], f"a.csv: non-numeric value {shown} in the data rows")


def test_vicon_csv_labels_that_do_not_line_up(tmp_path, cli):
    f = write_vicon_csv(tmp_path / "a.csv", person(20))
    lines = f.read_text().splitlines()
    row = next(i for i, ln in enumerate(lines) if "Subj:LASI" in ln)
    lines[row] = lines[row].replace(",Subj:RASI", "Subj:RASI,", 1)  # RASI moved above LASI's Z column
    f.write_text("\n".join(lines) + "\n")
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.csv: ")


@pytest.mark.parametrize("edit, expected", [
    (lambda t: t.replace("RHEE\tRTOE", "RHEE\xf0RTOE") if "RTOE" in t else t.replace("\tRPSI\tLHEE", "\tRPSI\xf0LHEE"),
     "NO_OF_MARKERS is '5' but MARKER_NAMES lists 4 names"),
    (lambda t: t.replace("NO_OF_MARKERS\t5\n", "").replace("\tRPSI\tLHEE", "\tRPSI\xf0LHEE"), "the column header row does not match MARKER_NAMES"),
    (lambda t: t.replace("NO_OF_MARKERS\t5\n", "").replace("\tRPSI\tLHEE", "\tRPSI\xf0LHEE").replace("Frame\tTime", "FRAME_X\tTime"),
     "data rows have more columns, 12 expected for 4 markers"),  # no header row: no Frame and Time columns either
])
def test_qualisys_names_that_do_not_line_up(tmp_path, cli, edit, expected):
    """A damaged MARKER_NAMES line (two names merged) would give the following markers their neighbour's data."""
    f = write_qtm_tsv(tmp_path / "a.tsv", person(20))
    f.write_text(edit(f.read_text()))
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.tsv: " + expected)


def test_damaged_frame_number_is_not_a_gap(tmp_path, cli):
    f = write_vicon_csv(tmp_path / "a.csv", person(20), frames=np.r_[1:10, 1_000_000_010:1_000_000_021])
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.csv: frame numbers jump from 9 to 1e+09 at data row 10")


def test_c3d_header_announcing_fewer_frames_than_its_data(tmp_path, cli):
    f = write_c3d(tmp_path / "a.c3d", person(100))
    damage.overwrite(f, 8, (60).to_bytes(2, "little"))  # last frame 100 -> 60
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])],
                    "a.c3d: corrupt C3D header: the file holds 3392 bytes (42 frames' worth) beyond the 60 frames its header "
                    "announces (frames 1-60)")  # 40 frames of 5 points x 4 floats (3200 bytes) and the padding


def test_sampling_rate_outside_motion_capture_rates(tmp_path, cli):
    f = write_c3d(tmp_path / "a.c3d", person(30), rate=2e-5)
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.c3d: sampling rate 2e-05 Hz is not a motion-capture rate (1 to 10000 Hz)")


@pytest.mark.parametrize("target, shift, value", [("LABELS", -1, 0xFF), ("USED", 10, 0x88)])
def test_c3d_description_lengths_that_crashed_ezc3d(tmp_path, target, shift, value):
    """A character parameter turned into a group (gid byte -> negative: its type byte 0xFF read as a
    description length) made ezc3d segfault; a description length >= 128 made it hang."""
    f = write_c3d(tmp_path / "a.c3d", person(20))
    damage.overwrite(f, f.read_bytes().index(target.encode()) + shift, bytes([value]))
    with pytest.raises(InputError, match=f"a.c3d: corrupt C3D parameter section \\(description length {value} of '{target}' out of range\\)"):
        read_c3d(f)


def write_c3d_with_analogs(path, markers):
    """A C3D with two analog channels (1000 Hz) beside the markers (200 Hz)."""
    import ezc3d

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [RATE]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = tuple(markers)
    xyz = np.stack(list(markers.values()), axis=1) * 1000.0
    points = np.ones((4, xyz.shape[1], xyz.shape[0]))
    points[:3] = xyz.transpose(2, 1, 0)
    c3d["data"]["points"] = points
    c3d["parameters"]["ANALOG"]["RATE"]["value"] = [5 * RATE]
    c3d["parameters"]["ANALOG"]["LABELS"]["value"] = ("Fx", "Fy")
    c3d["data"]["analogs"] = np.zeros((1, 2, 5 * xyz.shape[0]))
    c3d.write(str(path))
    return Path(path)


def _record(f, group_id, name):
    return next(r for r in damage.c3d_parameter_records(f) if r["name"] == name and r["gid"] == group_id)


@pytest.mark.parametrize("damage_it, expected", [
    (lambda f: damage.overwrite(f, _record(f, 2, "SCALE")["offset"] + 1, bytes([60])),  # ANALOG:SCALE moved to group 60
     "ANALOG:SCALE holds 0 values for 2 analog channels"),
    (lambda f: damage.overwrite(f, _record(f, 2, "SCALE")["offset"] + 1, bytes([1])),  # ... into POINT, which has a SCALE
     "parameter POINT:SCALE given twice"),
    (lambda f: damage.overwrite(f, _record(f, 1, "RATE")["structure"][4], bytes([0xFF])),  # POINT:RATE a character scalar
     "bad parameter type of 'RATE'"),
])
def test_c3d_parameter_structures_that_crashed_ezc3d(tmp_path, damage_it, expected):
    """Each of these made ezc3d segfault (found by the parameter-record sweep of the fuzz run); refused before ezc3d."""
    f = write_c3d_with_analogs(tmp_path / "a.c3d", person(20))
    assert read_c3d(f).xyz.shape == (20, 5, 3)
    damage_it(f)
    with pytest.raises(InputError, match=f"a.c3d: corrupt C3D parameter section \\({re.escape(expected)}\\)"):
        read_c3d(f)


def test_a_label_given_twice_in_a_yaml_map_is_refused(tmp_path, cli):
    """PyYAML keeps the last of two equal keys silently: {SACR: LPSI, SACR: RPSI} would map SACR to RPSI only."""
    m = person(20)
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    mapfile = tmp_path / "labmap.yaml"
    mapfile.write_text("SACR: LPSI\nSACR: RPSI\n")
    assert_rejected(cli, tmp_path / "ws", [proto, "--marker-map", mapfile], "labmap.yaml: key 'SACR' given twice in the mapping at line 1")
    proto.write_text(proto.read_text() + "marker_map:\n  SACR: LPSI\n  SACR: RPSI\n")
    assert_rejected(cli, tmp_path / "ws", [proto], "protocol.yaml: key 'SACR' given twice")


@pytest.mark.parametrize("writer, name", [(write_vicon_csv, "a.csv"), (write_qtm_tsv, "a.tsv")])
def test_text_export_cut_inside_its_last_line(tmp_path, cli, writer, name):
    """A truncated export ends in a cut number (1523.4 -> 15): refused; cut at a line end it is a shorter export."""
    f = writer(tmp_path / name, person(30))
    text = f.read_text().rstrip("\n")
    f.write_text(text[:-3])
    assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], f"{name}: truncated export: its last line is cut off")
    f.write_text(text[:text.rindex("\n") + 1])  # the last row dropped whole
    code, _, err = cli("import", protocol(tmp_path, [f]), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    assert read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)["n_frames"].tolist() == [29]


def test_vicon_csv_with_a_lone_carriage_return(tmp_path, cli):
    """A stray CR byte inside a data row splits it (as the csv module reads line ends): refused, not a crash."""
    f = write_vicon_csv(tmp_path / "a.csv", person(20))
    data = f.read_bytes()
    row = data.index(b"\n5,0,") + 1
    f.write_bytes(data[:row + 12] + b"\r" + data[row + 12:])
    msg = assert_rejected(cli, tmp_path / "ws", [protocol(tmp_path, [f])], "a.csv: ")
    assert "internal error" not in msg


@pytest.mark.parametrize("option, example", [("--lab-extent", "100"), ("--max-speed", "20"), ("--max-spike", "0.05")])
def test_import_limits_are_checked_by_the_api_for_the_command_line_too(tmp_path, cli, option, example):
    """The range of the plausibility limits was typer's (min=0, a usage block of 4 lines) on the command line, and
    api.import_markers' own check, which the import stage bypassed (it planned the import itself): both now call
    api.options.import_limits, one line naming the option, nothing written."""
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", person(10))])
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", option, "-1")
    assert code == 2 and err.splitlines() == [f"error: {option} must be >= 0, got -1; e.g. {option} {example}"]
    assert not (tmp_path / "ws").exists()


# ---- the lab's vertical axis ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def z_and_y_up(tmp_path_factory):
    """A synthetic walking study (z-up, as it is written) and a copy of its C3D files in a y-up lab (OptiTrack
    Motive's frame: x kept, y = height, z = -y), each imported and preprocessed with --up auto."""
    import shutil

    import ezc3d

    from cobot_analysis.cli import run
    from cobot_analysis.synth import walking

    root = tmp_path_factory.mktemp("vertical")
    walking.generate(root / "z-up", n_subjects=1, n_trials=1, conditions=["N1500", "E1515"])
    shutil.copytree(root / "z-up", root / "y-up")
    for f in sorted((root / "y-up").rglob("*.c3d")):
        c = ezc3d.c3d(str(f))
        p = c["data"]["points"]
        p[:3] = p[0], p[2], -p[1]
        c["data"]["points"] = p
        c.write(str(f))
    for lab in ("z-up", "y-up"):
        assert run(["-q", "import", str(root / lab / "protocol.yaml"), "--out", str(root / f"ws-{lab}"), "--preprocess", "-j", "1"]) == 0
    return root


def test_a_y_up_lab_is_found_from_the_pelvis_and_turned_to_z_up(z_and_y_up, cli):
    """Read as z-up, the y-up copy lost a horizontal coordinate: its walk along z became a path along x alone (N1500
    'nobody walks', E1515 0.03 m wide instead of 0.6 m), and average took it. Its vertical axis is now found from the
    pelvis and every trial rotated to z up ((x, y, z) -> (z, x, y)): the z-up study's trajectories turned by a quarter
    turn about z, bit for bit, and the import says so."""
    from cobot_analysis.schema import TRAJECTORIES

    z, y = (read_table(z_and_y_up / f"ws-{lab}" / "preprocess" / "trajectories.parquet", TRAJECTORIES) for lab in ("z-up", "y-up"))
    assert len(z) == len(y) == 1000
    assert np.array_equal(y["x"], -z["y"]) and np.array_equal(y["y"], z["x"]) and np.array_equal(y["travel_time"], z["travel_time"])
    np.testing.assert_allclose(np.angle(np.exp(1j * (y["theta"] - z["theta"] - np.pi / 2))), 0, atol=1e-12)
    meta = [table_metadata(z_and_y_up / f"ws-{lab}" / "import" / "markers.parquet")["vertical"] for lab in ("z-up", "y-up")]
    assert set(meta[0].values()) == {"z (detected)"} and set(meta[1].values()) == {"y (detected)"}
    assert "2 of 2 trials had y as their vertical axis (detected from the pelvis markers): rotated to z up." in \
        (z_and_y_up / "ws-y-up" / "import" / "results.md").read_text()
    code, _, err = cli("import", z_and_y_up / "y-up" / "protocol.yaml", "--out", z_and_y_up / "ws-y-again", "-j", "1")
    assert code == 0 and "warning: 2 of 2 trials had y as their vertical axis (detected from the pelvis markers): rotated to z " \
                          "up (--up gives the axis)" in " ".join(err.split()), err


@pytest.mark.parametrize("lab", ["y-up", "z-up"])
def test_up_gives_the_vertical_axis(z_and_y_up, lab):
    """--up y imports the y-up copy as auto does, --up z the z-up study (given, not detected; nothing said)."""
    from cobot_analysis.cli import run

    ws = z_and_y_up / f"ws-{lab}-given"
    axis = lab[0]
    assert run(["-q", "import", str(z_and_y_up / lab / "protocol.yaml"), "--out", str(ws), "--up", axis, "-j", "1"]) == 0
    assert set(table_metadata(ws / "import" / "markers.parquet")["vertical"].values()) == {f"{axis} (given)"}
    got, auto = (read_table(w / "import" / "markers.parquet", MARKERS) for w in (ws, z_and_y_up / f"ws-{lab}"))
    assert got[["x", "y", "z"]].equals(auto[["x", "y", "z"]])


def test_an_up_the_pelvis_contradicts_is_refused(z_and_y_up, cli):
    """--up z on the y-up copy: every pelvis points along y of the file, sideways in the frame --up z gives."""
    assert_rejected(cli, z_and_y_up / "ws-contradicted", [z_and_y_up / "y-up" / "protocol.yaml", "--up", "z"],
                    "S01_N1500_1.c3d): the pelvis of walker has its up direction along y of the file's frame, not along its "
                    "vertical z (given)", "give the lab's vertical axis with --up (auto finds it from the pelvis)")


def test_left_and_right_swapped_are_refused_and_the_marker_map_swaps_them(z_and_y_up, tmp_path, cli):
    """LASI and RASI swapped in the labels (the walker's orientation would be off by pi, walking backwards): the pelvis
    points down once the frame is z-up. Refused, whatever --up says; the remedy's marker map imports it as the original."""
    import shutil

    import ezc3d

    from cobot_analysis.cli import run

    lab = tmp_path / "swapped"
    shutil.copytree(z_and_y_up / "z-up", lab)
    for f in sorted(lab.rglob("*.c3d")):
        c = ezc3d.c3d(str(f))
        labels = list(c["parameters"]["POINT"]["LABELS"]["value"])
        i, j = labels.index("LASI"), labels.index("RASI")
        labels[i], labels[j] = "RASI", "LASI"
        c["parameters"]["POINT"]["LABELS"]["value"] = labels
        c.write(str(f))
    for up in ("auto", "z"):
        assert_rejected(cli, tmp_path / f"ws-{up}", [lab / "protocol.yaml", "--up", up],
                        "the pelvis of walker points down (its up direction, forward x left, is -z in the file, whose vertical "
                        "is z", "LASI and RASI look swapped", "--map LASI=RASI --map RASI=LASI")
    ws = tmp_path / "ws-mapped"
    assert run(["-q", "import", str(lab / "protocol.yaml"), "--out", str(ws), "--map", "LASI=RASI", "--map", "RASI=LASI", "-j", "1"]) == 0
    got, original = (read_table(w / "import" / "markers.parquet", MARKERS) for w in (ws, z_and_y_up / "ws-z-up"))
    assert got[["marker", "x", "y", "z"]].equals(original[["marker", "x", "y", "z"]])


def test_a_table_alone_in_a_y_up_lab_asks_for_the_axis(tmp_path, cli):
    """A table recorded without anyone: its top is vertical in a frame read as z-up; a table cannot tell the sign of
    the vertical, so the axis is asked for; given, the table lies flat."""
    from cobot_analysis.cli import run

    flat = table(50, prefix="")
    yup = {k: np.column_stack([v[:, 0], v[:, 2], -v[:, 1]]) for k, v in flat.items()}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", yup)], study="test-table")
    assert_rejected(cli, tmp_path / "ws", [proto], "the table's top is not horizontal in a frame whose vertical is z (assumed): "
                    "its normal is along y of the file's frame", "--up y or --up -y (a table alone cannot tell its sign)")
    assert run(["-q", "import", str(proto), "--out", str(tmp_path / "ws-y"), "--up", "y", "-j", "1"]) == 0
    z = read_table(tmp_path / "ws-y" / "import" / "markers.parquet", MARKERS).groupby("marker")["z"].agg(["min", "max"])
    assert np.allclose(z.to_numpy(), 0.77)  # (x, y, z) -> (z, x, y): the height back on z


def test_an_unknown_up_is_refused_before_reading(tmp_path, cli):
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", person(10))])
    msg = assert_rejected(cli, tmp_path / "ws", [proto, "--up", "w"], "unknown --up 'w': the lab's vertical axis",
                          "use one of auto, z, y, x, -z, -y, -x")
    assert msg.count("error") == 1


@pytest.mark.parametrize("axis", ["z", "y", "x", "-z", "-y", "-x"])
@pytest.mark.parametrize("pelvis", ["psis", "sacrum"])
def test_pelvis_up_finds_each_lab_axis_through_a_tilted_turning_pelvis(axis, pelvis):
    """A pelvis tilted 20 degrees forward, walking a half circle (every heading): its up direction is within 20 degrees
    of the vertical, and the axis the frame has as vertical is found, for each of the six; left and right swapped, it
    points down."""
    from cobot_analysis.kinematics import levelling, pelvis_up, vertical_axis

    heading = np.linspace(0, np.pi, 50)
    tilt = np.radians(20)
    c, s = np.cos(heading), np.sin(heading)

    def point(fwd, left, up):  # pelvis frame (x forward, y left, z up), tilted about y, turned about z, walked along a circle
        fx, fz = fwd * np.cos(tilt) + up * np.sin(tilt), -fwd * np.sin(tilt) + up * np.cos(tilt)
        return np.column_stack([2 * s + c * fx - s * left, 2 - 2 * c + s * fx + c * left, np.full_like(c, 0.95 + fz)])

    back = point(-0.16, 0.0, 0.02) if pelvis == "sacrum" else (point(-0.16, 0.045, 0.02) + point(-0.16, -0.045, 0.02)) / 2
    lasi, rasi = point(0.0, 0.12, 0.0), point(0.0, -0.12, 0.0)
    R = levelling(axis).T  # z-up lab -> a lab whose vertical is ``axis``
    up = pelvis_up(lasi @ R.T, rasi @ R.T, back @ R.T)
    assert vertical_axis(up) == axis
    assert np.degrees(np.arccos(up @ (R @ [0, 0, 1]))) == pytest.approx(20, abs=0.5)
    assert vertical_axis(pelvis_up(rasi @ R.T, lasi @ R.T, back @ R.T)) == ("-" + axis).replace("--", "")
    assert pelvis_up(np.full((3, 3), np.nan), rasi[:3], back[:3]) is None


def test_the_same_recording_under_two_trials_is_refused_once(tmp_path, cli):
    """A trials table that lists one file twice, or a copy of it: one recording counted as two trials (it weighed twice in
    every mean and test). The later trials are refused and listed, the first kept; with --strict the run is refused; the
    API (markers returned, not streamed) refuses them alike."""
    import shutil

    from cobot_analysis.api import import_markers

    a = write_c3d(tmp_path / "a.c3d", person(30))
    b = write_c3d(tmp_path / "b.c3d", person(30, y0=1.0))
    shutil.copy(a, tmp_path / "copy.c3d")
    proto = protocol(tmp_path, [a, b, a, tmp_path / "copy.c3d"])
    code, _, err = cli("import", proto, "--out", tmp_path / "ws", "--jobs", "1")
    text = " ".join(err.split())
    assert code == 3, err
    assert "t3 (a.c3d): the same recording as trial 't1' (the files are identical, SHA-256" in text
    assert "t4 (copy.c3d): the same recording as trial 't1'" in text
    assert "remedy: give each trial its own recording: remove the repeated row from the protocol's trials" in text
    assert read_table(tmp_path / "ws" / "import" / "trials.parquet", TRIALS)["trial"].tolist() == ["t1", "t2"]
    assert_rejected(cli, tmp_path / "ws-strict", [proto, "--strict"], "t3 (a.c3d): the same recording as trial 't1'")
    result = import_markers(proto, jobs=1)
    assert [r.trial for r in result.refused] == ["t3", "t4"] and result.trials["trial"].tolist() == ["t1", "t2"]
    assert sorted(result.markers["trial"].unique()) == ["t1", "t2"]


@pytest.mark.parametrize("labels, expected", [
    ({"TAB2": "TAB3", "TAB3": "TAB2"}, "table corners: TAB1 -> TAB2 (0.80 m) is shorter than TAB1 -> TAB3 (1.22 m): TAB2 "
                                       "must be along a long side; swap TAB2 and TAB3 with the marker map (--map TAB2=TAB3 --map TAB3=TAB2)"),
    ({"TAB1": "TAB2", "TAB2": "TAB1"}, "table corners: the angle at TAB1 between TAB2 and TAB3 is 33 degrees, not a right "
                                       "angle: TAB1 is not the corner between TAB2 and TAB3"),
])
def test_table_corners_against_the_convention_are_refused(tmp_path, cli, labels, expected):
    """The table's centre is the midpoint of TAB2 and TAB3, its orientation TAB2 - TAB1: corners labelled otherwise gave
    a side's midpoint and a quarter turn, without a word. The marker map the remedy names imports them as labelled right."""
    from cobot_analysis.cli import run

    m = {**person(50, prefix="S1:"), **person(50, x0=1.8, prefix="S2:", extra=()), **table(50)}
    relabelled = {f"Table:{labels.get(k.split(':')[1], k.split(':')[1])}" if k.startswith("Table:") else k: v for k, v in m.items()}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", relabelled)], pair=["P1"])
    assert_rejected(cli, tmp_path / "ws", [proto], expected)
    maps = [a for k, v in labels.items() for a in ("--map", f"{v}={k}")]
    assert run(["-q", "import", str(proto), "--out", str(tmp_path / "ok"), *maps, "-j", "1"]) == 0
    right = read_table(tmp_path / "ok" / "import" / "markers.parquet", MARKERS)
    centre = right[right["entity"] == "table"].groupby("marker")[["x", "y"]].first()
    assert centre.loc["TAB2"].to_numpy() - centre.loc["TAB1"].to_numpy() == pytest.approx([1.22, 0.0])


@pytest.mark.parametrize("names, expected", [
    ({"LASI": "L_IAS", "RASI": "R_IAS", "LPSI": "L_IPS", "RPSI": "R_IPS"},  # Qualisys sports marker set
     "--map L_IAS=LASI --map L_IPS=LPSI --map R_IAS=RASI --map R_IPS=RPSI"),
    ({"LASI": "Daphnee:ASISl", "RASI": "Daphnee:ASISr", "LPSI": "Daphnee:PSISl", "RPSI": "Daphnee:PSISr"},  # pyomeca's
     "--map Daphnee:ASISl=LASI --map Daphnee:PSISl=LPSI --map Daphnee:ASISr=RASI --map Daphnee:PSISr=RPSI"),
])
def test_a_pelvis_of_another_marker_set_is_refused_with_the_map_that_imports_it(tmp_path, cli, names, expected):
    """The remedy was a generic 'map the lab's labels with --map LAB=CANON'; for the pelvis names of common marker sets it
    is now the exact options (never applied on its own: a guess would be a silent error), and they import the file."""
    from cobot_analysis.cli import run

    m = {names.get(k, k): v for k, v in person(30).items()}
    proto = protocol(tmp_path, [write_c3d(tmp_path / "a.c3d", m)])
    msg = assert_rejected(cli, tmp_path / "ws", [proto], "required markers missing: walker:LASI",
                          f"the labels look like another marker set's pelvis: {expected}")
    assert msg.count("--map") == 4
    assert run(["-q", "import", str(proto), "--out", str(tmp_path / "ok"), *expected.split(), "-j", "1"]) == 0


def test_stats_take_the_anthropometrics_of_the_study_imported_not_of_a_synthetic_study_beside_it(tmp_path):
    """stats' default anthropometrics were OUT/synth-pairs's whenever the workspace held the synthetic study: a lab's
    pairs P1... imported into the same workspace got the synthetic pairs' weights and heights, without a word. Now they
    are the subjects and pairs of the protocol the import read; none without weights and heights."""
    from cobot_analysis.cli import run
    from cobot_analysis.stages.analysis import protocol_anthropometrics

    m = {**person(50, prefix="S1:"), **person(50, x0=1.8, prefix="S2:", extra=()), **table(50)}
    write_c3d(tmp_path / "a.c3d", m)
    trials = pd.DataFrame({"trial": ["t1"], "file": ["a.c3d"], "pair": ["P1"]})
    subjects = pd.DataFrame({"id": ["A", "B"], "weight": [60.0, 85.5], "height": [1.60, 1.90]})
    pairs = pd.DataFrame({"id": ["P1"], "subject1": ["A"], "subject2": ["B"]})
    proto = save_protocol(tmp_path / "protocol.yaml", "lab-pairs", trials, subjects=subjects, pairs=pairs)
    ws = tmp_path / "ws"
    (ws / "synth-pairs").mkdir(parents=True)  # a synthetic study's tables beside it, with the same pair id
    pairs.to_csv(ws / "synth-pairs" / "pairs.csv", index=False)
    subjects.assign(weight=[70.0, 70.0], height=[1.7, 1.7]).to_csv(ws / "synth-pairs" / "subjects.csv", index=False)
    assert run(["-q", "import", str(proto), "--out", str(ws), "-j", "1"]) == 0
    anthro, files = protocol_anthropometrics(ws)
    assert anthro.to_dict("records") == [{"pair": "P1", "weight_diff": 25.5, "height_diff": pytest.approx(0.30)}]
    assert files == [proto, tmp_path / "subjects.csv", tmp_path / "pairs.csv"]
    save_protocol(proto, "lab-pairs", trials, subjects=subjects.drop(columns=["weight", "height"]), pairs=pairs)
    assert protocol_anthropometrics(ws) == (None, [])
    assert protocol_anthropometrics(tmp_path / "no-import") == (None, [])
