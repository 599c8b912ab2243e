"""A robot run, from its bag to its localisation errors, with the Python API.

A synthetic run stands in for the robot's recording: ``synth_localisation`` writes a ROS1 bag in which
a humanoid walks to a commanded goal, with motion capture (``/mocap/pose``, 200 Hz, the truth) and
its on-board ICP localisation (``/icp/pose``, 10 Hz) planted 0.55 s late and offset from the
motion-capture frame; ``truth.json`` beside the bag holds the planted values. With a real run, start
from your own bag (ROS1 .bag, ROS2 bag directory or .mcap). Then (docs/methods.md sec. 9):

    bag_topics (what the bag holds) -> localise (delay, offset, per-axis errors, APE, drift, goals)

Run it with ``python docs/examples/robot_localisation.py [OUT]`` (default ``robot-example``);
``tests/test_examples.py`` runs it and checks the delay and offsets against the planted ones.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt  # noqa: E402

import cobot_analysis.api as ca  # noqa: E402

# the smallest run: one goal, 3 s stop, 0.3 m/s (about 14 s of recording)
RUN = dict(goals_per_lap=1, stop=3.0, speed=0.3)


def main(out: str | Path = "robot-example") -> dict:
    """Run the example into ``out``; return its key numbers (also printed)."""
    out = Path(out)

    # 1. the recording: out/synth-localisation/run.bag, goals.csv and truth.json
    bag = ca.synth_localisation(out / "synth-localisation", **RUN, formats="ros1").bags[0]
    planted = json.loads((out / "synth-localisation" / "truth.json").read_text())

    # 2. what the bag holds: pose-like topics and tf frame pairs (choose the truth and ICP streams)
    topics, frames = ca.bag_topics(bag)
    for t in topics:
        if t["pose"]:
            rate = f" at {t['rate']:g} Hz" if t["count"] > 1 else ""
            print(f"topic {t['topic']:<16} {t['type']:<32} {t['count']:>5} message(s){rate}")
    print("tf:", ", ".join(f"{f['parent']}->{f['child']}" for f in frames))

    # 3. localisation accuracy: the delay is estimated (least squares over --delay-window 0,1.5 s), the
    #    structural offset removed (alignment "mean"), ICP compared with the truth interpolated at its stamps
    result = ca.localise([bag], truth="/mocap/pose", icp="/icp/pose", goal_topic="/goal")
    run = result.runs.iloc[0]
    print(f"delay {run['delay']:.4f} ± {run['delay_sd']:.4f} s (planted {planted['delay']} s)")
    print("offset, ICP minus truth (m, rad): " + ", ".join(
        f"{a} {run[f'offset_{a}']:+.4f} (planted {planted['offset'][a]:+.4f})" for a in ("x", "y", "z", "yaw")))
    print("per-axis errors after the offset (RMSE): " + ", ".join(
        f"{a} {1000 * run[f'err_{a}_rmse']:.1f} mm" for a in ("x", "y", "z")) + f", yaw {run['err_yaw_rmse']:.4f} rad")
    print(f"APE RMSE {1000 * run['ape_rmse']:.1f} mm over {int(run['n'])} ICP poses, "
          f"drift {1000 * run['drift']:+.2f} mm/m, goals reached {run['goals_found']}/{run['goals_commanded']}")

    # 4. a figure: the per-axis errors over time (one row per associated ICP pose in result.errors)
    errors = result.errors
    fig, ax = plt.subplots(figsize=(7, 3.5))
    t = errors["t"] - errors["t"].iloc[0]
    for a in ("x", "y", "z"):
        ax.plot(t, 1000 * errors[f"err_{a}"], lw=0.9, label=a)
    ax.set(xlabel="time (s)", ylabel="ICP - truth (mm)", title="Localisation errors after delay and offset")
    ax.axhline(0, color="k", lw=0.5)
    ax.legend()
    figure = out / "errors.png"
    fig.savefig(figure, dpi=100, bbox_inches="tight")
    plt.close(fig)
    print("figure:", figure)

    # 5. the result's headline numbers (what the command line writes to metrics.json) and its own figures
    numbers = result.metrics().as_dict()
    print(f"metrics: {len(numbers)} numbers, e.g. localisation.run.ape_rmse = {numbers['localisation.run.ape_rmse']:.4f} m")
    drawn = []
    for name, fig in result.figures().items():  # paths, error_time, error_distribution, delay_cost, timeseries_run
        drawn.append(out / f"{name}.png")
        fig.savefig(drawn[-1], dpi=100, bbox_inches="tight")
        plt.close(fig)
    print("figures:", ", ".join(p.name for p in drawn))

    return {"planted": planted, "run": run.to_dict(), "errors": errors, "topics": topics, "figure": figure,
            "metrics": numbers, "figures": drawn}


if __name__ == "__main__":
    main(*sys.argv[1:2])
