"""The results fragments (docs/results.md) of the analysis stages: ``average``, ``compare``, ``stats``
and ``reconstruct`` (docs/methods.md sec. 2.9, 3, 4, 8)."""

from __future__ import annotations

from pathlib import Path


def _range(low: int, high: int) -> str:
    """``3`` or ``1 to 3``."""
    return f"{low}" if low == high else f"{low} to {high}"


def average_markdown(result, source: str) -> str:
    """What the means are made of: input, grouping, counts, how angles were averaged."""
    means = result.means
    n_means = means.drop_duplicates(["trial", "entity"]).shape[0]
    first = means[means["sample"].eq(0)]
    lines = ["## Mean trajectories", "",
             f"- Input: `{source}` ({result.study}); {result.source}.",
             f"- Grouping: {', '.join(result.groups)}; {n_means} mean {'trajectory' if n_means == 1 else 'trajectories'}; trials per mean "
             f"{int(first['n_trials'].min())} to {int(first['n_trials'].max())}.",
             "- Positions: sample-wise arithmetic mean; angles: circular mean (theta unwrapped along the path), "
             "trajectories without orientation excluded from the angle means only; band = mean +- 1.96 sd.",
             f"- Means without any orientation: {int((first['n_theta'] == 0).sum())}."]
    if result.spread:
        lines.append(f"- {len(result.spread)} mean(s) average trajectories that do not share a frame (start or end points "
                     "spread beyond the limit around the group's median, `average --max-spread`): flagged `frames_differ`, not drawn in the report and "
                     "not compared with their trials. " + "; ".join(result.spread))
    unit, few, many, fewest, most = result.units
    if result.weigh == "subjects":
        lines.append(f"- Weighting (`average --weigh subjects`): each mean is the mean of its {unit}s' means "
                     f"({_range(few, many)} {unit}s per mean; {_range(fewest, most)} trajectories per {unit}), sd between the "
                     f"{unit}s' means (0 for a mean of one {unit}): a {unit} with more trials weighs no more.")
    elif result.n_averaged:
        lines.append("- Weighting (`average --weigh trials`, the published method): every trajectory alike.")
    n, unit, fewest, most = result.unequal
    if n and result.weigh == "trials":
        lines.append(f"- In {n} mean(s) the {unit}s contribute unequal numbers of trajectories ({fewest} to {most}): each mean "
                     f"weighs its trajectories alike, so a {unit} with more of them weighs more (the published means had one "
                     f"trajectory per {unit}); `average --weigh subjects` takes the mean of the {unit}s' means instead.")
    if result.truncated:
        lines.append(f"- {result.truncated} of the {result.n_averaged} trajectories averaged are flagged `truncated` (they run "
                     "off their recording: travel time and path cover only the recorded part).")
    return "\n".join(lines) + "\n"


def compare_markdown(result, sd_ddof: int, weigh: str = "trials") -> str:
    """d_xy, d_theta, d_gamma mean +- sd per comparison and entity, with how they were computed (``weigh``: how the
    means compared with were weighed, ``average --weigh``)."""
    d = result.distances
    summary = d.groupby(["comparison", "entity"])[["d_xy", "d_theta", "d_gamma"]].agg(
        ["mean", lambda v: v.std(ddof=sd_ddof), "count"]).rename(columns={"<lambda_0>": "std"})
    how = ("pointwise on the time-normalised samples, angle differences wrapped to [-pi, pi], sample sd"
           if result.convention == "continuous" else
           "after resampling both paths by arc length (scipy splprep, s = 0), each angle wrapped to [-pi, pi] on "
           "its own, population sd (the authors' scripts)")
    lines = [f"## Distances between trajectories ({result.convention} convention)", "",
             f"d_xy (m), d_theta (rad), d_gamma (rad, N-1 samples) (docs/methods.md sec. 3, 11), {how}; "
             "symmetry = forward vs time-reversed return; angular distances only where both trajectories have "
             "orientation." + (f" The means are the means weighted by {weigh} (`average --weigh {weigh}`): the mean of "
                              "each subject's (pair's) mean." if weigh != "trials" else ""), "",
             "| comparison | entity | n | d_xy mean +- sd | d_theta mean +- sd | d_gamma mean +- sd |", "|---|---|---|---|---|---|"]
    single, frames = (getattr(result, "excluded", {}) or {}).get("single", 0), (getattr(result, "excluded", {}) or {}).get("frames", 0)
    if summary.empty:  # no table of headers alone
        lines[-2:] = ["No pair of trajectories was compared" + (" (below: which were left out and why)." if single or frames else ".")]
    for (comp, ent), r in summary.iterrows():
        fmt = [f"{r[(k, 'mean')]:.3f} +- {r[(k, 'std')]:.3f} (n={int(r[(k, 'count')])})" if r[(k, "count")] else "n/a"
               for k in ("d_xy", "d_theta", "d_gamma")]
        lines.append(f"| {comp} | {ent} | {int(r[('d_xy', 'count')])} | " + " | ".join(fmt) + " |")
    comparisons = set(d["comparison"]) if "comparison" in d else set()
    table = "model" in comparisons and d.loc[d["comparison"] == "model", "entity"].eq("table").all()
    if result.convention == "published" and table:
        # the pair study: the published table means, carried unchanged by average, are fit-ioc's mean block
        lines += ["", "The model rows compare the generated table paths with the table means above, the means fit-ioc "
                      "--model table compares under the published convention (on the published study, average carries "
                      "the authors' means unchanged): the same paths and means, the same d_xy and d_theta (docs/methods.md "
                      "sec. 11)."]
    elif result.convention == "published" and "model" in comparisons:
        # one answer per question: fit-ioc's comparison of the same paths differs in d_gamma only, and says why here
        shift = d.loc[d["comparison"] == "mean-published", "d_gamma"].dropna()
        lines += ["", "The model rows compare the generated paths with the means above (recomputed from the trials). "
                      "fit-ioc's model comparison under the published convention takes the same paths against the authors' "
                      "mean block (import-published), as their scripts did: the same d_xy; d_gamma differs because the "
                      "recorded gamma of the mean block is not the gamma of the recomputed means"
                  + (f" (they differ by d_gamma {shift.mean():.3f} rad, row mean-published)" if len(shift) else "")
                  + " (docs/methods.md sec. 11)."]
    if single or frames:
        from cobot_analysis.compare import EXCLUDED_REASONS

        lines += ["", f"Not compared with their mean (left out of the individual-mean rows and of the statistics): {single} "
                      f"trial(s) {EXCLUDED_REASONS['single']} (the distance would be 0), "
                      f"{frames} trial(s) {EXCLUDED_REASONS['frames']}."]
    return "\n".join(lines) + "\n"


def statistics_markdown(result, config_path: Path, n_trajectories: int, n_samples: int, source: str,
                        distances: Path | None = None, convention: str = "continuous", weigh: str = "trials") -> tuple[str, str]:
    """(stats.md, results.md): the tests table, and the same with the choices behind the numbers (``weigh``: how the
    means the distances were measured to were weighed, ``average --weigh``)."""
    from cobot_analysis.stats import analyses

    what = Path(config_path).name if config_path else "no study file"
    if not result.declared:
        what += ": default descriptive questions"
    md = analyses.markdown(result.table, f"Statistics: {result.study} ({what}, {convention} convention)", result.config.alpha)
    choices = [
        "Choices behind these numbers:",
        f"- Trajectories: {n_trajectories} from `{source}`, {n_samples} time-normalised samples each (as given; "
        "no further resampling); angle differences wrapped to [-pi, pi] before averaging (d_theta, d_gamma).",
        *([f"- Distances: `{distances.parent.name}/{distances.name}` ({convention} convention, docs/methods.md sec. 11)"
           + (f"; the individual-mean rows against the means weighted by {weigh} (`average --weigh {weigh}`): the mean of "
              "each subject's (pair's) mean." if weigh != "trials" else ".")] if distances is not None else []),
        f"- Questions of `{what}`: each row names its subset, test and grouping. Holm correction "
        f"(statsmodels) within each family; alpha = {result.config.alpha}; descriptive rows (describe, largest subset) "
        "are outside the families.",
        "- Trial-level tests treat every trial as independent (a row whose values repeat subjects or pairs says so); "
        "`pair-level` rows first average each pair; "
        "`paired` rows (Wilcoxon) match values by the listed columns (several returns of a pair and goal are averaged); "
        "`unpaired` rows ignore the pairing.",
        "- Normality (Shapiro-Wilk for the pair study, Kolmogorov-Smirnov against N(mean, sd) for the walking study) "
        "only switches to the parametric test where the configuration names one, when every group is shown normal (the "
        "published rule); an ANOVA whose groups' variances differ (Levene) says so.",
        "- Largest indistinguishable subset: exact search over all subsets up to 12 groups, greedy backward "
        "elimination above (the row says which); the walking thesis's definition beside it (pairwise_subset: every "
        "pair Mann-Whitney p > 0.05, docs/methods.md sec. 4).",
    ]
    waiting = [f"- Waiting ({why}): {', '.join(ids)} (skipped, expected)." for why, ids in (result.waiting or {}).items()]
    if waiting:
        choices += ["Questions these data cannot answer yet:", *waiting]
    return md, md + "\n" + result.summary() + "\n\n" + "\n".join(choices) + "\n"


def reconstruct_markdown(result) -> str:
    """d_xy and d_theta of the reconstructed subjects per relative pose, trajectories, direction, subject."""
    rec = result.reconstruction
    s = rec.groupby(["relative_pose", "kind", "direction", "entity"])[["d_xy", "d_theta"]].agg(["mean", "std", "count"])
    lines = ["## Subjects reconstructed from the table", "",
             f"Relative pose: mean subject pose in the table frame over scenario-{result.scenario} trajectories "
             "(or the published subject*_wrt_table.dat); reconstructed trajectories compared with the measured ones "
             "(docs/methods.md sec. 8).", "",
             "| relative pose | trajectories | direction | subject | n | d_xy (m) mean +- sd | d_theta (rad) mean +- sd |",
             "|---|---|---|---|---|---|---|"]
    for (src, kind, direction, ent), r in s.iterrows():
        lines.append(f"| {src} | {kind} | {direction} | {ent} | {int(r[('d_xy', 'count')])} | "
                     f"{r[('d_xy', 'mean')]:.3f} +- {r[('d_xy', 'std')]:.3f} | {r[('d_theta', 'mean')]:.3f} +- {r[('d_theta', 'std')]:.3f} |")
    return "\n".join(lines) + "\n"
