"""The CPU of the package's figures (``Stage.savefig``) in the small demo, against another version (issue 22 point 4).

    python benchmarks/bench_figures.py [--rounds 2] [--against DIR]

Each run is ``demo --size small --jobs 1`` (35 figures, PNG and PDF) in its own process, with a fresh
workspace, and ``Stage.savefig`` timed inside it (CPU: ``getrusage`` of the process, which has no workers at
``--jobs 1``); the process's CPU (user + system, from ``wait4``) beside it. ``--against DIR`` (a source tree of
another version, e.g. ``git archive COMMIT | tar -x -C DIR``) runs it with that tree first on the path too,
alternating with this one round by round (the order rotating, so that the machine's load hits each alike), and
prints the per-round ratios of this / DIR and their medians; then compares the last round's figures: PNG
pixels, PDF page sizes.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]

#: the demo in-process with Stage.savefig timed; prints one JSON line
DRIVER = """
import json, resource, sys
from cobot_analysis import workspace
from cobot_analysis.cli import run
cpu = lambda: sum(resource.getrusage(resource.RUSAGE_SELF)[:2])
spent = [0.0, 0]
save = workspace.Stage.savefig
def timed(self, *a, **k):
    t = cpu()
    try:
        return save(self, *a, **k)
    finally:
        spent[0] += cpu() - t; spent[1] += 1
workspace.Stage.savefig = timed
code = run(["-q", "demo", "--out", sys.argv[1], "--size", "small", "--jobs", "1"])
import cobot_analysis
print(json.dumps({"code": code, "savefig": spent[0], "figures": spent[1], "package": cobot_analysis.__file__}))
"""


def one_run(tree: Path, out: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "MPLBACKEND": "Agg"}
    t = time.perf_counter()
    # cwd: the parent of the workspace, not a source tree (``-c`` puts the cwd first on the path)
    proc = subprocess.Popen([sys.executable, "-c", DRIVER, str(out)], env=env, stdout=subprocess.PIPE, text=True, cwd=out.parent)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t
    result = json.loads(proc.stdout.read().strip().splitlines()[-1])
    assert status == 0 and result["code"] == 0, f"the demo failed with {tree}"
    assert Path(result["package"]).is_relative_to(tree), f"{result['package']} imported, not {tree}'s"
    return {**result, "wall": wall, "cpu": usage.ru_utime + usage.ru_stime}


def page(pdf: Path) -> tuple[float, float]:
    box = re.search(rb"/MediaBox \[ *([\d. ]+)\]", pdf.read_bytes()).group(1).split()
    return float(box[2]), float(box[3])


def compare(new: Path, old: Path) -> None:
    """PNG pixels and PDF page sizes of two demo workspaces."""
    import numpy as np
    from PIL import Image

    pngs = sorted(new.rglob("*.png"))
    other = [p.relative_to(new) for p in pngs
             if (a := np.asarray(Image.open(p))).shape != (b := np.asarray(Image.open(old / p.relative_to(new)))).shape
             or (a != b).any()]
    print(f"PNGs with other pixels: {len(other)} of {len(pngs)} {[str(p) for p in other]}")
    moved = {p.relative_to(new): (page(old / p.relative_to(new)), page(p)) for p in sorted(new.rglob("*.pdf"))}
    moved = {k: v for k, v in moved.items() if v[0] != v[1]}
    print(f"PDF pages that moved ({old.name} -> {new.name}, pt): {len(moved)}, largest change "
          f"{max((max(abs(x - y) for x, y in zip(*v)) for v in moved.values()), default=0):.2f} pt")
    for name, (a, b) in moved.items():
        print(f"  {name}: {a[0]:.2f} x {a[1]:.2f} -> {b[0]:.2f} x {b[1]:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--against", type=Path, default=None, help="source tree of the version to compare with")
    args = ap.parse_args()
    trees = {"this": HERE, **({"against": args.against.resolve()} if args.against else {})}
    root = Path(tempfile.mkdtemp(prefix="bench_figures-"))
    runs: dict[str, list[dict]] = {k: [] for k in trees}
    print(f"{datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, load {os.getloadavg()[0]:.2f}; {sys.executable}")
    for r in range(args.rounds):
        for name in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
            res = one_run(trees[name], root / f"{name}-{r}")
            runs[name].append(res)
            print(f"round {r + 1} {name:8s} savefig {res['savefig']:6.2f} s CPU ({res['figures']} figures), process "
                  f"{res['cpu']:6.2f} s CPU, {res['wall']:6.2f} s wall; load {os.getloadavg()[0]:.2f}")
    for name, rs in runs.items():
        print(f"median {name}: savefig {statistics.median(x['savefig'] for x in rs):.2f} s CPU, "
              f"process {statistics.median(x['cpu'] for x in rs):.2f} s CPU")
    if args.against:
        for what in ("savefig", "cpu"):
            ratios = [a[what] / b[what] for a, b in zip(runs["this"], runs["against"])]
            print(f"{what} this / against per round: {', '.join(f'{x:.3f}' for x in ratios)}; median {statistics.median(ratios):.3f}")
        last = args.rounds - 1
        compare(root / f"this-{last}", root / f"against-{last}")


if __name__ == "__main__":
    main()
