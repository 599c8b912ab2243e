"""Benchmark: single-level against bi-level IOC on the same targets, in one run (docs/benchmarks.md).

    python benchmarks/bench_ioc.py --workspace OUT/walking-2020 [--paths 37] [--intervals 50] [--jobs 2]
    python benchmarks/bench_ioc.py --workspace OUT/pair-carriage-2022 --model table --jobs 2
    python benchmarks/bench_ioc.py --means WS/average/means.parquet
    python benchmarks/bench_ioc.py --synthetic 8 --intervals 20 --fit a2,a4
    python benchmarks/bench_ioc.py --workspace OUT/walking-2020 --convention published --fit a1,a2,a3,a4 --jobs 2
    python benchmarks/bench_ioc.py --workspace OUT/walking-2020 --per-subject 0 [--bootstrap 200] [--skip-bilevel]
    python benchmarks/bench_ioc.py --workspace OUT/walking-2020 --perturbed 0,1e-12,-1e-12,1e-9,-1e-9,1e-6,-1e-6

``--workspace``: the means of a workspace (average/means.parquet) fitted as ``fit-ioc`` fits them under the
continuous convention (``--model improved``: the walking means, a2, a3, a4 from the walking-2021 preset;
``table``: the pair study's per-scenario means, from table-2022), both methods with the time gauge fitted
to the subjects' durations (import-published: the trials' speeds, or the pair study's durations.parquet);
then the bi-level fit's weights re-solved with the single-level fit's paths as a further warm start
(``single_level.cross_check``: both D from the same candidate paths). ``--means``: those means without
durations (no pace in either method). ``--synthetic N``: N paths of the model at the walking-2021 weights
(noise ``--noise`` m), the fit started at twice the fitted weights. The single-level fit
(``single_level.fit_feasible_path``) runs first, then the bi-level fit, each with its lower levels (and
the single-level Newton corrections) on ``--jobs`` worker processes (1: inline), in ``--chunks`` tasks (default
4 x jobs, as ``fit-ioc``). Prints wall and CPU time (this process and its workers), the exact D (lower level re-solved),
the weights, the peak resident memory of each, and the time ratio, then the single-level D and weights (per
subject: each fit's) to full precision, to check two trees' fits with ==; ``--paths N`` takes N targets spread
over the list. ``--perturbed F,...``: the continuous single-level fit alone, in this process, once per start with the
first fitted weight times (1 + F): the spread of its routes (the steps it takes, hence its time, follow the route:
docs/methods.md sec. 6.1), CPU, D and steps per start, and their mean.
"""

from __future__ import annotations

import argparse
import math
import resource
import time
from dataclasses import replace

import numpy as np


def workspace_targets(workspace: str, model: str, intervals: int, fit: str, convention: str = "continuous"):
    """(spec, targets, measured durations) of a workspace's means as ``fit-ioc --model MODEL`` builds them
    (published convention: no measured durations, the fit holds the duration rule's horizons)."""
    from dataclasses import replace
    from pathlib import Path

    import pandas as pd

    from cobot_analysis import conventions
    from cobot_analysis.api.models import goal_rule, ioc_spec, read_trajectories
    from cobot_analysis.models.ioc import targets_from_table
    from cobot_analysis.models.ioc.pace import target_durations
    from cobot_analysis.stages.models import fit_inputs

    ws = Path(workspace)
    means_path, traj_path = fit_inputs(ws, convention)  # the files fit-ioc reads (published: the authors' mean block)
    means = read_trajectories(means_path if means_path is not None else traj_path)
    df = means[means["kind"] == "mean"] if "kind" in means else means
    if "scenario" in df and df["scenario"].notna().any():
        df = df[df["scenario"].notna()]
    spec = replace(ioc_spec(model, convention=convention, fit=fit.split(",") if fit else None), n_intervals=intervals)
    targets = targets_from_table(df, entity="table" if model == "table" else "walker", goal=goal_rule("auto", df),
                                 convention=conventions.get(convention))
    if convention == "published":
        return spec, targets, None
    trials = read_trajectories(traj_path)
    dpath = traj_path.parent / "durations.parquet"
    keys = ["scenario", "condition", "direction"]
    measured_T = target_durations(targets, means=df, trials=trials[trials["kind"] == "trial"],
                                  durations=pd.read_parquet(dpath) if dpath.is_file() else None,
                                  mean_keys=df.groupby("trial")[keys].first() if set(keys) <= set(df.columns) else None)
    return spec, targets, measured_T


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workspace")
    ap.add_argument("--model", default="improved", choices=("improved", "table"))
    ap.add_argument("--means")
    ap.add_argument("--synthetic", type=int)
    ap.add_argument("--paths", type=int, default=0, help="N targets spread over the list (0: all)")
    ap.add_argument("--intervals", type=int, default=50)
    ap.add_argument("--fit", help="the fitted set (default: a2,a3,a4; --convention published: held_weights' complement)")
    ap.add_argument("--noise", type=float, default=0.0)
    ap.add_argument("--jobs", type=int, default=2, help="worker processes of the bi-level fit")
    ap.add_argument("--chunks", type=int, help="tasks per batch of lower levels (default: 4 x --jobs, as fit-ioc)")
    ap.add_argument("--skip-bilevel", action="store_true")
    ap.add_argument("--restarts", type=int, default=2, help="single-level restarts on re-solved paths (fit_feasible_path)")
    ap.add_argument("--convention", default="continuous", choices=("continuous", "published"),
                    help="with --workspace: published fits the single level at held horizons (fit_held_horizons)")
    ap.add_argument("--per-subject", type=int, default=None, metavar="N",
                    help="with --workspace: the per-subject fits of the first N subjects (0: all) as fit-ioc --per subject runs "
                         "them (start: WS/fit-ioc/weights.json), each with its --bootstrap")
    ap.add_argument("--bootstrap", type=int, default=200, help="with --per-subject: resamples after each fit (0: none)")
    ap.add_argument("--perturbed", help="F,F,...: single-level fits in-process, the first fitted weight's start x (1 + F)")
    args = ap.parse_args()
    args.chunks = args.chunks or 4 * args.jobs
    if args.fit is None:
        args.fit = "" if args.convention == "published" else "a2,a3,a4"
    if args.per_subject is not None:
        return per_subject(args)
    if args.perturbed:
        return perturbed(args)

    import pandas as pd

    from cobot_analysis.design import WALKING_GOAL
    from cobot_analysis.models.ioc import IOCSpec, fit, targets_from_table
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import cross_check, fit_feasible_path
    from cobot_analysis.models.presets import load_weights, names_for, weights_vector
    from cobot_analysis.parallel import executor

    measured_T = None
    w = weights_vector(load_weights("walking-2021", "improved"), "improved")
    spec = IOCSpec(model="improved", start_weights=tuple(w), n_intervals=args.intervals, fitted=tuple((args.fit or "a2,a3,a4").split(",")))
    if args.synthetic:
        targets = synthetic_targets(spec, w, args.synthetic, noise=args.noise)
        ws = w.copy()
        for n in spec.fitted:
            ws[names_for("improved").index(n)] *= 2
        spec = replace(spec, start_weights=tuple(ws))
    elif args.workspace:
        spec, targets, measured_T = workspace_targets(args.workspace, args.model, args.intervals, args.fit, args.convention)
    else:
        df = pd.read_parquet(args.means)
        targets = targets_from_table(df[df["kind"] == "mean"] if "kind" in df else df, entity="walker", goal=WALKING_GOAL)
    if args.paths and args.paths < len(targets):
        keep = np.linspace(0, len(targets) - 1, args.paths).astype(int)
        targets = [targets[i] for i in keep]
        measured_T = None if measured_T is None else np.asarray(measured_T)[keep]
    rows = []
    t0, c0 = time.perf_counter(), cpu()
    published = spec.convention == "published"
    with executor(args.jobs) as pool:
        if published:
            from cobot_analysis.models.ioc.single_level_published import fit_held_horizons

            s = fit_held_horizons(spec, targets, pool=pool)  # one task per path
        else:
            s = fit_feasible_path(spec, targets, pool=pool, chunks=args.chunks, restarts=args.restarts, measured_T=measured_T)
    ts, cs = time.perf_counter() - t0, cpu() - c0
    mem = lambda who: resource.getrusage(who).ru_maxrss / 1024  # noqa: E731  MB (Linux: kB)
    mem_s = (mem(resource.RUSAGE_SELF), mem(resource.RUSAGE_CHILDREN))
    if published:
        rows.append(("single-level", ts, cs, s.objective, s.weights, f"{s.message}; held D {s.held_objective:.4f}, horizons "
                     f"moved {s.horizons_changed}; peak memory {mem_s[0]:.0f} MB main, {mem_s[1]:.0f} MB largest worker"))
    else:
        split = ", ".join(f"{k} {v:.1f} s" for k, v in s.timing.items())
        rows.append(("single-level", ts, cs, s.objective, s.weights, f"{s.status}; {split}; D on the NLP's paths (smoothed) "
                     f"{s.nlp_objective:.4f}, failed {s.failed}; peak memory {mem_s[0]:.0f} MB main, {mem_s[1]:.0f} MB largest worker"))
    if not args.skip_bilevel:
        t0, c0 = time.perf_counter(), cpu()
        with executor(args.jobs) as pool:
            b = fit(spec, targets, pool=pool, chunks=args.chunks, measured_T=measured_T)
            crossed = math.nan if published else cross_check(spec, targets, s, b.weights, pool=pool, chunks=args.chunks)
        tb, cb = time.perf_counter() - t0, cpu() - c0
        rows.append(("bilevel", tb, cb, b.objective, b.weights, f"{b.evaluations} evaluations; peak memory of the largest worker "
                     f"so far {mem(resource.RUSAGE_CHILDREN):.0f} MB"))
    print(f"{len(targets)} paths, {spec.convention} convention, {args.intervals} intervals, fitted {','.join(spec.fitted)}, "
          f"start D {s.start_objective:.4f}")
    print("| method | wall (s) | CPU (s) | D | " + " | ".join(spec.fitted) + " | notes |")
    print("|---|---|---|---|" + "---|" * len(spec.fitted) + "---|")
    for m, t, c, D, wd, note in rows:
        print(f"| {m} | {t:.1f} | {c:.1f} | {D:.5f} | " + " | ".join(f"{wd[n]:.5g}" for n in spec.fitted) + f" | {note} |")
    print(f"exact single-level D and weights, to compare runs with ==: {s.objective!r} {[s.weights[n] for n in spec.fitted]!r}")
    if not args.skip_bilevel:
        print(f"ratios bilevel / single-level: wall {tb / ts:.2f}, CPU {cb / cs:.2f}; D single-level / bilevel: {s.objective / b.objective:.4f}")
        print(f"bilevel weights re-solved with the single-level paths as a further warm start (cross_check): D {crossed:.4f}; "
              f"D single-level / that: {s.objective / crossed:.4f}")


def per_subject(args) -> None:
    """The per-subject fits (``--per-subject``): ``api.fit_ioc(per="subject")`` of each method in one run, the
    fits and their bootstraps; wall and CPU time (this process and its workers), peak memory, D per subject."""
    from pathlib import Path

    from cobot_analysis.api.models import fit_ioc

    ws = Path(args.workspace)
    methods = ("single-level",) if args.skip_bilevel else ("single-level", "bilevel")
    for method in methods:
        t0, c0 = time.perf_counter(), cpu()
        r = fit_ioc(ws / "average" / "means.parquet", trials=ws / "import-published" / "trajectories.parquet", per="subject",
                    subjects=args.per_subject or None, start_weights=str(ws / "fit-ioc" / "weights.json"), compare=False,
                    jobs=args.jobs, method=method, bootstrap=args.bootstrap, intervals=args.intervals,
                    fit=args.fit.split(",") if args.fit else None)
        t, c = time.perf_counter() - t0, cpu() - c0
        mem = [resource.getrusage(who).ru_maxrss / 1024 for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]
        n = sum(len(v) for v in r.fits.values())
        print(f"{method}: {len(r.results)} subjects, {n} paths, bootstrap {args.bootstrap}: wall {t:.1f} s, CPU {c:.1f} s; "
              f"peak memory {mem[0]:.0f} MB main, {mem[1]:.0f} MB largest worker")
        print("| subject | paths | D | " + " | ".join(r.names) + " | fit (s) |")
        print("|---|---|---|" + "---|" * len(r.names) + "---|")
        for k, v in r.results.items():
            print(f"| {k} | {len(r.fits[k])} | {v.objective:.4f} | " + " | ".join(f"{v.weights[m]:.4g}" for m in r.names)
                  + f" | {r.seconds[k]:.1f} |")
        print("exact (D, weights) per subject, to compare runs with ==:",
              {k: (v.objective, {m: v.weights[m] for m in r.names}) for k, v in r.results.items()})


def perturbed(args) -> None:
    """The continuous single-level fit from perturbed starts (``--perturbed``), in this process: CPU, D and steps each."""
    from cobot_analysis.models.ioc.single_level import fit_feasible_path
    from cobot_analysis.models.presets import names_for

    spec, targets, measured_T = workspace_targets(args.workspace, args.model, args.intervals, args.fit)
    i = names_for(spec.model).index(spec.fitted[0])
    cpus, Ds = [], []
    print(f"| start {spec.fitted[0]} x (1 + f) | CPU (s) | D | steps | " + " | ".join(spec.fitted) + " |")
    print("|---|---|---|---|" + "---|" * len(spec.fitted))
    for f in map(float, args.perturbed.split(",")):
        w = list(spec.start_weights)
        w[i] *= 1 + f
        c0 = time.process_time()
        r = fit_feasible_path(replace(spec, start_weights=tuple(w)), targets, measured_T=measured_T, chunks=args.chunks,
                              restarts=args.restarts)
        cpus.append(time.process_time() - c0)
        Ds.append(r.objective)
        print(f"| {f:+g} | {cpus[-1]:.2f} | {r.objective:.5f} | {r.iterations} | "
              + " | ".join(f"{r.weights[n]:.4g}" for n in spec.fitted) + " |")
    distinct = len({round(D, 9) for D in Ds})  # the re-solve at the end leaves round-off in D: the same fit to 1e-9
    print(f"mean CPU {np.mean(cpus):.2f} s, median D {np.median(Ds):.5f}, {distinct} distinct D (to 1e-9) in {len(Ds)} starts")


def cpu() -> float:
    """CPU seconds of this process and of its finished worker processes."""
    return sum(resource.getrusage(who).ru_utime + resource.getrusage(who).ru_stime
               for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
