"""Benchmark: the full pair-study analysis from trajectories.parquet to the report.

    python benchmarks/bench_analysis.py --workspace WS      # WS/preprocess/trajectories.parquet from
                                                            # synth pairs + import + preprocess
    python benchmarks/bench_analysis.py                     # fallback: 3240 in-memory trajectories

Runs average, compare, stats, reconstruct and report in a fresh copy of the workspace (so nothing
is skipped as up to date), in-process through ``cobot_analysis.cli.run`` (the code path of the
command line, without the interpreter start-up), and prints the wall time of each stage and the
total (wall and process CPU time) as a Markdown table. Also times the vectorised distances against a per-pair Python loop.
"""

from __future__ import annotations

import argparse
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np



def _fallback_table(path: Path) -> None:
    from cobot_analysis.schema import TRAJECTORIES, write_table
    from cobot_analysis.synth.tables import pair_table

    write_table(pair_table(seed=0, n_pairs=20, goals=9, n=500), path, TRAJECTORIES)


def bench_pipeline(workspace: Path | None) -> list[tuple[str, float, float]]:
    from cobot_analysis.cli import run

    tmp = Path(tempfile.mkdtemp(prefix="bench-analysis-"))
    ws = tmp / "ws"
    (ws / "preprocess").mkdir(parents=True)
    if workspace:
        shutil.copy(workspace / "preprocess" / "trajectories.parquet", ws / "preprocess" / "trajectories.parquet")
        if (workspace / "synth-pairs").is_dir():
            (ws / "synth-pairs").mkdir()
            for name in ("pairs.csv", "subjects.csv"):
                shutil.copy(workspace / "synth-pairs" / name, ws / "synth-pairs" / name)
    else:
        _fallback_table(ws / "preprocess" / "trajectories.parquet")
    times = []
    try:
        for args in (["average"], ["compare"], ["stats"], ["reconstruct"], ["report", "synthetic-pairs", "--to", str(tmp / "report")]):
            t0, c0 = time.perf_counter(), time.process_time()
            code = run(["-q", *args, "--out", str(ws)])
            times.append((args[0], time.perf_counter() - t0, time.process_time() - c0))
            if code != 0:
                raise SystemExit(f"{args[0]} failed with exit code {code}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return times


def bench_distances(n_pairs: int = 20000, n: int = 500) -> tuple[float, float]:
    """Seconds for ``n_pairs`` distance triples: vectorised ``pair_distances`` vs a loop of
    per-pair calls (the loop is timed on 1000 pairs and scaled)."""
    from cobot_analysis.distances import d_gamma, d_theta, d_xy, pair_distances

    rng = np.random.default_rng(0)
    a = {k: rng.normal(size=(3240, n)) for k in ("x", "y", "theta", "gamma")}
    ia, ib = rng.integers(0, 3240, n_pairs), rng.integers(0, 3240, n_pairs)
    t0 = time.perf_counter()
    pair_distances(a, a, ia, ib)
    vec = time.perf_counter() - t0
    t0 = time.perf_counter()
    for i, j in zip(ia[:1000], ib[:1000]):
        d_xy(a["x"][i], a["y"][i], a["x"][j], a["y"][j])
        d_theta(a["theta"][i], a["theta"][j])
        d_gamma(a["gamma"][i], a["gamma"][j])
    loop = (time.perf_counter() - t0) * n_pairs / 1000
    return vec, loop


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, help="workspace holding preprocess/trajectories.parquet")
    args = parser.parse_args()
    times = bench_pipeline(args.workspace)
    vec, loop = bench_distances()
    print(f"machine: {platform.processor() or platform.machine()}, {len(__import__('os').sched_getaffinity(0))} cores; "
          f"python {platform.python_version()}; date {time.strftime('%Y-%m-%d')}")
    print(f"load average at the end: {__import__('os').getloadavg()[0]:.1f}")
    print("| stage | wall time (s) | CPU time (s) |\n|---|---|---|")
    for name, t, c in times:
        print(f"| {name} | {t:.1f} | {c:.1f} |")
    print(f"| **total** | **{sum(t for _, t, _ in times):.1f}** | **{sum(c for _, _, c in times):.1f}** |")
    print(f"\n20000 trajectory pairs x 500 samples (d_xy, d_theta, d_gamma): vectorised {vec:.2f} s, "
          f"per-pair loop {loop:.2f} s (extrapolated from 1000 pairs)")


if __name__ == "__main__":
    main()
