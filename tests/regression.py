"""Metric regression: run each study's pipeline into fresh workspaces, then compare its stage
metrics with the committed baseline (``cobot-analysis metrics check``), or rewrite the baseline.

    python tests/regression.py                 # every study; exit 1 if a metric moved, 2 on bad input
    python tests/regression.py walking-2020    # one study
    python tests/regression.py --update        # rewrite the baselines, printing every change
    python tests/regression.py --verbose       # also every step (with its wall and CPU time) and every metric's row

By default a check prints only what failed (the failing step, or the rows of the metrics that are not
ok) and, at the end, one line per study with its counts.

The published studies need ``../shared/datasets`` (or ``$COBOT_DATASETS``) and are skipped, saying
so, without it. Steps run in-process, exactly as typed on the command line (``cobot_analysis.cli.run``).
Model stages run in one workspace per OC convention (``<study>-models-<convention>``) on the
analysis workspace's tables: their metrics carry the convention, and a baseline holds both.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import resource
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from conftest import datasets_dir  # tests/ is on sys.path, as a script and under pytest

ROOT = Path(__file__).resolve().parents[1]
BASELINES = ROOT / "tests" / "baselines"

#: OC conventions the model stages run under (docs/methods.md sec. 11), with the options that select
#: each; each runs its model stages in its own workspace (``<study>-models-<convention>``).
CONVENTIONS: dict[str, list[str]] = {"continuous": ["--convention", "continuous"], "published": ["--convention", "published"]}

Steps = list[list[str]]


@dataclass(frozen=True)
class Study:
    """A baseline and how to produce its workspaces: ``plan(root, datasets, jobs) -> (workspaces, steps)``."""
    baseline: str
    plan: Callable[[Path, Path | None, list[str]], tuple[list[Path], Steps]]
    needs_datasets: bool = False


def _synthetic(which: str):
    def plan(root: Path, datasets: Path | None, j: list[str]) -> tuple[list[Path], Steps]:
        from cobot_analysis.cli.pipeline import demo_steps

        out = root / "synthetic"
        return [out / which], demo_steps(out, "small", int(j[1]))[which]  # the README's demo, small size
    return plan


def _localisation(root: Path, datasets: Path | None, j: list[str]) -> tuple[list[Path], Steps]:
    ws = root / "localisation"
    return [ws], [["synth", "localisation", "--out", str(ws), "--goals-per-lap", "3"],
                  ["localisation", "--out", str(ws), "--map-name", "synthetic", *j]]


def _walking(root: Path, datasets: Path | None, j: list[str]) -> tuple[list[Path], Steps]:
    ws = root / "walking-2020"
    steps = [["import-published", "walking-2020", str(datasets / "walking-2020"), "--out", str(ws)],
             ["average", "--out", str(ws)], ["compare", "--out", str(ws)], ["stats", "--out", str(ws)]]
    tables = ["--means", str(ws / "average" / "means.parquet"), "--trajectories", str(ws / "import-published" / "trajectories.parquet")]
    workspaces = [ws]
    published_means = ["--means", tables[3], "--trajectories", tables[3]]  # the authors' mean block
    for conv, options in CONVENTIONS.items():
        m = root / f"walking-2020-models-{conv}"
        workspaces.append(m)
        if conv == "published":  # a short fit (its rule-chosen horizons are long), the preset's paths, prediction
            steps += [["fit-ioc", "--out", str(m), *published_means, "--max-evaluations", "3", "--no-compare", *options, *j],
                      ["generate", "--out", str(m), "--study", "walking-2020", "--weights", "walking-2021", "--means", tables[3],
                       *options, *j],
                      ["compare", "--out", str(m), *tables, "--against", str(m / "generate-published" / "generated.parquet"),
                       "--comparison", "model", *options]]
        else:
            # no profile likelihoods: this short fit's disputed a2 would cost ~50 s of CPU to profile (.ci/run has
            # none to spare); the profiles are checked by tests/test_ioc_profile.py and tests/test_ioc_wiring.py
            steps += [["fit-ioc", "--out", str(m), *tables, "--max-evaluations", "20", "--profiles", "none", *options, *j],
                      # the single-level method beside it (its D and weights guarded): one feasible-path step per
                      # round on the 20-interval grid, no bootstrap
                      ["fit-ioc", "--out", str(m), *tables, "--method", "single-level", "--max-evaluations", "1", "--intervals", "20",
                       "--bootstrap", "0", "--no-compare", *options, *j],
                      ["generate", "--out", str(m), "--study", "walking-2020", "--weights", str(m / "fit-ioc" / "weights.json"),
                       *options, *j],
                      # the goal-aware predictor to the design goal, with the weights fitted just above
                      ["predict", "--out", str(m), tables[2], tables[3], "--kind", "trial", "--every", "40", "--settings", "50:100",
                       "--predictors", "goal,cv", "--weights", str(m / "fit-ioc" / "weights.json"), "--stage-name", "predict-goal",
                       *options, *j]]
        steps += [["predict", "--out", str(m), tables[2], tables[3], "--kind", "trial", "--every", "40", "--settings", "50:100",
                   *options, *j]]
    return workspaces, steps


def _pairs(root: Path, datasets: Path | None, j: list[str]) -> tuple[list[Path], Steps]:
    ws, data = root / "pair-carriage-2022", datasets / "pair-carriage-2022"
    steps = [["import-published", "pair-carriage-2022", str(data), "--out", str(ws)],
             ["average", "--out", str(ws)], ["compare", "--out", str(ws)], ["stats", "--out", str(ws)],
             ["reconstruct", "--out", str(ws), "--wrt-table", str(data)]]
    tables = ["--means", str(ws / "average" / "means.parquet"), "--trajectories", str(ws / "import-published" / "trajectories.parquet")]
    workspaces = [ws]
    for conv, options in CONVENTIONS.items():
        m = root / f"pair-carriage-2022-models-{conv}"
        workspaces.append(m)
        if conv == "published":  # the table model only (the coupled model has no published convention here)
            steps += [["fit-ioc", "--out", str(m), "--means", tables[3], "--trajectories", tables[3], "--model", "table",
                       "--max-evaluations", "3", "--no-compare", *options, *j]]
        else:
            steps += [["fit-ioc", "--out", str(m), *tables, "--model", "table", "--max-evaluations", "20", *options, *j],
                      ["fit-ioc", "--out", str(m), *tables, "--model", "coupled", "--max-evaluations", "10", *options, *j]]
        steps += [["predict", "--out", str(m), tables[2], tables[3], "--entity", "table", "--every", "10", "--settings", "50:100",
                   *options, *j]]
    return workspaces, steps


STUDIES: dict[str, Study] = {
    "synthetic-walking": Study("synthetic-walking.json", _synthetic("walking")),
    "synthetic-pairs": Study("synthetic-pairs.json", _synthetic("pairs")),
    "localisation": Study("localisation.json", _localisation),
    "walking-2020": Study("walking-2020.json", _walking, needs_datasets=True),
    "pair-carriage-2022": Study("pair-carriage-2022.json", _pairs, needs_datasets=True),
}



def _cpu() -> float:
    """CPU time (user + system, s) of this process and of its ended worker processes."""
    own, workers = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + workers.ru_utime + workers.ru_stime


def run_study(name: str, study: Study, root: Path, datasets: Path | None, jobs: int, update: bool, baselines: Path,
              verbose: bool = False) -> tuple[int, str]:
    """Run one study's steps, then check (or update) its baseline: the exit code of the first failure and
    the summary line of the check ("passed: 1783 metrics: ..."). Quiet unless ``verbose`` or failing:
    the steps are printed with ``verbose`` only (a failing one always), the check's table lists every
    metric with ``verbose``, else only those not ok (nothing at all when every metric passes)."""
    from cobot_analysis.cli import run

    workspaces, steps = study.plan(root, datasets, ["--jobs", str(jobs)])
    for argv in steps:
        if verbose:
            print(f"$ cobot-analysis {' '.join(argv)}", flush=True)
        wall, cpu = time.perf_counter(), _cpu()
        code = run(["-q", *argv])
        if verbose:
            print(f"  ({time.perf_counter() - wall:.1f} s, CPU {_cpu() - cpu:.1f} s with its workers)", flush=True)
        if code != 0:
            print(f"{name}: step failed with exit code {code}: cobot-analysis {' '.join(argv)}", flush=True)
            return code, ""
    check = ["metrics", "update" if update else "check", str(baselines / study.baseline), *map(str, workspaces)]
    if update or verbose:
        code = run(check)
        return code, ""
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        code = run([*check, "--failures-only"])
    lines = printed.getvalue().splitlines()
    last = next((line for line in reversed(lines) if line.startswith(("passed: ", "FAILED: "))), "")
    if code != 0:
        print(f"{name}:\n" + "\n".join(lines), flush=True)
    return code, last.split("; not ok")[0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("studies", nargs="*", choices=[[], *STUDIES], metavar="STUDY", help=f"default: all ({', '.join(STUDIES)})")
    parser.add_argument("--update", action="store_true", help="rewrite the baselines (printing every change) instead of checking")
    parser.add_argument("--verbose", "-v", action="store_true",
                        help="print every step and every metric's row of the check (default: only failures and one line per study)")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes of the heavy stages (default 2)")
    parser.add_argument("--keep", type=Path, help="keep the workspaces in this directory (default: a temporary one, removed)")
    parser.add_argument("--baselines", type=Path, default=BASELINES, help="baseline directory (default tests/baselines)")
    args = parser.parse_args(argv)
    os.environ.setdefault("MPLBACKEND", "Agg")
    datasets = datasets_dir()
    root = args.keep or Path(tempfile.mkdtemp(prefix="cobot-regression-"))
    results: list[tuple[str, str, float, float, str]] = []
    try:
        for name in args.studies or list(STUDIES):
            study = STUDIES[name]
            if study.needs_datasets and datasets is None:
                print(f"{name}: skipped: published datasets not found (set $COBOT_DATASETS or place them in ../shared/datasets)",
                      flush=True)
                results.append((name, "skipped (no datasets)", 0.0, 0.0, ""))
                continue
            if args.update or args.verbose:
                print(f"\n=== {name} ({'update' if args.update else 'check'} {args.baselines / study.baseline})", flush=True)
            t0, cpu0 = time.perf_counter(), _cpu()
            code, counts = run_study(name, study, root, datasets, args.jobs, args.update, args.baselines, args.verbose)
            results.append((name, {0: "passed" if not args.update else "updated", 1: "FAILED"}.get(code, f"error (exit {code})"),
                            time.perf_counter() - t0, _cpu() - cpu0, counts.partition(": ")[2]))
    finally:
        if args.keep is None:
            shutil.rmtree(root, ignore_errors=True)
    print("\nmetric regression:")
    for name, status, seconds, cpu, counts in results:
        print(f"  {name:20s} {status:22s} {seconds:6.1f} s (CPU {cpu:6.1f} s)  {counts}".rstrip())
    failed = [s for _, s, _, _, _ in results if s not in ("passed", "updated", "skipped (no datasets)")]
    return 0 if not failed else 2 if any(s.startswith("error") for s in failed) else 1


if __name__ == "__main__":
    sys.exit(main())
