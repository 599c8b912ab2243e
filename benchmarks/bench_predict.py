"""Prediction benchmarks (docs/benchmarks.md, section "Prediction").

    python benchmarks/bench_predict.py windows TRAJECTORIES.parquet [--n 6] [--convention NAME]
        OC windows per second of CPU time on one core (N0 = 50, N_OC = 100: 100-node windows, solved as the
        50-node measured past plus the zero-control coast, see OCPredictor), and the baselines, on n trial
        trajectories. Continuous convention (default): warm-started (the previous window shifted) and
        cold; published: cold from rest, 0.1 s Euler nodes (the convention's own rule).
    python benchmarks/bench_predict.py published-floor TRAJECTORIES.parquet [--n 6]
        CPU per trajectory of the published (50, 100) sweep split into the fatrop solves and the rest
        (issue 22), extrapolated to the 400 walking-2020 trials on 2 cores against the 60 s target.
    python benchmarks/bench_predict.py stats TRAJECTORIES.parquet [--n 6] [--convention published]
        The (50, 100) sweep with the OC solves reading fatrop's stats after each converged solve (before) and
        not (after), alternated per trajectory: CPU per trajectory, the ratio, rows identical or not.
    python benchmarks/bench_predict.py sweep TRAJECTORIES.parquet --out DIR [--convention NAME] [--dask] [--every K] [--limit N]
                                             [--predictors goal,cv]
        Wall time of `cobot-analysis predict --settings 50:100 --kind trial --convention NAME` from an
        empty work directory: local pool of 2 processes, or a 2-worker local Dask cluster (--dask).

    python benchmarks/bench_predict.py horizons WALKING.parquet [--pairs PAIRS.parquet] [--every K] [--jobs 2]
        Wall time of the horizon sweep (models.prediction.horizons) at N0 = 50.
    python benchmarks/bench_predict.py stages WALKING.parquet [--pairs PAIRS.parquet] [--n 3] [--weights W]
        CPU per trajectory of each prediction stage of the Makefile (issue 22 point 5), one process: predict
        (4 settings, both conventions) and the predict-goal stages with their horizon sweep,
        the settings and the horizons predicted by one run per predictor (the stage) against two runs
        (before: the horizon sweep predicted every window again), alternated per trajectory; the ratio.
    python benchmarks/bench_predict.py goal WALKING.parquet [--pairs PAIRS.parquet] [--n 6] [--weights W]
        The goal-aware predictors per window on one core: goal on n walking trials; goal and goal-inferred
        on n table means.

TRAJECTORIES.parquet: e.g. the output of `cobot-analysis import-published walking-2020 ...`.
BLAS is limited to one thread per process, as in the pipeline's pool.
"""

from __future__ import annotations

import argparse
import os
import shutil
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402


def load(path: Path, n: int):
    from cobot_analysis.models.prediction.sweep import SweepConfig, trajectories_from_table
    from cobot_analysis.schema import TRAJECTORIES, read_table

    df = read_table(path, TRAJECTORIES)
    df = df[df["kind"] == "trial"]
    trials = df["trial"].unique()[:: max(1, len(df["trial"].unique()) // n)][:n]
    return trajectories_from_table(df[df["trial"].isin(trials)], SweepConfig(settings=((50, 100),)))


def bench_windows(path: Path, n: int, convention: str) -> None:
    from cobot_analysis.models.prediction.predictor import OCPredictor, make_predictor

    trajs = load(path, n)
    first = OCPredictor(50, 100, trajs[0].dt, convention=convention)  # build the NLP once (cached per process)
    t0 = time.perf_counter()
    from cobot_analysis.models.oc.problem import WalkerOCP

    WalkerOCP(first.ocp.shape)
    build = time.perf_counter() - t0
    print(f"{convention} convention; NLP build (49 intervals, {first.scheme}: the window's measured past): {build:.2f} s")
    runs = (("oc warm", {"warm_start": True}), ("oc cold", {"warm_start": False})) if first.warm_start else (("oc cold from rest", {}),)
    solve = WalkerOCP.solve
    for label, kw in runs:
        times, iters, failed = [], [], 0
        for t in trajs:
            p = OCPredictor(50, 100, t.dt, convention=convention, **kw)
            p.reset()
            for pose in t.seen:
                before = p.last_solution
                s = time.process_time()
                p.update(pose)
                if p.last_solution is not before:  # a window was solved
                    times.append(time.process_time() - s)
            failed += p.failed
            # the windows again, untimed, reading fatrop's stats for the iteration counts (the predictor does not)
            WalkerOCP.solve = lambda self, *a, **k: solve(self, *a, **{**k, "stats": True})
            try:
                p.reset()
                for pose in t.seen:
                    before = p.last_solution
                    p.update(pose)
                    if p.last_solution is not before:
                        iters.append(p.last_solution.iterations)
            finally:
                WalkerOCP.solve = solve
        times = np.array(times)
        print(f"{label}: {len(times)} windows, {1 / times.mean():.0f} windows/s (mean {1e3 * times.mean():.2f} ms, "
              f"median {1e3 * np.median(times):.2f} ms, p95 {1e3 * np.percentile(times, 95):.2f} ms), "
              f"iterations median {np.median(iters):.0f}, failed {failed}")
    for name in ("cv", "ctrv"):
        s = time.process_time()
        count = sum(make_predictor(name, 50, 100, t.dt).predict_offline(t.seen).shape[0] for t in trajs)
        print(f"{name}: {count / (time.process_time() - s):.0f} windows/s")


def bench_published_floor(path: Path, n: int, target: float = 60.0) -> None:
    """Issue 22: CPU per trajectory of the published (50, 100) sweep, split into the fatrop solves and
    the rest, in one process; extrapolated to the 400 walking-2020 trials on 2 fully used cores and
    compared with the 60 s target (the solves alone are the floor local edits cannot go below)."""
    from cobot_analysis import conventions
    from cobot_analysis.models.oc import problem
    from cobot_analysis.models.prediction.sweep import SweepConfig, predict_trajectory

    config = SweepConfig(settings=((50, 100),), convention=conventions.get("published"))
    trajs = load(path, n + 1)
    solve = {"cpu": 0.0, "calls": 0}
    call = problem._BufferedCall.__call__

    def timed(self, *args):
        s = time.process_time()
        try:
            return call(self, *args)
        finally:
            solve["cpu"] += time.process_time() - s
            solve["calls"] += 1

    predict_trajectory(trajs[0], config)  # NLP set-up and the compiled functions loaded once, outside the timing
    problem._BufferedCall.__call__ = timed
    try:
        s = time.process_time()
        for t in trajs[1:]:
            predict_trajectory(t, config)
        total = (time.process_time() - s) / (len(trajs) - 1)
    finally:
        problem._BufferedCall.__call__ = call
    fatrop = solve["cpu"] / (len(trajs) - 1)
    print(f"published (50, 100), {len(trajs) - 1} trajectories, {solve['calls'] / (len(trajs) - 1):.0f} OC windows each: "
          f"{total:.3f} s CPU per trajectory, of which fatrop (with stats) {fatrop:.3f} s ({100 * fatrop / total:.0f} %), "
          f"the rest {total - fatrop:.3f} s")
    print(f"400 trials on 2 cores, start-up and tables left out: {400 * total / 2:.0f} s wall at best; the solves alone "
          f"{400 * fatrop / 2:.0f} s: {400 * fatrop / 2 / target:.2f} of the {target:.0f} s target")


def bench_stats(path: Path, n: int, convention: str) -> None:
    """The (50, 100) sweep of ``convention`` with the OC solves reading the solver's stats (before) and not
    (after: ``WalkerOCP.solve(stats=False)``, what the predictor does), alternated per trajectory in one
    process; CPU per trajectory, the ratio, and whether the rows are identical."""
    from cobot_analysis import conventions
    from cobot_analysis.models.oc.problem import WalkerOCP
    from cobot_analysis.models.prediction.sweep import SweepConfig, predict_trajectory

    config = SweepConfig(settings=((50, 100),), convention=conventions.get(convention))
    trajs = load(path, n + 1)
    solve = WalkerOCP.solve

    def with_stats(self, *args, **kw):
        return solve(self, *args, **{**kw, "stats": True})

    def run(t, before: bool):
        WalkerOCP.solve = with_stats if before else solve
        try:
            s = time.process_time()
            rows = predict_trajectory(t, config)
            return time.process_time() - s, rows
        finally:
            WalkerOCP.solve = solve

    run(trajs[0], False), run(trajs[0], True)  # NLP set-up and the compiled functions loaded once, outside the timing
    before, after, same = [], [], True
    for i, t in enumerate(trajs[1:]):  # alternated: the load hits both alike
        for b in ((True, False) if i % 2 == 0 else (False, True)):
            cpu, rows = run(t, b)
            (before if b else after).append((cpu, rows))
        same &= all(x.equals(y) for x, y in zip(before[-1][1], after[-1][1]))
    b, a = np.mean([c for c, _ in before]), np.mean([c for c, _ in after])
    print(f"{convention} (50, 100), {len(trajs) - 1} trajectories: stats read {b:.3f} s CPU per trajectory, not read {a:.3f} s: "
          f"ratio {a / b:.3f} (per trajectory {', '.join(f'{x[0] / y[0]:.2f}' for x, y in zip(after, before))}); rows identical: {same}")


def bench_goal(trajs, weights: str | None = None, name: str = "goal", turn_weight: float | None = None) -> None:
    """A goal-aware predictor (``goal``: each trajectory's design goal; ``goal-inferred``: the study's candidate
    goals): windows per second of CPU time, one core; ``turn_weight``: the identified a3, as the stage uses it."""
    from cobot_analysis.models.prediction.predictor import make_predictor
    from cobot_analysis.models.prediction.sweep import SweepConfig, predictor_options

    config = SweepConfig(settings=((50, 100),), predictors=(name,), weights=weights, turn_weight=turn_weight)
    times, failed = [], 0
    for t in trajs:
        p = make_predictor(name, 50, 100, t.dt, **predictor_options(name, t, config))
        for pose in t.seen:
            s = time.process_time()
            path = p.update(pose)
            if path is not None or len(p._past) == p.n0:
                times.append(time.process_time() - s)
        failed += p.failed
    times = np.array(times)
    print(f"{name} ({weights or 'entity preset'}{f', a3 {turn_weight:.3g}' if turn_weight else ''}): {len(times)} windows, {1 / times.mean():.0f} windows/s (mean {1e3 * times.mean():.2f} ms, "
          f"median {1e3 * np.median(times):.2f} ms, p95 {1e3 * np.percentile(times, 95):.2f} ms, max {1e3 * times.max():.0f} ms), failed {failed}")


def bench_goal_predictors(walking: Path, pairs: Path | None, n: int, weights: str | None) -> None:
    """``goal`` on n walking trials (``weights``, else walking-2021); with ``pairs``, ``goal`` and ``goal-inferred``
    on n table means (table-2022)."""
    from cobot_analysis.models.prediction.sweep import SweepConfig, trajectories_from_table
    from cobot_analysis.schema import TRAJECTORIES, read_table

    from cobot_analysis.api.prediction import with_turn_weight

    s = time.process_time()
    walk_config = with_turn_weight(SweepConfig(settings=((50, 100),), predictors=("goal",), weights=weights), read_table(walking, TRAJECTORIES))
    print(f"a3 of the goal plans identified on the walking means: {walk_config.turn_weight:.3g} ({time.process_time() - s:.1f} s CPU)")
    bench_goal(load(walking, n), weights, turn_weight=walk_config.turn_weight)
    if pairs is not None:
        df = read_table(pairs, TRAJECTORIES)
        tables = trajectories_from_table(df[df["entity"] == "table"], SweepConfig(settings=((50, 100),)))
        tables = tables[:: max(1, len(tables) // n)][:n]
        bench_goal(tables)
        bench_goal(tables, name="goal-inferred")


def bench_stages(walking: Path, pairs: Path | None, n: int, weights: str | None) -> None:
    """CPU per trajectory (``time.process_time``, one process) of each prediction stage's work on n
    trajectories after a warm-up one; the predict-goal stages with the horizon sweep by one run per
    predictor (``trajectory_runs`` over the whole path: what the stage does) and by two (the settings,
    then ``trajectory_horizons`` predicting again: before), alternated per trajectory."""
    from cobot_analysis import conventions
    from cobot_analysis.api.prediction import with_turn_weight
    from cobot_analysis.models.prediction.horizons import HORIZONS, horizon_rows
    from cobot_analysis.models.prediction.sweep import trajectory_horizons
    from cobot_analysis.models.prediction.sweep import (SweepConfig, predict_trajectory, setting_rows, trajectories_from_table,
                                                        trajectory_runs)
    from cobot_analysis.schema import TRAJECTORIES, read_table

    def shared(t, c):
        runs = trajectory_runs(t, c, 50)
        return setting_rows(t, c, runs), horizon_rows(t, c, 50, HORIZONS, runs)

    def separate(t, c):
        return predict_trajectory(t, c), trajectory_horizons(t, c, 50, HORIZONS)

    def cpu(f, t, c):
        s = time.process_time()
        f(t, c)
        return time.process_time() - s

    walk = read_table(walking, TRAJECTORIES)
    published = conventions.get("published")
    cases = [("predict (4 settings, continuous)", SweepConfig(), walk, "walker", None),
             ("predict-published (4 settings)", SweepConfig(convention=published), walk, "walker", None),
             ("predict-goal walking (oc,goal,cv,ctrv + horizons)",
              SweepConfig(settings=((50, 100),), predictors=("oc", "goal", "cv", "ctrv"), weights=weights), walk, "walker", True)]
    if pairs is not None:
        cases.append(("predict-goal pairs (oc,goal,goal-inferred,cv,ctrv + horizons)",
                      SweepConfig(settings=((50, 100),), predictors=("oc", "goal", "goal-inferred", "cv", "ctrv")),
                      read_table(pairs, TRAJECTORIES), "table", True))
    for label, config, table, entity, horizons in cases:
        config = with_turn_weight(config, table, entities=[entity])  # as the stage
        df = table[(table["entity"] == entity) & ((table["kind"] == "trial") if entity == "walker" else True)]
        trajs = trajectories_from_table(df, config)
        trajs = trajs[:: max(1, len(trajs) // (n + 1))][: n + 1]
        if not horizons:
            predict_trajectory(trajs[0], config)  # NLP set-up and the compiled functions loaded once, outside the timing
            per = sum(cpu(predict_trajectory, t, config) for t in trajs[1:]) / n
            print(f"{label}: {per:.3f} s CPU per trajectory ({len(trajs) - 1} trajectories)")
            continue
        shared(trajs[0], config)
        one, two = [], []
        for i, t in enumerate(trajs[1:]):  # alternated: the load hits both alike
            order = (shared, separate) if i % 2 == 0 else (separate, shared)
            for f in order:
                (one if f is shared else two).append(cpu(f, t, config))
        print(f"{label}: one run {np.mean(one):.3f} s CPU per trajectory, two runs (before) {np.mean(two):.3f} s: "
              f"ratio {np.mean(one) / np.mean(two):.2f} (per trajectory {', '.join(f'{a / b:.2f}' for a, b in zip(one, two))})")


def bench_horizons(walking: Path, pairs: Path | None, every: int, jobs: int) -> None:
    """Wall time of the horizon sweep (N0 = 50, horizons 5..200 and the whole path) of oc, goal, cv, ctrv on the
    walking trials (every ``every``-th) and, with goal-inferred too, on the pair study's table means."""
    from cobot_analysis.api.prediction import with_turn_weight
    from cobot_analysis.models.prediction.sweep import horizon_sweep
    from cobot_analysis.models.prediction.sweep import SweepConfig, trajectories_from_table
    from cobot_analysis.schema import TRAJECTORIES, read_table

    for path, entity, predictors in ((walking, "walker", ("oc", "goal", "cv", "ctrv")),
                                     (pairs, "table", ("oc", "goal", "goal-inferred", "cv", "ctrv"))):
        if path is None:
            continue
        table = read_table(path, TRAJECTORIES)
        df = table[(table["entity"] == entity) & ((table["kind"] == "trial") if entity == "walker" else True)]
        config = with_turn_weight(SweepConfig(settings=((50, 100),), predictors=predictors), table, entities=[entity])  # as the stage
        trajs = trajectories_from_table(df, config)[::every]
        s = time.perf_counter()
        horizon_sweep(trajs, config, 50, jobs=jobs)
        print(f"horizon sweep {path.parent.name} {len(trajs)} trajectories x {len(predictors)} predictors, -j {jobs}: "
              f"wall {time.perf_counter() - s:.0f} s, load average after {os.getloadavg()[0]:.1f}")


def bench_sweep(path: Path, out: Path, dask: bool, limit: int | None, every: int = 1, convention: str = "continuous",
                predictors: str = "oc,cv,ctrv") -> None:
    from cobot_analysis.cli import run

    shutil.rmtree(out / ".predict-work", ignore_errors=True)
    argv = ["-q", "predict", "--out", str(out), "--trajectories", str(path), "--kind", "trial", "--settings", "50:100",
            "--convention", convention, "--predictors", predictors, "--force", "--every", str(every), *(["--limit", str(limit)] if limit else [])]
    if dask:
        from distributed import LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            s = time.perf_counter()
            code = run([*argv, "--scheduler", cluster.scheduler_address])
            wall = time.perf_counter() - s
    else:
        s = time.perf_counter()
        code = run([*argv, "--jobs", "2"])
        wall = time.perf_counter() - s
    cpu = sum(os.times()[:4])  # this process and its finished children (the pool's workers)
    print(f"sweep (50,100) {predictors}, {convention} convention, {'dask 2 workers' if dask else 'local pool -j 2'}: exit {code}, "
          f"wall {wall:.0f} s, CPU {cpu:.0f} s, load average after {os.getloadavg()[0]:.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    w = sub.add_parser("windows")
    w.add_argument("trajectories", type=Path)
    w.add_argument("--n", type=int, default=6)
    w.add_argument("--convention", choices=("continuous", "published"), default="continuous")
    f = sub.add_parser("published-floor")
    f.add_argument("trajectories", type=Path)
    f.add_argument("--n", type=int, default=6)
    f = sub.add_parser("stats")
    f.add_argument("trajectories", type=Path)
    f.add_argument("--n", type=int, default=6)
    f.add_argument("--convention", choices=("continuous", "published"), default="published")
    s = sub.add_parser("sweep")
    s.add_argument("trajectories", type=Path)
    s.add_argument("--out", type=Path, required=True)
    s.add_argument("--dask", action="store_true")
    s.add_argument("--limit", type=int)
    s.add_argument("--every", type=int, default=1)
    s.add_argument("--convention", choices=("continuous", "published"), default="continuous")
    s.add_argument("--predictors", default="oc,cv,ctrv")
    g = sub.add_parser("goal")
    g.add_argument("walking", type=Path)
    g.add_argument("--pairs", type=Path)
    g.add_argument("--n", type=int, default=6)
    g.add_argument("--weights")
    st = sub.add_parser("stages")
    st.add_argument("walking", type=Path)
    st.add_argument("--pairs", type=Path)
    st.add_argument("--n", type=int, default=3)
    st.add_argument("--weights")
    h = sub.add_parser("horizons")
    h.add_argument("walking", type=Path)
    h.add_argument("--pairs", type=Path)
    h.add_argument("--every", type=int, default=1)
    h.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    print(f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, load average "
          f"{', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    if a.what == "windows":
        bench_windows(a.trajectories, a.n, a.convention)
    elif a.what == "published-floor":
        bench_published_floor(a.trajectories, a.n)
    elif a.what == "stats":
        bench_stats(a.trajectories, a.n, a.convention)
    elif a.what == "goal":
        bench_goal_predictors(a.walking, a.pairs, a.n, a.weights)
    elif a.what == "stages":
        bench_stages(a.walking, a.pairs, a.n, a.weights)
    elif a.what == "horizons":
        bench_horizons(a.walking, a.pairs, a.every, a.jobs)
    else:
        bench_sweep(a.trajectories, a.out, a.dask, a.limit, a.every, a.convention, a.predictors)


if __name__ == "__main__":
    main()
