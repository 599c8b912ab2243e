"""Start-up of the command line and the fixed cost of a stage, against references (issue 22 point 3).

    python benchmarks/bench_startup.py [--rounds 7] [--against DIR]

Runs each command as a separate process, in rounds (one run of every command per round, the
order rotating between rounds, so that the machine's load hits each alike), after one warm-up
run of each (Python's bytecode cache on, as an installed program runs):
- references: `python -c pass` (the interpreter alone) and `evo_ape -h` (evo, the test extra: a
  Python tool of the same kind) when installed;
- ours: `python -m cobot_analysis --help`, `cobot-analysis --help` (the installed script), and the
  fixed cost of every stage (``STAGES``): the stage on an empty workspace, or given a missing input file
  (`import`, `import-published`, `localisation`, `bag-info`), or with no start (`generate`). Each
  checks its options, looks for its input and stops there with exit 2, so what it costs is start-up: the
  interpreter, the command line, option parsing, the option checks and the imports made before the
  input is found (the cost a real run pays before its first real work).
Prints per command the median wall and CPU time (user + system, from wait4: the steadier figure
on a shared machine), and the medians of the per-round ratios against each reference, with the
load average before and after. The target (issue 22): under 0.5 s wall on the idle machine.
``--against DIR`` (a source tree of another version, e.g. ``git archive COMMIT cobot_analysis | tar -x -C DIR``) also runs
every command of ours with that tree first on the path, in the same rounds, and prints CPU(this) / CPU(DIR).
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

#: every stage, refused at its first check: on an empty workspace (EMPTY: an empty directory), given a missing
#: input (MISSING...: a path in that directory) or with no start to generate from
STAGES = {
    "import MISSING.yaml": ["import", "MISSING.yaml", "--out", "EMPTY"],
    "import-published MISSING": ["import-published", "walking-2020", "MISSING", "--out", "EMPTY"],
    **{f"{stage} --out EMPTY": [stage, "--out", "EMPTY"] for stage in ("preprocess", "average", "compare", "stats", "reconstruct", "report")},
    "generate --out EMPTY (no --start)": ["generate", "--out", "EMPTY"],
    **{f"{stage} --out EMPTY": [stage, "--out", "EMPTY"] for stage in ("fit-ioc", "velocity-commands", "predict")},
    "localisation MISSING.bag": ["localisation", "MISSING.bag", "--out", "EMPTY"],
    "bag-info MISSING.bag": ["bag-info", "MISSING.bag"],
}

# Bytecode cache on, as for an installed program (some shells set PYTHONDONTWRITEBYTECODE).
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def script(name: str) -> str | None:
    """The console script beside this interpreter (not a pyenv shim, which adds its own start-up)."""
    beside = Path(sys.executable).parent / name
    return str(beside) if beside.is_file() else shutil.which(name)


def run(cmd: list[str], codes: tuple[int, ...], cwd: Path, env: dict[str, str] = ENV) -> tuple[float, float]:
    """Wall and CPU time (user + system, s) of one process; its exit code must be one of ``codes``. It runs
    in ``cwd`` (an empty directory: ``python -m`` puts the working directory first on the path, so from a
    checkout it would import that checkout, not the package ``$PYTHONPATH`` or the installation names)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, cwd=cwd)
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
    ap.add_argument("--against", type=Path, help="source tree of another version of cobot_analysis to compare with")
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
    for name, argv in STAGES.items():
        argv = [str(empty) if a == "EMPTY" else str(empty / a) if a.startswith("MISSING") else a for a in argv]
        ours[name] = ([py, "-m", "cobot_analysis", *argv], (2,))
    commands = {name: (cmd, codes, ENV) for name, (cmd, codes) in {**refs, **ours}.items()}
    if args.against:
        env = {**ENV, "PYTHONPATH": str(args.against.resolve())}
        commands.update({f"{name} [against]": (cmd, codes, env) for name, (cmd, codes) in ours.items() if cmd[0] == py})
    package = subprocess.run([py, "-c", "import cobot_analysis; print(cobot_analysis.__file__)"], capture_output=True, text=True,
                             env=ENV, cwd=empty).stdout.strip()
    load0 = os.getloadavg()
    for cmd, codes, env in commands.values():  # warm-up: bytecode and file caches
        run(cmd, codes, empty, env)
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in commands}
    names = list(commands)
    for r in range(args.rounds):
        order = names[r % len(names):] + names[:r % len(names)]
        for name in order:
            cmd, codes, env = commands[name]
            times[name].append(run(cmd, codes, empty, env))
    load1 = os.getloadavg()
    shutil.rmtree(empty, ignore_errors=True)

    print(f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, {os.cpu_count()} cores, {args.rounds} rounds, "
          f"load average {load0[0]:.1f} -> {load1[0]:.1f}; {py}; cobot_analysis from {package}")
    if args.against:
        print(f"[against]: cobot_analysis from {args.against.resolve()}")

    def ratio(name: str, ref: str) -> float:
        return statistics.median(c / rc for (_, c), (_, rc) in zip(times[name], times[ref]))

    head = f"{'command':46s} {'wall s':>7s} {'CPU s':>6s}" + "".join(f"  {'CPU / ' + ref:>18s}" for ref in refs)
    print(head + ("  CPU / [against]" if args.against else ""))
    for name in names:
        wall = statistics.median(w for w, _ in times[name])
        cpu = statistics.median(c for _, c in times[name])
        ratios = "".join(f"  {ratio(name, ref):18.2f}" for ref in refs)
        against = f"  {ratio(name, name + ' [against]'):16.2f}" if name + " [against]" in times else ""
        print(f"{name:46s} {wall:7.3f} {cpu:6.3f}{ratios}{against}")
    print("ratios: median over the rounds of CPU(command) / CPU(reference) in the same round")


if __name__ == "__main__":
    main()
