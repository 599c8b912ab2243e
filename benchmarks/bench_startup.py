"""Start-up of the command line and the fixed cost of a stage, against references (issue 22 point 3).

    python benchmarks/bench_startup.py [--rounds 7]

Runs each command as a separate process, in rounds (one run of every command per round, the
order rotating between rounds, so that the machine's load hits each alike), after one warm-up
run of each (Python's bytecode cache on, as an installed program runs):
- references: `python -c pass` (the interpreter alone) and `evo_ape -h` (evo, the test extra: a
  Python tool of the same kind) when installed;
- ours: `python -m cobot_analysis --help`, `cobot-analysis --help` (the installed script), and the
  fixed cost of a stage: `average`, `compare`, `stats` on an empty workspace and `localisation` of
  a missing bag (each stops at its first check with exit 2, so what it costs is start-up: the
  interpreter, the command line, option parsing and the imports made before the check), plus
  `predict` on an empty workspace, which checks its options with the models imported first.
Prints per command the median wall and CPU time (user + system, from wait4: the steadier figure
on a shared machine), and the medians of the per-round ratios against each reference, with the
load average before and after. The target (issue 22): under 0.5 s wall on the idle machine.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

# Bytecode cache on, as for an installed program (some shells set PYTHONDONTWRITEBYTECODE).
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def script(name: str) -> str | None:
    """The console script beside this interpreter (not a pyenv shim, which adds its own start-up)."""
    beside = Path(sys.executable).parent / name
    return str(beside) if beside.is_file() else shutil.which(name)


def run(cmd: list[str], codes: tuple[int, ...], cwd: Path) -> tuple[float, float]:
    """Wall and CPU time (user + system, s) of one process; its exit code must be one of ``codes``. It runs
    in ``cwd`` (an empty directory: ``python -m`` puts the working directory first on the path, so from a
    checkout it would import that checkout, not the package ``$PYTHONPATH`` or the installation names)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV, cwd=cwd)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code not in codes:
        raise SystemExit(f"{' '.join(cmd)} exited {code}, expected {codes}:\n{err}")
    return wall, usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=7)
    args = ap.parse_args()
    py = sys.executable
    empty = Path(tempfile.mkdtemp(prefix="bench-startup-"))
    refs = {"python -c pass": ([py, "-c", "pass"], (0,))}
    evo = script("evo_ape")
    if evo:
        refs["evo_ape -h"] = ([evo, "-h"], (0,))
    ours = {"python -m cobot_analysis --help": ([py, "-m", "cobot_analysis", "--help"], (0,))}
    cli = script("cobot-analysis")
    if cli:
        ours["cobot-analysis --help"] = ([cli, "--help"], (0,))
    for stage in ("average", "compare", "stats", "predict"):
        ours[f"{stage} --out EMPTY"] = ([py, "-m", "cobot_analysis", stage, "--out", str(empty)], (2,))
    ours["localisation MISSING.bag"] = ([py, "-m", "cobot_analysis", "localisation", str(empty / "missing.bag"), "--out", str(empty)], (2,))
    commands = {**refs, **ours}
    package = subprocess.run([py, "-c", "import cobot_analysis; print(cobot_analysis.__file__)"], capture_output=True, text=True,
                             env=ENV, cwd=empty).stdout.strip()
    load0 = os.getloadavg()
    for cmd, codes in commands.values():  # warm-up: bytecode and file caches
        run(cmd, codes, empty)
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in commands}
    names = list(commands)
    for r in range(args.rounds):
        order = names[r % len(names):] + names[:r % len(names)]
        for name in order:
            times[name].append(run(*commands[name], empty))
    load1 = os.getloadavg()
    shutil.rmtree(empty, ignore_errors=True)

    print(f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, {args.rounds} rounds, "
          f"load average {load0[0]:.1f} -> {load1[0]:.1f}; {py}; cobot_analysis from {package}")
    head = f"{'command':34s} {'wall s':>7s} {'CPU s':>6s}" + "".join(f"  {'CPU / ' + ref:>22s}" for ref in refs)
    print(head)
    for name in names:
        wall = statistics.median(w for w, _ in times[name])
        cpu = statistics.median(c for _, c in times[name])
        ratios = "".join(f"  {statistics.median(c / rc for (_, c), (_, rc) in zip(times[name], times[ref])):22.2f}" for ref in refs)
        print(f"{name:34s} {wall:7.3f} {cpu:6.3f}{ratios}")
    print("ratios: median over the rounds of CPU(command) / CPU(reference) in the same round")


if __name__ == "__main__":
    main()
