"""Benchmarks of the walking OC solver and the IOC (docs/benchmarks.md, "OC and IOC").

    python benchmarks/bench_models.py solver            # compiled vs VM; cold / warm / window / crocoddyl
    python benchmarks/bench_models.py ioc --data ../shared/datasets/walking-2020 [--subjects 10]
    python benchmarks/bench_models.py grid --means WS/average/means.parquet [--pairs]   # the Mombaur grid's solves

Prints a Markdown block with the machine, the load average and the date. The IOC part runs the CLI
(import-published, then fit-ioc) in a temporary workspace.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

GOAL = (0.0, 0.0, math.pi / 2)
#: how the timed 500/100/50-node problems reach the goal (``OCPShape.goal``). Since the continuous convention made the
#: goal pose at rest a terminal constraint (2dbdb73), ``solve_model`` (which gives T* here) solves that problem;
#: "cost" times the b0..b3 terminal-cost problem of the 2026-11-22 figures, at the constrained problem's T*.
SHAPE_GOAL = "constraint"
#: 6 start poses of the walking design (global distance 1.6 to 5.5 m, the four orientations)
STARTS = [(-1.5, -3.4, 0.0), (-4.0, 0.6, math.pi), (-4.0, -3.4, math.pi / 2), (-0.6, -1.5, -math.pi / 2),
          (-1.5, 0.0, 0.0), (-4.0, -0.9, -math.pi / 2)]


def header() -> str:
    load = os.getloadavg()
    return (f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
            f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC; load average at start {load[0]:.1f} / {load[1]:.1f} "
            f"(1 / 5 min; other jobs shared the 2 cores)")


def timed(fn, repeat=5):
    """Median CPU time of ``fn()`` (``time.process_time``: the solvers are single-threaded, so on a
    machine shared with other jobs this is what an idle core would take; wall time is load-bound)."""
    ts, out = [], None
    for _ in range(repeat):
        t = time.process_time()
        out = fn()
        ts.append(time.process_time() - t)
    return statistics.median(ts), out


def bench_solver(n_nodes=(500, 100, 50)) -> str:
    from cobot_analysis.models.oc import solve_model
    from cobot_analysis.models.oc.problem import OCPShape, get_ocp
    from cobot_analysis.models.presets import PRESETS, weights_vector

    w = weights_vector(PRESETS["walking-2021"])
    w_near = w * np.r_[1.0, 1.05, 0.95, 1.0, 1.05, 1, 1, 0.95, 1.05, 1.0, 1.0]  # ~5 % change
    rows = []
    Ts = {s: solve_model("improved", s, GOAL, w, n_intervals=100).T for s in STARTS}
    for n in n_nodes:
        t = time.perf_counter()
        ocp = get_ocp(OCPShape(n, goal=SHAPE_GOAL))
        build = time.perf_counter() - t
        free = get_ocp(OCPShape(n, free_time=True, goal=SHAPE_GOAL))
        cold, warm, cold_free, warm_free, its = [], [], [], [], []
        for s in STARTS:
            dt, sol = timed(lambda: ocp.solve(s, GOAL, w, Ts[s], guess="rest"))
            cold.append(dt)
            its.append(sol.iterations)
            warm.append(timed(lambda: ocp.solve(s, GOAL, w_near, Ts[s], guess=sol.primal))[0])
            dt, fs = timed(lambda: free.solve(s, GOAL, w, Ts[s], guess="rest"), 3)
            cold_free.append(dt)
            warm_free.append(timed(lambda: free.solve(s, GOAL, w_near, Ts[s], guess=fs.primal))[0])
        rows.append(f"| {n} | {build:.2f} | {1e3 * statistics.median(cold):.1f} ({1e3 * min(cold):.0f}-{1e3 * max(cold):.0f}) | "
                    f"{statistics.median(its):.0f} | {1e3 * statistics.median(warm):.1f} | {1e3 * statistics.median(cold_free):.1f} | "
                    f"{1e3 * statistics.median(warm_free):.1f} |")
    out = ["Improved model, walking-2021 weights, 6 start poses, fatrop, medians of CPU time per solve (ms):", "",
           "| nodes | build (s) | cold, fixed T* (min-max) | iterations | warm, 5 % weight change | cold, free T | warm, free T |",
           "|---|---|---|---|---|---|---|", *rows, ""]
    # receding-horizon window (prediction): 100 nodes, tracking on the first 50, free end, warm from the shifted window
    ocp = get_ocp(OCPShape(100))
    wp = np.array([7.9, 4.0, 20.1, 1e-6, 0, 0, 0, 0, 0, 0, 0])
    ref = solve_model("improved", STARTS[0], GOAL, w, n_intervals=400)
    dtw = ref.T / 400
    times, prev = [], "rest"
    for k in range(0, 300, 5):
        track = np.c_[ref.X[k:k + 50, :3]]
        x0 = ref.X[k]
        t = time.process_time()
        sol = ocp.solve(x0[:3], (50.0, 50.0, 0.0), wp, 100 * dtw, guess=prev, start_velocity=x0[3:], track=track)
        times.append(time.process_time() - t)
        prev = sol.primal
    out += [f"Receding-horizon window (100 nodes, tracking on 50, warm from the previous window), CPU time: median "
            f"{1e3 * statistics.median(times):.1f} ms, p95 {1e3 * np.percentile(times, 95):.1f} ms, "
            f"{1 / statistics.median(times):.0f} windows/s per core.", ""]
    # crocoddyl on the same problems
    try:
        from cobot_analysis.models.oc import crocoddyl_backend as cb
    except ImportError:
        cb = None
    if cb is not None and cb.available():
        ocp = get_ocp(OCPShape(500))
        ratio, rows = [], []
        for s in STARTS:
            tc, sol = timed(lambda: ocp.solve(s, GOAL, w, Ts[s], guess="rest"), 3)
            tk, res = timed(lambda: cb.solve(s, GOAL, w, Ts[s], n_intervals=500), 1)
            ratio.append(tk / tc)
            rows.append(f"| {s[0]:.1f}, {s[1]:.1f}, {s[2]:.2f} | {1e3 * tc:.0f} | {1e3 * tk:.0f} | {sol.cost:.6f} | {res[2]:.6f} | "
                        f"{1e3 * np.hypot(*(res[0][:, :2] - sol.X[:, :2]).T).max():.3f} |")
        out += ["Same problems (500 nodes, fixed T*), casadi+fatrop vs crocoddyl FDDP (Python action model), cold from rest, CPU time:", "",
                "| start | fatrop (ms) | crocoddyl (ms) | cost fatrop | cost crocoddyl | max path distance (mm) |",
                "|---|---|---|---|---|---|", *rows, "",
                f"crocoddyl / fatrop time ratio: median {statistics.median(ratio):.1f}.", ""]
    return "\n".join(out)


def bench_backends(n: int = 500, repeat: int = 9) -> str:
    """Compiled NLP functions vs casadi's SX virtual machine (``ocp.py``) on the same 6 problems,
    measured interleaved (each repeat runs both backends back to back, so both see the same load),
    and where the time of a compiled solve goes (fatrop's own timers)."""
    from cobot_analysis.models.oc import solve_model
    from cobot_analysis.models.oc.problem import OCPShape, WalkerOCP, get_ocp
    from cobot_analysis.models.presets import PRESETS, weights_vector

    w = weights_vector(PRESETS["walking-2021"])
    w_near = w * np.r_[1.0, 1.05, 0.95, 1.0, 1.05, 1, 1, 0.95, 1.05, 1.0, 1.0]
    Ts = {s: solve_model("improved", s, GOAL, w, n_intervals=100).T for s in STARTS}
    saved = {k: os.environ.get(k) for k in ("COBOT_ANALYSIS_OCP_COMPILE", "COBOT_ANALYSIS_CACHE")}
    ocps, build = {}, {}
    with tempfile.TemporaryDirectory() as cache:
        for label, flag in (("vm", "0"), ("first", "1"), ("cc", "1")):  # "first" compiles, "cc" loads the cached library
            os.environ["COBOT_ANALYSIS_OCP_COMPILE"], os.environ["COBOT_ANALYSIS_CACHE"] = flag, cache
            get_ocp.cache_clear()  # guess="coarse" solves on get_ocp's 50-interval problem: compiled too
            t = time.perf_counter()
            ocps[label] = WalkerOCP(OCPShape(n, goal=SHAPE_GOAL))
            build[label] = time.perf_counter() - t
        del ocps["first"]
        cases = {("vm", "cold"), ("vm", "warm"), ("vm", "zero"), ("cc", "cold"), ("cc", "warm"), ("cc", "zero"), ("cc", "coarse")}
        times = {c: [] for c in cases}  # per case: per start, the list of repeats
        its, parts, same = {"vm": [], "cc": []}, {}, 0
        for s in STARTS:
            for c in cases:
                times[c].append([])
            for r in range(repeat):
                for b, ocp in ocps.items():
                    t = time.process_time()
                    sol = ocp.solve(s, GOAL, w, Ts[s], guess="rest")
                    times[b, "cold"][-1].append(time.process_time() - t)
                    if b == "cc" and r == 0:
                        st = ocp._call("fatrop").buffer.stats()["fatrop"]
                        for k in ("compute_sd_time", "initialization_time", "eval_hess_time", "eval_jac_time",
                                  "eval_grad_time", "eval_obj_time", "eval_cv_time"):
                            parts.setdefault(k, []).append(st[k] / st["time_total"])
                    if r == 0:
                        its[b].append(sol.iterations)
                    for case, kw in (("warm", dict(weights=w_near, guess=sol.primal)), ("zero", dict(weights=w, guess=sol.primal)),
                                     ("coarse", dict(weights=w, guess="coarse"))):
                        if (b, case) in cases:
                            t = time.process_time()
                            other = ocp.solve(s, GOAL, T=Ts[s], **kw)
                            times[b, case][-1].append(time.process_time() - t)
                            same += case == "coarse" and r == 0 and abs(other.cost - sol.cost) < 1e-6 * sol.cost
    get_ocp.cache_clear()
    for k, v in saved.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v

    def cell(b, case):  # median over starts of the per-start median / minimum over the repeats
        if (b, case) not in times:
            return ""
        return (f"{1e3 * statistics.median(statistics.median(x) for x in times[b, case]):.1f} / "
                f"{1e3 * statistics.median(min(x) for x in times[b, case]):.1f}")

    rows = [f"| SX virtual machine (as before; same call path) | {build['vm']:.2f} | {cell('vm', 'cold')} | {statistics.median(its['vm']):.0f} | "
            f"{cell('vm', 'warm')} | {cell('vm', 'zero')} | |",
            f"| compiled stage functions | {build['cc']:.2f} ({build['first']:.2f} with the compilation) | {cell('cc', 'cold')} | "
            f"{statistics.median(its['cc']):.0f} | {cell('cc', 'warm')} | {cell('cc', 'zero')} | {cell('cc', 'coarse')} |"]
    share = {k: 100 * statistics.median(v) for k, v in parts.items()}
    evals = sum(share[k] for k in ("eval_hess_time", "eval_jac_time", "eval_grad_time", "eval_obj_time", "eval_cv_time"))
    return "\n".join([
        f"{n} nodes, improved model, walking-2021 weights, 6 start poses, fatrop, CPU time per solve (ms): median over the starts "
        f"of the per-start median / minimum over {repeat} repeats (the minimum is what a less loaded core gives). "
        "'at the solution' = a solve started at its own solution (0 iterations: the fixed cost of a call); "
        f"guess='coarse' reached the rest-guess optimum on {same} of {len(STARTS)} starts:", "",
        "| NLP functions | build (s) | cold, fixed T* | iterations | warm, 5 % weight change | at the solution | cold, guess='coarse' |",
        "|---|---|---|---|---|---|---|", *rows, "",
        f"Where fatrop's time goes in a compiled cold solve (fatrop's own timers, median share over the 6 starts): "
        f"search directions (Riccati factorisations and solves, blasfeo) {share['compute_sd_time']:.0f} %, "
        f"initialisation (least-squares multiplier estimate: one more factorisation) {share['initialization_time']:.0f} %, "
        f"function evaluations incl. copying them into fatrop's blocks {evals:.0f} %, "
        f"rest (line search, residuals) {100 - share['compute_sd_time'] - share['initialization_time'] - evals:.0f} %.", ""])


def run_cli(args, cwd) -> tuple[float, float]:
    """Wall time and CPU time (the command and its worker processes) of one CLI run."""
    import resource

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "cobot_analysis", "-q", *args], cwd=cwd, check=True)
    wall = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def bench_ioc(data: Path, subjects: int, max_evaluations: int, subject_evaluations: int) -> str:
    import json

    out = []
    with tempfile.TemporaryDirectory() as tmp:
        ws = Path(tmp) / "ws"
        run_cli(["import-published", "walking-2020", str(data), "--out", str(ws)], tmp)
        for label, start in (("published weights (walking-2021)", "walking-2021"), ("neutral start (all ones)", "ones")):
            dt, cpu = run_cli(["fit-ioc", "--out", str(ws), "--start-weights", start, "--no-compare", "--force",
                               "--max-evaluations", str(max_evaluations), "-j", "2"], tmp)
            fitted = json.loads((ws / "fit-ioc" / "weights.json").read_text())["fits"]["all"]
            out.append(f"| full IOC, 37 means, from {label} | {dt / 60:.1f} min | {cpu / 60:.1f} min | {fitted['evaluations']} evaluations, "
                       f"{fitted['iterations']} Powell iterations, D {fitted['start_objective']:.4f} -> {fitted['objective']:.4f} |")
        if subjects:
            dt, cpu = run_cli(["fit-ioc", "--out", str(ws), "--per", "subject", "--subjects", str(subjects), "--no-compare", "--force",
                               "--max-evaluations", str(subject_evaluations), "-j", "2"], tmp)
            fits = json.loads((ws / "fit-ioc-subjects" / "weights.json").read_text())["fits"]
            d = [f["objective"] for f in fits.values()]
            ev = [f["evaluations"] for f in fits.values()]
            out.append(f"| {len(fits)} per-subject fits (budget {subject_evaluations} evaluations each) | {dt / 60:.1f} min | {cpu / 60:.1f} min | "
                       f"{sum(ev)} evaluations, D median {statistics.median(d):.4f} |")
    return "\n".join(["| run | wall time | CPU time (all processes) | result |", "|---|---|---|---|", *out, ""])


def bench_grid(means: Path, pairs: bool) -> str:
    """Every solve of the Mombaur model's duration grid (``duration.grid_duration``) as fit-ioc's model comparison
    runs it on the continuous convention (the walking means' design goal, or with ``pairs`` each table mean's last
    pose; both cold guesses, 21 horizons each): how many fatrop solves converge and in how many iterations, how many
    the IPOPT fallback rescues, how many fail both, and the CPU time of each (``time.process_time``)."""
    import pandas as pd

    from cobot_analysis.api.models import pair_cases, walking_cases
    from cobot_analysis.models.oc import problem, solve_model
    from cobot_analysis.models.presets import load_weights, weights_vector

    table = pd.read_parquet(means)
    cases = pair_cases("continuous", table)[0] if pairs else walking_cases("continuous", table)
    w = weights_vector(load_weights("mombaur-2010", "improved"))
    calls = []  # (fatrop?, converged, iterations, CPU s) of every solver call, in order
    call = problem._BufferedCall.__call__

    def timed(self, *args, **kw):
        t = time.process_time()
        out = call(self, *args, **kw)
        calls.append((self.raises, bool(out[2].get("success")), int(out[2].get("iter_count", -1)), time.process_time() - t))
        return out

    problem._BufferedCall.__call__ = timed
    try:
        for _, start, goal in cases:
            solve_model("mombaur", start, goal, w, convention="continuous", guess=("rest", "line"))  # as generate
    finally:
        problem._BufferedCall.__call__ = call
    solves = []  # per solve: the fatrop call and the IPOPT call after it, if any
    for c in calls:
        if c[0]:
            solves.append([c])
        else:
            solves[-1].append(c)
    converged = [s[0] for s in solves if s[0][1]]
    rescued = [s for s in solves if not s[0][1] and s[-1][1]]
    failed = [s for s in solves if not s[-1][1]]
    its = sorted(c[2] for c in converged)
    cpu = lambda rows: sum(c[3] for c in rows)  # noqa: E731
    return "\n".join([
        f"{len(cases)} {'table means' if pairs else 'walking means'}, {len(solves)} grid solves", "",
        "| solves | count | iterations | CPU s |", "|---|---|---|---|",
        f"| fatrop converged | {len(converged)} | median {its[len(its) // 2]}, 99th percentile {its[int(0.99 * len(its))]}, "
        f"max {its[-1]} (fatrop's cap {problem.OCPShape().max_iter}) | {cpu(converged):.1f} |",
        f"| fatrop failed, IPOPT converged | {len(rescued)} | IPOPT max {max((s[1][2] for s in rescued), default=0)} | "
        f"{cpu(s[0] for s in rescued):.1f} + {cpu(s[1] for s in rescued):.1f} |",
        f"| both failed | {len(failed)} | fatrop max {max((s[0][2] for s in failed), default=0)}, IPOPT max "
        f"{max((s[-1][2] for s in failed), default=0)} | {cpu(s[0] for s in failed):.1f} + {cpu(s[1] for s in failed if len(s) > 1):.1f} |",
        ""])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["solver", "ioc", "grid", "all"])
    ap.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[2] / "shared" / "datasets" / "walking-2020")
    ap.add_argument("--subjects", type=int, default=10)
    ap.add_argument("--max-evaluations", type=int, default=600)
    ap.add_argument("--subject-evaluations", type=int, default=100)
    ap.add_argument("--goal", choices=["constraint", "cost"], default=SHAPE_GOAL,
                    help="solver: the goal as a terminal constraint (the continuous convention's problem) or as a cost")
    ap.add_argument("--means", type=Path, help="grid: the means table (average/means.parquet of a workspace)")
    ap.add_argument("--pairs", action="store_true", help="grid: the means are the pair study's (its table means' poses)")
    a = ap.parse_args()
    if a.what == "grid" and a.means is None:
        ap.error("grid needs --means")
    globals()["SHAPE_GOAL"] = a.goal
    print(header() + f"; OC problems with the goal as a {a.goal}", "\n")
    if a.what in ("solver", "all"):
        print(bench_backends(), flush=True)
        print(bench_solver(), flush=True)
    if a.what in ("ioc", "all"):
        print(bench_ioc(a.data, a.subjects, a.max_evaluations, a.subject_evaluations), flush=True)
    if a.what == "grid":
        print(bench_grid(a.means, a.pairs), flush=True)


if __name__ == "__main__":
    main()
