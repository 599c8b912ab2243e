"""Fuzz the raw-marker import (and preprocess) with damaged C3D, Vicon CSV and Qualisys TSV files,
and `bag-info` + `localisation` with damaged ROS1, ROS2 and MCAP bags.

    python benchmarks/fuzz_inputs.py --n 10000 --out /tmp/fuzz          # run (or resume) 10,000 inputs
    python benchmarks/fuzz_inputs.py --n 10000 --out /tmp/fuzz-bags --formats ros1,ros2,mcap --jobs 2
    python benchmarks/fuzz_inputs.py --out /tmp/fuzz --report           # summary of a run

Marker inputs: seed files (a small synthetic walking study, ``cobot_analysis.synth.walking``, written as
C3D and converted to the two text exports; the files of ``../shared/realdata`` or
``$COBOT_REALDATA`` when present), each damaged by one seeded mutation built on ``tests/damage.py``:
random bytes anywhere, in the header / parameter part or in the data part, truncation, a special
value written into one coordinate (inf, NaN, 1e35, 0, ...), C3D header words, a structural byte of
a C3D parameter record (group id, pointer, type, dimensions, description length), text lines
deleted, duplicated or swapped. Input ``i`` is fully determined by ``--seed`` and ``i``.

Each marker input is imported and, when the import succeeds, preprocessed in-process
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

Bag inputs: a 14 s synthetic robot run (``synth localisation``) as ROS1 (plain and lz4 chunks),
ROS2 (sqlite3 and mcap storage) and MCAP (CDR, and ROS1-encoded with zstd chunks), each damaged by
one mutation (``mutate_bag``): bytes anywhere or in one region (header, index, chunk structure,
payload: ``damage.bag_regions``), a structural byte of a record, a random block, truncation (at
record boundaries too), a pose field or stamp of one PoseStamped message set to a chosen value,
a metadata.yaml line, or an edit of the message list written through the synth writers (a topic
missing or renamed, NaN or zero-quaternion poses, swapped or repeated messages; and, for the
compressed seeds, the pose and stamp damage). Each runs ``bag-info`` and ``localisation`` (with
one of the option sets ``BAG_OPTIONS``). The checks are those above, and for an exit-0
``localisation`` (``_bag_findings``): poses finite, stamps within 60 s of the recording, positions
within 1000 m, no isolated spike faster than 10 m/s or 10 rad/s (one at an end of a stream only if
the run warns about a jump), finite results; and when the mutation set one pose value or stamp
(the *target*) to something implausible (a position moved by 5 m or more, a quaternion turned by
1 rad or more or off unit norm, a stamp moved by more than 60 s or an invalid nanosec), that value
must not be in the poses the run used: compared with the undamaged seed's run with the same
options, no pose moved by more than 1 m or 0.5 rad, no new stamp at the damaged one, the goals
unchanged. Damage to bytes that the run does not read (another topic, an index the reader
rebuilds) may pass with exit 0; damage to values it reads must be refused, dropped with a warning
(NaN, a quaternion off unit norm), or plausible.

Formats are a registry (``FORMATS``): a format names the commands to run on an input and its
family (markers or bag).

Results go to ``OUT/results.jsonl``, one line per input, so that a run resumes where it stopped;
inputs with a finding are kept in ``OUT/findings/``.
"""

from __future__ import annotations

import argparse
import functools
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


# ---- bags: seeds and mutations -----------------------------------------------------------------
BAG_RUN = dict(n_goals=1, stop=3.0, speed=0.3)  # a 14 s run: 2,813 motion-capture poses, 135 ICP poses, 1 goal
BAG_TOPICS = {"/mocap/pose": "truth", "/icp/pose": "icp", "/goal": "goal"}
BAG_OPTIONS = ((), ("--icp", "/icp/odom"), ("--icp", "tf:map->base_link"), ("--time", "record"))
POSITION_DELTAS = (5.0, -5.0, 50.0, -50.0, 1e3, -1e3, 1e6, -1e6)
POSITION_SPECIALS = (float("inf"), -float("inf"), float("nan"), 1e35, -1e35, 1.7e308)
QUAT_VALUES = (0.5, 2.0, 0.0, float("nan"), float("inf"), 1e35, "negate", "nudge")
STAMP_CHANGES = (("sec", 1), ("sec", -1), ("sec", 3600), ("sec", -3600), ("sec", 10**6), ("sec", "zero"), ("sec", "max"),
                 ("nanosec", 10**9), ("nanosec", 2 * 10**9), ("nanosec", "max"))
STAMP_SLACK = 60.0  # s: stamps further than this outside the seed's span are damaged (the oracle)
MAX_SPEED_BAG = 10.0  # m/s, rad/s: the oracle's limits on pose streams (the pipeline's, restated)
MAX_TURN = 10.0
POSITION_LIMIT = 1000.0  # m from the frame origin


@dataclass(frozen=True)
class BagSeed:
    """A seed bag: its format, path (a file, or a ROS2 directory), the file whose bytes are damaged
    (the path itself, or the storage file of a directory), the writer that made it (to write
    edited copies) and whether its messages are compressed (no byte-level pose edits then)."""

    fmt: str
    path: Path
    data: Path
    writer: str
    compressed: bool = False
    protocol_extra: str = ""


def _writers():
    from cobot_analysis.localisation import synth

    return {"ros1": synth.write_ros1, "ros1-lz4": lambda run, path, edit=None: synth.write_ros1(run, path, edit, "lz4"),
            "ros2": synth.write_ros2, "ros2-mcap": lambda run, path, edit=None: synth.write_ros2(run, path, "mcap", edit),
            "mcap": synth.write_mcap, "mcap-ros1": synth.write_mcap_ros1}


@functools.lru_cache(maxsize=1)
def _bag_run():
    from cobot_analysis.localisation import synth

    return synth.make_run(synth.SynthParams(**BAG_RUN))


def bag_seeds(work: Path) -> list[BagSeed]:
    """A short synthetic robot run as ROS1 (plain and lz4 chunks), ROS2 (sqlite3 and mcap storage) and
    MCAP (CDR, and ROS1-encoded with zstd chunks, as mcap-ros1-support writes it)."""
    d = work / "seeds" / "bags"
    d.mkdir(parents=True, exist_ok=True)
    run = None
    specs = [("ros1", "run.bag", "ros1", False), ("ros1", "run_lz4.bag", "ros1-lz4", True),
             ("ros2", "run_ros2", "ros2", False), ("ros2", "run_ros2_mcap", "ros2-mcap", False),
             ("mcap", "run.mcap", "mcap", False), ("mcap", "run_ros1.mcap", "mcap-ros1", True)]
    seeds = []
    for fmt, name, writer, compressed in specs:
        path = d / name
        if not path.exists():
            run = run or _bag_run()
            _writers()[writer](run, path)
        data = next(p for p in sorted(path.iterdir()) if p.suffix in (".db3", ".mcap")) if path.is_dir() else path
        seeds.append(BagSeed(fmt, path, data, writer, compressed))
    return seeds


@functools.lru_cache(maxsize=None)
def _layout(path: Path) -> dict:
    """The records, regions and messages of a seed's file (``tests/damage.py``), parsed once."""
    data = path.read_bytes()
    kind = damage.bag_kind(data)
    records = damage.ros1_records(data) if kind == "ros1" else damage.mcap_records(data) if kind == "mcap" else []
    return {"records": records, "regions": damage.bag_regions(data), "messages": damage.bag_messages(data)}


def _target_plausible(topic: str, field: str, before: dict, value: float) -> bool:
    """Whether a pose field changed to ``value`` is still a plausible pose (the oracle's rule): positions
    moved by less than 5 m (a goal: anywhere within the position limit) and unit quaternions turned
    by less than 1 rad (a goal: any unit quaternion)."""
    import math

    goal = topic == "/goal"
    if field in ("x", "y", "z"):
        if not math.isfinite(value) or abs(value) > POSITION_LIMIT:
            return False
        return goal or abs(value - before[field]) < 5.0
    q = [before[f] for f in ("qx", "qy", "qz", "qw")]
    q[("qx", "qy", "qz", "qw").index(field)] = value
    norm = math.sqrt(sum(c * c for c in q)) if all(math.isfinite(c) for c in q) else float("nan")
    if not abs(norm - 1.0) <= 0.01:
        return False
    q0 = [before[f] for f in ("qx", "qy", "qz", "qw")]
    angle = 2 * math.acos(min(1.0, abs(sum(a * b for a, b in zip(q0, q))) / norm))
    return goal or angle < 1.0


def _edit_of(kind: str, rng: random.Random, run) -> tuple[Callable, str]:
    """A message-list edit (``tests/damage.py``) chosen by ``rng``: structure damage a byte flip rarely reaches."""
    import numpy as np

    topic = rng.choice(("/mocap/pose", "/icp/pose", "/goal"))
    n = {"/mocap/pose": len(run.t_mocap), "/icp/pose": len(run.t_icp), "/goal": len(run.goals)}[topic]
    some = sorted(rng.sample(range(n), min(n, rng.choice((1, 2, 5, 50)))))
    which = rng.choice(("all", "some"))
    sel = set(range(n)) if which == "all" else set(some)
    if kind == "drop-topic":
        return damage.drop_topic(topic), f"edit: {topic} missing"
    if kind == "rename-topic":
        return damage.rename_topic(topic, topic + "_old"), f"edit: {topic} renamed"
    if kind == "nan":
        value = rng.choice((float("nan"), float("inf"), -float("inf")))
        field = rng.randrange(7)

        def fn(tp, i, xyz, q):
            if tp == topic and i in sel:
                v = np.concatenate([xyz, q])
                v[field] = value
                return v[:3], v[3:]
            return xyz, q
        return damage.edit_poses(fn), f"edit: {value} in field {field} of {which} ({len(sel)}) {topic}"
    if kind == "zero-quaternion":
        return (damage.edit_poses(lambda tp, i, xyz, q: (xyz, np.zeros(4) if tp == topic and i in sel else q)),
                f"edit: zero quaternion in {which} ({len(sel)}) {topic}")
    if kind == "swap":
        pairs = [(a, a + rng.choice((1, 7, 100))) for a in some if a + 100 < n]
        return damage.swap_messages(topic, pairs), f"edit: {len(pairs)} {topic} message pairs swapped"
    if kind == "duplicate":
        def dup(msgs, store):
            idx = [i for i, m in enumerate(msgs) if m[1] == topic]
            extra = [msgs[idx[k]] for k in some if k < len(idx)]
            return sorted(list(msgs) + extra, key=lambda m: m[0])
        return dup, f"edit: {len(some)} {topic} messages recorded twice"
    # only the first few messages of a topic
    keep = rng.choice((0, 1, 2, 3))

    def few(msgs, store):
        seen = {}
        out = []
        for m in msgs:
            if m[1] == topic:
                seen[topic] = seen.get(topic, 0) + 1
                if seen[topic] > keep:
                    continue
            out.append(m)
        return out
    return few, f"edit: {topic} with {keep} message(s)"


def mutate_bag(seed: BagSeed, data: bytes, rng: random.Random) -> tuple[Callable[[Path], Path], str, dict | None]:
    """One seeded mutation of a seed bag: ``(write(dir) -> input path, description, target)``; ``target``
    names the pose message whose value was changed (for the corrupted-value oracle)."""
    kinds = ["bytes", "header", "index", "chunk", "payload", "structure", "block", "truncate", "pose", "pose", "stamp", "edit"]
    if seed.path.is_dir():
        kinds.append("metadata")
    kind = rng.choice(kinds)
    lay = _layout(seed.data)
    target = None
    b = bytearray(data)
    yaml_text = (seed.path / "metadata.yaml").read_text() if seed.path.is_dir() else None
    edit = None
    what = kind
    if kind == "bytes":
        n = rng.choice((1, 1, 2, 4, 8, 32))
        for _ in range(n):
            b[rng.randrange(len(b))] = rng.randrange(256)
        what = f"bytes x{n}"
    elif kind in ("header", "index", "chunk", "payload"):
        ranges = lay["regions"][kind]
        n = rng.choice((1, 1, 2, 4, 8, 32))
        sizes = [e - s for s, e in ranges]
        for _ in range(n if ranges else 0):
            s, e = rng.choices(ranges, weights=sizes)[0]
            b[rng.randrange(s, e)] = rng.randrange(256)
        what = f"{kind} bytes x{n}"
    elif kind == "structure":
        if lay["records"]:
            rec = rng.choice(lay["records"])
            at = rng.choice(rec["structure"])
            b[at] = rng.choice((0, 1, 0x7F, 0x80, 0xFF, b[at] ^ 1, b[at] ^ 0x80, rng.randrange(256)))
            what = f"structure: {rec['op']} record at {rec['offset']}, byte {at - rec['offset']} = {b[at]}"
        else:  # SQLite: a page header or cell pointer
            s, e = rng.choice(lay["regions"]["chunk"])
            at = rng.randrange(s, e)
            b[at] = rng.choice((0, 1, 0x7F, 0x80, 0xFF, b[at] ^ 1, rng.randrange(256)))
            what = f"structure: page byte at {at} = {b[at]}"
    elif kind == "block":
        size = rng.choice((16, 64, 512, 4096))
        at = rng.randrange(len(b))
        b[at:at + size] = bytes(rng.randrange(256) for _ in range(min(size, len(b) - at)))
        what = f"block of {size} at {at}"
    elif kind == "truncate":
        if rng.random() < 0.5 and lay["records"]:
            keep = min(len(b), max(0, rng.choice(lay["records"])[rng.choice(("offset", "end"))] + rng.choice((-8, -1, 0, 1, 8))))
        else:
            keep = rng.randrange(len(b))
        b = b[:keep]
        what = f"truncate at {keep} of {len(data)}"
    elif kind in ("pose", "stamp") and not seed.compressed:
        topic = rng.choice(("/mocap/pose", "/mocap/pose", "/icp/pose", "/icp/pose", "/goal"))
        count = sum(m["topic"] == topic for m in lay["messages"])
        index = rng.randrange(count)
        before = damage.pose_of(data, topic, index, lay["messages"])
        if kind == "pose":
            field = rng.choice(damage.POSE_FIELDS)
            if field in ("x", "y", "z"):
                value = (before[field] + rng.choice(POSITION_DELTAS)) if rng.random() < 0.6 else rng.choice(POSITION_SPECIALS)
            else:
                v = rng.choice(QUAT_VALUES)
                value = -before[field] if v == "negate" else before[field] + 1e-3 if v == "nudge" else v
            b[before["offsets"][field]:before["offsets"][field] + 8] = struct.pack("<d", value)
            target = {"topic": topic, "source": BAG_TOPICS[topic], "index": index, "t": before["t"], "field": field,
                      "before": before[field], "after": value, "plausible": _target_plausible(topic, field, before, value),
                      "end": index in (0, count - 1)}
            what = f"pose: {topic}[{index}].{field} {before[field]:.6g} -> {value:.6g}"
        else:
            field, change = rng.choice(STAMP_CHANGES)
            old = before[field]
            value = (0 if change == "zero" else 0xFFFFFFFF if change == "max" else (old + change) & 0xFFFFFFFF)
            b[before["offsets"][field]:before["offsets"][field] + 4] = struct.pack("<I", value)
            t_new = (value if field == "sec" else before["sec"]) + (value if field == "nanosec" else before["nanosec"]) * 1e-9
            target = {"topic": topic, "source": BAG_TOPICS[topic], "index": index, "t": before["t"], "field": field,
                      "t_after": t_new, "before": old, "after": value,
                      "plausible": field == "sec" and abs(t_new - before["t"]) <= STAMP_SLACK}
            what = f"stamp: {topic}[{index}].{field} {old} -> {value}"
    elif kind in ("pose", "stamp", "edit"):  # compressed seeds: pose and stamp damage written through the writer
        from cobot_analysis.localisation import synth

        run = _bag_run()
        if kind == "edit":
            edit, what = _edit_of(rng.choice(("drop-topic", "rename-topic", "nan", "zero-quaternion", "swap", "duplicate", "few")), rng, run)
        elif kind == "stamp":
            topic = rng.choice(("/mocap/pose", "/icp/pose"))
            times = run.t_mocap if topic == "/mocap/pose" else run.t_icp
            index = rng.randrange(len(times))
            ns = int(round((float(times[index]) + synth.T0) * 1e9))
            sec, nsec = divmod(ns, 10**9)
            field, change = rng.choice(STAMP_CHANGES)
            old = sec if field == "sec" else nsec
            value = (0 if change == "zero" else 0xFFFFFFFF if change == "max" else (old + change) & 0xFFFFFFFF)
            signed = value - (1 << 32) if field == "sec" and value >= 1 << 31 else value  # same bytes: sec is int32
            edit = damage.edit_stamp(topic, index, **{field: signed})
            t_new = (value if field == "sec" else sec) + (value if field == "nanosec" else nsec) * 1e-9
            target = {"topic": topic, "source": BAG_TOPICS[topic], "index": index, "t": sec + nsec * 1e-9, "field": field,
                      "t_after": t_new, "before": old, "after": value,
                      "plausible": field == "sec" and abs(t_new - sec - nsec * 1e-9) <= STAMP_SLACK}
            what = f"stamp (written): {topic}[{index}].{field} {old} -> {value}"
        else:
            topic = rng.choice(("/mocap/pose", "/icp/pose"))
            n = len(run.t_mocap) if topic == "/mocap/pose" else len(run.t_icp)
            index = rng.randrange(n)
            field = rng.choice(("x", "y", "z"))
            delta = rng.choice(POSITION_DELTAS) if rng.random() < 0.6 else None
            special = rng.choice(POSITION_SPECIALS)
            box = {}

            def change(tp, i, xyz, q):
                if tp == topic and i == index:
                    xyz = xyz.copy()
                    k = "xyz".index(field)
                    box["before"] = float(xyz[k])
                    xyz[k] = xyz[k] + delta if delta is not None else special
                    box["after"] = float(xyz[k])
                return xyz, q
            edit = damage.edit_poses(change)
            t = float((run.t_mocap if topic == "/mocap/pose" else run.t_icp)[index]) + synth.T0
            target = {"topic": topic, "source": BAG_TOPICS[topic], "index": index, "t": t, "field": field, "plausible": False,
                      "end": index in (0, n - 1), "box": box}
            what = f"pose (written): {topic}[{index}].{field} " + (f"+ {delta:g}" if delta is not None else f"= {special:g}")
    elif kind == "metadata":
        lines = yaml_text.split("\n")
        op = rng.choice(("delete", "duplicate", "garbage", "value"))
        i = rng.randrange(len(lines))
        if op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, lines[i])
        elif op == "garbage":
            lines.insert(i, "".join(chr(rng.randrange(32, 127)) for _ in range(rng.randrange(1, 40))))
        else:
            key, sep, _ = lines[i].partition(":")
            lines[i] = key + sep + " " + rng.choice(("-1", "0", "99999999999999999999", "''", "[]", "{}", "null", "x", "1e400", "mcap", "sqlite3"))
        yaml_text = "\n".join(lines)
        what = f"metadata.yaml line {op} at {i}"

    def write(work: Path) -> Path:
        if edit is not None:
            out = work / seed.path.name
            _writers()[seed.writer](_bag_run(), out, edit=edit)
            if target is not None and "box" in target:
                box = target.pop("box")
                target.update(before=box.get("before"), after=box.get("after"))
            return out
        if seed.path.is_dir():
            out = work / seed.path.name
            shutil.copytree(seed.path, out)
            (out / seed.data.name).write_bytes(bytes(b))
            (out / "metadata.yaml").write_text(yaml_text)
            return out
        out = work / seed.path.name
        out.write_bytes(bytes(b))
        return out

    return write, what, target


# ---- formats -----------------------------------------------------------------------------------
def marker_commands(proto: Path, ws: Path, extra: tuple = ()) -> list[list[str]]:
    return [["-q", "import", str(proto), "--out", str(ws), "--jobs", "1"], ["-q", "preprocess", "--out", str(ws), "--jobs", "1"]]


def bag_commands(bag: Path, ws: Path, extra: tuple = ()) -> list[list[str]]:
    return [["-q", "bag-info", str(bag)], ["-q", "localisation", str(bag), "--out", str(ws), "--no-figures", *extra]]


@dataclass(frozen=True)
class Format:
    """A fuzzed input format: its file suffix, the commands run on an input (``(input, workspace,
    options)`` -> argument lists), and its family: ``markers`` (the input is listed in a one-trial
    protocol; a refused command ends the input) or ``bag`` (the bag is the argument; every command
    runs)."""

    suffix: str
    commands: Callable[..., list[list[str]]]
    family: str = "markers"


FORMATS: dict[str, Format] = {
    "c3d": Format(".c3d", marker_commands),
    "vicon-csv": Format(".csv", marker_commands),
    "qualisys-tsv": Format(".tsv", marker_commands),
    "ros1": Format(".bag", bag_commands, "bag"),
    "ros2": Format("", bag_commands, "bag"),  # a directory: metadata.yaml and its storage file
    "mcap": Format(".mcap", bag_commands, "bag"),
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


def _spikes(t, values, angle: bool, limit: float) -> tuple[int, int]:
    """Isolated samples that leave both neighbours faster than ``limit`` while the neighbours agree,
    and end samples that leave their neighbour faster while the next step is slow: ``(interior,
    ends)``; positions (m/s) or unit quaternions (rad/s)."""
    import numpy as np

    if len(t) < 3:
        return 0, 0

    def rate(a, b, dt):
        d = 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0, 1)) if angle else np.linalg.norm(a - b, axis=1)
        return d / np.maximum(dt, 1e-12)

    step = rate(values[1:], values[:-1], np.diff(t))
    over = rate(values[2:], values[:-2], t[2:] - t[:-2])
    inner = (step[:-1] > limit) & (step[1:] > limit) & (over <= limit)
    ends = int(step[0] > limit and step[1] <= limit) + int(step[-1] > limit and step[-2] <= limit)
    return int(inner.sum()), ends


def _bag_findings(ws: Path, job: dict) -> tuple[list[str], float | None]:
    """What is implausible in the outputs of an exit-0 `localisation` (the oracle, independent of the
    pipeline): non-finite values, stamps outside the recording, positions beyond the limit, isolated
    spikes, the damaged pose (or stamp) of an implausible target in the poses; and the largest change
    of a pose against the undamaged seed's run with the same options."""
    import numpy as np
    import pandas as pd

    found = []
    loc = ws / "localisation"
    poses = pd.read_parquet(loc / "poses.parquet")
    runs = pd.read_parquet(loc / "localisation.parquet")
    t0, t1 = job["span"]
    # a damaged pose at an end of a stream looks like a real jump (e.g. ICP's first fix): it may pass if the run warns
    warned = "jump(s) between consecutive poses" in " ".join(runs["warnings"].astype(str))
    for source, g in poses.groupby("source"):
        t, xyz, q = g["t"].to_numpy(), g[["x", "y", "z"]].to_numpy(), g[["qx", "qy", "qz", "qw"]].to_numpy()
        if not (np.isfinite(t).all() and np.isfinite(xyz).all() and np.isfinite(q).all()):
            found.append(f"non-finite {source} poses")
        elif ((t < t0 - STAMP_SLACK) | (t > t1 + STAMP_SLACK)).any():
            found.append(f"{source} stamps {t.min():.9g}..{t.max():.9g} outside the recording {t0:.9g}..{t1:.9g}")
        elif (np.abs(xyz) > POSITION_LIMIT).any():
            found.append(f"{source} position {np.abs(xyz).max():.3g} m")
        else:
            (n_pos, end_pos), (n_rot, end_rot) = _spikes(t, xyz, False, MAX_SPEED_BAG), _spikes(t, q, True, MAX_TURN)
            if n_pos or n_rot or ((end_pos or end_rot) and not warned):
                found.append(f"{source}: {n_pos} position and {n_rot} orientation spike(s), {end_pos + end_rot} at the ends"
                             + ("" if warned else " (no jump warned)"))
    cols = ["delay", "offset_x", "offset_y", "offset_z", "offset_yaw", "ape_rmse", "err_x_mean", "err_yaw_mean", "distance"]
    bad = [c for c in cols if not np.isfinite(runs[c].astype(float)).all()]
    if bad:
        found.append(f"non-finite {', '.join(bad)} in localisation.parquet")
    goals = loc / "goals.parquet"
    if goals.is_file():
        g = pd.read_parquet(goals)[["goal_x", "goal_y", "goal_yaw"]].to_numpy(dtype=float)
        if not np.isfinite(g).all() or (np.abs(g[:, :2]) > POSITION_LIMIT).any():
            found.append(f"implausible goal {g.tolist()}")
    change = None
    base_dir = Path(job["baseline"]) if job.get("baseline") else None
    if base_dir is not None and (base_dir / "poses.parquet").is_file():
        base = pd.read_parquet(base_dir / "poses.parquet")
        j = poses.merge(base, on=["source", "t"], suffixes=("", "_0"))
        dpos = np.linalg.norm(j[["x", "y", "z"]].to_numpy() - j[["x_0", "y_0", "z_0"]].to_numpy(), axis=1)
        dot = np.abs(np.sum(j[["qx", "qy", "qz", "qw"]].to_numpy() * j[["qx_0", "qy_0", "qz_0", "qw_0"]].to_numpy(), axis=1))
        drot = 2 * np.arccos(np.clip(dot, 0, 1))
        change = float(np.nanmax(dpos)) if len(dpos) else 0.0
        new = poses.merge(base[["source", "t"]], on=["source", "t"], how="left", indicator=True)
        new = new[new["_merge"] == "left_only"]
        tg = job.get("target")
        if tg and not tg["plausible"]:
            if tg["field"] in ("sec", "nanosec"):
                hit = new[(new["source"] == tg["source"]) & (np.abs(new["t"] - tg["t_after"]) < 1e-6)]
                if len(hit):
                    found.append(f"the damaged stamp {tg['t_after']:.9g} of {tg['topic']}[{tg['index']}] used")
            elif tg["source"] == "goal":
                bg = base_dir / "goals.parquet"
                if goals.is_file() and bg.is_file():
                    a = pd.read_parquet(goals)[["goal_x", "goal_y", "goal_yaw"]].to_numpy(dtype=float)
                    b0 = pd.read_parquet(bg)[["goal_x", "goal_y", "goal_yaw"]].to_numpy(dtype=float)
                    if a.shape != b0.shape or not np.allclose(a, b0, atol=1e-6, equal_nan=True):
                        found.append(f"the damaged goal ({tg['field']} = {tg['after']}) used: {a.tolist()}")
            else:
                moved = (dpos > 1.0) | (drot > 0.5) | ~np.isfinite(dpos)
                if moved.any() and not (tg["end"] and warned):
                    found.append(f"the damaged pose of {tg['topic']}[{tg['index']}] ({tg['field']} = {tg.get('after')}) used: "
                                 f"{int(moved.sum())} pose(s) moved by up to {np.nanmax(dpos):.3g} m / {np.nanmax(drot):.3g} rad")
    return found, change


def run_one(job: dict) -> dict:
    """Run the commands of one input in-process; return exit codes, message and findings."""
    import io

    from cobot_analysis import console as con
    from cobot_analysis.cli import run

    fmt = FORMATS[job["fmt"]]
    work = Path(job["work"])
    ws = work / "ws"
    if fmt.family == "markers":
        target = work / "protocol.yaml"
        target.write_text(f"study: fuzz\ntrials:\n  - {{trial: t1, file: {job['file']}, condition: c1}}\n{job['extra']}")
    else:
        target = Path(job["file"])
    codes, message, findings = [], "", []
    for argv in fmt.commands(target, ws, tuple(job.get("options", ()))):
        buf = io.StringIO()
        con.console.file = buf
        saved = sys.stderr, sys.stdout
        sys.stderr = sys.stdout = buf
        try:
            code = run(["-v"] + argv[1:])  # -v: the traceback of an internal error
        finally:
            sys.stderr, sys.stdout = saved
        codes.append(code)
        text = buf.getvalue()
        errors = [ln for ln in text.splitlines() if ln.startswith("error:")]
        if code not in (0, 2):
            findings.append(("internal error" if code == 1 else f"exit {code}") + f" ({argv[1]}): "
                            + (errors[-1] if errors else "") + " | " + text[-1500:])
        if code == 2:
            message = errors[-1] if errors else text.strip()
            if len(errors) != 1:
                findings.append(f"exit 2 with {len(errors)} error lines ({argv[1]})")
            elif Path(job["file"]).name not in message and "protocol.yaml" not in message and "markers.parquet" not in message:
                findings.append(f"exit 2 message names no file ({argv[1]})")
        if code != 0 and fmt.family == "markers":
            break
    result = {"codes": codes, "message": message[:400]}
    if fmt.family == "markers" and codes and codes[0] == 0:  # what the import (and the preprocess, if it passed) wrote must be plausible
        findings += [f"exit 0 with {f}" for f in _plausibility_findings(ws)]
        result["max_change"] = _max_change(ws, Path(job["baseline"]) if job.get("baseline") else None)
    if fmt.family == "bag" and len(codes) > 1 and codes[1] == 0:
        found, result["max_change"] = _bag_findings(ws, job)
        findings += [f"exit 0 with {f}" for f in found]
    result["findings"] = findings
    return result


def worker(conn) -> None:
    """Serve jobs from ``conn`` until it closes; the address space is capped (MemoryError, not swapping)."""
    import resource

    import typer.main

    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    # typer builds the command tree at every call (a third of a bag input's time): build it once per worker
    typer.main.get_command = functools.lru_cache(maxsize=None)(typer.main.get_command)
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
def _options(seed) -> list[tuple]:
    """The option sets an input of ``seed`` may be run with (bags: other streams, the record time)."""
    return list(BAG_OPTIONS) if isinstance(seed, BagSeed) else [()]


def baselines(seeds: list, out: Path, w: Worker) -> dict[tuple, dict]:
    """Run every undamaged seed once (a bag once per option set): its exit codes and outputs (for the
    change count and the corrupted-value oracle)."""
    base = {}
    for k, s in enumerate(seeds):
        for o, options in enumerate(_options(s)):
            work = out / "baseline" / (str(k) if isinstance(s, Seed) else f"{k}-{o}")
            if (work / "result.json").exists():
                base[s.path, options] = json.loads((work / "result.json").read_text())
                continue
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir(parents=True)
            job = {"fmt": s.fmt, "file": str(s.path), "extra": s.protocol_extra, "work": str(work), "options": options}
            if isinstance(s, BagSeed):
                job["span"] = _bag_span()
            res = w.run(job, 600)
            res["markers"] = str(work / "ws" / "import" / "markers.parquet")
            res["outputs"] = str(work / "ws" / "localisation")
            (work / "result.json").write_text(json.dumps(res))
            base[s.path, options] = res
    return base


def _bag_span() -> tuple[float, float]:
    from cobot_analysis.localisation import synth

    run = _bag_run()
    return float(run.t_mocap[0] + synth.T0), float(run.t_mocap[-1] + synth.T0)


def fuzz(n: int, out: Path, seed: int, timeout: float, formats: list[str], jobs: int = 1) -> None:
    """Run (or resume) inputs ``0 .. n-1`` in ``jobs`` worker processes; one line per input in ``OUT/results.jsonl``."""
    import queue
    import threading
    from concurrent.futures import ThreadPoolExecutor

    out.mkdir(parents=True, exist_ok=True)
    results = out / "results.jsonl"
    done = set()
    if results.exists():
        done = {json.loads(ln)["i"] for ln in results.read_text().splitlines() if ln.strip()}
    workers = queue.Queue()  # (worker process, its work directory), each used by one input at a time
    for k in range(jobs):
        workers.put((Worker(), out / f"work{k}"))
    first = workers.queue[0][0]
    markers = [f for f in formats if FORMATS[f].family == "markers"]
    seeds = [s for s in (synthetic_seeds(out) + realdata_seeds() if markers else []) if s.fmt in formats]
    seeds += [s for s in bag_seeds(out) if s.fmt in formats]
    base = baselines(seeds, out, first)
    for s in seeds:
        for options in _options(s):
            b = base[s.path, options]
            print(f"seed {s.fmt:13s} {s.path.name} {' '.join(options)}: exit codes {b['codes']} {b['message'][:100]} {b['findings'][:1]}")
    data = {s.path: (s.data if isinstance(s, BagSeed) else s.path).read_bytes() for s in seeds}
    t_start = time.perf_counter()
    lock = threading.Lock()

    def one(i: int, log) -> None:
        w, work = workers.get()
        try:
            s = seeds[i % len(seeds)]
            rng = random.Random(f"{seed}-{i}")
            shutil.rmtree(work, ignore_errors=True)
            work.mkdir()
            target, options = None, ()
            if isinstance(s, BagSeed):
                options = rng.choice(BAG_OPTIONS)
                write, what, target = mutate_bag(s, data[s.path], rng)
                f = write(work)
            else:
                mutated, what = mutate(data[s.path], s.fmt, rng)
                f = work / f"input{FORMATS[s.fmt].suffix}"
                f.write_bytes(mutated)
            t0 = time.perf_counter()
            b = base[s.path, options]
            ok_base = b["codes"] and b["codes"][-1 if isinstance(s, BagSeed) else 0] == 0
            job = {"fmt": s.fmt, "file": str(f), "extra": s.protocol_extra, "work": str(work), "options": options,
                   "target": target, "baseline": (b["outputs"] if isinstance(s, BagSeed) else b["markers"]) if ok_base else None}
            if isinstance(s, BagSeed):
                job["span"] = _bag_span()
            res = w.run(job, timeout)
            res.update(i=i, fmt=s.fmt, seed=s.path.name, mutation=what, options=" ".join(options), target=target,
                       seconds=round(time.perf_counter() - t0, 3))
            if res["findings"]:
                keep = out / "findings"
                keep.mkdir(exist_ok=True)
                if f.is_dir():
                    shutil.copytree(f, keep / f"{i}_{f.name}", dirs_exist_ok=True)
                else:
                    shutil.copy(f, keep / f"{i}{f.suffix}")
                (keep / f"{i}.yaml").write_text(s.protocol_extra)
                print(f"[{i}] {s.fmt} {s.path.name} {' '.join(options)} {what}: {res['findings']}", flush=True)
            with lock:
                log.write(json.dumps(res) + "\n")
                log.flush()
            if i % 500 == 0:
                print(f"{i} inputs, {time.perf_counter() - t_start:.0f} s", flush=True)
        finally:
            workers.put((w, work))

    with open(results, "a") as log, ThreadPoolExecutor(jobs) as pool:
        for future in [pool.submit(one, i, log) for i in range(n) if i not in done]:
            future.result()
    for k in range(jobs):
        shutil.rmtree(out / f"work{k}", ignore_errors=True)


def report(out: Path) -> str:
    """Markdown summary of ``OUT/results.jsonl`` (for docs/benchmarks.md)."""
    rows = [json.loads(ln) for ln in (out / "results.jsonl").read_text().splitlines() if ln.strip()]
    marker_rows = [r for r in rows if FORMATS[r["fmt"]].family == "markers"]
    bag_rows = [r for r in rows if FORMATS[r["fmt"]].family == "bag"]
    lines = []

    def outcome(r):
        if r["findings"]:
            return "finding"
        c = r["codes"]
        return "import refused (2)" if c[0] == 2 else "preprocess refused (2)" if len(c) > 1 and c[1] == 2 else "accepted (0)"

    if marker_rows:
        lines += ["| format | inputs | accepted (0) | import refused (2) | preprocess refused (2) | findings | median s/input |",
                  "|---|---|---|---|---|---|---|"]
        for fmt in sorted({r["fmt"] for r in marker_rows}):
            sub = [r for r in marker_rows if r["fmt"] == fmt]
            cnt = Counter(outcome(r) for r in sub)
            lines.append(f"| {fmt} | {len(sub)} | {cnt['accepted (0)']} | {cnt['import refused (2)']} | "
                         f"{cnt['preprocess refused (2)']} | {cnt['finding']} | {statistics.median(r['seconds'] for r in sub):.2f} |")
    if bag_rows:
        lines += [""] if lines else []
        lines += ["| format (seeds) | inputs | localisation 0 | localisation 2 | bag-info 0 | bag-info 2 | implausible pose values: "
                  "refused (2) / not used (0: dropped, or a topic not read) / used (finding) | findings | median s/input |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for fmt in sorted({r["fmt"] for r in bag_rows}):
            sub = [r for r in bag_rows if r["fmt"] == fmt]
            loc = Counter(r["codes"][1] if len(r["codes"]) > 1 else None for r in sub)
            info = Counter(r["codes"][0] if r["codes"] else None for r in sub)
            tg = [r for r in sub if r.get("target") and not r["target"]["plausible"]]
            refused = sum(len(r["codes"]) > 1 and r["codes"][1] == 2 for r in tg)
            used = sum(any(" used" in f for f in r["findings"]) for r in tg)
            unused = sum(len(r["codes"]) > 1 and r["codes"][1] == 0 for r in tg) - used
            seeds = ", ".join(sorted({r["seed"] for r in sub}))
            lines.append(f"| {fmt} ({seeds}) | {len(sub)} | {loc[0]} | {loc[2]} | {info[0]} | {info[2]} | {len(tg)}: {refused} / "
                         f"{unused} / {used} | {sum(bool(r['findings']) for r in sub)} | {statistics.median(r['seconds'] for r in sub):.2f} |")
        kinds = Counter(r["mutation"].split(":")[0].split(" ")[0] for r in bag_rows)
        lines += ["", "Bag mutations: " + ", ".join(f"{k} {v}" for k, v in kinds.most_common()) + "."]
    changed = [r["max_change"] for r in rows if r.get("max_change")]
    findings = Counter(f.split(":")[0] for r in rows for f in r["findings"])
    slow = max((r["seconds"] for r in rows), default=0)
    lines += ["", f"{len(rows)} inputs, {sum(r['seconds'] for r in rows) / 60:.1f} min of runs (slowest input {slow:.2f} s); "
              f"findings: {dict(findings) or 'none'}; accepted inputs whose values differ from the seed's: {len(changed)} "
              f"(largest difference {max(changed, default=0):.3g} m)."]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=10_000, help="number of inputs (a rerun resumes)")
    ap.add_argument("--out", type=Path, default=Path("fuzz-out"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per input before it counts as a hang")
    ap.add_argument("--formats", default=",".join(FORMATS))
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (inputs run in parallel)")
    ap.add_argument("--report", action="store_true", help="print the summary of OUT/results.jsonl and exit")
    a = ap.parse_args()
    if not a.report:
        fuzz(a.n, a.out, a.seed, a.timeout, a.formats.split(","), a.jobs)
    print(report(a.out))


if __name__ == "__main__":
    main()
