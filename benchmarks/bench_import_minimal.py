"""`import` + `preprocess` against a minimal script doing the core work with the same libraries (issue 22).

    python benchmarks/bench_import_minimal.py [--subjects 4] [--pairs 3] [--jobs 2] [--study DIR]

The reference (``minimal`` below, run as its own process): a pool of ``--jobs`` processes; per C3D
file, ezc3d read, the pelvis centre (mean of LASI, RASI, LPSI, RPSI), a 4th-order Butterworth
low-pass at 10 Hz run forward-backward (``scipy.signal`` ``butter`` + ``filtfilt``), resampled to
500 samples; one Parquet file of every trajectory. No check of any kind, no gaps, no segmentation,
no kinematics beyond the centre: the floor the pipeline's two stages are compared with. Ours:
``cobot-analysis import PROTOCOL --jobs N`` then ``preprocess --jobs N``, fresh processes, into an
empty workspace. The two alternate in pairs (the order alternating too); printed: the median of
the per-pair ratios of the wall times ours / minimal, and each side's median wall time.
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


def wall(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", type=int, default=4, help="synthetic subjects x 40 conditions x 3 trials (4: 480 files)")
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--study", type=Path, help="existing study directory (protocol.yaml, raw/*.c3d)")
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

        def ours() -> float:
            ws = tmp / "ws"
            shutil.rmtree(ws, ignore_errors=True)
            return (wall([*cli, "import", str(protocol), "--out", str(ws), "--jobs", str(args.jobs)])
                    + wall([*cli, "preprocess", "--out", str(ws), "--jobs", str(args.jobs)]))

        def minimal() -> float:
            return wall([sys.executable, str(script), str(raw), str(tmp / "minimal.parquet"), str(args.jobs)])

        pairs = []
        for k in range(args.pairs):
            o, m = (ours(), minimal()) if k % 2 == 0 else (minimal(), ours())[::-1]
            pairs.append((o, m))
            print(f"pair {k + 1}: ours {o:.1f} s, minimal {m:.1f} s, ratio {o / m:.2f}", file=sys.stderr)
        load1 = os.getloadavg()
        ratio = statistics.median(o / m for o, m in pairs)
        print(f"{started:%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, load average {load0[0]:.1f} before, {load1[0]:.1f} after; "
              f"{n_files} C3D files, --jobs {args.jobs}, {args.pairs} alternating pairs: import + preprocess "
              f"{statistics.median(o for o, _ in pairs):.1f} s, minimal script {statistics.median(m for _, m in pairs):.1f} s, "
              f"ratio (median of pairs) **{ratio:.2f}** (target <= 1.3)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
