"""Benchmark: single-level against bi-level IOC on the same targets, in one run (docs/benchmarks.md).

    python benchmarks/bench_ioc.py --means WS/average/means.parquet [--paths 37] [--intervals 50] [--jobs 2]
    python benchmarks/bench_ioc.py --synthetic 8 --intervals 20 --fit a2,a4

``--means``: the walking means (improved model, goal (0, 0, pi/2), a2, a3, a4 fitted from the walking-2021
preset, as ``fit-ioc`` under the continuous convention: a0, a1 and the unused b0..b3 held; no pace
calibration in either method); ``--synthetic N``: N paths of the model at the walking-2021 weights
(noise ``--noise`` m), the fit started at twice the fitted weights. The single-level fit
(``single_level.fit_feasible_path``) runs first, then the bi-level fit, each with its lower levels (and
the single-level Newton corrections) on ``--jobs`` worker processes (1: inline). Prints wall and CPU time (this process and its workers), the exact D (lower level re-solved),
the weights, the peak resident memory of each, and the time ratio; ``--paths N`` takes N targets spread
over the list.
"""

from __future__ import annotations

import argparse
import resource
import time
from dataclasses import replace

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--means")
    ap.add_argument("--synthetic", type=int)
    ap.add_argument("--paths", type=int, default=0, help="N targets spread over the list (0: all)")
    ap.add_argument("--intervals", type=int, default=50)
    ap.add_argument("--fit", default="a2,a3,a4", help="the continuous walker's fitted set (held_weights)")
    ap.add_argument("--noise", type=float, default=0.0)
    ap.add_argument("--jobs", type=int, default=2, help="worker processes of the bi-level fit")
    ap.add_argument("--skip-bilevel", action="store_true")
    ap.add_argument("--restarts", type=int, default=2, help="single-level restarts on re-solved paths (fit_feasible_path)")
    args = ap.parse_args()

    import pandas as pd

    from cobot_analysis.design import WALKING_GOAL
    from cobot_analysis.models.ioc import IOCSpec, fit, targets_from_table
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import fit_feasible_path
    from cobot_analysis.models.presets import load_weights, names_for, weights_vector
    from cobot_analysis.parallel import executor

    w = weights_vector(load_weights("walking-2021", "improved"), "improved")
    spec = IOCSpec(model="improved", start_weights=tuple(w), n_intervals=args.intervals, fitted=tuple(args.fit.split(",")))
    if args.synthetic:
        targets = synthetic_targets(spec, w, args.synthetic, noise=args.noise)
        ws = w.copy()
        for n in spec.fitted:
            ws[names_for("improved").index(n)] *= 2
        spec = replace(spec, start_weights=tuple(ws))
    else:
        df = pd.read_parquet(args.means)
        targets = targets_from_table(df[df["kind"] == "mean"] if "kind" in df else df, entity="walker", goal=WALKING_GOAL)
    if args.paths and args.paths < len(targets):
        targets = [targets[i] for i in np.linspace(0, len(targets) - 1, args.paths).astype(int)]
    def cpu() -> float:  # CPU seconds of this process and of its finished worker processes
        return sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
                   for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))

    rows = []
    t0, c0 = time.perf_counter(), cpu()
    with executor(args.jobs) as pool:
        s = fit_feasible_path(spec, targets, pool=pool, chunks=args.jobs, restarts=args.restarts)
    ts, cs = time.perf_counter() - t0, cpu() - c0
    mem = lambda who: resource.getrusage(who).ru_maxrss / 1024  # noqa: E731  MB (Linux: kB)
    mem_s = (mem(resource.RUSAGE_SELF), mem(resource.RUSAGE_CHILDREN))
    split = ", ".join(f"{k} {v:.1f} s" for k, v in s.timing.items())
    rows.append(("single-level", ts, cs, s.objective, s.weights, f"{s.status}; {split}; D on the NLP's paths (smoothed) {s.nlp_objective:.4f}, "
                 f"failed {s.failed}; peak memory {mem_s[0]:.0f} MB main, {mem_s[1]:.0f} MB largest worker"))
    if not args.skip_bilevel:
        t0, c0 = time.perf_counter(), cpu()
        with executor(args.jobs) as pool:
            b = fit(spec, targets, pool=pool, chunks=4 * args.jobs)
        tb, cb = time.perf_counter() - t0, cpu() - c0
        rows.append(("bilevel", tb, cb, b.objective, b.weights, f"{b.evaluations} evaluations; peak memory of the largest worker "
                     f"so far {mem(resource.RUSAGE_CHILDREN):.0f} MB"))
    print(f"{len(targets)} paths, {args.intervals} intervals, fitted {','.join(spec.fitted)}, start D {s.start_objective:.4f}")
    print("| method | wall (s) | CPU (s) | D | " + " | ".join(spec.fitted) + " | notes |")
    print("|---|---|---|---|" + "---|" * len(spec.fitted) + "---|")
    for m, t, c, D, wd, note in rows:
        print(f"| {m} | {t:.1f} | {c:.1f} | {D:.4f} | " + " | ".join(f"{wd[n]:.4g}" for n in spec.fitted) + f" | {note} |")
    if not args.skip_bilevel:
        print(f"ratios bilevel / single-level: wall {tb / ts:.2f}, CPU {cb / cs:.2f}; D single-level / bilevel: {s.objective / b.objective:.4f}")


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
