"""Import + preprocess of the full synthetic walking study, and per-step throughput vs kineticstoolkit / pyomeca.

    python benchmarks/bench_foundation.py [--study DIR] [--conditions 40] [--files N] [--jobs 2]

1. Generates the synthetic walking study (10 subjects x 40 conditions x 3 trials = 1200 C3D files)
   with ``cobot-analysis synth walking`` unless ``--study`` names an existing one (with
   protocol.yaml), then times the CLI end to end in fresh processes: ``import --jobs J`` and
   ``preprocess --jobs J`` (target: both together under 60 s on 2 cores).
2. Per step, in this process, one library after the other on the same files (``--files``, default
   all), throughput in frames/s (frames of one recording x all its 14 markers):
   - C3D reading: ``io.c3d.read_c3d`` vs ``kineticstoolkit.read_c3d`` vs ``pyomeca.Markers.from_c3d``;
   - low-pass filtering (Butterworth, 4th-order design, 10 Hz, zero-phase) of each library's own
     data: ``preprocess.filtering.lowpass`` vs ``ktk.filters.butter(order=4)`` vs
     ``Markers.meca.low_pass(order=4)``;
   - time normalisation to 500 samples: ``preprocess.normalisation.normalise`` vs
     ``ktk.cycles.time_normalize`` vs ``Markers.meca.time_normalize``.
3. Recovery on the whole study: CoM and theta RMS errors against the truth (as tests/test_recovery.py).
Prints a Markdown fragment for the "Import + preprocess" section of docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from datetime import datetime, timezone
from pathlib import Path

import numpy as np


def cli(*args: str) -> tuple[float, float]:
    """Wall time and CPU time (user + system, all its processes) of one ``cobot-analysis`` run in a
    fresh process (s). CPU time is what a loaded shared machine distorts least."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(["cobot-analysis", "-q", *map(str, args)], check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def interleaved(fns: dict, items: list) -> tuple[dict[str, float], dict[str, list]]:
    """Total time of each function over ``items``, calling them in turn on each item (rotating the
    order) so that a machine whose load changes during the run penalises no library in particular."""
    total = {k: 0.0 for k in fns}
    outs: dict[str, list] = {k: [] for k in fns}
    names = list(fns)
    for i, item in enumerate(items):
        for name in names[i % len(names):] + names[: i % len(names)]:
            arg = item[name] if isinstance(item, dict) else item
            t0 = time.perf_counter()
            outs[name].append(fns[name](arg))
            total[name] += time.perf_counter() - t0
    return total, outs


def same_data(raw, ktk, Markers) -> dict:
    """One recording's markers, gaps filled linearly (ends held), as an array (frames, 3 x markers)
    for us, a ``ktk.TimeSeries`` and a ``pyomeca.Markers``."""
    x = raw.xyz.reshape(len(raw.xyz), -1).copy()
    frames = np.arange(len(x))
    for j in np.flatnonzero(np.isnan(x).any(axis=0)):  # columns with a gap
        ok = ~np.isnan(x[:, j])
        x[~ok, j] = np.interp(frames[~ok], frames[ok], x[ok, j])
    t = frames / raw.rate
    ts = ktk.TimeSeries(time=t)
    xyz = x.reshape(len(x), -1, 3)
    for k, label in enumerate(raw.labels):
        ts.data[label] = np.column_stack([xyz[:, k], np.ones(len(x))])
    m = Markers(np.concatenate([xyz.transpose(2, 1, 0), np.ones((1, xyz.shape[1], len(x)))]), channels=raw.labels, time=t)
    return {"ours": x, "kineticstoolkit": ts, "pyomeca": m}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=Path, help="existing synthetic walking study (directory with protocol.yaml)")
    ap.add_argument("--conditions", type=int, default=40, help="start conditions to generate (40 = full study)")
    ap.add_argument("--files", type=int, default=0, help="files for the per-step comparison (0 = all)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--workdir", type=Path, help="where to put the study and workspace (default: a temporary directory)")
    args = ap.parse_args()
    warnings.simplefilter("ignore")

    work = args.workdir or Path(tempfile.mkdtemp(prefix="bench_foundation."))
    work.mkdir(parents=True, exist_ok=True)
    ws = work / "ws"
    load0 = os.getloadavg()[0]
    times: dict[str, tuple[float, float]] = {}
    if args.study:
        protocol = args.study / "protocol.yaml"
    else:
        synth_args = ["synth", "walking", "--out", ws, "--jobs", args.jobs]
        if args.conditions != 40:
            synth_args += ["--conditions", args.conditions]
        times["synth walking"] = cli(*synth_args)
        protocol = ws / "synth-walking" / "protocol.yaml"
    times["import"] = cli("import", protocol, "--out", ws, "--jobs", args.jobs, "--force")
    times["preprocess"] = cli("preprocess", "--out", ws, "--jobs", args.jobs, "--force")
    load1 = os.getloadavg()[0]

    # ---- per-step comparison ---------------------------------------------------------------------
    import kineticstoolkit as ktk
    from pyomeca import Markers

    from cobot_analysis.io.c3d import read_c3d
    from cobot_analysis.preprocess import filtering, normalisation

    files = sorted((protocol.parent / "raw").glob("*.c3d"))
    if args.files:
        files = files[: args.files]
    for f in files[:2]:  # warm the caches and imports of every library
        read_c3d(f), ktk.read_c3d(str(f)), Markers.from_c3d(str(f))
    steps: dict[str, dict[str, float]] = {}
    steps["C3D reading"], read = interleaved({
        "ours": read_c3d,
        "kineticstoolkit": lambda f: ktk.read_c3d(str(f))["Points"],
        "pyomeca": lambda f: Markers.from_c3d(str(f)),
    }, files)
    frames = sum(r.xyz.shape[0] for r in read["ours"])
    rate = read["ours"][0].rate
    # Filtering and normalisation get the same gap-free data in each library's own container
    # (pyomeca's filtfilt turns a channel with a gap into NaN; ktk interpolates gaps itself).
    data = [same_data(r, ktk, Markers) for r in read["ours"]]
    del read

    def our_filter(x):
        return filtering.lowpass(x, filtering.butter_sos(10.0, rate, 4, "design"))

    steps["filtering"], _ = interleaved({
        "ours": our_filter,
        "kineticstoolkit": lambda ts: ktk.filters.butter(ts, 10.0, order=4),
        "pyomeca": lambda m: m.meca.low_pass(order=4, cutoff=10, freq=rate),
    }, data)

    def ktk_normalise(ts):
        ts = ts.add_event(ts.time[0], "start").add_event(ts.time[-1], "end")
        return ktk.cycles.time_normalize(ts, "start", "end", n_points=500)

    steps["time normalisation"], _ = interleaved({
        "ours": lambda x: normalisation.normalise(x, 0, len(x) - 1, 500),
        "kineticstoolkit": ktk_normalise,
        # pyomeca's default time vector fails with current xarray (linspace over 0-d DataArrays): pass it
        "pyomeca": lambda m: m.meca.time_normalize(time_vector=np.linspace(float(m.time[0]), float(m.time[-1]), 500)),
    }, data)
    del data

    # ---- recovery against the truth --------------------------------------------------------------
    from cobot_analysis.angles import angle_diff
    from cobot_analysis.schema import TRAJECTORIES, read_table
    from cobot_analysis.synth.truth import TRUTH

    traj = read_table(ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    truth = read_table(protocol.parent / "truth.parquet", TRUTH)
    truth_by = {k: g.sort_values("time") for k, g in truth.groupby("trial", observed=True)}
    com, th, flags = [], [], []
    for trial, g in traj.groupby("trial"):
        tr = truth_by[trial]
        t = g["record_time"].to_numpy()
        ex = g["x"].to_numpy() - np.interp(t, tr["time"], tr["x"])
        ey = g["y"].to_numpy() - np.interp(t, tr["time"], tr["y"])
        com.append(np.sqrt(np.mean(ex**2 + ey**2)))
        if not np.isnan(g["theta"].to_numpy()).all():
            th.append(np.sqrt(np.mean(angle_diff(g["theta"].to_numpy(), np.interp(t, tr["time"], tr["theta"])) ** 2)))
        flags.append(g["quality"].iloc[0])
    com, th = np.array(com) * 1000, np.array(th)

    # ---- report ----------------------------------------------------------------------------------
    date = datetime.now(timezone.utc).strftime("%Y-%m-%d")
    n_files = len(files)
    print(f"\n`python benchmarks/bench_foundation.py --jobs {args.jobs}` ({date}, {platform.machine()}, "
          f"{os.cpu_count()} cores; load average {load0:.1f} before / {load1:.1f} after the CLI runs).\n")
    print("| stage (CLI, fresh process) | wall time (s) | CPU time, all processes (s) |\n|---|---|---|")
    for k, (wall, cpu) in times.items():
        print(f"| `{k}` | {wall:.1f} | {cpu:.1f} |")
    both = [times["import"][i] + times["preprocess"][i] for i in (0, 1)]
    print(f"| import + preprocess | {both[0]:.1f} | {both[1]:.1f} |\n")
    print(f"Per step, one process, {n_files} files, {frames:,} frames x 14 markers (frames/s; ratio = ours / library):\n")
    print("| step | ours | kineticstoolkit | pyomeca | ours / ktk | ours / pyomeca |\n|---|---|---|---|---|---|")
    for step, t in steps.items():
        fps = {k: frames / v for k, v in t.items()}
        print(f"| {step} | {fps['ours']:,.0f} | {fps['kineticstoolkit']:,.0f} | {fps['pyomeca']:,.0f} | "
              f"{fps['ours'] / fps['kineticstoolkit']:.1f} | {fps['ours'] / fps['pyomeca']:.1f} |")
    print(f"\nRecovery over {len(com)} trials: CoM RMS error median {np.median(com):.2f} mm, max {com.max():.2f} mm; "
          f"theta RMS error median {np.median(th):.4f} rad, max {th.max():.4f} rad over {len(th)} trials with "
          f"orientation ({sum('orientation_missing' in f for f in flags)} flagged orientation_missing).")
    if not args.workdir:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
