"""Issue 21: what is read is trusted only when it is consistent: declared rates, C3D headers
against their parameter section, byte-order marks, duplicate labels, bounded inputs."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import pandas as pd
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.io.c3d import read_c3d
from cobot_analysis.io.protocol import save_protocol
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).parent))
import damage  # noqa: E402
from test_import import assert_rejected, person, write_c3d, write_c3d_with_analogs, write_qtm_tsv, write_vicon_csv  # noqa: E402


def one_trial_protocol(tmp_path, f, rate=None, invalid_rate=None):
    trials = pd.DataFrame({"trial": ["t1"], "file": [Path(f).name]})
    p = save_protocol(tmp_path / "protocol.yaml", "rates", trials, rate=rate)
    if invalid_rate:
        p.write_text(p.read_text() + f"invalid_rate: {invalid_rate}\n")
    return p


def _c3d_rate(value):
    def make(d):
        return damage.c3d_set_parameter(write_c3d(d / "a.c3d", person(60)), "POINT", "RATE", struct.pack("<f", value))
    return make


def _text_rate(writer, name: str, header: str, text: str):
    """A text export whose declared rate line ``header + "200"`` says ``header + text`` instead."""
    def make(d):
        f = writer(d / name, person(60))
        f.write_text(f.read_text().replace(f"{header}200\n", f"{header}{text}\n"))
        return f
    return make


def _vicon_rate(text):
    return _text_rate(write_vicon_csv, "a.csv", "Trajectories\n", text)


def _qtm_rate(text):
    return _text_rate(write_qtm_tsv, "a.tsv", "FREQUENCY\t", text)


#: the seven invalid declared rates of the issue: file maker, what the refusal says.
INVALID_RATES = {
    "c3d-zero": (_c3d_rate(0.0), "a.c3d: invalid sampling rate 0 Hz (POINT:RATE)"),
    "c3d-negative": (_c3d_rate(-200.0), "a.c3d: invalid sampling rate -200 Hz (POINT:RATE)"),
    "vicon-zero": (_vicon_rate("0"), "a.csv: invalid sampling rate 0 Hz (the rate line after 'Trajectories')"),
    "vicon-negative": (_vicon_rate("-200"), "a.csv: invalid sampling rate -200 Hz (the rate line after 'Trajectories')"),
    "vicon-nan": (_vicon_rate("NaN"), "a.csv: invalid sampling rate nan Hz (the rate line after 'Trajectories')"),
    "qtm-zero": (_qtm_rate("0"), "a.tsv: invalid sampling rate 0 Hz (FREQUENCY)"),
    "qtm-nan": (_qtm_rate("NaN"), "a.tsv: invalid sampling rate nan Hz (FREQUENCY)"),
}


@pytest.mark.parametrize("case", sorted(INVALID_RATES))
def test_an_invalid_declared_rate_is_refused_not_replaced(tmp_path, cli, case):
    """With 'rate: 150' in the protocol the data were stored as 150 Hz, exit 0: now refused, one line, a remedy."""
    make, expected = INVALID_RATES[case]
    f = make(tmp_path)
    msg = assert_rejected(cli, tmp_path / "ws", [one_trial_protocol(tmp_path, f, rate=150)], expected, "invalid_rate: protocol")
    assert len(msg.splitlines()) == 1


@pytest.mark.parametrize("case", sorted(INVALID_RATES))
def test_an_invalid_rate_is_replaced_only_by_the_explicit_protocol_option(tmp_path, cli, case):
    make, _ = INVALID_RATES[case]
    f = make(tmp_path)
    code, _, err = cli("import", one_trial_protocol(tmp_path, f, rate=150, invalid_rate="protocol"), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    assert "replaced by the protocol's rate 150 Hz (invalid_rate: protocol)" in " ".join(err.split())
    assert pq.read_table(tmp_path / "ws" / "import" / "trials.parquet").to_pandas()["rate"].tolist() == [150.0]
    assert "replaced by the protocol's rate 150 Hz" in (tmp_path / "ws" / "import" / "results.md").read_text()


def test_invalid_rate_protocol_needs_a_rate(tmp_path, cli):
    f = write_c3d(tmp_path / "a.c3d", person(30))
    assert_rejected(cli, tmp_path / "ws", [one_trial_protocol(tmp_path, f, invalid_rate="protocol")],
                    "protocol.yaml: 'invalid_rate' must be refuse or protocol ('protocol' with a 'rate'), not 'protocol'")


@pytest.mark.parametrize("writer, name", [(write_c3d, "a.c3d"), (write_vicon_csv, "a.csv"), (write_qtm_tsv, "a.tsv")])
def test_a_valid_file_rate_wins_with_one_warning_naming_both(tmp_path, cli, writer, name):
    f = writer(tmp_path / name, person(60))
    code, _, err = cli("import", one_trial_protocol(tmp_path, f, rate=150), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    warnings = [w for w in err.splitlines() if "differs from the protocol's rate" in w]
    assert len(warnings) == 1 and "rate 200 Hz" in warnings[0] and "150 Hz" in warnings[0], err
    assert pq.read_table(tmp_path / "ws" / "import" / "trials.parquet").to_pandas()["rate"].tolist() == [200.0]


def test_c3d_nan_point_rate_is_refused_before_ezc3d(tmp_path):
    """ezc3d fails on a NaN POINT:RATE (vector::_M_default_append): refused with the true reason."""
    f = _c3d_rate(float("nan"))(tmp_path)
    with pytest.raises(InputError, match=r"a.c3d: invalid sampling rate: POINT:RATE is NaN \(the header says 200 Hz\)"):
        read_c3d(f)


# ---- C3D header against the parameter section -------------------------------------------------
def _set_int(group, name, value):
    return lambda f: damage.c3d_set_parameter(f, group, name, struct.pack("<h", value))


@pytest.mark.parametrize("edit, expected", [
    # the two clinical files: analog values announced by the header, ANALOG:USED 0 (y = 0 everywhere, "check the units")
    (_set_int("ANALOG", "USED", 0), "the header announces 10 analog values per frame but ANALOG:USED is 0 (or absent): "
                                    "the marker data would be read with a wrong stride"),
    (_set_int("ANALOG", "USED", 3), "the header announces 10 analog values per frame, not a multiple of ANALOG:USED 3"),
    (lambda f: damage.c3d_set_parameter(f, "ANALOG", "RATE", struct.pack("<f", 2000.0)),
     "the header announces 10 analog values per frame for 2 channels (5 samples per frame), ANALOG:RATE / POINT:RATE is 2000 / 200"),
    (_set_int("POINT", "FRAMES", 25), "the header announces frames 1-20 (20), POINT:FRAMES 25"),
    (_set_int("POINT", "DATA_START", 9), "the header's data start block is"),
    (lambda f: damage.c3d_set_parameter(f, "POINT", "SCALE", struct.pack("<f", 0.1)),
     "the header's scale factor says float data, POINT:SCALE 0.1 says integer"),
])
def test_c3d_header_disagreeing_with_its_parameters_is_refused(tmp_path, edit, expected):
    f = write_c3d_with_analogs(tmp_path / "a.c3d", person(20))
    assert read_c3d(f).xyz.shape == (20, 5, 3)
    edit(f)
    with pytest.raises(InputError, match="a.c3d: inconsistent C3D file: " + expected.replace("(", r"\(").replace(")", r"\)")):
        read_c3d(f)


def test_c3d_point_rate_disagreeing_with_the_header_is_a_note(tmp_path):
    f = damage.c3d_set_parameter(write_c3d(tmp_path / "a.c3d", person(30)), "POINT", "RATE", struct.pack("<f", 100.0))
    raw = read_c3d(f)
    assert raw.rate == 100.0
    assert any("POINT:RATE 100 Hz differs from the header's frame rate 200 Hz" in n for n in raw.notes)


# ---- duplicate labels ---------------------------------------------------------------------------
def test_a_required_label_given_twice_gets_a_remedy_that_works(tmp_path, cli):
    """Two markers named 'sacrum': 'fix the marker map' could not work; an occurrence key does."""
    m = person(60)
    lasi, rasi, lpsi, rpsi = (m[k] for k in ("LASI", "RASI", "LPSI", "RPSI"))
    sacrum = (lpsi + rpsi) / 2
    import ezc3d
    import numpy as np

    c3d = ezc3d.c3d()
    c3d["parameters"]["POINT"]["RATE"]["value"] = [200.0]
    c3d["parameters"]["POINT"]["LABELS"]["value"] = ("LASI", "RASI", "sacrum", "sacrum")
    c3d["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    xyz = np.stack([lasi, rasi, sacrum, sacrum + [0.0, 0.0, 0.3]], axis=1) * 1000.0
    points = np.ones((4, 4, 60))
    points[:3] = xyz.transpose(2, 1, 0)
    c3d["data"]["points"] = points
    c3d.write(str(tmp_path / "a.c3d"))
    proto = one_trial_protocol(tmp_path, tmp_path / "a.c3d")
    msg = assert_rejected(cli, tmp_path / "ws", [proto, "--map", "sacrum=SACR"],
                          "a.c3d: label 'sacrum' is given twice (points 3 and 4 of the file), both walker SACR",
                          "--map 'sacrum#2=sacrum_2'")
    assert "fix the marker map" not in msg
    code, _, err = cli("import", proto, "--map", "sacrum=SACR", "--map", "sacrum#2=sacrum_2", "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    markers = pq.read_table(tmp_path / "ws" / "import" / "markers.parquet").to_pandas()
    sacr = markers[markers["marker"] == "SACR"].sort_values("frame")
    np.testing.assert_allclose(sacr["z"].to_numpy(), sacrum[:, 2], atol=1e-4)  # the first occurrence, not the second
    assert set(markers["marker"]) == {"LASI", "RASI", "SACR"}


# ---- text exports: byte-order mark, units row ---------------------------------------------------
@pytest.mark.parametrize("writer, name", [(write_vicon_csv, "a.csv"), (write_qtm_tsv, "a.tsv")])
def test_a_byte_order_mark_is_read(tmp_path, cli, writer, name):
    ref = writer(tmp_path / f"ref{Path(name).suffix}", person(60))
    f = tmp_path / name
    f.write_bytes(b"\xef\xbb\xbf" + ref.read_bytes())
    from cobot_analysis.io.markers import read_markers

    import numpy as np

    fmt, raw = read_markers(f)
    np.testing.assert_array_equal(raw.xyz, read_markers(ref)[1].xyz)
    code, _, err = cli("import", one_trial_protocol(tmp_path, f), "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err


def test_a_utf16_export_is_refused_with_the_true_reason(tmp_path, cli):
    f = tmp_path / "a.csv"
    f.write_bytes(write_vicon_csv(tmp_path / "ref.csv", person(30)).read_text().encode("utf-16"))
    assert_rejected(cli, tmp_path / "ws", [one_trial_protocol(tmp_path, f)], "a.csv: UTF-16 text", "save the file as UTF-8")


def test_a_vicon_export_without_its_units_row(tmp_path, cli):
    """Was 'mixed length units ['-18.154', ...': now the true reason, and read when --units states them."""
    ref = write_vicon_csv(tmp_path / "ref.csv", person(60))
    lines = ref.read_text().split("\n")
    f = tmp_path / "a.csv"
    f.write_text("\n".join(ln for ln in lines if not ln.startswith(",,mm")))
    proto = one_trial_protocol(tmp_path, f)
    assert_rejected(cli, tmp_path / "ws", [proto], "a.csv: no units row in the Trajectories section", "--units mm")
    from cobot_analysis.io.text_exports import read_vicon_csv

    import numpy as np

    np.testing.assert_array_equal(read_vicon_csv(f, units="mm").xyz, read_vicon_csv(ref).xyz)
    code, _, err = cli("import", proto, "--units", "mm", "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err


# ---- protocol paths -----------------------------------------------------------------------------
def _outside_study(tmp_path, how):
    """A protocol in tmp/study whose trial file lies outside its folder: via '..', an absolute path, or a symlink."""
    study, elsewhere = tmp_path / "study", tmp_path / "elsewhere"
    study.mkdir()
    elsewhere.mkdir()
    f = write_c3d(elsewhere / "a.c3d", person(60))
    if how == "dotdot":
        name = "../elsewhere/a.c3d"
    elif how == "absolute":
        name = str(f)
    else:
        (study / "link.c3d").symlink_to(f)
        name = "link.c3d"
    p = save_protocol(study / "protocol.yaml", "paths", pd.DataFrame({"trial": ["t1"], "file": [name]}))
    return p, f, name


@pytest.mark.parametrize("how", ["dotdot", "absolute", "symlink"])
def test_a_trial_file_outside_the_protocols_folder_is_refused(tmp_path, cli, how):
    p, f, name = _outside_study(tmp_path, how)
    assert_rejected(cli, tmp_path / "ws", [p], f"protocol.yaml: trial t1 names file {name}, outside the protocol's folder ({f})",
                    "'allow_outside: true'")


@pytest.mark.parametrize("how", ["dotdot", "symlink"])
def test_allow_outside_accepts_and_records_them(tmp_path, cli, how):
    import json

    p, f, _ = _outside_study(tmp_path, how)
    p.write_text(p.read_text() + "allow_outside: true\n")
    code, _, err = cli("import", p, "--out", tmp_path / "ws", "--jobs", "1")
    assert code == 0, err
    manifest = json.loads((tmp_path / "ws" / "import" / "manifest.json").read_text())
    assert manifest["params"]["allow_outside"] is True and manifest["params"]["outside_files"] == [str(f)]
    assert f"Files outside the protocol's folder (allow_outside: true): {f}." in (tmp_path / "ws" / "import" / "results.md").read_text()


def test_a_csv_table_outside_the_protocols_folder_is_refused(tmp_path, cli):
    study = tmp_path / "study"
    study.mkdir()
    write_c3d(study / "a.c3d", person(60))
    pd.DataFrame({"trial": ["t1"], "file": ["a.c3d"]}).to_csv(tmp_path / "trials.csv", index=False)
    p = study / "protocol.yaml"
    p.write_text("study: x\ntrials: ../trials.csv\n")
    assert_rejected(cli, tmp_path / "ws", [p], "protocol.yaml: the trials file ../trials.csv is outside the protocol's folder")
