"""What the two conventions cost (docs/benchmarks.md, "OC and IOC").

    python benchmarks/bench_conventions.py generate --data ../shared/datasets/walking-2020 [--jobs 2]
    python benchmarks/bench_conventions.py ioc --data ../shared/datasets/walking-2020 [--jobs 2] [--max-evaluations N]

``generate``: the 40 walking-2020 means with the improved model and the walking-2021 weights, through
the CLI (fresh processes: what a user gets, NLP construction included), under each convention; the
first run of a convention also builds the solver's compiled functions once per machine, so each is
run twice and both times are printed. ``ioc``: ``fit-ioc`` on the 37 means with orientation under
each convention (the published one holds each mean's horizon during the fit, then re-runs the rule).
Prints a Markdown block with the machine, the load average and the date.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bench_models import header  # noqa: E402


def cli(*args: str) -> float:
    """Wall time of one ``cobot-analysis`` command (a fresh process)."""
    t = time.perf_counter()
    subprocess.run([sys.executable, "-m", "cobot_analysis", "-q", *args], check=True)
    return time.perf_counter() - t


def bench_generate(data: Path, jobs: int) -> str:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        cli("import-published", "walking-2020", str(data), "--out", tmp)
        for conv in ("continuous", "published"):
            times = [cli("generate", "--out", tmp, "--study", "walking-2020", "--weights", "walking-2021", "--convention", conv,
                         "--jobs", str(jobs), "--force") for _ in range(2)]
            stage = "generate" if conv == "continuous" else "generate-published"
            nodes = json.loads((Path(tmp) / stage / "manifest.json").read_text())["duration_s"]
            rows.append(f"| {conv} | {times[0]:.1f} | {times[1]:.1f} | {nodes:.1f} |")
    return "\n".join([header(), "", f"`generate --study walking-2020 --weights walking-2021 --jobs {jobs}` (40 means), wall time:", "",
                      "| convention | first run (s) | second run (s) | stage time in the manifest, 2nd run (s) |",
                      "|---|---|---|---|", *rows])


def bench_ioc(data: Path, jobs: int, max_evaluations: int | None) -> str:
    rows = []
    extra = ["--max-evaluations", str(max_evaluations)] if max_evaluations else []
    with tempfile.TemporaryDirectory() as tmp:
        cli("import-published", "walking-2020", str(data), "--out", tmp)
        cli("average", "--out", tmp)
        for conv in ("continuous", "published"):
            t = cli("fit-ioc", "--out", tmp, "--convention", conv, "--no-compare", "--jobs", str(jobs), *extra)
            stage = "fit-ioc" if conv == "continuous" else "fit-ioc-published"
            fit = json.loads((Path(tmp) / stage / "weights.json").read_text())["fits"]["all"]
            rows.append(f"| {conv} | {t / 60:.1f} | {fit['evaluations']} | {fit['start_objective']:.4f} | {fit['objective']:.4f} | "
                        f"{fit.get('horizons_changed')} | {fit['message'].strip()} |")
    return "\n".join([header(), "", f"`fit-ioc --no-compare --jobs {jobs}` on the walking-2020 means, wall time:", "",
                      "| convention | minutes | evaluations | D start | D fitted | horizons moved by the rule at the fit | optimiser |",
                      "|---|---|---|---|---|---|---|", *rows])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=("generate", "ioc"))
    ap.add_argument("--data", type=Path, default=Path("../shared/datasets/walking-2020"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--max-evaluations", type=int, default=None)
    a = ap.parse_args()
    print(bench_generate(a.data, a.jobs) if a.what == "generate" else bench_ioc(a.data, a.jobs, a.max_evaluations))


if __name__ == "__main__":
    main()
