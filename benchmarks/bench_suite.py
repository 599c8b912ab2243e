"""The test suite a contributor runs, and CI, against the targets of issue 22 point 4.

    python benchmarks/bench_suite.py [--checkout DIR] [--ci] [--serial] [--pytest-args "-x -q"]
    python benchmarks/bench_suite.py --against OLD [--pairs 3] [--pytest-args "-m slow"]

Runs README command 2 (``python -m pytest``, the quick selection) in the checkout (default: this one, with it
first on ``PYTHONPATH``), and with ``--ci`` then ``./.ci/run`` (the quick and the slow selections and the metric
regression; set ``COBOT_DATASETS`` / ``COBOT_REALDATA`` as for CI). Prints for each the wall time, the CPU time of
the command and everything it ran (user + system), the pytest summary line, the exit code and the load average
before and after, against the targets: README command 2 under 2.5 min and ``.ci/run`` under 6 min, on this machine
idle. The targets are absolute, so there is no reference to alternate with: a run at a load above about 1.5 is
reported as loaded, and its CPU time / cores is printed as the bound an idle machine would give if the run kept
both cores busy. ``--pytest-args`` replaces pytest's arguments (e.g. ``-k startup`` to try the script on a few
tests); the targets then do not apply. ``--serial`` runs README command 2 a second time with ``-n 0`` (the tests in
one process, as before pytest-xdist) and prints the ratio of the two wall and CPU times, measured in the same run.
``--against OLD`` (a checkout of another version) runs the same pytest command in both, ``--pairs`` times each,
alternating and rotating which goes first, and prints the per-pair ratios this / OLD of wall and CPU time and their
medians: the figure to quote when the machine's speed drifts between runs.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import statistics
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS = {"README command 2": 150.0, ".ci/run": 360.0}


def timed(name: str, cmd: list[str], cwd: Path, env: dict[str, str]) -> dict:
    load0 = os.getloadavg()[0]
    started = datetime.now(timezone.utc)
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in proc.stdout:
        lines.append(line)
        sys.stderr.write(line)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    summary = [ln.strip("= \n") for ln in lines if re.search(r"\d+ (passed|failed|error)", ln)]
    return {"name": name, "cmd": " ".join(cmd), "start": f"{started:%Y-%m-%d %H:%M}", "wall": wall,
            "cpu": usage.ru_utime + usage.ru_stime, "exit": os.waitstatus_to_exitcode(status),
            "summary": "; ".join(summary[-3:]) or "(no pytest summary line)", "load0": load0, "load1": os.getloadavg()[0]}


def with_path(checkout: Path) -> dict[str, str]:
    """The environment with ``checkout`` first on PYTHONPATH (its package is the one imported)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(checkout), os.environ.get("PYTHONPATH")]))}


def against(checkout: Path, other: Path, extra: list[str], pairs: int) -> int:
    """``--against``: the pytest command in both checkouts, alternated; per-pair ratios and their medians."""
    cmd = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *extra]
    rows = []
    for i in range(pairs):
        order = [(checkout, "this"), (other, "other")][:: 1 if i % 2 == 0 else -1]
        rows.append({who: timed(who, cmd, tree, with_path(tree)) for tree, who in order})
    print(f"\n`{' '.join(cmd[1:])}`: this {checkout}, other {other}\n")
    print("| pair | this wall / CPU (s) | other wall / CPU (s) | wall ratio | CPU ratio | load start -> end | exits |")
    print("|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows, 1):
        t, o = r["this"], r["other"]
        first = min((t, o), key=lambda x: x["start"])
        print(f"| {i} ({first['start']}) | {t['wall']:.1f} / {t['cpu']:.1f} | {o['wall']:.1f} / {o['cpu']:.1f} | "
              f"{t['wall'] / o['wall']:.3f} | {t['cpu'] / o['cpu']:.3f} | {min(t['load0'], o['load0']):.1f} -> "
              f"{max(t['load1'], o['load1']):.1f} | {t['exit']}, {o['exit']} |")
    med = lambda k: statistics.median(r["this"][k] / r["other"][k] for r in rows)
    print(f"\nmedian of the per-pair ratios this / other: wall {med('wall'):.3f}, CPU {med('cpu'):.3f}")
    print("pytest: this " + rows[-1]["this"]["summary"] + "; other " + rows[-1]["other"]["summary"])
    return max(max(r["this"]["exit"], r["other"]["exit"]) for r in rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkout", type=Path, default=ROOT, help="the checkout to test (default: this one)")
    ap.add_argument("--ci", action="store_true", help="also run ./.ci/run (several minutes; the whole of CI)")
    ap.add_argument("--pytest-args", help="pytest's arguments instead of none (README command 2); no target then")
    ap.add_argument("--serial", action="store_true", help="also README command 2 with -n 0 (one process): the ratio")
    ap.add_argument("--against", type=Path, help="another checkout: the same pytest command alternated, per-pair ratios")
    ap.add_argument("--pairs", type=int, default=3, help="with --against: runs of each (default 3)")
    a = ap.parse_args()
    checkout = a.checkout.resolve()
    extra = shlex.split(a.pytest_args) if a.pytest_args else []
    if a.against:
        sys.exit(against(checkout, a.against.resolve(), extra, a.pairs))
    env = with_path(checkout)
    runs = [timed("README command 2", [sys.executable, "-m", "pytest", *extra], checkout, env)]
    if a.serial:
        runs.append(timed("README command 2, -n 0", [sys.executable, "-m", "pytest", *extra, "-n", "0"], checkout, env))
    if a.ci:
        runs.append(timed(".ci/run", ["./.ci/run"], checkout, env))
    cores = os.cpu_count() or 1
    print(f"\n{checkout} ({subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=checkout, capture_output=True, text=True).stdout.strip()}), "
          f"{cores} cores\n")
    print("| command | start (UTC) | wall (s) | CPU (s) | CPU / cores (s) | load start -> end | exit | pytest | target |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        target = TARGETS.get(r["name"]) if not extra else None
        loaded = max(r["load0"], r["load1"]) > 1.5
        verdict = ("-" if target is None else f"< {target:.0f} s: {'met' if r['wall'] < target else 'not met'}"
                   + (" (loaded: not an idle figure)" if loaded else ""))
        print(f"| `{r['cmd']}` | {r['start']} | **{r['wall']:.1f}** | {r['cpu']:.1f} | {r['cpu'] / cores:.1f} | "
              f"{r['load0']:.1f} -> {r['load1']:.1f} | {r['exit']} | {r['summary']} | {verdict} |")
    if a.serial:
        quick, serial = runs[0], runs[1]
        print(f"\nREADME command 2 / the same with -n 0: wall {quick['wall'] / serial['wall']:.2f}, "
              f"CPU {quick['cpu'] / serial['cpu']:.2f}")
    sys.exit(max(r["exit"] for r in runs))


if __name__ == "__main__":
    main()
