"""Fuzz the raw-marker import (and preprocess) with damaged C3D, Vicon CSV and Qualisys TSV files.

    python benchmarks/fuzz_inputs.py --n 10000 --out /tmp/fuzz          # run (or resume) 10,000 inputs
    python benchmarks/fuzz_inputs.py --out /tmp/fuzz --report           # summary of a run

Inputs: seed files (a small synthetic walking study, ``cobot_analysis.synth.walking``, written as
C3D and converted to the two text exports; the files of ``../shared/realdata`` or
``$COBOT_REALDATA`` when present), each damaged by one seeded mutation built on ``tests/damage.py``:
random bytes anywhere, in the header / parameter part or in the data part, truncation, a special
value written into one coordinate (inf, NaN, 1e35, 0, ...), C3D header words, a structural byte of
a C3D parameter record (group id, pointer, type, dimensions, description length), text lines
deleted, duplicated or swapped. Input ``i`` is fully determined by ``--seed`` and ``i``.

Each input is imported and, when the import succeeds, preprocessed in-process
(``cobot_analysis.cli.run``) in a worker process (memory capped), and checked:

- no internal error: the exit code is never 1, and the worker never dies (a crash of ezc3d);
- no hang: every input finishes within ``--timeout`` seconds (else the worker is killed);
- exit 2 gives one line that names the damaged file (or the protocol listing it);
- never exit 0 with something implausible in the outputs, checked here independently of the
  pipeline's own checks: marker coordinates finite and within 100 m of the origin, no marker
  faster than 20 m/s between visible samples, a rate of 1 Hz to 10 kHz, trajectories within the
  lab, travel times within the recording, and a walk that starts at the first frame or ends at the
  last one flagged ``truncated``.

Exit-0 inputs whose marker values differ from the undamaged seed's are counted (plausible damage
cannot be told from data; the count says how much of it passes).

Formats are a registry (``FORMATS``): a format names its seed files and its mutations, and the
commands to run on an input. Bags (``cobot-analysis localisation``) are added as one more entry
(seeds from ``synth localisation``, the byte mutations, ``commands`` = the localisation command).

Results go to ``OUT/results.jsonl``, one line per input, so that a run resumes where it stopped;
inputs with a finding are kept in ``OUT/findings/``.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import statistics
import struct
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import damage  # noqa: E402

LAB_EXTENT = 100.0  # m: the oracle's own limits (the pipeline's defaults, restated)
MAX_SPEED = 20.0  # m/s
RATES = (1.0, 10_000.0)  # Hz
SPECIAL_FLOATS = (float("inf"), -float("inf"), float("nan"), 1e35, -1e35, 1e-35, 0.0, 1e5, -1e5, 3.4e38, 2e4)
SPECIAL_CELLS = ("inf", "-inf", "nan", "NaN", "1e35", "-1e35", "1e-35", "", "0", "12,5", "abc", "1e308", "99999999", "-0", "1e5")
MEMORY_LIMIT = 3 << 30  # bytes of address space for the worker: a huge allocation fails instead of swapping


# ---- seeds -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Seed:
    fmt: str
    path: Path
    protocol_extra: str = ""  # YAML lines added to the one-trial protocol (e.g. a marker map)


def synthetic_seeds(work: Path) -> list[Seed]:
    """Two synthetic walking trials (1 subject) as C3D, Vicon CSV and Qualisys TSV."""
    from cobot_analysis.io.c3d import read_c3d
    from cobot_analysis.synth import walking
    from test_import import write_qtm_tsv, write_vicon_csv

    d = work / "seeds"
    if not (d / "synth" / "protocol.yaml").exists():
        walking.generate(d / "synth", n_subjects=1, n_trials=1, conditions=["E1500", "N0615"])
    seeds = []
    for f in sorted((d / "synth" / "raw").glob("*.c3d")):
        raw = read_c3d(f)
        markers = {lab: raw.xyz[:, k] for k, lab in enumerate(raw.labels)}
        csv, tsv = d / f"{f.stem}.csv", d / f"{f.stem}.tsv"
        if not csv.exists():
            write_vicon_csv(csv, markers)
            write_qtm_tsv(tsv, markers)
        seeds += [Seed("c3d", f), Seed("vicon-csv", csv), Seed("qualisys-tsv", tsv)]
    return seeds


def realdata_seeds() -> list[Seed]:
    env = os.environ.get("COBOT_REALDATA")
    base = Path(env) if env else ROOT.parent / "shared" / "realdata"
    if not base.is_dir():
        return []
    daphnee = ("marker_map: {'Daphnee:ASISr': RASI, 'Daphnee:ASISl': LASI, 'Daphnee:PSISr': RPSI, "
               "'Daphnee:PSISl': LPSI}\n")
    found = [Seed("c3d", base / "c3d" / f"{n}.c3d") for n in ("Gait", "FunctionalWalk", "PiG_Motion-FlatFoot-Full")]
    found.append(Seed("vicon-csv", base / "csv" / "pyomeca_markers.csv", daphnee))
    return [s for s in found if s.path.is_file()]


# ---- mutations ---------------------------------------------------------------------------------
def _split(data: bytes, fmt: str) -> int:
    """Offset where the data part starts: C3D data section, or the first data row of a text export."""
    if fmt == "c3d":
        try:
            return min(damage.c3d_data_offset(data), len(data))
        except Exception:  # noqa: BLE001 - a seed is never broken, but stay total
            return min(1024, len(data))
    lines = data.split(b"\n")
    head = next((i for i, ln in enumerate(lines) if ln[:1].isdigit() and i > 2), min(8, len(lines)))
    return len(b"\n".join(lines[:head])) + 1


def mutate(data: bytes, fmt: str, rng: random.Random) -> tuple[bytes, str]:
    """One seeded mutation of ``data``: ``(damaged bytes, description)``."""
    split = _split(data, fmt)
    kinds = ["bytes", "head-bytes", "data-bytes", "truncate", "special"] + (["header-word", "record"] if fmt == "c3d" else ["lines"])
    kind = rng.choice(kinds)
    b = bytearray(data)
    if kind in ("bytes", "head-bytes", "data-bytes"):
        lo, hi = {"bytes": (0, len(b)), "head-bytes": (0, split), "data-bytes": (split, len(b))}[kind]
        n = rng.choice((1, 1, 2, 4, 8, 32))
        for _ in range(n):
            if hi > lo:
                b[rng.randrange(lo, hi)] = rng.randrange(256)
        return bytes(b), f"{kind} x{n}"
    if kind == "truncate":
        keep = rng.randrange(0, len(b))
        return bytes(b[:keep]), f"truncate at {keep}"
    if kind == "header-word" and fmt == "c3d":
        word = rng.randrange(0, 12)
        value = rng.choice((0, 1, 2, 0xFFFF, 0x7FFF, 0x8000, rng.randrange(65536)))
        b[2 * word:2 * word + 2] = struct.pack("<H", value)
        return bytes(b), f"header word {word + 1} = {value}"
    if kind == "record":  # a structural byte of a parameter record (group id, pointer, type, dimensions, description)
        records = damage.c3d_parameter_records(data)
        rec = rng.choice(records)
        at = rng.choice(rec["structure"])
        b[at] = rng.choice((0, 1, 0x7F, 0x80, 0xFF, b[at] ^ 1, b[at] ^ 0x80, rng.randrange(256)))
        return bytes(b), f"record {rec['name']} byte {at - rec['offset']} = {b[at]}"
    if kind == "special":
        if fmt == "c3d":
            lay = damage.c3d_layout(data)
            if lay["points"] and lay["frames"] > 0:
                frame, point, axis = rng.randrange(lay["frames"]), rng.randrange(lay["points"]), rng.randrange(3)
                off = split + (frame * (4 * lay["points"] + lay["analogs"]) + point * 4 + axis) * (4 if lay["float"] else 2)
                value = rng.choice(SPECIAL_FLOATS)
                payload = struct.pack("<f", value) if lay["float"] else struct.pack("<h", rng.choice((32767, -32768, 0)))
                b[off:off + len(payload)] = payload
                return bytes(b), f"special {value} at frame {frame} point {point} axis {axis}"
            return bytes(b), "special (no points)"
        lines = data.split(b"\n")
        rows = [i for i, ln in enumerate(lines) if ln[:1].isdigit()]
        if rows:
            i = rng.choice(rows)
            sep = b"\t" if fmt == "qualisys-tsv" else b","
            cells = lines[i].split(sep)
            j = rng.randrange(len(cells))
            cells[j] = rng.choice(SPECIAL_CELLS).encode()
            lines[i] = sep.join(cells)
            return b"\n".join(lines), f"special cell row {i} col {j} = {cells[j].decode()!r}"
        return bytes(b), "special (no rows)"
    lines = data.split(b"\n")
    op = rng.choice(("delete", "duplicate", "swap", "garbage"))
    i = rng.randrange(len(lines))
    if op == "delete":
        del lines[i]
    elif op == "duplicate":
        lines.insert(i, lines[i])
    elif op == "swap":
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    else:
        lines.insert(i, bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40))))
    return b"\n".join(lines), f"line {op} at {i}"


# ---- formats -----------------------------------------------------------------------------------
def marker_commands(proto: Path, ws: Path) -> list[list[str]]:
    return [["-q", "import", str(proto), "--out", str(ws), "--jobs", "1"], ["-q", "preprocess", "--out", str(ws), "--jobs", "1"]]


@dataclass(frozen=True)
class Format:
    """A fuzzed input format: its file suffix, the commands run on an input, and the oracle on their outputs."""

    suffix: str
    commands: Callable[[Path, Path], list[list[str]]]


FORMATS: dict[str, Format] = {
    "c3d": Format(".c3d", marker_commands),
    "vicon-csv": Format(".csv", marker_commands),
    "qualisys-tsv": Format(".tsv", marker_commands),
    # "bag": Format(".bag", lambda bag, ws: [["-q", "localisation", str(bag), "--out", str(ws), "--no-figures"]]),
}


# ---- the worker: runs the commands in-process and checks the outputs ---------------------------
def _plausibility_findings(ws: Path) -> list[str]:
    """What is implausible in the outputs of an exit-0 run (the oracle, independent of the pipeline)."""
    import numpy as np
    import pandas as pd

    found = []
    mk = ws / "import" / "markers.parquet"
    if mk.is_file():
        df = pd.read_parquet(mk)
        tr = pd.read_parquet(ws / "import" / "trials.parquet")
        rate = tr["rate"].astype(float)
        if not ((rate >= RATES[0]) & (rate <= RATES[1])).all():
            found.append(f"rate {rate.tolist()} Hz")
        xyz = df[["x", "y", "z"]].to_numpy()
        vis = ~df["occluded"].to_numpy()
        if not np.isfinite(xyz[vis]).all():
            found.append("non-finite marker values")
        elif (np.abs(xyz[vis]) > LAB_EXTENT).any():
            found.append(f"marker value {np.abs(xyz[vis]).max():.3g} m")
        r = dict(zip(tr["trial"].astype(str), rate))
        for (trial, entity, marker), g in df[vis].groupby(["trial", "entity", "marker"], observed=True):
            g = g.sort_values("frame")
            if len(g) > 1:
                speed = np.linalg.norm(np.diff(g[["x", "y", "z"]].to_numpy(), axis=0), axis=1) * r[str(trial)] / np.diff(g["frame"])
                if speed.max() > MAX_SPEED:
                    found.append(f"{marker} moves at {speed.max():.3g} m/s")
                    break
    tj = ws / "preprocess" / "trajectories.parquet"
    if tj.is_file():
        t = pd.read_parquet(tj)
        xy = t[["x", "y"]].to_numpy()
        if np.isinf(xy).any() or (np.abs(xy[np.isfinite(xy)]) > LAB_EXTENT).any():
            found.append("trajectory outside the lab")
        frames = pd.read_parquet(ws / "import" / "trials.parquet").set_index("trial")
        for trial, g in t.groupby("trial"):
            rec = str(trial).rsplit("_", 1)[0] if str(trial) not in frames.index else str(trial)
            if rec not in frames.index:
                continue
            length = (frames.loc[rec, "n_frames"] - 1) / frames.loc[rec, "rate"]
            tt, start = float(g["travel_time"].iloc[0]), float(g["record_time"].iloc[0])
            if not 0 < tt <= length + 1e-9:
                found.append(f"travel time {tt:.4g} s of a {length:.4g} s recording")
            at_edge = start < 0.5 / frames.loc[rec, "rate"] or start + tt > length - 0.5 / frames.loc[rec, "rate"]
            if at_edge and "truncated" not in str(g["quality"].iloc[0]).split(";"):
                found.append("walk at the recording's edge not flagged truncated")
    return found


def _max_change(ws: Path, baseline: Path | None) -> float | None:
    """Largest |difference| (m) between the imported markers and the undamaged seed's, where both are visible."""
    import numpy as np
    import pandas as pd

    mk = ws / "import" / "markers.parquet"
    if baseline is None or not mk.is_file() or not baseline.is_file():
        return None
    cols = ["trial", "entity", "marker", "frame", "x", "y", "z"]
    a = pd.read_parquet(mk, columns=cols).astype({"trial": str, "entity": str, "marker": str})
    b = pd.read_parquet(baseline, columns=cols).astype({"trial": str, "entity": str, "marker": str})
    j = a.merge(b, on=["trial", "entity", "marker", "frame"], suffixes=("", "_0"))
    d = np.abs(j[["x", "y", "z"]].to_numpy() - j[["x_0", "y_0", "z_0"]].to_numpy())
    d = d[np.isfinite(d)]
    return float(d.max()) if d.size else 0.0


def run_one(job: dict) -> dict:
    """Run the commands of one input in-process; return exit codes, message and findings."""
    import io

    from cobot_analysis import console as con
    from cobot_analysis.cli import run

    work = Path(job["work"])
    ws = work / "ws"
    proto = work / "protocol.yaml"
    proto.write_text(f"study: fuzz\ntrials:\n  - {{trial: t1, file: {job['file']}, condition: c1}}\n{job['extra']}")
    codes, message, findings = [], "", []
    for argv in FORMATS[job["fmt"]].commands(proto, ws):
        buf = io.StringIO()
        con.console.file = buf
        saved = sys.stderr
        sys.stderr = buf
        try:
            code = run(["-v"] + argv[1:])  # -v: the traceback of an internal error
        finally:
            sys.stderr = saved
        codes.append(code)
        text = buf.getvalue()
        errors = [ln for ln in text.splitlines() if ln.startswith("error:")]
        if code == 1:
            findings.append("internal error: " + (errors[-1] if errors else "") + " | " + text[-1500:])
        if code == 2:
            message = errors[-1] if errors else text.strip()
            if len(errors) != 1:
                findings.append(f"exit 2 with {len(errors)} error lines")
            elif Path(job["file"]).name not in message and "protocol.yaml" not in message and "markers.parquet" not in message:
                findings.append("exit 2 message names no file")
        if code != 0:
            break
    result = {"codes": codes, "message": message[:400]}
    if codes and codes[0] == 0:  # what the import (and the preprocess, if it passed) wrote must be plausible
        findings += [f"exit 0 with {f}" for f in _plausibility_findings(ws)]
        result["max_change"] = _max_change(ws, Path(job["baseline"]) if job.get("baseline") else None)
    result["findings"] = findings
    return result


def worker(conn) -> None:
    """Serve jobs from ``conn`` until it closes; the address space is capped (MemoryError, not swapping)."""
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    while True:
        try:
            job = conn.recv()
        except EOFError:
            return
        try:
            conn.send(run_one(job))
        except MemoryError:
            conn.send({"codes": [], "message": "", "findings": ["MemoryError outside the CLI"]})


class Worker:
    """A worker process with a per-input timeout; restarted after a hang or a crash."""

    def __init__(self):
        import multiprocessing as mp

        self.ctx = mp.get_context("spawn")
        self.start()

    def start(self):
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=worker, args=(child,), daemon=True)
        self.proc.start()

    def run(self, job: dict, timeout: float) -> dict:
        self.conn.send(job)
        if self.conn.poll(timeout):
            try:
                return self.conn.recv()
            except EOFError:
                pass
        else:
            self.proc.kill()
            self.proc.join()
            self.start()
            return {"codes": [], "message": "", "findings": [f"hang: no result within {timeout:g} s"]}
        self.proc.join()
        code = self.proc.exitcode
        self.start()
        return {"codes": [], "message": "", "findings": [f"worker died (exit code {code}: a crash)"]}


# ---- driver -------------------------------------------------------------------------------------
def baselines(seeds: list[Seed], out: Path, w: Worker) -> dict[Path, dict]:
    """Run every undamaged seed once: its exit codes and imported markers (for the change count)."""
    base = {}
    for k, s in enumerate(seeds):
        work = out / "baseline" / str(k)
        if (work / "result.json").exists():
            base[s.path] = json.loads((work / "result.json").read_text())
            continue
        shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True)
        res = w.run({"fmt": s.fmt, "file": str(s.path), "extra": s.protocol_extra, "work": str(work)}, 600)
        res["markers"] = str(work / "ws" / "import" / "markers.parquet")
        (work / "result.json").write_text(json.dumps(res))
        base[s.path] = res
    return base


def fuzz(n: int, out: Path, seed: int, timeout: float, formats: list[str]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    results = out / "results.jsonl"
    done = set()
    if results.exists():
        done = {json.loads(ln)["i"] for ln in results.read_text().splitlines() if ln.strip()}
    w = Worker()
    seeds = [s for s in synthetic_seeds(out) + realdata_seeds() if s.fmt in formats]
    base = baselines(seeds, out, w)
    for s in seeds:
        print(f"seed {s.fmt:13s} {s.path.name}: exit codes {base[s.path]['codes']} {base[s.path]['message'][:100]}")
    data = {s.path: s.path.read_bytes() for s in seeds}
    t_start = time.perf_counter()
    with open(results, "a") as log:
        for i in range(n):
            if i in done:
                continue
            s = seeds[i % len(seeds)]
            rng = random.Random(f"{seed}-{i}")
            mutated, what = mutate(data[s.path], s.fmt, rng)
            work = out / "work"
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir()
            f = work / f"input{FORMATS[s.fmt].suffix}"
            f.write_bytes(mutated)
            t0 = time.perf_counter()
            ok_base = base[s.path]["codes"] and base[s.path]["codes"][0] == 0
            res = w.run({"fmt": s.fmt, "file": str(f), "extra": s.protocol_extra, "work": str(work),
                         "baseline": base[s.path]["markers"] if ok_base else None}, timeout)
            res.update(i=i, fmt=s.fmt, seed=s.path.name, mutation=what, seconds=round(time.perf_counter() - t0, 3))
            if res["findings"]:
                keep = out / "findings"
                keep.mkdir(exist_ok=True)
                shutil.copy(f, keep / f"{i}{FORMATS[s.fmt].suffix}")
                (keep / f"{i}.yaml").write_text(s.protocol_extra)
                print(f"[{i}] {s.fmt} {s.path.name} {what}: {res['findings']}", flush=True)
            log.write(json.dumps(res) + "\n")
            log.flush()
            if i % 500 == 0:
                print(f"{i} inputs, {time.perf_counter() - t_start:.0f} s", flush=True)
    shutil.rmtree(out / "work", ignore_errors=True)


def report(out: Path) -> str:
    """Markdown summary of ``OUT/results.jsonl`` (for docs/benchmarks.md)."""
    rows = [json.loads(ln) for ln in (out / "results.jsonl").read_text().splitlines() if ln.strip()]

    def outcome(r):
        if r["findings"]:
            return "finding"
        c = r["codes"]
        return "import refused (2)" if c[0] == 2 else "preprocess refused (2)" if len(c) > 1 and c[1] == 2 else "accepted (0)"

    lines = ["| format | inputs | accepted (0) | import refused (2) | preprocess refused (2) | findings | median s/input |",
             "|---|---|---|---|---|---|---|"]
    for fmt in sorted({r["fmt"] for r in rows}):
        sub = [r for r in rows if r["fmt"] == fmt]
        cnt = Counter(outcome(r) for r in sub)
        lines.append(f"| {fmt} | {len(sub)} | {cnt['accepted (0)']} | {cnt['import refused (2)']} | "
                     f"{cnt['preprocess refused (2)']} | {cnt['finding']} | {statistics.median(r['seconds'] for r in sub):.2f} |")
    changed = [r["max_change"] for r in rows if r.get("max_change")]
    findings = Counter(f.split(":")[0] for r in rows for f in r["findings"])
    lines += ["", f"{len(rows)} inputs, {sum(r['seconds'] for r in rows) / 60:.1f} min of runs; findings: "
              f"{dict(findings) or 'none'}; accepted inputs whose values differ from the seed's: {len(changed)} "
              f"(largest difference {max(changed, default=0):.3g} m)."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10_000, help="number of inputs (a rerun resumes)")
    ap.add_argument("--out", type=Path, default=Path("fuzz-out"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per input before it counts as a hang")
    ap.add_argument("--formats", default=",".join(FORMATS))
    ap.add_argument("--report", action="store_true", help="print the summary of OUT/results.jsonl and exit")
    a = ap.parse_args()
    if not a.report:
        fuzz(a.n, a.out, a.seed, a.timeout, a.formats.split(","))
    print(report(a.out))


if __name__ == "__main__":
    main()
