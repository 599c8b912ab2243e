"""Benchmark: the weights' uncertainty of a fit (docs/methods.md sec. 6.3), its two parts timed apart:
the curvature of D at the fitted weights (1 + 2k + k(k-1) stencil points, one lower-level solve per
path each) and the bootstrap's ``--resamples`` quadratic refits (default 200, as ``fit-ioc``).

    python benchmarks/bench_bootstrap.py WS/fit-ioc/weights.json WS/average/means.parquet [--jobs 2]
    python benchmarks/bench_bootstrap.py WS/fit-ioc-subjects/weights.json WS/import-published/trajectories.parquet --fit S01

The targets are those ``fit-ioc`` fitted: the mean paths (``kind == mean``) or, with ``--fit SUBJECT``,
that subject's trials; the model, convention, fitted weights and grid come from weights.json. Prints
the wall time of each part, the peak memory, the verdicts and intervals.
"""

from __future__ import annotations

import argparse
import resource
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("weights", help="a fit-ioc weights.json")
    ap.add_argument("table", help="means.parquet (or trajectories.parquet with --fit SUBJECT)")
    ap.add_argument("--fit", default="all", help="the fit of weights.json: all (the means) or a subject (its trials)")
    ap.add_argument("--resamples", type=int, default=200)
    ap.add_argument("--jobs", type=int, default=2, help="worker processes of the stencil's solves (1: in-process)")
    args = ap.parse_args()

    import json
    from dataclasses import replace

    from cobot_analysis.api.models import goal_rule, read_trajectories
    from cobot_analysis import conventions
    from cobot_analysis.models.ioc import IOCSpec, targets_from_table
    from cobot_analysis.models.ioc import uncertainty as unc

    doc = json.loads(open(args.weights).read())
    r = doc["fits"][args.fit]
    spec = IOCSpec(**{**r["spec"], "start_weights": tuple(r["spec"]["start_weights"]), "fitted": tuple(r["spec"]["fitted"])})
    spec = replace(spec, start_weights=tuple(r["weights"][n] for n in r["weights"]))
    conv = conventions.get(doc["convention"])
    df = read_trajectories(args.table)
    df = df[df["kind"] == ("mean" if args.fit == "all" else "trial")]
    if args.fit != "all":
        df = df[df["subject"] == args.fit]
    entity = "table" if spec.model == "table" else "walker"
    if "scenario" in df and df["scenario"].notna().any():
        df = df[df["scenario"].notna()]
    targets = targets_from_table(df, path=args.table, entity=entity, goal=goal_rule("auto", df), convention=conv)
    from cobot_analysis.parallel import executor

    t0 = time.perf_counter()
    with executor(args.jobs) as pool:
        c = unc.curvature(spec, targets, r["weights"], pool=pool, chunks=4 * args.jobs)
    t1 = time.perf_counter()
    cpu = sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
              for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    b = unc.bootstrap(c, args.resamples)
    t2 = time.perf_counter()
    k = len(spec.fitted)
    print(f"{args.weights} fit {args.fit}: {len(targets)} paths, {spec.n_intervals} intervals, fitted {','.join(spec.fitted)} "
          f"({doc['convention']}, {doc.get('method', 'bilevel')})")
    print(f"curvature: {1 + 2 * k + k * (k - 1)} stencil points x {len(targets)} solves: {t1 - t0:.1f} s wall, "
          f"process CPU so far {cpu:.1f} s, --jobs {args.jobs} "
          f"({c.failed} failed solves, lack of fit {c.lack_of_fit:.3f})")
    print(f"bootstrap: {args.resamples} quadratic refits: {t2 - t1:.2f} s wall")
    print(f"total {t2 - t0:.1f} s; peak memory {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB")
    for n, v in unc.verdicts(spec.fitted, c.H, c.D, r["weights"], lack=c.lack_of_fit).items():
        lo, hi = b["intervals"][n]
        print(f"  {n} {r['weights'][n]:.4g} [{lo:.4g}, {hi:.4g}] {v}")


if __name__ == "__main__":
    main()
