"""A new walking study, from raw C3D files to its statistics and a figure, with the Python API.

A synthetic study stands in for the lab's recordings: ``synth_walking`` writes raw C3D files and the
``protocol.yaml`` that names each trial's file, subject and start condition (docs/protocol.md); with
real data, start from your own protocol file instead. Then, all in memory (no workspace):

    import_markers -> preprocess -> average -> compare -> statistics -> a figure (matplotlib)

with the headline numbers of a result (``.metrics()``, what the command line writes to ``metrics.json``)
and the figures it draws itself (``.figures()``).

Run it with ``python docs/examples/walking_study.py [OUT]`` (OUT: where the synthetic study and the
figure go; default ``walking-example``). ``tests/test_examples.py`` runs it and checks its numbers.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no window
import matplotlib.pyplot as plt  # noqa: E402

import cobot_analysis.api as ca  # noqa: E402
from cobot_analysis.stages.data import synth_walking  # noqa: E402

# 4 subjects x 4 start conditions x 2 repetitions. A condition is its start orientation (N: facing the goal's
# direction +y, E: facing +x) and its grid position (docs/methods.md sec. 1.1): 0.9 m to 5.3 m from the goal.
SUBJECTS, REPETITIONS, CONDITIONS = 4, 2, ["N1500", "E4015", "N0640", "E4040"]

# The study's questions (keys: cobot_analysis/stats/config.py; pipelines/walking-2020.toml has the full set).
# As a dict here; a TOML file with the same content works too (config="my-study.toml").
QUESTIONS = {
    "study": "synthetic-walking",
    "alpha": 0.05,
    "analysis": [
        {"id": "subjects", "description": "d_xy to the condition's mean differs across subjects (Kruskal-Wallis)",
         "source": "distances", "filter": {"comparison": "individual-mean"}, "value": "d_xy", "group": "subject",
         "test": "kruskal", "family": "variability"},
        {"id": "orientation", "description": "d_xy by start orientation (Mann-Whitney)",
         "source": "distances", "filter": {"comparison": "individual-mean"}, "value": "d_xy",
         "group": "start_orientation", "test": "mannwhitneyu", "family": "variability"},
        {"id": "distance", "description": "d_xy vs the start's distance to the goal (Pearson)",
         "source": "distances", "filter": {"comparison": "individual-mean"}, "value": "d_xy",
         "versus": "global_distance", "test": "pearson", "family": "variability"},
    ],
}


def main(out: str | Path = "walking-example") -> dict:
    """Run the example into ``out``; return its key numbers (also printed)."""
    out = Path(out)

    # 1. raw data: out/synth-walking/raw/*.c3d and out/synth-walking/protocol.yaml
    synth_walking(out, subjects=SUBJECTS, repetitions=REPETITIONS, conditions=CONDITIONS, jobs=1)
    protocol = out / "synth-walking" / "protocol.yaml"

    # 2. import: every trial read and checked (units, plausibility); markers in metres
    imported = ca.import_markers(protocol, jobs=1)
    print("import:", imported.summary())

    # 3. preprocess: gaps, low-pass filter, pelvis kinematics, walk segmentation, 500 samples per walk
    walks = ca.preprocess(imported, jobs=1).trajectories  # the documented trajectories table (docs/schemas.md)
    n_walks = walks.groupby(["trial", "entity"]).ngroups
    print(f"preprocess: {n_walks} trajectories of {walks['sample'].nunique()} samples")

    # 4. mean path per start condition, 5. each walk's distance to its condition's mean
    averaged = ca.average(walks)
    means = averaged.means
    compared = ca.compare(walks, means)
    distances = compared.distances
    per_subject = distances.groupby("subject")["d_xy"].mean()
    print("mean d_xy per subject (m):", ", ".join(f"{s} {v:.3f}" for s, v in per_subject.items()))
    # the result's headline numbers (name -> value; units in compared.metrics()[i].unit)
    numbers = compared.metrics().as_dict()
    key = "compare.individual-mean.walker.d_xy"
    print(f"d_xy to the condition's mean: {numbers[key + '.mean']:.3f} ± {numbers[key + '.sd']:.3f} m "
          f"over {numbers['compare.individual-mean.walker.n']} walks")

    # 6. the statistics of the study's questions (Holm correction within each family)
    stats = ca.statistics(walks, distances, config=QUESTIONS)
    print("statistics:", stats.summary())
    for _, row in stats.table.iterrows():
        print(f"  {row['id']:<12} {row['test']:<13} n={row['n']:<3} statistic={row['statistic']:.3f} "
              f"p={row['p']:.3g} Holm p={row['p_holm']:.3g}")

    # 7. a figure: every walk (thin) and the mean of its condition (thick), in the lab frame (m)
    fig, ax = plt.subplots(figsize=(6, 5))
    colours = dict(zip(CONDITIONS, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    for (condition, _), walk in walks.groupby(["condition", "trial"]):
        ax.plot(walk["x"], walk["y"], color=colours[condition], lw=0.6, alpha=0.5)
    for condition, mean in means.groupby("condition"):
        ax.plot(mean["x"], mean["y"], color=colours[condition], lw=2.5, label=f"{condition} mean")
    ax.plot(0, 0, "k*", ms=12, label="goal")
    ax.set(xlabel="x (m)", ylabel="y (m)", aspect="equal", title="Synthetic walking study: walks and means")
    ax.legend(fontsize=8)
    figure = out / "walks.png"
    fig.savefig(figure, dpi=100, bbox_inches="tight")
    plt.close(fig)
    print("figure:", figure)

    # 8. the figures the results draw themselves (matplotlib Figures by name): the means, the distances
    drawn = []
    for name, fig in {**averaged.figures(), **compared.figures()}.items():
        drawn.append(out / f"{name}.png")
        fig.savefig(drawn[-1], dpi=100, bbox_inches="tight")
        plt.close(fig)
    print("figures:", ", ".join(p.name for p in drawn))

    return {"trials": len(imported.trials), "trajectories": n_walks, "means": means.groupby("condition").ngroups,
            "distances": distances, "stats": stats.table, "figure": figure, "metrics": numbers, "figures": drawn}


if __name__ == "__main__":
    main(*sys.argv[1:2])
