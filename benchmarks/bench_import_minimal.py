"""`import` + `preprocess` against a minimal script doing the core work with the same libraries (issue 22).

    python benchmarks/bench_import_minimal.py [--subjects 4] [--pairs 3] [--jobs 2] [--study DIR]

The reference (``minimal`` below, run as its own process): a pool of ``--jobs`` processes; per C3D
file, ezc3d read, the pelvis centre (mean of LASI, RASI, LPSI, RPSI), a 4th-order Butterworth
low-pass at 10 Hz run forward-backward (``scipy.signal`` ``butter`` + ``filtfilt``), resampled to
500 samples; one Parquet file of every trajectory. No check of any kind, no gaps, no segmentation,
no kinematics beyond the centre: the floor the pipeline's two stages are compared with. Ours:
``cobot-analysis import PROTOCOL --jobs N`` then ``preprocess --jobs N``, fresh processes, into an
empty workspace. The two alternate in pairs (the order alternating too); printed: the median of
the per-pair ratios of the wall times ours / minimal (and of the CPU times, user + system of all
processes, which a shared machine distorts less), each side's median wall time, and the peak memory
of our two commands (the largest process, and the sum of the RSS of the process and its workers, sampled
every 50 ms).
``--one-pass``: ours is ``cobot-analysis import PROTOCOL --preprocess --jobs N`` (the two stages in one
pass, each trial preprocessed where it is read: the same outputs). ``--scaling`` adds ours with
``--jobs 1`` to each round and prints the median speed-up of ``--jobs N`` over ``--jobs 1`` (issue 22:
at least 1.7x with 2 jobs), and the minimal script's own (its pool of 1 process against N). ``--before DIR`` adds, to each
round, ours run from the package in DIR (e.g. ``git archive <commit> | tar -x -C DIR``; with ``--scaling`` also its
``--jobs 1``) and prints the median ratio now / before (and its own speed-up). With ``--one-pass``, the CPU time of
the main process alone (without its workers) is printed for each version and ``--jobs``: the part of the work the
pool does not share.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

MINIMAL = r'''
import sys
from multiprocessing import Pool
from pathlib import Path

import ezc3d
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from scipy.signal import butter, filtfilt

PELVIS = ("LASI", "RASI", "LPSI", "RPSI")


def trial(path):
    c = ezc3d.c3d(str(path))
    labels = c["parameters"]["POINT"]["LABELS"]["value"]
    rate = float(c["parameters"]["POINT"]["RATE"]["value"][0])
    xyz = c["data"]["points"][:3, [labels.index(m) for m in PELVIS], :] / 1000.0
    centre = np.nanmean(xyz, axis=1).T  # (frames, 3)
    b, a = butter(4, 10.0 / (rate / 2))
    smooth = filtfilt(b, a, centre, axis=0)
    t = np.linspace(0.0, 1.0, 500)
    s = np.linspace(0.0, 1.0, len(smooth))
    return path.stem, np.column_stack([np.interp(t, s, smooth[:, k]) for k in range(3)])


if __name__ == "__main__":
    files, out, jobs = sorted(Path(sys.argv[1]).glob("*.c3d")), sys.argv[2], int(sys.argv[3])
    with Pool(jobs) as pool:
        rows = pool.map(trial, files, chunksize=8)
    names = np.repeat([n for n, _ in rows], 500)
    data = np.concatenate([r for _, r in rows])
    pq.write_table(pa.table({"trial": names, "x": data[:, 0], "y": data[:, 1], "z": data[:, 2]}), out)
'''


PARENT_CPU: dict[str, float] = {}  # command -> CPU time (s) of the main process alone, last sampled (``run``)


def run(cmd: list[str], env: dict | None = None, cwd: Path | None = None) -> tuple[float, float, float, float]:
    """Wall time (s), CPU time of the process and its children (s), peak memory of the process tree (sum of
    the RSS of the process and its workers; forked workers' shared pages counted twice) and of its largest
    process (MiB). The main process's own CPU time (without its workers), sampled every 50 ms, is left in
    ``PARENT_CPU``: with a pool it bounds the wall time from below."""
    import resource

    import psutil

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, env=env, cwd=cwd)
    peak = one = 0
    tree = psutil.Process(proc.pid)
    while proc.poll() is None:
        try:
            rss = [p.memory_info().rss for p in [tree, *tree.children(recursive=True)]]
            peak, one = max(peak, sum(rss)), max(one, max(rss))
            own = tree.cpu_times()
            PARENT_CPU[" ".join(cmd)] = own.user + own.system
        except psutil.Error:
            pass
        time.sleep(0.05)
    wall = time.perf_counter() - t0
    if proc.returncode:
        raise SystemExit(f"{' '.join(cmd)}: exit {proc.returncode}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, peak / 2**20, one / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, default=4, help="synthetic subjects x 40 conditions x 3 trials (4: 480 files)")
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--study", type=Path, help="existing study directory (protocol.yaml, raw/*.c3d)")
    ap.add_argument("--scaling", action="store_true", help="also time ours and the minimal script with --jobs 1 (speed-up of --jobs N)")
    ap.add_argument("--one-pass", action="store_true", help="ours: import --preprocess (one command) instead of import, then preprocess")
    ap.add_argument("--before", type=Path, help="a source tree of an earlier version: also time ours from it in each round")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench-import-minimal-"))
    load0 = os.getloadavg()
    started = datetime.now(timezone.utc)
    try:
        if args.study:
            protocol = args.study / "protocol.yaml"
        else:
            from cobot_analysis.design import WALKING_CONDITIONS
            from cobot_analysis.synth import walking

            protocol = walking.generate(tmp / "study", n_subjects=args.subjects, n_trials=3,
                                        conditions=list(WALKING_CONDITIONS), jobs=args.jobs)
        raw = protocol.parent / "raw"
        n_files = len(list(raw.glob("*.c3d")))
        script = tmp / "minimal.py"
        script.write_text(MINIMAL)
        cli = [sys.executable, "-m", "cobot_analysis", "-q"]

        def ours(jobs: int, tree: Path | None = None) -> tuple[float, float, float, float]:
            ws = tmp / "ws"
            shutil.rmtree(ws, ignore_errors=True)
            env = None if tree is None else {**os.environ, "PYTHONPATH": str(tree.resolve())}
            if args.one_pass:
                cmd = [*cli, "import", str(protocol), "--out", str(ws), "--jobs", str(jobs), "--preprocess"]
                r = run(cmd, env, cwd=tree)
                parent_cpu.append((jobs, tree is None, PARENT_CPU.get(" ".join(cmd), float("nan")), r[1]))
                return r
            a = run([*cli, "import", str(protocol), "--out", str(ws), "--jobs", str(jobs)], env, cwd=tree)
            b = run([*cli, "preprocess", "--out", str(ws), "--jobs", str(jobs)], env, cwd=tree)
            return a[0] + b[0], a[1] + b[1], max(a[2], b[2]), max(a[3], b[3])

        def minimal(jobs: int = args.jobs) -> tuple[float, float, float, float]:
            return run([sys.executable, str(script), str(raw), str(tmp / "minimal.parquet"), str(jobs)])

        pairs, scaling, before, min_scaling, before_scaling, parent_cpu = [], [], [], [], [], []
        for k in range(args.pairs):
            if args.before:
                old = ours(args.jobs, args.before)
                before.append(old)
                print(f"  before ({args.before}): {old[0]:.1f} s (CPU {old[1]:.1f} s)", file=sys.stderr)
                if args.scaling:
                    old1 = ours(1, args.before)
                    before_scaling.append(old1[0] / old[0])
                    print(f"  before, --jobs 1: {old1[0]:.1f} s (CPU {old1[1]:.1f} s): speed-up of --jobs {args.jobs} "
                          f"{old1[0] / old[0]:.2f}", file=sys.stderr)
            o, m = (ours(args.jobs), minimal()) if k % 2 == 0 else (minimal(), ours(args.jobs))[::-1]
            pairs.append((o, m))
            print(f"pair {k + 1}: ours {o[0]:.1f} s (CPU {o[1]:.1f} s, {o[2]:.0f} MiB, largest process {o[3]:.0f} MiB), "
                  f"minimal {m[0]:.1f} s (CPU {m[1]:.1f} s, {m[2]:.0f} MiB), "
                  f"ratio {o[0] / m[0]:.2f} (CPU {o[1] / m[1]:.2f})", file=sys.stderr)
            if args.scaling:
                one = ours(1)
                scaling.append(one[0] / o[0])
                m1 = minimal(1)
                min_scaling.append(m1[0] / m[0])
                print(f"  ours --jobs 1: {one[0]:.1f} s (CPU {one[1]:.1f} s): speed-up of --jobs {args.jobs} {one[0] / o[0]:.2f}; "
                      f"minimal with 1 process: {m1[0]:.1f} s (CPU {m1[1]:.1f} s): its speed-up {m1[0] / m[0]:.2f}", file=sys.stderr)
        load1 = os.getloadavg()
        ratio = statistics.median(o[0] / m[0] for o, m in pairs)
        cpu = statistics.median(o[1] / m[1] for o, m in pairs)
        print(f"{started:%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, load average {load0[0]:.1f} before, {load1[0]:.1f} after; "
              f"{n_files} C3D files, --jobs {args.jobs}, {args.pairs} alternating pairs: import + preprocess"
              f"{' (one pass: import --preprocess)' if args.one_pass else ''} "
              f"{statistics.median(o[0] for o, _ in pairs):.1f} s, minimal script {statistics.median(m[0] for _, m in pairs):.1f} s, "
              f"ratio (median of pairs) **{ratio:.2f}** (target <= 1.3; CPU time ratio {cpu:.2f}); peak memory of ours "
              f"{max(o[3] for o, _ in pairs):.0f} MiB in its largest process, {max(o[2] for o, _ in pairs):.0f} MiB summed over "
              f"the process tree (the minimal script's tree {max(m[2] for _, m in pairs):.0f} MiB)"
              + (f"; --jobs {args.jobs} over --jobs 1: **{statistics.median(scaling):.2f}x** (target >= 1.7; the minimal "
                 f"script's own: {statistics.median(min_scaling):.2f}x)" if scaling else "")
              + (f"; now / before ({args.before}): wall {statistics.median(o[0] / b[0] for (o, _), b in zip(pairs, before)):.2f}, "
                 f"CPU {statistics.median(o[1] / b[1] for (o, _), b in zip(pairs, before)):.2f}" if before else "")
              + (f"; before, --jobs {args.jobs} over --jobs 1: {statistics.median(before_scaling):.2f}x" if before_scaling else ""))
        for jobs in sorted({j for j, *_ in parent_cpu}):
            for now in (True, False):
                rows = [(own, total) for j, n, own, total in parent_cpu if j == jobs and n == now]
                if rows:
                    print(f"  {'now' if now else 'before'} --jobs {jobs}: main process CPU {statistics.median(o for o, _ in rows):.2f} s "
                          f"of {statistics.median(t for _, t in rows):.2f} s (median over {len(rows)} runs)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
