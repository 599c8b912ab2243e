"""Coupled-model IOC on the published scenario-3 means (docs/methods.md 5.6, 6): time of one coupled
OC solve (cold: best of 'rest' and 'line'; warm: re-solve after a 10 % change of every weight) and
of one upper-level evaluation (31 lower levels, warm-started, on a local pool of --jobs processes).

    python benchmarks/bench_coupled_ioc.py [--jobs 2] [--intervals 50] [--means PATH]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--intervals", type=int, default=50)
    ap.add_argument("--means", type=Path, default=Path("cobot-out/pair-carriage-2022/average/means.parquet"))
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()

    from cobot_analysis.averaging import MEANS
    from cobot_analysis.models.oc.coupled import get_coupled_ocp
    from cobot_analysis.models.ioc import IOCSpec, evaluate_chunk, pair_targets_from_table, solve_target
    from cobot_analysis.models.oc.problem import OCPShape
    from cobot_analysis.models.presets import PRESETS, weights_vector
    from cobot_analysis.parallel import executor
    from cobot_analysis.schema import read_table

    df = read_table(a.means, MEANS)
    targets = pair_targets_from_table(df[df["scenario"].notna()], path=a.means)
    w = weights_vector(PRESETS["pair-2022"], "coupled")
    spec = IOCSpec(model="coupled", start_weights=tuple(w), n_intervals=a.intervals)
    t0 = time.perf_counter()
    get_coupled_ocp(OCPShape(a.intervals, free_time=True, goal="constraint"))  # the shape solve_pair uses
    build = time.perf_counter() - t0
    cold, warm, primals, failed = [], [], [], 0
    w2 = w * 1.1
    for t in targets:
        t0 = time.perf_counter()
        d, sol = solve_target(spec, w, t, ("rest", "line"))
        cold.append(time.perf_counter() - t0)
        failed += not d["success"]
        primals.append(sol.primal)
        t0 = time.perf_counter()
        solve_target(spec, w2, t, sol.primal)
        warm.append(time.perf_counter() - t0)
    n_chunks = 4 * a.jobs
    parts = [list(range(i, len(targets), n_chunks)) for i in range(n_chunks)]
    rng = np.random.default_rng(0)
    evals = []
    with executor(a.jobs, None) as pool:
        for _ in range(a.repeat + 1):
            wk = w * 10 ** rng.uniform(-0.3, 0.3, len(w))
            t0 = time.perf_counter()
            futs = [pool.submit(evaluate_chunk, (spec, wk, [targets[i] for i in p], [primals[i] for i in p])) for p in parts]
            [f.result() for f in futs]
            evals.append(time.perf_counter() - t0)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; {time.strftime('%Y-%m-%d')}")
    print(f"{len(targets)} pair targets, {a.intervals} intervals; NLP build {build:.2f} s; cold not converged: {failed}")
    print(f"one coupled solve: cold (2 guesses) median {statistics.median(cold) * 1e3:.0f} ms (max {max(cold) * 1e3:.0f}), "
          f"warm after +10 % weights median {statistics.median(warm) * 1e3:.0f} ms (max {max(warm) * 1e3:.0f})")
    print(f"one upper-level evaluation ({len(targets)} warm lower levels, {a.jobs} processes, weights x 10^U(-0.3, 0.3)): "
          f"median {statistics.median(evals[1:]):.2f} s (first, with worker start-up: {evals[0]:.2f} s)")


if __name__ == "__main__":
    main()
