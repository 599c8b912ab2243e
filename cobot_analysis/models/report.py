"""Comparison of the walking-path models against measured trajectories, and the fit report
(METHODS.md sec. 4-6): distances per model and trajectory, summary tables overall / by start
orientation / by global distance, statistics of model error vs subject-to-mean distances, figures.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from cobot_analysis.design import GLOBAL_DISTANCE_SPLIT
from cobot_analysis.models.ioc import Target, distances

#: models of the comparison: label -> (model, weights). "fitted" is filled in by the caller.
COMPARED = {
    "unicycle": ("unicycle", "walking-2021"),
    "clothoid": ("clothoid", None),
    "Mombaur OC": ("mombaur", "mombaur-2010"),
    "improved OC (published)": ("improved", "walking-2021"),
}


def orientation_of(condition: str) -> str:
    """Start orientation letter of a walking condition code ('' if not a walking code)."""
    from cobot_analysis.design import walking_condition

    try:
        return walking_condition(condition).orientation
    except ValueError:
        return ""


def compare_task(task) -> list[dict]:
    """Worker task: every compared model on one target (top-level, picklable)."""
    from cobot_analysis.models import generate
    from cobot_analysis.models.presets import weights_vector

    target, models, n_intervals, angle_weight, angle = task
    rows = []
    for label, (model, weights) in models.items():
        w = weights if isinstance(weights, str | None) else dict(zip(
            ("a0", "a1", "a2", "a3", "a4", "a5", "a6", "b0", "b1", "b2", "b3"), weights_vector(weights)))
        try:
            df = generate(model, target.start, target.goal, weights=w, n_samples=len(target.x), n_intervals=n_intervals)
            d = distances(target, df["x"].to_numpy(), df["y"].to_numpy(), df["theta"].to_numpy())
            ok = True
        except Exception as exc:  # noqa: BLE001 - a failed model is a flagged row, not a crash
            from cobot_analysis.errors import SolverError

            if not isinstance(exc, SolverError):
                raise
            d, ok = {"d_xy": math.nan, "d_theta": math.nan, "d_gamma": math.nan}, False
        rows.append({"model": label, "trial": target.trial, "condition": target.condition, "subject": target.subject,
                     "orientation": orientation_of(target.condition), "global_distance": target.global_distance,
                     **d, "D": d["d_xy"] + angle_weight * d[f"d_{angle}"], "converged": ok})
    return rows


def compare_models(targets: list[Target], models: dict, *, n_intervals: int = 100, angle: str = "gamma",
                   angle_weight: float = 0.5, jobs=None, scheduler=None, fit: str = "all") -> pd.DataFrame:
    """Distances of every model in ``models`` (label -> (model, weights)) to every target."""
    from cobot_analysis.parallel import map_tasks

    tasks = [(t, models, n_intervals, angle_weight, angle) for t in targets]
    rows = map_tasks(compare_task, tasks, jobs=jobs, scheduler=scheduler, description="model comparison")
    df = pd.DataFrame([r for rs in rows for r in rs])
    df.insert(1, "fit", fit)
    return df


def subject_distances(trials: list[Target], means: list[Target], angle: str = "gamma") -> pd.DataFrame:
    """Distance of each subject trajectory to the mean of its condition (METHODS.md sec. 4)."""
    by_condition = {m.condition: m for m in means}
    rows = []
    for t in trials:
        m = by_condition.get(t.condition)
        if m is None or len(m.x) != len(t.x):
            continue
        d = distances(m, t.x, t.y, t.theta)
        rows.append({"model": "subjects vs mean", "fit": "", "trial": t.trial, "condition": t.condition, "subject": t.subject,
                     "orientation": orientation_of(t.condition), "global_distance": m.global_distance, **d,
                     "D": d["d_xy"] + 0.5 * d[f"d_{angle}"], "converged": True})
    return pd.DataFrame(rows)


def _ms(v: pd.Series, digits: int = 3) -> str:
    v = v.dropna()
    return f"{v.mean():.{digits}f} ± {v.std(ddof=1):.{digits}f}" if len(v) > 1 else (f"{v.mean():.{digits}f}" if len(v) else "–")


def summary_table(df: pd.DataFrame, angle: str = "gamma") -> str:
    """Markdown: d_xy and d_<angle> (mean ± sd) per model, overall / by orientation / by global distance."""
    df = df.copy()
    df["distance group"] = np.where(df["global_distance"] < GLOBAL_DISTANCE_SPLIT, f"< {GLOBAL_DISTANCE_SPLIT:g} m",
                                    f"> {GLOBAL_DISTANCE_SPLIT:g} m")
    cols = [("all", None)]
    cols += [(f"θ0 {o}", ("orientation", o)) for o in "NESO" if (df["orientation"] == o).any()]
    cols += [(g, ("distance group", g)) for g in sorted(df["distance group"].unique())]
    lines = []
    for metric, unit in (("d_xy", "m"), (f"d_{angle}", "rad")):
        lines += [f"**{metric}** ({unit}, mean ± sd over trajectories)", "",
                  "| model | n | " + " | ".join(c for c, _ in cols) + " |", "|---|---|" + "---|" * len(cols)]
        for model, g in df.groupby("model", sort=False):
            cells = [_ms(g[metric] if sel is None else g.loc[g[sel[0]] == sel[1], metric]) for _, sel in cols]
            lines.append(f"| {model} | {g[metric].notna().sum()} | " + " | ".join(cells) + " |")
        lines.append("")
    failed = df.loc[~df["converged"].astype(bool)]
    if len(failed):
        lines.append(f"Not converged (left out of the means): {len(failed)} of {len(df)} model runs "
                     f"({', '.join(sorted(set(failed['model'])))}).")
        lines.append("")
    return "\n".join(lines)


def statistics(df: pd.DataFrame, model: str, angle: str = "gamma", alpha: float = 0.05) -> str:
    """Model error vs subject-to-mean distances (Mann-Whitney), across models (Kruskal), and the
    effect of start orientation (4 groups) and global distance (2 groups) on the model's error
    (KS normality, then ANOVA if normal else Kruskal / Mann-Whitney) (METHODS.md sec. 4)."""
    from cobot_analysis.stats import tests

    def line(name, r) -> str:
        sig = "significant" if r.p < alpha else "not significant"
        ns = ", ".join(f"{k}: {v}" for k, v in r.n.items())
        return (f"- {name}: {r.test} statistic = {r.statistic:.3g}, p = {r.p:.3g} ({sig} at {alpha}), n = ({ns}), "
                f"{r.effect_name} = {r.effect_size:.3g}")

    out = []
    ok = df[df["converged"].astype(bool)]
    mine = ok[ok["model"] == model]
    subj = ok[ok["model"] == "subjects vs mean"]
    for metric in ("d_xy", f"d_{angle}"):
        if len(mine) >= 2 and len(subj) >= 2:
            out.append(line(f"{metric}, {model} vs subjects-to-mean",
                            tests.mannwhitneyu({model: mine[metric].dropna(), "subjects": subj[metric].dropna()})))
        groups = {m: g[metric].dropna().to_numpy() for m, g in ok.groupby("model", sort=False) if m != "subjects vs mean"}
        groups = {k: v for k, v in groups.items() if len(v) >= 2}
        if len(groups) >= 2:
            out.append(line(f"{metric}, across models", tests.kruskal(groups)))
        for factor, label in (("orientation", "start orientation"), ("global_distance", "global distance < / > 3 m")):
            key = mine[factor] if factor == "orientation" else np.where(mine[factor] < GLOBAL_DISTANCE_SPLIT, "<3m", ">3m")
            g = {k: v[metric].dropna().to_numpy() for k, v in mine.groupby(key) if k and len(v) >= 2}
            if len(g) < 2:
                continue
            normal = all(tests.normality(v, "ks") >= alpha for v in g.values())
            r = tests.anova(g) if normal else (tests.kruskal(g) if len(g) > 2 else tests.mannwhitneyu(g))
            out.append(line(f"{metric} of {model} by {label} ({'normal: ANOVA' if normal else 'not normal (KS)'})", r))
    return "\n".join(out) + "\n"


def figure_paths(targets: list[Target], generated: dict[str, list[pd.DataFrame]], title: str):
    """Generated vs measured paths per trajectory, with orientation arrows every 50 samples."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(targets)
    cols = min(8, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.2 * cols, 2.2 * rows), squeeze=False)
    colors = {"measured": "k"}
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    for i, t in enumerate(targets):
        ax = axes[i // cols][i % cols]
        series = [("measured", t.x, t.y, t.theta)] + [(lab, g[i]["x"].to_numpy(), g[i]["y"].to_numpy(), g[i]["theta"].to_numpy())
                                                     for lab, g in generated.items() if g[i] is not None]
        for j, (lab, x, y, th) in enumerate(series):
            c = colors.get(lab, palette[(j - 1) % len(palette)])
            ax.plot(x, y, color=c, lw=1.2 if lab == "measured" else 0.9, label=lab)
            k = np.arange(0, len(x), 50)
            ax.quiver(x[k], y[k], np.cos(th[k]), np.sin(th[k]), color=c, scale=18, width=0.006)
        ax.set_title(t.condition or t.trial, fontsize=7)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=5)
    for j in range(n, rows * cols):
        axes[j // cols][j % cols].axis("off")
    axes[0][0].legend(fontsize=5, loc="best")
    fig.suptitle(title, fontsize=9)
    return fig


def figure_boxplots(df: pd.DataFrame, angle: str = "gamma"):
    """Box plots (median, quartiles, whiskers 1.5 IQR, outliers) of d_xy and d_angle per model."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = list(dict.fromkeys(df["model"]))
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    for ax, metric, unit in zip(axes, ("d_xy", f"d_{angle}"), ("m", "rad")):
        ax.boxplot([df.loc[df["model"] == m, metric].dropna() for m in models], whis=1.5, showfliers=True)
        ax.set_xticks(range(1, len(models) + 1), models, rotation=30, ha="right", fontsize=7)
        ax.set_ylabel(f"{metric} ({unit})")
    fig.tight_layout()
    return fig
