"""The numpy reader of C3D point data (``io.c3d._numpy_points``) gives exactly what ezc3d gives
(``read_c3d(..., numpy=False)``, the reference): positions, NaN pattern, labels, rate, units and
notes, on the real lab files, the synthetic C3D the project writes, integer-scaled files, odd
label bytes, and damaged files (refused with the same one-line message, or read identically)."""

from __future__ import annotations

import random
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.io import c3d as C
from cobot_analysis.synth.c3d import write_c3d

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
import damage  # noqa: E402

LABELS = ["LASI", "RASI", "LPSI", "RPSI", "LHEE", "RHEE"]


def uses_numpy(path: Path) -> bool:
    """True if ``read_c3d`` reads the point data of ``path`` with numpy (not ezc3d)."""
    return C._numpy_points(Path(path), C._check(Path(path))[1]) is not None


def outcome(path: Path, numpy: bool):
    """``("ok", RawMarkers)`` or ``("refused", message)``."""
    try:
        return "ok", C.read_c3d(path, numpy=numpy)
    except InputError as exc:
        return "refused", str(exc)


def assert_same(path: Path) -> str:
    """Both readers agree on ``path``: same refusal (one line), or same values. Returns the outcome kind."""
    (kind, a), (ref_kind, b) = outcome(path, True), outcome(path, False)
    assert kind == ref_kind, (path, a, b)
    if kind == "refused":
        assert a == b and "\n" not in a
        return kind
    assert a.labels == b.labels and a.units == b.units and a.notes == b.notes
    assert a.rate == b.rate or (np.isnan(a.rate) and np.isnan(b.rate))
    assert a.xyz.dtype == b.xyz.dtype and a.xyz.shape == b.xyz.shape
    assert np.array_equal(np.isnan(a.xyz), np.isnan(b.xyz))
    assert np.array_equal(a.xyz, b.xyz, equal_nan=True)  # exact, not close
    return kind


def synthetic(path: Path, frames: int = 120, seed: int = 0, labels=LABELS) -> Path:
    """A float C3D as the project writes it: random walk positions, some samples missing, the last
    frames all missing (a reader could drop trailing empty frames)."""
    rng = np.random.default_rng(seed)
    xyz = np.cumsum(rng.normal(0, 0.01, (frames, len(labels), 3)), axis=0) + rng.uniform(-3, 3, (1, len(labels), 3))
    missing = rng.random((frames, len(labels))) < 0.1
    missing[-3:] = True
    write_c3d(path, labels, xyz, 200.0, missing=missing)
    return path


def to_integer(src: Path, dst: Path, seed: int = 0) -> Path:
    """``src`` (a float C3D without analog data, Intel) rewritten as integer data: positions as int16
    x a positive POINT:SCALE, then a camera-mask byte and a signed residual byte (negative for the
    missing samples, random values otherwise)."""
    data = bytearray(src.read_bytes())
    lay = damage.c3d_layout(data)
    assert lay["float"] and lay["analogs"] == 0
    start, n, frames = damage.c3d_data_offset(data), lay["points"], lay["frames"]
    values = np.frombuffer(bytes(data[start:start + frames * n * 16]), "<f4").reshape(frames, n, 4)
    missing = np.frombuffer(bytes(data[start:start + frames * n * 16]), "<i2").reshape(frames, n, 8)[..., 7] < 0
    xyz = values[..., :3].astype(float)
    scale = float(np.float32(np.nanmax(np.abs(xyz)) / 30000.0 * 1.01))
    words = np.zeros((frames, n, 4), "<i2")
    words[..., :3] = np.where(np.isfinite(xyz), np.round(np.nan_to_num(xyz) / scale), 0)
    rng = np.random.default_rng(seed)
    residual = np.where(missing, rng.integers(-128, 0, missing.shape), rng.integers(0, 128, missing.shape))
    words[..., 3] = (residual.astype(np.int16) << 8) | rng.integers(0, 128, missing.shape).astype(np.int16)
    body = words.tobytes()
    body += bytes(-len(body) % C.BLOCK)
    out = bytes(data[:start]) + body
    out = out[:12] + struct.pack("<f", scale) + out[16:]
    dst.write_bytes(out)
    return damage.c3d_set_parameter(dst, "POINT", "SCALE", struct.pack("<f", scale))


def real_c3d(realdata: Path) -> list[Path]:
    files = sorted((realdata / "c3d").glob("*.c3d"))
    assert files, realdata
    return files


# ---- equal on intact files --------------------------------------------------------------------
def test_real_lab_files_read_as_ezc3d_reads_them(realdata):
    files = real_c3d(realdata)
    for f in files:
        assert assert_same(f) == "ok", f
    # the numpy reader is what reads the Intel files (Gait.c3d is DEC: ezc3d reads it)
    assert {f.name for f in files if uses_numpy(f)} >= {"FunctionalWalk.c3d", "PiG_Motion-FlatFoot-Full.c3d",
                                                         "pyomeca_markers_analogs.c3d"}


def test_real_integer_file_converted_to_intel_reads_as_ezc3d(realdata, tmp_path):
    """Gait.c3d (DEC, integer data) with its processor type and floats rewritten as Intel: the numpy
    reader's integer path against ezc3d on a real integer file with analog channels."""
    src = realdata / "c3d" / "Gait.c3d"
    data = bytearray(src.read_bytes())
    param = (data[0] - 1) * C.BLOCK
    assert data[param + 3] == 85

    def dec_to_ieee(b: bytes) -> bytes:  # DEC float: words swapped, exponent 2 higher (ezc3d's readFloat)
        swapped = bytes([b[2], b[3], b[0], (b[1] - 1) & 0xFF if b[1] else 0])
        return swapped

    for at in (12, 20):  # header scale factor, frame rate
        data[at:at + 4] = dec_to_ieee(bytes(data[at:at + 4]))
    for rec in damage.c3d_parameter_records(bytes(data)):
        if rec["gid"] > 0:
            body = rec["structure"][3] + 1
            dtype, ndims = struct.unpack("bB", data[body:body + 2])
            if dtype == 4:
                count = int(np.prod(list(data[body + 2:body + 2 + ndims]))) if ndims else 1
                first = body + 2 + ndims
                for k in range(count):
                    data[first + 4 * k:first + 4 * k + 4] = dec_to_ieee(bytes(data[first + 4 * k:first + 4 * k + 4]))
    data[param + 3] = 84
    f = tmp_path / "gait_intel.c3d"
    f.write_bytes(bytes(data))
    assert uses_numpy(f) and not C.check_c3d_header(f)["float"]
    assert assert_same(f) == "ok"
    ref = C.read_c3d(src, numpy=False)  # and the same values as the DEC original
    assert np.array_equal(C.read_c3d(f).xyz, ref.xyz, equal_nan=True) and C.read_c3d(f).labels == ref.labels


def test_synthetic_float_files_read_as_ezc3d_reads_them(tmp_path):
    for seed in range(3):
        f = synthetic(tmp_path / f"s{seed}.c3d", seed=seed)
        assert uses_numpy(f)
        assert assert_same(f) == "ok"
        raw = C.read_c3d(f)
        assert raw.xyz.shape == (120, len(LABELS), 3) and np.isnan(raw.xyz[-3:]).all()  # trailing empty frames kept


def test_project_study_files_read_with_numpy(tmp_path):
    """The files `synth walking` writes (the ones the benchmarks import) take the numpy path."""
    from cobot_analysis.synth import walking

    protocol = walking.generate(tmp_path / "study", n_subjects=1, n_trials=1, conditions=["E1500"])
    files = sorted((protocol.parent / "raw").glob("*.c3d"))
    assert files and all(uses_numpy(f) for f in files)
    for f in files:
        assert assert_same(f) == "ok"


def test_integer_files_read_as_ezc3d_reads_them(tmp_path):
    for seed in range(3):
        f = to_integer(synthetic(tmp_path / f"f{seed}.c3d", seed=seed), tmp_path / f"i{seed}.c3d", seed=seed)
        assert uses_numpy(f) and not C.check_c3d_header(f)["float"]
        assert assert_same(f) == "ok"
        raw = C.read_c3d(f)
        assert np.isnan(raw.xyz).any() and not np.isnan(raw.xyz).all()


def test_residual_words_and_nan_coordinates(tmp_path):
    """Float files whose residual words hold any negative value (invalid) or any positive one, and NaN
    coordinates with a valid residual (counted as occluded, noted)."""
    f = synthetic(tmp_path / "r.c3d", frames=40)
    data = bytearray(f.read_bytes())
    start, n = damage.c3d_data_offset(data), len(LABELS)
    rng = random.Random(3)
    for frame in range(0, 36):
        for p in range(n):
            at = start + (frame * n + p) * 16
            data[at + 14:at + 16] = struct.pack("<h", rng.choice((-32768, -16512, -1, 0, 1, 32767, rng.randrange(-32768, 32768))))
            data[at + 12:at + 14] = struct.pack("<h", rng.randrange(-32768, 32768))  # camera mask word
    data[start + 4:start + 8] = struct.pack("<f", float("nan"))  # y of point 0, frame 0
    data[start + 14:start + 16] = struct.pack("<h", 5)
    f.write_bytes(bytes(data))
    assert uses_numpy(f) and assert_same(f) == "ok"
    raw = C.read_c3d(f)
    assert np.isnan(raw.xyz[0, 0]).all() and any("NaN coordinate" in n for n in raw.notes)


@pytest.mark.parametrize("label", [b"\xffX", b"\x00B", b" C", b"\xc3\xa9t", b"A\x00B", b"  ", b"\x80\x81"])
def test_label_bytes_decoded_as_ezc3d_decodes_them(tmp_path, label):
    f = synthetic(tmp_path / "l.c3d", frames=20, labels=["AAAA", "BBBB", "CCCC"])
    at = damage.c3d_parameter_offset(f, "POINT", "LABELS")
    damage.overwrite(f, at + 4, label)  # into the second label (width 4)
    assert uses_numpy(f) and assert_same(f) == "ok"


def test_outside_the_numpy_reader_ezc3d_reads(tmp_path, realdata):
    """DEC files, a first frame of 0, a missing POINT:DATA_START record value... go to ezc3d."""
    assert not uses_numpy(realdata / "c3d" / "Gait.c3d")
    f = synthetic(tmp_path / "z.c3d", frames=20)
    damage.overwrite(f, 6, struct.pack("<H", 0))  # first frame 0 (ezc3d keeps it 0, others subtract 1)
    damage.overwrite(f, 8, struct.pack("<H", 19))
    assert not uses_numpy(f)
    assert_same(f)


# ---- damaged files ----------------------------------------------------------------------------
def _damaged_cases(seeds: list[Path], n: int, tmp: Path):
    import fuzz_inputs

    rng = random.Random(22)
    for i in range(n):
        src = seeds[i % len(seeds)]
        data, what = fuzz_inputs.mutate(src.read_bytes(), "c3d", rng)
        f = tmp / f"d{i}.c3d"
        f.write_bytes(data)
        yield f, f"{src.name}: {what}"


def _check_damaged(tmp_path: Path, realdata: Path, n: int) -> None:
    seeds = [synthetic(tmp_path / "s.c3d"), to_integer(synthetic(tmp_path / "f.c3d", seed=1), tmp_path / "i.c3d")]
    seeds += [f for f in real_c3d(realdata) if uses_numpy(f)]
    kinds = {"ok": 0, "refused": 0}
    for f, what in _damaged_cases(seeds, n, tmp_path):
        try:
            kinds[assert_same(f)] += 1
        except AssertionError as exc:
            raise AssertionError(f"{what}: {exc}") from exc
    assert min(kinds.values()) > n // 10, kinds  # both outcomes exercised


def test_damaged_files_refused_or_read_as_ezc3d(tmp_path, realdata):
    """Seeded mutations (benchmarks/fuzz_inputs.py) of synthetic float and integer files and of the
    real Intel files: the numpy reader never reads a file another way than ezc3d, and refuses what
    the reference refuses, with the same one line."""
    _check_damaged(tmp_path, realdata, 40)


@pytest.mark.slow
def test_many_damaged_files_refused_or_read_as_ezc3d(tmp_path, realdata):
    """The same on 1500 mutations (the first 40 are the quick test's)."""
    _check_damaged(tmp_path, realdata, 1500)


# ---- found by comparing the two readers on damaged parameters (targeted values) ---------------
@pytest.mark.parametrize("value", [-1, -32768])
def test_negative_rotation_count_refused(tmp_path, value):
    """ROTATION:RATIO < 0 made ezc3d allocate without end (bad_alloc) or crash the process (a
    segfault in get_rotations): refused by the checks, whichever reader follows."""
    f = synthetic(tmp_path / "r.c3d", frames=20)
    damage.c3d_set_parameter(f, "ROTATION", "RATIO", struct.pack("<h", value))
    with pytest.raises(InputError, match=f"ROTATION:RATIO is {value}"):
        C.read_c3d(f)


def test_negative_point_frames_read_as_unsigned_and_refused(tmp_path):
    """POINT:FRAMES -32768 is 32768 frames stored in a signed word: not the header's 20, refused (ezc3d
    read until the end of the file, and crashed when the rotation data start was damaged too)."""
    f = synthetic(tmp_path / "r.c3d", frames=20)
    damage.c3d_set_parameter(f, "POINT", "FRAMES", struct.pack("<h", -32768))
    with pytest.raises(InputError, match="POINT:FRAMES 32768"):
        C.read_c3d(f)


@pytest.mark.parametrize("rate", [float("nan"), float("inf"), -1.0, 1e30])
def test_damaged_analog_rate_without_analogs_left_to_ezc3d(tmp_path, rate):
    """ezc3d makes int(ANALOG:RATE / POINT:RATE) analog subframes per frame even without channels (a
    NaN or huge ratio: bad_alloc): such files are not the numpy reader's, the outcome is ezc3d's."""
    f = synthetic(tmp_path / "r.c3d", frames=20)
    damage.c3d_set_parameter(f, "ANALOG", "RATE", struct.pack("<f", rate))
    assert not uses_numpy(f)
    assert_same(f)


def test_import_stage_tables_equal_with_either_reader(tmp_path, monkeypatch):
    """End to end: the markers and trials tables of `import` are the same whichever reader reads the C3D files."""
    from cobot_analysis import api
    from cobot_analysis.io import markers as M
    from cobot_analysis.synth import walking

    protocol = walking.generate(tmp_path / "study", n_subjects=1, n_trials=2, conditions=["E1500", "N0615"])
    ours = api.import_markers(protocol, jobs=1)
    calls = []

    def reference(path, units=None):
        calls.append(path)
        return C.read_c3d(path, units=units, numpy=False)

    monkeypatch.setitem(M.READERS, "c3d", reference)
    ref = api.import_markers(protocol, jobs=1)
    assert len(calls) == 4  # the reference read every file
    assert len(ours.markers) > 10_000 and ours.markers["occluded"].any()
    pd_testing = pytest.importorskip("pandas").testing
    pd_testing.assert_frame_equal(ours.markers, ref.markers, check_exact=True)
    pd_testing.assert_frame_equal(ours.trials, ref.trials, check_exact=True)


def test_vicon_file_without_trial_group_left_to_ezc3d(realdata, tmp_path):
    """ezc3d looks up the TRIAL group of a file whose MANUFACTURER:COMPANY names Vicon and fails
    without it (found by the 1500-mutation test: one flipped byte of the group's name)."""
    f = tmp_path / "v.c3d"
    data = bytearray((realdata / "c3d" / "FunctionalWalk.c3d").read_bytes())
    at = data.find(b"TRIAL", (data[0] - 1) * C.BLOCK)
    data[at:at + 5] = b"XRIAL"
    f.write_bytes(bytes(data))
    assert not uses_numpy(f)
    assert assert_same(f) == "refused"
    at = data.find(b"Vicon Motion")  # the same file from another company: read by numpy
    data[at:at + 5] = b"Qicon"
    f.write_bytes(bytes(data))
    assert uses_numpy(f) and assert_same(f) == "ok"


@pytest.mark.parametrize("group,name", [("ANALOG", "SCALE"), ("ANALOG", "OFFSET"), ("POINT", "RATE"), ("POINT", "POINT")])
def test_point_and_analog_names_in_lower_case_refused(realdata, tmp_path, group, name):
    """ezc3d looks the POINT and ANALOG parameters up by exact name: with ANALOG:scale or offset in
    lower case it crashed the process (found renaming every record of the real files); refused."""
    f = tmp_path / "n.c3d"
    data = bytearray((realdata / "c3d" / "pyomeca_markers_analogs.c3d").read_bytes())
    rec = next(r for r in damage.c3d_parameter_records(bytes(data)) if r["name"] == name and (
        r["gid"] < 0 if name == group else r["gid"] > 0 and next(
            g for g in damage.c3d_parameter_records(bytes(data)) if g["gid"] == -r["gid"])["name"] == group))
    data[rec["offset"] + 2:rec["offset"] + 2 + len(name)] = name.lower().encode()
    f.write_bytes(bytes(data))
    with pytest.raises(InputError, match=f"named '{name.lower()}', not in upper case"):
        C.read_c3d(f)
