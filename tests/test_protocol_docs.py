"""The examples of docs/protocol.md import: their files are taken from the document, the raw files
they name are made from a small synthetic study relabelled the way each example's lab labels them."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from cobot_analysis.io.c3d import read_c3d
from cobot_analysis.schema import MARKERS, TRIALS, read_table
from cobot_analysis.synth import pairs, walking
from cobot_analysis.synth.c3d import write_c3d

DOC = Path(__file__).resolve().parents[1] / "docs" / "protocol.md"
FILE = re.compile(r"^File `([^`]+)`:\n\n```[a-z]*\n(.*?)```", re.M | re.S)
PELVIS = {"LASI": "ASISl", "RASI": "ASISr", "LPSI": "PSISl", "RPSI": "PSISr"}


def doc_files() -> dict[str, str]:
    """``{relative path: text}`` of every example file of docs/protocol.md."""
    return {path: text for path, text in FILE.findall(DOC.read_text())}


def write_tsv(path: Path, labels: list[str], xyz: np.ndarray, rate: float) -> None:
    """Qualisys TSV export (mm; occluded samples as 0 0 0, as QTM writes them)."""
    mm = np.nan_to_num(xyz * 1000.0, nan=0.0)
    head = [f"NO_OF_FRAMES\t{len(mm)}", f"NO_OF_MARKERS\t{len(labels)}", f"FREQUENCY\t{rate:g}", "DATA_INCLUDED\t3D",
            "MARKER_NAMES\t" + "\t".join(labels), "Frame\tTime\t" + "\t".join(f"{m} {a}" for m in labels for a in "XYZ")]
    rows = [f"{i + 1}\t{i / rate:.5f}\t" + "\t".join(f"{v:.3f}" for v in mm[i].ravel()) for i in range(len(mm))]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(head + rows) + "\n")


@pytest.fixture(scope="module")
def examples(tmp_path_factory) -> Path:
    """docs/protocol.md's example files under one directory, with raw files for every example but the sacrum one."""
    root = tmp_path_factory.mktemp("protocol-docs")
    for rel, text in doc_files().items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    src = tmp_path_factory.mktemp("synth")
    walking.generate(src / "w", seed=3, n_subjects=2, n_trials=2, conditions=["E4015"])
    pairs.generate(src / "p", seed=3, n_pairs=1, goals=["d1_p4_gris"], scenarios=[1, 3])
    for subject in ("S01", "S02"):  # Vicon: subject name before each label
        raw = read_c3d(src / "w" / "raw" / f"{subject}_E4015_1.c3d")
        (root / "vicon-walking" / "raw").mkdir(parents=True, exist_ok=True)
        write_c3d(root / "vicon-walking" / "raw" / f"{subject}_E4015_1.c3d", [f"{subject}:{m}" for m in raw.labels],
                  raw.xyz, raw.rate)
    qtm = {"LASI": "L_ASIS", "RASI": "R_ASIS", "LPSI": "L_PSIS", "RPSI": "R_PSIS", "LHEE": "L_HEEL", "RHEE": "R_HEEL"}
    for rep in (1, 2):
        raw = read_c3d(src / "w" / "raw" / f"S01_E4015_{rep}.c3d")
        write_tsv(root / "qtm-walking" / "qtm" / f"P1_N1500_{rep}.tsv", [qtm.get(m, m) for m in raw.labels], raw.xyz, raw.rate)
    names = {"S1": "Daphnee", "S2": "Hugo", "Table": "Table"}
    corners = {"TAB1": "C1", "TAB2": "C2", "TAB3": "C3"}
    for scenario in (1, 3):
        raw = read_c3d(src / "p" / "raw" / f"P01_d1_p4_gris_s{scenario}.c3d")
        labels = []
        for label in raw.labels:
            prefix, name = label.split(":")
            labels.append(f"{names[prefix]}:{PELVIS.get(name, corners.get(name, name))}")
        (root / "pairs" / "raw").mkdir(parents=True, exist_ok=True)
        write_c3d(root / "pairs" / "raw" / f"P01_d1_p4_gris_s{scenario}.c3d", labels, raw.xyz, raw.rate)
    root.joinpath("source").symlink_to(src)
    return root


def test_the_document_has_the_four_examples():
    files = doc_files()
    assert {"vicon-walking/protocol.yaml", "qtm-walking/protocol.yaml", "pairs/protocol.yaml",
            "sacrum-walking/protocol.yaml", "pairs/pairs.csv", "pairs/trials.csv"} <= set(files)
    assert "VSAC: SACR" in files["sacrum-walking/protocol.yaml"]  # the sacrum marker set's one key


@pytest.mark.parametrize("example, n_trials, entities", [
    ("vicon-walking", 2, {"walker"}),
    ("qtm-walking", 2, {"walker"}),
    ("pairs", 2, {"subject1", "subject2", "table"}),
])
def test_examples_import(examples, cli, tmp_path, example, n_trials, entities):
    code, _, err = cli("-q", "import", examples / example / "protocol.yaml", "--out", tmp_path)
    assert code == 0, err
    trials = read_table(tmp_path / "import" / "trials.parquet", TRIALS)
    markers = read_table(tmp_path / "import" / "markers.parquet", MARKERS)
    assert len(trials) == n_trials and set(markers["entity"]) == entities
    assert trials["source_format"].iloc[0] == ("qualisys-tsv" if example == "qtm-walking" else "c3d")
    # the mapped markers are the original ones, in place (no left/right swap, no lost corner)
    src = examples / "source"
    if example == "pairs":
        raw = read_c3d(src / "p" / "raw" / "P01_d1_p4_gris_s3.c3d")
        trial, checks = "P01_d1_p4_gris_s3", [("subject1", "S1:LASI"), ("subject2", "S2:RPSI"), ("table", "Table:TAB2")]
    else:
        raw = read_c3d(src / "w" / "raw" / "S01_E4015_1.c3d")
        trial = "S01_E4015_1" if example == "vicon-walking" else "P1_N1500_1"
        checks = [("walker", "LASI"), ("walker", "RPSI"), ("walker", "RHEE")]
    for entity, label in checks:
        canon = label.split(":")[-1]
        got = markers[(markers["trial"] == trial) & (markers["entity"] == entity) & (markers["marker"] == canon)]
        want = raw.xyz[:, raw.labels.index(label)]
        np.testing.assert_allclose(got[["x", "y", "z"]].to_numpy(), want, atol=1e-5)
