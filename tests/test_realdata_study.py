"""A study of one's own, end to end: the five real recordings of three labs (../shared/realdata),
with a protocol and a study file written from docs/protocol.md and docs/statistics.md alone, from
``import`` to ``report`` with no built-in study name (skips without the recordings)."""

from __future__ import annotations

import json

import pytest

PROTOCOL = """\
study: realdata-gait
allow_outside: true        # the recordings stay where they are, outside the protocol's folder (docs/protocol.md)
marker_map:                # pyomeca's ISB names (Daphnee:ASISr) -> canonical
  ASISr: RASI
  ASISl: LASI
  PSISr: RPSI
  PSISl: LPSI
trials:
  - {{trial: pig_flatfoot, file: {d}/c3d/PiG_Motion-FlatFoot-Full.c3d, subject: btk1, condition: walk}}
  - {{trial: functional_walk, file: {d}/c3d/FunctionalWalk.c3d, subject: btk2, condition: walk}}
  - {{trial: gait, file: {d}/c3d/Gait.c3d, subject: btk3, condition: walk}}
  - {{trial: pyomeca_c3d, file: {d}/c3d/pyomeca_markers_analogs.c3d, subject: daphnee, condition: static}}
  - {{trial: pyomeca_csv, file: {d}/csv/pyomeca_markers.csv, subject: daphnee, condition: static}}
"""

STUDY = """\
study = "realdata-gait"
title = "Five recordings from three labs"
entities = ["walker"]

[[factor]]
column = "subject"
label = "recorded person"
meaning = "one person per lab file"

[[factor]]
column = "condition"
label = "task"
levels = { walk = "level walking", static = "standing still" }
"""


@pytest.mark.slow
def test_a_study_of_three_labs_runs_from_import_to_report(realdata, tmp_path, cli):
    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "protocol.yaml").write_text(PROTOCOL.format(d=realdata))
    (lab / "study.toml").write_text(STUDY)
    ws = tmp_path / "ws"
    code, _, err = cli("import", lab / "protocol.yaml", "--out", ws, "--jobs", "1")
    assert code == 0, err
    # three labs' z-up frames, each pelvis found upright (io.markers.lab_vertical): nothing rotated, nothing said
    from cobot_analysis.schema import table_metadata

    assert set(table_metadata(ws / "import" / "markers.parquet")["vertical"].values()) == {"z (detected)"}
    assert "vertical axis" not in err
    code, _, err = cli("preprocess", "--out", ws, "--jobs", "1")  # the static recordings are refused, the walks go on
    assert code == 3, err
    refused = json.loads((ws / "preprocess" / "manifest.json").read_text())["refused"]
    assert sorted((r["trial"], r["file"].rsplit("/", 1)[-1]) for r in refused) == [
        ("pyomeca_c3d", "pyomeca_markers_analogs.c3d"), ("pyomeca_csv", "pyomeca_markers.csv")]
    assert all("nobody walks" in r["reason"] for r in refused)
    assert "markers.parquet" not in err and err.count("remedy:") == 1
    code, _, err = cli("average", "--out", ws)  # three labs, three frames: said, and kept out of the comparisons
    assert code == 0, err
    assert "starts spread" in err and "frames_differ" in err
    for args in (["compare"], ["stats"], ["report", "--to", tmp_path / "report"]):
        code, _, err = cli(*args, "--out", ws)
        assert code == 0, (args, err)
    report = (tmp_path / "report" / "README.md").read_text()
    assert "# Five recordings from three labs: report" in report
    assert "pyomeca_markers_analogs.c3d" in report and "Refused trials" in report
    assert "no questions declared: default descriptive statistics" in report
    assert "W1" not in report and "Q1" not in report
    # nothing compared (three frames): a sentence, not a table of headers alone
    assert "No pair of trajectories was compared" in report and "| comparison | entity |" not in report
    assert (tmp_path / "report" / "paths.png").stat().st_size > 1000
