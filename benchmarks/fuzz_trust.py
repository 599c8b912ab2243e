"""Fuzz the checks of issue 21 (what is read and what is reused is trusted only when consistent).

    python benchmarks/fuzz_trust.py --n 400 --out /tmp/fuzz-trust          # run, print the counts
    python benchmarks/fuzz_trust.py --n 400 --out /tmp/fuzz-trust --report # counts of a previous run

Input ``i`` is fully determined by ``--seed`` and ``i``; one kind per input, drawn at random:

- ``rate``: a C3D (POINT:RATE damaged), Vicon CSV or Qualisys TSV whose declared rate is drawn from
  valid, out-of-range and invalid values (0, negative, NaN, inf), a protocol ``rate`` or none, and
  ``invalid_rate: protocol`` or not; imported. Exit 0 must store the declared rate when it is valid
  (and warn once naming both when the protocol's differs), or the protocol's rate only with
  ``invalid_rate: protocol`` and a warning saying it replaced an invalid one;
- ``header``: a C3D with analog channels whose header word (analog values per frame, first/last
  frame, data start) or parameter (ANALOG:USED, ANALOG:RATE, POINT:FRAMES, POINT:DATA_START,
  POINT:SCALE) is set to a random value; exit 0 must give the undamaged file's markers exactly
  (a wrong stride never passes);
- ``text``: a text export with or without a UTF-8 / UTF-16 byte-order mark, its units row, a long
  line or a wide row, with or without ``--units``; exit 0 must give the reference markers;
- ``paths``: a trial file inside or outside the protocol's folder (``..``, absolute, symbolic
  link) with or without ``allow_outside``; exit 0 exactly when inside or allowed, and the files
  outside listed in the manifest;
- ``cache``: a cache directory with a random mode, owner link and parent mode, and an artefact
  whose bytes or digest are damaged or planted; it may be loaded exactly when the directory is
  private and the artefact matches its digest;
- ``lock``: a stage entered while another run of it (or of another stage) holds the workspace;
  the same stage is refused with one line, another stage runs.

Every import runs in-process (``cobot_analysis.cli.run``); an exit code other than 0 or 2, or an
exit 2 whose message is not one line naming the file (or option), is a finding. Results go to
``OUT/results.jsonl``; the summary counts inputs by kind and outcome.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import shutil
import struct
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import damage  # noqa: E402
from test_import import person, write_c3d, write_c3d_with_analogs, write_qtm_tsv, write_vicon_csv  # noqa: E402

KINDS = ("rate", "header", "text", "paths", "cache", "lock")


def _import(proto: Path, ws: Path, *extra: str) -> tuple[int, str]:
    from cobot_analysis.cli import run

    buf = io.StringIO()
    saved = sys.stderr, sys.stdout
    sys.stderr = sys.stdout = buf
    try:
        code = run(["import", str(proto), "--out", str(ws), "--jobs", "1", "--force", *extra])
    finally:
        sys.stderr, sys.stdout = saved
    return code, buf.getvalue()


def _protocol(d: Path, name: str, rate=None, invalid=None, extra: str = "") -> Path:
    text = f"study: fuzz\n{f'rate: {rate}' if rate is not None else ''}\n{f'invalid_rate: {invalid}' if invalid else ''}\n{extra}"
    p = d / "protocol.yaml"
    p.write_text(text + f"trials:\n  - {{trial: t1, file: '{name}'}}\n")
    return p


def _markers(ws: Path) -> np.ndarray:
    import pyarrow.parquet as pq

    df = pq.read_table(ws / "import" / "markers.parquet").to_pandas().sort_values(["entity", "marker", "frame"])
    return df[["x", "y", "z"]].to_numpy(dtype=float)


def _rate_of(ws: Path) -> float:
    import pyarrow.parquet as pq

    return float(pq.read_table(ws / "import" / "trials.parquet").to_pandas()["rate"].iloc[0])


def _one_line(err: str, name: str) -> list[str]:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    if not lines or not lines[-1].startswith("error: "):
        return [f"exit 2 without an error line: {err[-300:]!r}"]
    errors = [ln for ln in lines if ln.startswith("error: ")]
    if len(errors) != 1 or lines[-1] != errors[0] or name not in errors[0]:
        return [f"exit 2 message is not one line naming {name}: {err[-300:]!r}"]
    return []


def case_rate(rng: random.Random, d: Path) -> dict:
    fmt = rng.choice(["c3d", "vicon", "qtm"])
    declared = rng.choice([0.0, -200.0, -1.0, float("nan"), float("inf"), 1e-9, 0.5, 2e4, 1e30, 200.0, 150.0,
                           rng.uniform(50, 2000)])
    if fmt == "qtm" and declared < 0 and rng.random() < 0.5:
        declared = 0.0
    protocol_rate = rng.choice([None, 150.0, 200.0])
    invalid = rng.choice([None, "protocol"]) if protocol_rate else None
    m = person(60)
    if fmt == "c3d":
        f = damage.c3d_set_parameter(write_c3d(d / "a.c3d", m), "POINT", "RATE", struct.pack("<f", declared))
        declared = float(np.float32(declared))
    else:
        f = (write_vicon_csv if fmt == "vicon" else write_qtm_tsv)(d / ("a.csv" if fmt == "vicon" else "a.tsv"), m)
        key = "Trajectories\n200\n" if fmt == "vicon" else "FREQUENCY\t200\n"
        text = f"{declared!r}" if not np.isfinite(declared) else f"{declared:.17g}"
        new = key.replace("200", {"nan": "NaN", "inf": "inf"}.get(text, text))
        f.write_text(f.read_text().replace(key, new))
    code, err = _import(_protocol(d, f.name, protocol_rate, invalid), d / "ws")
    findings = []
    valid = np.isfinite(declared) and declared > 0
    in_range = valid and 1.0 <= declared <= 10_000.0
    message = " ".join(err.split())
    if code == 0:
        stored = _rate_of(d / "ws")
        if valid:
            if not in_range or stored != declared:
                findings.append(f"declared {declared} stored {stored}")
            if protocol_rate and declared != protocol_rate and message.count("differs from the protocol's rate") != 1:
                findings.append("no single warning naming both rates")
        elif not (invalid == "protocol" and stored == protocol_rate and "replaced by the protocol's rate" in message):
            findings.append(f"invalid declared {declared} replaced by {stored} without the explicit option and a warning")
    elif code == 2:
        findings += _one_line(err, f.name)
        if in_range:
            findings.append(f"valid rate {declared} refused: {message[-200:]}")
    else:
        findings.append(f"exit {code}: {err[-300:]!r}")
    return {"what": f"{fmt} declared={declared!r} protocol={protocol_rate} invalid_rate={invalid}", "code": code, "findings": findings}


HEADER_EDITS = ("ANALOG:USED", "ANALOG:RATE", "POINT:FRAMES", "POINT:DATA_START", "POINT:SCALE", "header:analogs",
                "header:last", "header:data_start")


def case_header(rng: random.Random, d: Path) -> dict:
    ref = write_c3d_with_analogs(d / "ref.c3d", person(20))
    f = d / "a.c3d"
    shutil.copy(ref, f)
    edit = rng.choice(HEADER_EDITS)
    value = rng.choice([0, 1, 2, 3, 5, 10, 19, 20, 21, 40, -1, rng.randrange(-32768, 32767)])
    if edit in ("ANALOG:RATE", "POINT:SCALE"):
        value = rng.choice([0.0, -1.0, 0.1, 1000.0, 2000.0, 999.0, rng.uniform(-1e4, 1e4)])
        group, name = edit.split(":")
        damage.c3d_set_parameter(f, group, name, struct.pack("<f", value))
    elif edit.startswith("header:"):
        offset = {"header:analogs": 4, "header:last": 8, "header:data_start": 16}[edit]
        damage.overwrite(f, offset, struct.pack("<H", value % 65536))
    else:
        group, name = edit.split(":")
        damage.c3d_set_parameter(f, group, name, struct.pack("<h", value))
    (d / "refws").mkdir()
    code0, _ = _import(_protocol(d / "refws", "../ref.c3d", extra="allow_outside: true\n"), d / "wsref")
    code, err = _import(_protocol(d, f.name), d / "ws")
    findings = []
    if code == 0:
        if code0 != 0 or _markers(d / "ws").shape != _markers(d / "wsref").shape or \
                not np.allclose(_markers(d / "ws"), _markers(d / "wsref"), equal_nan=True):
            findings.append("exit 0 with markers that differ from the undamaged file's")
    elif code == 2:
        findings += _one_line(err, f.name)
    else:
        findings.append(f"exit {code}: {err[-300:]!r}")
    return {"what": f"{edit}={value!r}", "code": code, "findings": findings}


def case_text(rng: random.Random, d: Path) -> dict:
    fmt = rng.choice(["vicon", "qtm"])
    ref = (write_vicon_csv if fmt == "vicon" else write_qtm_tsv)(d / ("ref.csv" if fmt == "vicon" else "ref.tsv"), person(40))
    text = ref.read_text()
    what = [fmt]
    if fmt == "vicon" and rng.random() < 0.4:
        text = "\n".join(ln for ln in text.split("\n") if not ln.startswith(",,mm"))
        what.append("no units row")
    lines = text.split("\n")
    if rng.random() < 0.3:
        n = rng.choice([1 << 10, 1 << 19, (1 << 20) + 1, 3 << 20])
        lines.insert(len(lines) - 5, ("1," if fmt == "vicon" else "1\t") * (n // 2))
        what.append(f"line of {n} bytes")
    text = "\n".join(lines)
    bom = rng.choice(["none", "utf-8", "utf-16"])
    data = {"none": text.encode(), "utf-8": b"\xef\xbb\xbf" + text.encode(), "utf-16": text.encode("utf-16")}[bom]
    what.append(f"bom {bom}")
    f = d / ("a.csv" if fmt == "vicon" else "a.tsv")
    f.write_bytes(data)
    units = ["--units", "mm"] if rng.random() < 0.5 else []
    what += units
    (d / "refws").mkdir()
    shutil.copy(ref, d / "refws" / ref.name)
    code0, _ = _import(_protocol(d / "refws", ref.name), d / "wsref")
    code, err = _import(_protocol(d, f.name), d / "ws", *units)
    findings = []
    if code == 0:
        if code0 != 0 or not np.allclose(_markers(d / "ws"), _markers(d / "wsref"), equal_nan=True):
            findings.append("exit 0 with markers that differ from the reference")
    elif code == 2:
        findings += _one_line(err, f.name)
        if bom == "utf-8" and "line of" not in " ".join(what) and ("no units row" not in what or units):
            findings.append(f"refused although readable: {' '.join(err.split())[-200:]}")
    else:
        findings.append(f"exit {code}: {err[-300:]!r}")
    return {"what": " ".join(what), "code": code, "findings": findings}


def case_paths(rng: random.Random, d: Path) -> dict:
    study, elsewhere = d / "study", d / "elsewhere"
    study.mkdir()
    elsewhere.mkdir()
    where = rng.choice(["inside", "dotdot", "absolute-in", "absolute-out", "link-in", "link-out", "dotdot-back"])
    f_in, f_out = write_c3d(study / "in.c3d", person(40)), write_c3d(elsewhere / "out.c3d", person(40))
    name = {"inside": "in.c3d", "dotdot": "../elsewhere/out.c3d", "absolute-in": str(f_in), "absolute-out": str(f_out),
            "link-in": "lnk.c3d", "link-out": "lnk.c3d", "dotdot-back": "../study/in.c3d"}[where]
    if where.startswith("link"):
        (study / "lnk.c3d").symlink_to(f_in if where == "link-in" else f_out)
    allow = rng.random() < 0.5
    code, err = _import(_protocol(study, name, extra="allow_outside: true\n" if allow else ""), d / "ws")
    outside = where in ("dotdot", "absolute-out", "link-out")
    findings = []
    if code == 0:
        if outside and not allow:
            findings.append("a file outside the protocol's folder imported without allow_outside")
        listed = json.loads((d / "ws" / "import" / "manifest.json").read_text())["params"]["outside_files"]
        if listed != ([str(f_out)] if outside else []):
            findings.append(f"outside_files {listed}")
    elif code == 2:
        findings += _one_line(err, "protocol.yaml")
        if not outside or allow:
            findings.append(f"refused: {' '.join(err.split())[-200:]}")
    else:
        findings.append(f"exit {code}: {err[-300:]!r}")
    return {"what": f"{where} allow_outside={allow}", "code": code, "findings": findings}


def case_cache(rng: random.Random, d: Path) -> dict:
    from cobot_analysis.models.oc import cache

    parent = d / "parent"
    parent.mkdir()
    pmode = rng.choice([0o700, 0o755, 0o777, 0o1777])
    os.chmod(parent, pmode)
    cdir = parent / "ocp"
    form = rng.choice(["fresh", "dir", "link"])
    mode = rng.choice([0o700, 0o755, 0o775, 0o777, 0o1777, 0o750])
    if form == "dir":
        cdir.mkdir()
        os.chmod(cdir, mode)
    elif form == "link":
        (parent / "real").mkdir(mode=0o700)
        cdir.symlink_to(parent / "real")
    reason = cache.untrusted_reason(cdir)
    private = (pmode & 0o002 == 0 or pmode & 0o1000) and (form == "fresh" or (form == "dir" and mode & 0o022 == 0))
    findings = [] if (reason is None) == bool(private) else [f"untrusted_reason {reason!r} for parent {pmode:o} {form} {mode:o}"]
    if reason is None:
        built = cdir / "build.tmp"
        built.write_bytes(os.urandom(64))
        art = cdir / "lib.so"
        cache.install(built, art)
        change = rng.choice(["none", "bytes", "planted", "digest", "no-digest"])
        if change == "bytes":
            data = bytearray(art.read_bytes())
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
            art.write_bytes(bytes(data))
        elif change == "planted":
            art.write_bytes(os.urandom(64))
        elif change == "digest":
            cache.digest_file(art).write_text("0" * 64 + "\n")
        elif change == "no-digest":
            cache.digest_file(art).unlink()
        if cache.verified(art) != (change == "none"):
            findings.append(f"verified {cache.verified(art)} after {change}")
    else:
        change = "-"
    os.chmod(parent, 0o700)
    return {"what": f"parent {pmode:o} {form} {mode:o} {change}", "code": 0 if reason is None else 2, "findings": findings}


def case_lock(rng: random.Random, d: Path) -> dict:
    from cobot_analysis.errors import InputError
    from cobot_analysis.workspace import Stage

    ws = d / "ws"
    first, second = rng.choice(["a", "b"]), rng.choice(["a", "b"])
    findings, code = [], 0
    with Stage(ws, first, params={"i": 1}, force=True) as s1:
        s1.path("x.txt").write_text("1")
        try:
            with Stage(ws, second, params={"i": 2}, force=True) as s2:
                s2.path("x.txt").write_text("2")
        except InputError as exc:
            code = 2
            if first != second or "is being run into this workspace by another process" not in str(exc) or "\n" in str(exc):
                findings.append(f"refused: {exc}")
        else:
            if first == second:
                findings.append("a second run of the same stage was not refused")
    if (ws / first / "x.txt").read_text() != "1":
        findings.append("the first run's output was replaced")
    if list(ws.glob(".*.lock")) or list(ws.glob(".*.tmp")):
        findings.append(f"left {[p.name for p in ws.glob('.*')]}")
    return {"what": f"{first} then {second}", "code": code, "findings": findings}


CASES = {"rate": case_rate, "header": case_header, "text": case_text, "paths": case_paths, "cache": case_cache, "lock": case_lock}


def fuzz(n: int, out: Path, seed: int, kinds: tuple[str, ...] = KINDS) -> None:
    out.mkdir(parents=True, exist_ok=True)
    results = out / "results.jsonl"
    done = max((json.loads(ln)["i"] + 1 for ln in results.open()), default=0) if results.exists() else 0
    with results.open("a") as fh:
        for i in range(done, n):
            rng = random.Random(f"{seed}-{i}")
            kind = rng.choice(KINDS)
            if kind not in kinds:
                continue
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                try:
                    row = CASES[kind](rng, Path(tmp))
                except Exception as exc:  # noqa: BLE001 - a crash of the harness or the package is a finding
                    row = {"what": "", "code": 1, "findings": [f"{type(exc).__name__}: {exc}"]}
            row.update(i=i, kind=kind, seconds=round(time.perf_counter() - t0, 3))
            fh.write(json.dumps(row) + "\n")
            fh.flush()


def report(out: Path) -> str:
    rows = [json.loads(ln) for ln in (out / "results.jsonl").open()]
    by = Counter((r["kind"], r["code"]) for r in rows)
    findings = [r for r in rows if r["findings"]]
    lines = [f"{len(rows)} inputs, {len(findings)} with a finding, {sum(r['seconds'] for r in rows):.0f} s", "",
             "| kind | inputs | exit 0 | exit 2 | other | findings |", "|---|---|---|---|---|---|"]
    for kind in KINDS:
        n = sum(v for (k, _), v in by.items() if k == kind)
        other = sum(v for (k, c), v in by.items() if k == kind and c not in (0, 2))
        lines.append(f"| {kind} | {n} | {by[(kind, 0)]} | {by[(kind, 2)]} | {other} | {sum(1 for r in findings if r['kind'] == kind)} |")
    for r in findings[:20]:
        lines.append(f"- [{r['i']}] {r['kind']} {r['what']}: {'; '.join(r['findings'])[:300]}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=400, help="number of inputs (a rerun resumes)")
    ap.add_argument("--out", type=Path, default=Path("fuzz-trust-out"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--kinds", default=",".join(KINDS), help="the kinds of input to run (the others are skipped)")
    ap.add_argument("--report", action="store_true", help="print the summary of OUT/results.jsonl and exit")
    args = ap.parse_args()
    if not args.report:
        fuzz(args.n, args.out, args.seed, tuple(args.kinds.split(",")))
    print(report(args.out))


if __name__ == "__main__":
    main()
