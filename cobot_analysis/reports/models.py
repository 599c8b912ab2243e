"""The report of the model stages (docs/methods.md sec. 4-6): summary tables overall / by start
orientation / by global distance, statistics of model error vs subject-to-mean distances, figures of
generated vs measured paths, flags of durations and weights at a bound, and the coupled model's section.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.design import GLOBAL_DISTANCE_SPLIT
from cobot_analysis.models.ioc import FAILED_D, Target


def p_text(p: float) -> str:
    """A p-value in 3 significant digits; 0 is a survival function that underflowed (chi2(2) at Q = 2000 is about
    exp(-1000)), printed as the bound it is: '< 1e-300'."""
    return "< 1e-300" if p == 0 else f"{p:.3g}"


def _ms(v: pd.Series, digits: int = 3, ddof: int = 1) -> str:
    v = v.dropna()
    return f"{v.mean():.{digits}f} ± {v.std(ddof=ddof):.{digits}f}" if len(v) > 1 else (f"{v.mean():.{digits}f}" if len(v) else "–")


def summary_table(df: pd.DataFrame, angle: str = "gamma", ddof: int = 1) -> str:
    """Markdown: d_xy and d_<angle> (mean ± sd, ``ddof`` of the sd) per model, overall / by orientation
    / by global distance."""
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
            g = g[g["converged"].astype(bool)]  # a run that did not converge (or missed its goal, continuous) is left out
            cells = [_ms(g[metric] if sel is None else g.loc[g[sel[0]] == sel[1], metric], ddof=ddof) for _, sel in cols]
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
    (KS normality, then ANOVA if normal else Kruskal / Mann-Whitney) (docs/methods.md sec. 4)."""
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


def _panel_grid(n: int, max_cols: int, size: float, cells: list[tuple[int, int]] | None = None):
    """A figure with ``n`` square panels (inches ``size``), at most ``max_cols`` per row, or one per
    (row, column) of ``cells``; returns (fig, 2-D array of axes), the unused axes hidden."""
    from cobot_analysis.reports.figures import path_grid

    cols = max(1, min(max_cols, n))
    return path_grid(cells or [divmod(i, cols) for i in range(max(n, 1))], size)


def _finish_grid(fig, axes, n: int, title: str, fontsize: float, cells: list[tuple[int, int]] | None = None,
                 group=None):
    """The ``n`` used panels (first ``n`` in reading order, or ``cells``): ticks at ``fontsize``, axis
    labels in metres, one figure legend under the title (columns grouped by ``group(label)``).
    Windows and scales are set before (``figures.square_groups``), arrows sized to them."""
    from cobot_analysis.reports.figures import figure_legend

    cells = cells or [divmod(j, axes.shape[1]) for j in range(n)]
    used = [axes[r][c] for r, c in cells[:n]]
    for ax in used:
        ax.tick_params(labelsize=fontsize)
    fig.supxlabel("x (m)")
    fig.supylabel("y (m)")
    figure_legend(fig, used, ncols=3, title=title, group=group)
    return fig


def figure_paths(targets: list[Target], generated: dict[str, list[pd.DataFrame]], title: str, *,
                 labels: dict[str, str] | None = None):
    """Generated vs measured paths, one panel per trajectory (walking conditions: start position x
    start orientation grid, one scale per row), 8 orientation arrows along each path. ``labels``:
    legend name of each generated set (default "model, <key> weights" for published / fitted / start)."""
    from cobot_analysis.reports import figures as F

    n = len(targets)
    conds = [t.condition for t in targets]
    codes = {t.condition for t in targets if t.orientation}  # walking-2020 codes the paths agree with
    grid = F.walking_grid(conds, codes) if len(set(conds)) == n else None  # one panel per walking condition
    cells = [grid[c] for c in conds] if grid else None
    fig, axes = _panel_grid(n, max_cols=8, size=2.4 if grid else 2.2, cells=cells)
    cells = cells or [divmod(i, axes.shape[1]) for i in range(n)]
    used = [axes[r][c] for r, c in cells[:n]]
    names = {"measured": "measured", **{lab: (labels or {}).get(lab, f"model, {lab} weights" if lab in ("published", "fitted", "start") else lab)
                                         for lab in generated}}
    palette = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    colors = {"measured": "k", **{lab: palette[k % len(palette)] for k, lab in enumerate(generated)}}
    series = []
    for i, t in enumerate(targets):
        s = [("measured", t.x, t.y, t.theta)] + [(lab, g[i]["x"].to_numpy(), g[i]["y"].to_numpy(), g[i]["theta"].to_numpy())
                                                for lab, g in generated.items() if g[i] is not None]
        for lab, x, y, _ in s:
            used[i].plot(x, y, color=colors[lab], lw=1.4 if lab == "measured" else 1.0, zorder=3 if lab == "measured" else 2,
                         label=names[lab])
        failed = [names[lab] for lab, g in generated.items() if g[i] is None]
        if failed:
            used[i].text(0.03, 0.03, "no solution: " + ", ".join(failed), transform=used[i].transAxes, fontsize=6, color="0.3")
        series.append(s)
    sides = F.square_groups(used, [c[0] if grid else -1 - i for i, c in enumerate(cells)])
    for ax, s, side in zip(used, series, sides):
        for lab, x, y, th in s:
            F.orientation_arrows(ax, x, y, th, 8, 0.07 * side, colors[lab], f"{names[lab]}: orientation θ")
    cols = [o for o in F.WALKING_COLUMNS if any(c[0] == o for c in conds)] if grid else []
    unique = len(set(conds)) == n and all(conds)
    F.panel_titles(used, cells, [F.walking_title(c) if grid else (c if unique else t.trial) for c, t in zip(conds, targets)],
                   [F.WALKING_COLUMNS[o] for o in cols] if grid else None, fontsize=7)
    return _finish_grid(fig, axes, n, title, fontsize=6, cells=cells, group=lambda lab: lab.split(": ")[0])


def figure_boxplots(df: pd.DataFrame, angle: str = "gamma", title: str = ""):
    """Box plots (median, quartiles, whiskers to 1.5 IQR, outliers) of d_xy and d_angle per model,
    the number of trajectories under each box; ``title`` above them."""
    from cobot_analysis.plotting import pyplot

    plt = pyplot()
    models = list(dict.fromkeys(df["model"]))
    fig, axes = plt.subplots(1, 2, figsize=(max(8.0, 2.2 * len(models) + 2), 4.2), layout="constrained")
    if title:
        fig.suptitle(title)
    for ax, metric, unit in zip(axes, ("d_xy", f"d_{angle}"), ("m", "rad")):
        values = [df.loc[df["model"] == m, metric].dropna().to_numpy(float) for m in models]
        ax.boxplot(values, whis=1.5, showfliers=True, widths=0.6, medianprops={"color": "k", "lw": 1.5},
                   flierprops={"marker": "o", "ms": 3, "mfc": "none", "alpha": 0.7})
        ax.set_xticks(range(1, len(models) + 1), [f"{m.replace(' (', chr(10) + '(')}\n(n = {len(v)})" for m, v in zip(models, values)],
                      fontsize=7)
        ax.set_xlabel("model")
        ax.set_ylabel(f"{metric} to the measured path ({unit})")
    return fig


def comparison_title(model: str, convention: str) -> str:
    """Title of ``figure_boxplots`` in fit-ioc: what is compared, under which convention."""
    return f"Distances of each model's paths to the mean paths ({model} OC fitted, {convention} convention)"


def paths_title(model: str, convention: str) -> str:
    """Title of fit-ioc's ``figure_paths``: the fitted model (improved or table) under its convention."""
    return f"mean (black) vs {model} OC: published, fitted weights ({convention} convention)"


# ---- T at its bound (every model) ----------------------------------------------------------------
def duration_flag(terms: list[dict], v_nominal: float = 1.0, convention: str = "continuous", bounds=None) -> str:
    """Markdown line: how many converged lower levels put the duration T on a bound: of ``bounds`` x T0
    (continuous, default ``ioc.T_BOUNDS``, the walker rules' ``OCRule.T_bounds``; there the fitted weights ask
    for a duration the problem does not allow), or of the authors' duration search, T < 200 d steps
    (published; J / T decreases with T, so the rule ends there)."""
    from cobot_analysis.models.ioc import T_BOUNDS

    T_BOUNDS = bounds or T_BOUNDS
    ok = [d for d in terms if d.get("success")]
    lo = sum(d.get("T_at_bound", 0) == -1 for d in ok)
    hi = sum(d.get("T_at_bound", 0) == 1 for d in ok)
    ratio = [d["T"] / d["T0"] for d in ok if d.get("T0")]
    if convention == "published":
        span = f"; T from {min(d['T'] for d in ok):.1f} to {max(d['T'] for d in ok):.1f} s" if ok else ""
        return (f"Duration: the authors' rule (Nelder-Mead on J / T from int(2/3 100 d) steps, T < 200 d steps) ends on its "
                f"upper bound for {hi} of {len(ok)} paths{span}: J / T = a0 / dt + J' / T (J' the cost without a0) keeps "
                "decreasing with T, so the rule takes the longest horizon it allows (20 s per metre of start-goal distance).")
    span = f"; T / T0 from {min(ratio):.2f} to {max(ratio):.2f}" if ratio else ""
    head = (f"**Warning: fitted duration T at its bound** ({T_BOUNDS[0]:g}, {T_BOUNDS[1]:g}) x T0 (T0 = start-goal "
            f"distance / {v_nominal:g} m/s + 1 s)" if lo + hi else f"Fitted duration T inside its bounds ({T_BOUNDS[0]:g}, {T_BOUNDS[1]:g}) x T0")
    return f"{head}: {lo + hi} of {len(ok)} paths ({lo} at the lower, {hi} at the upper bound){span}."


def weight_limit_flag(weights: dict[str, float], fitted: tuple[str, ...]) -> str:
    """Markdown line naming the fitted weights that end within a factor 1.12 (``fit.AT_LIMIT``, 0.05 in log10) of the
    search limits ``fit.LOG_BOUNDS``; there the data ask for a term the bounds cut, so the weight is a bound, not an estimate."""
    from cobot_analysis.models.ioc.fit import LOG_BOUNDS, search_limit_at

    near = [f"{n} = {weights[n]:.3g} at the {'lower' if search_limit_at(weights[n]) == LOG_BOUNDS[0] else 'upper'} limit"
            for n in fitted if search_limit_at(weights[n]) is not None]
    if not near:
        return f"Fitted weights inside the search limits 1e{LOG_BOUNDS[0]:g}..1e{LOG_BOUNDS[1]:g}."
    return (f"**Warning: fitted weights at a search limit** (1e{LOG_BOUNDS[0]:g}..1e{LOG_BOUNDS[1]:g}): {', '.join(near)}; "
            "the optimum may lie beyond the limit, so these values bound the estimate rather than estimate it.")


def coupled_summary(df: pd.DataFrame) -> str:
    """Markdown: d_xy and d_theta (mean ± sd over paths) per weight set and carrier, by direction."""
    lines = []
    for metric, unit in (("d_xy", "m"), ("d_theta", "rad")):
        lines += [f"**{metric}** of each carrier ({unit}, mean ± sd over the mean paths; carrier 1 = Subject 1 forward, "
                  "Subject 2 on returns)", "", "| weights | carrier | forward | return | all |", "|---|---|---|---|---|"]
        for (model, carrier), g in df.groupby(["model", "carrier"], sort=False):
            cells = [_ms(g.loc[g["direction"] == dr, metric]) for dr in ("forward", "return")] + [_ms(g[metric])]
            lines.append(f"| {model} | {carrier} | " + " | ".join(cells) + " |")
        lines.append("")
    failed = df.loc[~df["converged"].astype(bool)]
    if len(failed):
        lines += [f"Not converged (left out of the means): {failed['trial'].nunique()} of {df['trial'].nunique()} paths "
                  f"({', '.join(sorted(set(failed['model'])))}).", ""]
    return "\n".join(lines)


def weights_table(names: tuple[str, ...], columns: dict[str, dict[str, float]], fitted: tuple[str, ...]) -> str:
    """Markdown: one row per weight, one column per weight set; fitted weights marked."""
    lines = ["| weight | fitted | " + " | ".join(columns) + " |", "|---|---|" + "---|" * len(columns)]
    for n in names:
        lines.append(f"| {n} | {'yes' if n in fitted else 'held'} | " + " | ".join(f"{w[n]:.3g}" for w in columns.values()) + " |")
    return "\n".join(lines) + "\n"


def figure_pair_paths(targets, paths: dict[str, list], title: str):
    """Generated vs mean paths of both carriers (carrier 1 solid, carrier 2 dashed), one panel per
    target (its own scale), 6 orientation arrows along each path; measured in black."""
    from cobot_analysis.reports import figures as F

    n = len(targets)
    fig, axes = _panel_grid(n, max_cols=4, size=3.0)
    cells = [divmod(j, axes.shape[1]) for j in range(n)]
    used = [axes[r][c] for r, c in cells]
    palette = {lab: c for lab, c in zip(paths, ("tab:blue", "tab:orange", "tab:green", "tab:red"))}
    names = {"mean": "measured mean", **{lab: f"model, {lab} weights" if lab in ("published", "fitted", "start") else lab for lab in paths}}
    drawn = []
    for j, t in enumerate(targets):
        series = [("mean", "k", [(c.x, c.y, c.theta) for c in t.carriers])]
        series += [(lab, palette[lab], [(np.asarray(p["x"]), np.asarray(p["y"]), np.asarray(p["theta"])) for p in ps[j]])
                   for lab, ps in paths.items() if ps[j] is not None]
        for lab, color, carriers in series:
            for i, (x, y, _) in enumerate(carriers):
                used[j].plot(x, y, color=color, ls="-" if i == 0 else "--", lw=1.3 if lab == "mean" else 1.0,
                             zorder=3 if lab == "mean" else 2, label=f"{names[lab]}: carrier {i + 1}")
        failed = [names[lab] for lab, ps in paths.items() if ps[j] is None]
        if failed:
            used[j].text(0.03, 0.03, "not converged: " + ", ".join(failed), transform=used[j].transAxes, fontsize=6, color="0.3")
        drawn.append(series)
    sides = F.square_groups(used, range(n))
    for ax, series, side in zip(used, drawn, sides):
        for lab, color, carriers in series:
            for x, y, th in carriers:
                F.orientation_arrows(ax, x, y, th, 6, 0.07 * side, color, f"{names[lab]}: orientation θ")
    F.panel_titles(used, cells, [t.trial.replace("_sc3", "") for t in targets], fontsize=7)
    return _finish_grid(fig, axes, n, title + "\ncarrier 1 = Subject 1 on forward paths, Subject 2 on returns", fontsize=6,
                        cells=cells, group=lambda lab: lab.split(": ")[0])


def coupled_section(result, coupled, targets, stage, durations: pd.DataFrame | None = None) -> list[str]:
    """results.md lines of the coupled fit: paths used, D before / after, weights beside the published
    ones, per-carrier distances by direction, model durations T beside the measured scenario-3 trial
    durations (``durations``: the published durations table, optional), and the figure ``pair_paths``."""
    from cobot_analysis.models.presets import COUPLED_WEIGHTS, PRESETS

    df, paths = coupled
    spec = result.spec
    n_dir = {d: sum(t.direction == d for t in targets) for d in ("forward", "return")}
    D = df.groupby(["model", "trial"], sort=False)["D"].sum(min_count=2).groupby(level=0, sort=False).mean()
    lines = ["### Coupled model on the scenario-3 means", "",
             f"Paths: {n_dir['forward']} forward + {n_dir['return']} return scenario-3 mean paths of the two carriers "
             "(docs/methods.md 6: 13 + 18 in the published data), Subject 2 as carrier 1 on returns. "
             f"D = d_xy,1 + d_xy,2 + 0.5 (d_theta,1 + d_theta,2) per path, averaged: {result.start_objective:.4f} at the start "
             f"weights, {result.objective:.4f} fitted ({result.evaluations} upper-level evaluations, {result.iterations} "
             f"iterations); lower levels not converged at the fitted weights: {result.failed} of {len(targets)} "
             f"(each counted as D = {FAILED_D:g}, never averaged in silently).", "",
             "Weights (the fit starts from the model preset unless --start-weights says otherwise"
             + ("; a0 (the price of a second) and a1 are held: D compares time-normalised paths, and scaling the "
                "acceleration weights by c^4 only makes every path c times slower (docs/methods.md sec. 6); b0..b3 are "
                "held because both carriers end on their goals at rest, a constraint" if "a0" not in spec.fitted else "") + "):", "",
             weights_table(COUPLED_WEIGHTS, {"published (pair-2022)": PRESETS["pair-2022"],
                                             "start": dict(zip(COUPLED_WEIGHTS, spec.start_weights)),
                                             "fitted": result.weights}, spec.fitted),
             "Both weight sets re-solved from cold guesses (best of 'rest' and 'line'): mean D "
             + ", ".join(f"{m} {v:.4f}" for m, v in D.items()) + ".", "",
             coupled_summary(df)]
    lines += duration_lines(df, targets, durations, spec.v_nominal)
    conditions = list(dict.fromkeys(t.condition for t in targets))
    picked = [conditions[int(i)] for i in np.unique(np.linspace(0, len(conditions) - 1, min(4, len(conditions))).round())]
    idx = [next(i for i, t in enumerate(targets) if t.condition == c and t.direction == d)
           for c in picked for d in ("forward", "return") if any(t.condition == c and t.direction == d for t in targets)]
    stage.savefig(figure_pair_paths([targets[i] for i in idx], {lab: [ps[i] for i in idx] for lab, ps in paths.items()},
                                    "scenario-3 means (black; carrier 1 solid, carrier 2 dashed) vs coupled OC"), "pair_paths")
    lines += ["![generated vs mean paths of both carriers](pair_paths.png)", "",
              f"*Mean and generated paths of both carriers for {len(picked)} goals, forward and return* "
              "([PDF](pair_paths.pdf))", ""]
    return lines


def duration_lines(df: pd.DataFrame, targets, durations: pd.DataFrame | None, v_nominal: float) -> list[str]:
    """Markdown: duration T of the pair's OC solutions per weight set and direction, how many sit on a
    bound of ``T_BOUNDS`` x T0, and the measured scenario-3 durations (mean over the pairs' trials of
    the same goal, configuration and direction) in units of T0."""
    from cobot_analysis.models.oc.coupled import initial_pair_duration
    from cobot_analysis.models.ioc import T_BOUNDS

    T0 = {t.trial: initial_pair_duration(t.start, t.goal, v_nominal) for t in targets}
    lines = [f"Duration T of the pair (free, bounded to ({T_BOUNDS[0]:g}, {T_BOUNDS[1]:g}) x T0, T0 = longest carrier "
             f"distance / {v_nominal:g} m/s + 1 s; s, mean ± sd over the mean paths):", "",
             "| | forward | return | on a bound |", "|---|---|---|---|"]
    for model, g in df[df["carrier"] == 1].groupby("model", sort=False):
        ok = g[g["converged"].astype(bool)]
        cells = [_ms(ok.loc[ok["direction"] == dr, "T"], 2) for dr in ("forward", "return")]
        lines.append(f"| {model} | {cells[0]} | {cells[1]} | {int((ok['T_at_bound'] != 0).sum())} of {len(ok)} |")
    if durations is not None and {"scenario", "condition", "direction", "duration"} <= set(durations.columns):
        sc3 = durations[durations["scenario"] == 3]
        rows = []
        for t in targets:
            m = sc3[(sc3["condition"] == t.condition) & (sc3["direction"] == t.direction)]["duration"].dropna()
            if len(m):
                rows.append({"direction": t.direction, "T": m.mean(), "ratio": m.mean() / T0[t.trial]})
        meas = pd.DataFrame(rows)
        if len(meas):
            cells = [_ms(meas.loc[meas["direction"] == dr, "T"], 2) for dr in ("forward", "return")]
            over = int((meas["ratio"] > T_BOUNDS[1]).sum())
            lines += [f"| measured (durations.parquet, scenario 3, mean over trials per goal and direction) | {cells[0]} | "
                      f"{cells[1]} | {over} of {len(meas)} above {T_BOUNDS[1]:g} x T0 |", "",
                      f"Measured duration / T0 from {meas['ratio'].min():.2f} to {meas['ratio'].max():.2f}."]
            for model, g in df[(df["carrier"] == 1) & df["converged"].astype(bool)].groupby("model", sort=False):
                k = int((g["T_at_bound"] != 0).sum())
                if k:
                    lines[-1] += (f" {model}: {k} of {len(g)} durations on a bound, {g['T'].mean() / meas['T'].mean():.1f} x "
                                  "the measured ones on average. D compares time-normalised paths and does not see the "
                                  "duration: these weights describe the shape of the paths, not their timing.")
    else:
        lines += ["", "No published trial durations in this workspace (import-published/durations.parquet)."]
    return lines + [""]


# ---- the stages' results fragments ---------------------------------------------------------------
def generate_markdown(result, summary: str, weigh: str = "trials") -> str:
    """Generated paths: per trajectory the duration T, the mean speed (its time law), the subjects' own
    where the data hold them, the cost and the end's distance to the goal (``generated_section``); ``weigh``: how
    the means the poses come from were weighed (``average --weigh``)."""
    grid = (f"OC grid {result.n_intervals} intervals resampled to {result.n_samples} samples" if result.convention == "continuous" else
            "the authors' node step and duration rule, paths at their nodes")
    goals = sorted({(round(g[0], 3), round(g[1], 3), round(math.remainder(g[2], 2 * math.pi), 3)) for _, _, g in result.cases})
    pairs = result.study == "pair-carriage-2022"
    what = (f"the {len(result.cases)} per-scenario table means of the pair study, each from its first to its last measured "
            "pose (as fit-ioc --model table compares them; the pooled means left out)" if pairs else
            f"goal{'s' if len(goals) > 1 else ''} {goals[0] if len(goals) == 1 else f'of the {len(goals)} measured means'}")
    lines = [f"## Generated trajectories ({result.convention} convention{', pair study' if pairs else ''})", "",
             f"Models {', '.join(result.models)}; weights {result.weights or 'model presets'}; {what}; "
             f"{grid} (docs/methods.md sec. 11: {summary})."
             + (f" The poses come from the means weighted by {weigh} (`average --weigh {weigh}`): the mean of each "
                "subject's (pair's) mean." if weigh != "trials" else ""), "",
             *generated_section(result.generated, result.convention, result.measured_by_trial(),
                                source=PAIR_PACE if pairs else WALKING_PACE)]
    return "\n".join(lines) + "\n"


#: where the subjects' durations and speeds beside the generated paths come from (``generated_section``)
WALKING_PACE = ("their travel times, or where the data hold none (walking-2020) path length / the mean of their recorded "
                "speed (models.ioc.pace.subject_durations)")
PAIR_PACE = ("the means' travel times (speed: the mean path's length / travel time), or where the means hold none "
             "(pair-carriage-2022) the published durations: the mean duration and mean table velocity over the trials of "
             "the same scenario, goal and direction (import-published/durations.parquet; they do not record the end "
             "orientation, so both end orientations of a goal share them)")


def generated_section(df: pd.DataFrame, convention, measured: dict[str, tuple[float, float]] | None = None, *,
                      source: str = WALKING_PACE) -> list[str]:
    """results.md lines of ``generate``: per path its duration T, mean speed (the time law), the
    subjects' own where the data hold them (``measured``: trial -> (travel time, mean speed); ``source``: where
    they come from), the end's distance to the goal and whether it reached it (``models.goal_check``), and a summary."""
    from cobot_analysis import conventions
    from cobot_analysis.models import GOAL_TOLERANCE

    conv = conventions.get(convention)
    measured = {k: v for k, v in (measured or {}).items() if np.isfinite(v[0])}
    ends = df.groupby("trial", sort=False).tail(1).set_index("trial")
    cols = " subjects' T (s) | subjects' mean speed (m/s) |" if measured else ""
    lines = [f"| trial | T (s) | mean speed (m/s) |{cols} cost | end error (m) | heading error (rad) | goal reached | status |",
             "|---|---|---|" + ("---|---|" if measured else "") + "---|---|---|---|---|"]
    for trial, r in ends.iterrows():
        mine = ""
        if measured:
            mine = " {:.2f} | {:.2f} |".format(*measured[trial]) if trial in measured else " – | – |"
        cell = str(trial).replace("|", "\\|")  # a synthetic mean's name holds its grouping keys, joined by '|'
        lines.append(f"| {cell} | {r.travel_time:.2f} | {r.mean_speed:.2f} |{mine} {r.cost:.3f} | {r.end_position_error:.3f} | "
                     f"{r.end_heading_error:.3f} | {'yes' if r.goal_reached else 'no'} | {r.status} |")
    n, reached = len(ends), int(ends["goal_reached"].sum())
    v = ends["mean_speed"]
    missed = ends.index[~ends["goal_reached"].astype(bool)].tolist()
    summary = [
        f"Goal reached (end within {GOAL_TOLERANCE[0] * 100:g} cm and {GOAL_TOLERANCE[1]:g} rad): {reached} of {n} paths"
        + (f"; not reached: {', '.join(missed[:10])}{', ...' if len(missed) > 10 else ''} (status column)" if missed else "")
        + (". Under the continuous convention the goal at rest is a constraint of the OC problem (docs/methods.md "
           "sec. 5.5): a path that misses it did not converge." if conv.name == "continuous" else
           ". Under the published convention the goal is the terminal cost of the authors' models: a path may end "
           "near it, not on it."), "",
        f"Time law: durations T from {ends['travel_time'].min():.2f} to {ends['travel_time'].max():.2f} s, mean speed "
        f"(path length / T) from {v.min():.3g} to {v.max():.3g} m/s (median {v.median():.3g})"
        + (" (" + "; ".join(f"{m}: T {g['travel_time'].min():.2f}-{g['travel_time'].max():.2f} s, {g['mean_speed'].min():.3g}-"
                            f"{g['mean_speed'].max():.3g} m/s" for m, g in ends.groupby("model", sort=False)) + ")"
           if ends["model"].nunique() > 1 else "")
        + (". The authors' duration rule ends on its upper bound (20 s per metre of start-goal distance, docs/methods.md "
           "sec. 11): the shape of the path is what the papers compare, its timing is no human pace; time-dependent "
           "outputs (velocities, velocity-commands) need the continuous convention" if conv.name == "published" else "")
        + f"; {int(((v < 0.5) | (v > 2.0)).sum())} of {n} outside 0.5-2 m/s"
        + (f"; **{int(ends['status'].astype(str).str.startswith('duration on a bound').sum())} durations on a bound of "
           "their search** (status column)" if ends["status"].astype(str).str.startswith("duration on a bound").any() else "")
        + ("." + (f" The subjects' own ({_subject_pace(ends, measured)}) are in the table: {source}."
                  if measured else
                  " The input holds no subjects' durations to compare with (no travel times, no velocity rows).")), "",
        heading_line(df), ""]
    return summary + lines + [""]


def heading_line(df: pd.DataFrame) -> str:
    """Markdown: how the generated paths' headings turn (``models.heading_turns``): the paths that turn from their
    start to their goal heading more than half a turn beyond the shortest turn (the two headings given on other
    branches), those that spin (turning more than a full turn beyond their net turn, ``models.spins``) and the
    largest turning rate. Neither is a walker's path: named, never hidden."""
    from cobot_analysis.models import heading_turns, spins

    thetas = {trial: g["theta"].to_numpy(float) for trial, g in df.groupby("trial", sort=False)}
    turns = {trial: heading_turns(theta) for trial, theta in thetas.items()}
    n = len(turns)
    long_way = [t for t, h in turns.items() if abs(h["net"]) - abs(h["shortest"]) > math.pi]
    spin = [t for t, theta in thetas.items() if spins(theta)]
    omega = np.abs(df["omega"].to_numpy(float)) if "omega" in df else np.array([np.nan])
    rate = f"largest |omega| {np.nanmax(omega):.3g} rad/s" if np.isfinite(omega).any() else ""

    def named(trials):
        return ", ".join(map(str, trials[:10])) + (", ..." if len(trials) > 10 else "")

    if not long_way and not spin:
        return (f"Heading: every path turns from its start to its goal heading within half a turn of the shortest turn, "
                f"and none spins (turns more than a full turn beyond its net turn){'; ' + rate if rate else ''}.")
    parts = []
    if long_way:
        parts.append(f"{len(long_way)} of {n} paths turn from their start to their goal heading more than half a turn beyond "
                     f"the shortest turn ({named(long_way)}): the two headings were given on other branches (with --study, "
                     "the measured first theta and the goal on the branch of the last measured theta, docs/methods.md sec. "
                     "5.3), so the model walks the turns the measured heading winds through")
    if spin:
        parts.append(f"{len(spin)} of {n} paths spin, their heading turning more than a full turn beyond their net turn "
                     f"(sum |d theta| - |theta_N - theta_0| > 2 pi; {named(spin)}): the model prices the turning rate's "
                     "changes by a3 alone (docs/methods.md sec. 5.5), and with a3 near zero omega can alternate in sign "
                     "from node to node at almost no cost")
    return f"**Heading: no walker's turn**{f' ({rate})' if rate else ''}: " + "; ".join(parts) + "."


def turning_lines(turning: pd.DataFrame) -> list[str]:
    """Markdown: what walker-like paths cost (``models.turning_price``): per a3 the model paths that spin, D and the
    paired test against the fitted weights, then the least a3 at which none spins and whether the means reject it."""
    n = int(turning["paths"].iloc[0])
    lines = ["What walker-like paths would cost (docs/methods.md sec. 5.5, `models.turning_price`): a3, the only price of "
             "the turning rate's changes, raised by decades until no path spins, the other weights as fitted; the model "
             "paths on the means (generate's grid), those that spin, their D and the paired test of the per-mean rises of D "
             "against the fitted weights (the profile likelihood's, sec. 6.3: rejected when significant at 95 % and above "
             "0.1 % of D).", "",
             "| a3 | paths that spin | D | t (95 % bound) | rejected by the means |", "|---|---|---|---|---|"]
    for i, r in turning.iterrows():
        test = "" if i == 0 else f"{r['t']:.3g} ({r['t_q']:.3g})"
        verdict = "(the fitted weights)" if i == 0 else "yes" if r["rejected"] else "no"
        lines.append(f"| {r['a3']:.3g} | {int(r['spinning'])} of {n} | {r['D']:.4f} | {test} | {verdict} |")
    calm = turning[turning["spinning"] == 0]
    if calm.empty:
        lines += ["", "Every a3 up to the search limit leaves some path spinning.", ""]
        return lines
    r, D0 = calm.iloc[0], float(turning["D"].iloc[0])
    lines += ["", f"The least a3 at which no path spins: {r['a3']:.3g}, D {r['D']:.4f} against {D0:.4f} "
                  f"({100 * (r['D'] / D0 - 1):+.1f} %): "
              + ("the means reject it (the other weights as fitted; a3's profile likelihood, where the verdicts computed "
                 "one, refits them): on these means a walker's heading costs this model that much fit." if r["rejected"] else
                 "the means do not reject it: those weights fit them as well and make walker-like paths (`generate "
                 "--weights` with a3 set to it)."), ""]
    return lines


def _subject_pace(ends: pd.DataFrame, measured: dict) -> str:
    """'T a-b s, mean speed a-b m/s, k of n outside 0.5-2 m/s; model T / subjects' T a-b' on the generated
    paths' conditions: the human range the model's time law is judged against."""
    have = [t for t in ends.index if t in measured]
    if not have:
        return "none on these paths"
    m = np.array([measured[t] for t in have])
    ratio = ends.loc[have, "travel_time"].to_numpy(float) / m[:, 0]
    outside = int(np.sum((m[:, 1] < 0.5) | (m[:, 1] > 2.0)))
    return (f"T {m[:, 0].min():.2f}-{m[:, 0].max():.2f} s, mean speed {m[:, 1].min():.3g}-{m[:, 1].max():.3g} m/s, "
            f"{outside} of {len(m)} outside 0.5-2 m/s; model T / subjects' T {np.nanmin(ratio):.2f}-{np.nanmax(ratio):.2f}, "
            f"median {np.nanmedian(ratio):.2f}")


def pace_lines(mean_keys: pd.DataFrame | None, targets, per_target: list[dict], durations: pd.DataFrame | None,
               pace: dict | None = None) -> list[str]:
    """Markdown: duration T and mean speed (path length / T) of the fitted paths (continuous convention),
    how many T sit on a bound, and beside them the subjects': with ``pace`` (``IOCResult.pace``, the time
    gauge fitted to the subjects' durations, docs/methods.md sec. 6.4) per target; else the pair study's
    ``durations`` (mean over the trials of the same scenario, goal and direction as each mean;
    ``mean_keys``: those columns per mean trial)."""
    ok = [(t, d) for t, d in zip(targets, per_target) if d.get("success") and d.get("length") is not None]
    if not ok:
        return []
    T = np.array([d["T"] for _, d in ok])
    v = np.array([d["length"] / d["T"] for _, d in ok])
    bound = sum(d.get("T_at_bound", 0) != 0 for _, d in ok)
    line = (f"Time law of the fitted paths: T {T.min():.2f}-{T.max():.2f} s, mean speed (path length / T) "
            f"{v.min():.3g}-{v.max():.3g} m/s (median {np.median(v):.3g}); "
            + (f"**{bound} of {len(ok)} durations on a bound**" if bound else f"no duration on a bound ({len(ok)} paths)"))
    if pace is not None:
        return _gauge_lines(line, targets, per_target, pace)
    keys = ["scenario", "condition", "direction"]
    if durations is None or mean_keys is None or not set(keys + ["duration", "mean_velocity"]) <= set(durations.columns) or \
            not set(keys) <= set(mean_keys.columns):
        return [line + ". The input holds no measured durations to compare with.", ""]
    meta = mean_keys[keys]
    measured = durations.groupby(keys)[["duration", "mean_velocity"]].mean()
    rows = [measured.loc[tuple(meta.loc[t.trial])] for t, _ in ok if t.trial in meta.index and tuple(meta.loc[t.trial]) in measured.index]
    if not rows:
        return [line + ". No measured duration matches these means.", ""]
    m = pd.DataFrame(rows)
    return [line + f"; the measured trials of the same scenario, goal and direction (durations.parquet, {len(m)} means): "
            f"T {m['duration'].mean():.2f} ± {m['duration'].std():.2f} s, mean speed {m['mean_velocity'].mean():.3g} ± "
            f"{m['mean_velocity'].std():.3g} m/s. D compares time-normalised paths: the pace comes from the held a0 and a1 "
            "(docs/methods.md sec. 6).", ""]


def interval_cells(uncertainty: dict | None, name: str) -> tuple[str, str]:
    """The 95 % interval and the verdict of weight ``name`` (``uncertainty``: one fit's entry of
    weights.json), the verdict led by the analysis that gave it (``uncertainty.judged``: *curvature*, *bootstrap*
    or *profile*); no interval for a weight the data do not determine, none at all without a bootstrap."""
    if not uncertainty:
        return "–", "not computed (--bootstrap 0)"
    v = uncertainty["verdicts"][name]
    by = (uncertainty.get("by") or {}).get(name)
    lo, hi = uncertainty["intervals"][name]
    return (f"{lo:.3g} .. {hi:.3g}" if v.startswith("determined") else "–"), (f"*{by}*: {v}" if by else v)


def uncertainty_lines(result) -> list[str]:
    """Markdown: each fitted weight with its bootstrap interval and identifiability verdict per fit
    (docs/methods.md sec. 6.3), and, per subject, whether the subjects' weights differ."""
    if not result.uncertainty:
        return []
    n = next(iter(result.uncertainty.values()))["resamples"]
    lines = [f"Each fitted weight with its 95 % interval ({n} bootstrap resamples of the fitted "
             f"{'means' if result.per == 'all' else 'trials'}, a quadratic refit each) and what the data determine "
             "(curvature of D at the fit; where D is not smooth there, where the fit is not at a minimum of D, or where the "
             "bootstrap overturns the curvature's "
             "\"determined\", the weight's profile likelihood, whose interval a \"determined (profile: ...)\" weight then "
             "shows; each verdict led by the analysis that gave it, one rule for both fit methods: docs/methods.md sec. 6.3); "
             "a weight the data do not determine has no interval.", "",
             "| fit | weight | fitted | 95 % interval | verdict |", "|---|---|---|---|---|"]
    for k, u in result.uncertainty.items():
        w = result.results[k].weights
        for name in result.names:
            lines.append(f"| {k} | {name} | {w[name]:.3g} | " + " | ".join(interval_cells(u, name)) + " |")
    lines.append("")
    boxed = {k: u["on_box"] for k, u in result.uncertainty.items() if u.get("on_box")}
    if boxed:
        lines += ["Resamples whose quadratic model has no minimum inside the search box (refitted on its edge; they "
                  "widen the bootstrap's intervals; a weight its profile judges takes the profile's): " + ", ".join(f"{k} {v} of {u_n}" for k, v in boxed.items()
                                                       for u_n in [result.uncertainty[k]["resamples"]]) + ".", ""]
    failed = sum(u["failed_solves"] for u in result.uncertainty.values())
    if failed:
        lines += [f"{failed} lower-level solves of the curvature did not converge (their points carry no information).", ""]
    if result.subjects_test:
        lines += ["Do the subjects' weights differ? Cochran's Q on log10 of each weight with the bootstrap standard "
                  "deviations, chi2(subjects - 1), Holm-adjusted over the weights; subjects where the weight is not "
                  "determined left out, and so are the subjects whose fit ended at the start weights every subject "
                  "started from (docs/methods.md sec. 6.3)"
                  + (": " + ", ".join(result.subjects_test[0]["at_start"]) if result.subjects_test[0].get("at_start") else "")
                  + ".", "",
                  "| weight | subjects | Q | df | p | p (Holm) | subjects differ |", "|---|---|---|---|---|---|---|"]
        for r in result.subjects_test:
            differ = "–" if r["differ"] is None else ("yes" if r["differ"] else "no")
            cells = [f"{r['Q']:.3g}", str(r["df"]), p_text(r["p"]), p_text(r["p_holm"])] if r["differ"] is not None else ["–"] * 4
            lines.append(f"| {r['weight']} | {r['subjects']} | " + " | ".join(cells) + f" | {differ} |")
        lines.append("")
    return lines


def methods_side_by_side(result, other: dict | None) -> list[str]:
    """Markdown: the single-level fit beside the workspace's bi-level fit (D, weights, time), then each
    weight by both methods with its interval and verdict (``other``: the bi-level weights.json's fits)."""
    if other is None:
        how = f"--model {result.model}" + (" --convention published" if result.convention == "published" else "")
        return [f"No bi-level fit of the {result.model} model in this workspace to compare with (run fit-ioc {how} "
                "without --method first).", ""]
    names = result.names
    lines = [f"Single-level and bi-level fits side by side (the bi-level fit from {other['path']}); both D re-solved "
             "exactly by the lower level at the fitted weights."
             + (" Each path's lower level keeps the least-cost of its candidate solutions, and the two fits try different "
                "candidates: the row 'bi-level weights, re-solved also from the single-level paths' adds the single-level "
                "fit's paths as candidates at the bi-level weights (docs/methods.md sec. 6.1, "
                "models.ioc.single_level.cross_check), so that both D come from the same candidates." if result.cross_checked else "")
             + (" The row 'single-level, started at the bi-level weights' runs the single-level steps from the bi-level fit's "
                "end (models.ioc.single_level_published.continued_from): a D below the bi-level one says that fit stopped short of a "
                "minimum of D; where the steps find no lower D, the row keeps the bi-level weights." if result.continued else ""),
             "",
             "| fit | method | D | time (s) | " + " | ".join(names) + " |", "|---|---|---|---|" + "---|" * len(names)]
    for k, r in result.results.items():
        b = other["fits"].get(k)
        if b is not None:
            t = b.get("seconds")
            lines.append(f"| {k} | bi-level | {b['objective']:.4f} | {'' if t is None else f'{t:.1f}'} | "
                         + " | ".join(f"{b['weights'][n]:.3g}" for n in names) + " |")
            if k in result.cross_checked:
                lines.append(f"| {k} | bi-level weights, re-solved also from the single-level paths | {result.cross_checked[k]:.4f} | | "
                             + " | ".join(f"{b['weights'][n]:.3g}" for n in names) + " |")
            if k in result.continued:
                c = result.continued[k]
                if math.isfinite(c["objective"]):
                    lines.append(f"| {k} | single-level, started at the bi-level weights | {c['objective']:.4f} | "
                                 f"{c['seconds']:.1f} | " + " | ".join(f"{c['weights'][n]:.3g}" for n in names) + " |")
                else:  # the steps could not start there: the reason, in place of a D
                    lines.append(f"| {k} | single-level, started at the bi-level weights: {c['message']} | – | "
                                 f"{c['seconds']:.1f} | " + " | ".join("–" for _ in names) + " |")
        lines.append(f"| {k} | single-level | {r.objective:.4f} | {result.seconds.get(k, float('nan')):.1f} | "
                     + " | ".join(f"{r.weights[n]:.3g}" for n in names) + " |")
    lines += ["", "Each fitted weight by both methods, with its 95 % interval and identifiability verdict, led by the "
              "analysis that gave it (curvature, bootstrap or profile likelihood: one rule for both methods, "
              "docs/methods.md sec. 6.3).", "",
              "| fit | weight | bi-level | 95 % interval | verdict | single-level | 95 % interval | verdict |",
              "|---|---|---|---|---|---|---|---|"]
    for k, r in result.results.items():
        b = other["fits"].get(k) or {}
        for n in names:
            bw = (b.get("weights") or {}).get(n)
            bcells = interval_cells(b.get("uncertainty"), n) if bw is not None else ("–", "no bi-level fit")
            lines.append(f"| {k} | {n} | {'–' if bw is None else f'{bw:.3g}'} | " + " | ".join(bcells)
                         + f" | {r.weights[n]:.3g} | " + " | ".join(interval_cells(result.uncertainty.get(k), n)) + " |")
    return lines + [""]


def ioc_overview(fits: dict[str, Path]) -> list[str]:
    """Markdown: every IOC fit of a workspace side by side (``fits``: stage directory -> its weights.json,
    e.g. ``fit-ioc``, ``fit-ioc-published``, ``fit-ioc-single``, ``fit-ioc-subjects``): per fit its method,
    convention, D and time, each fitted weight with its 95 % bootstrap interval and verdict
    (docs/methods.md sec. 6.3), and, per subject, whether the subjects' weights differ."""
    import json

    if not fits:
        return []
    lines = ["## Inverse optimal control: the fits side by side", "",
             "Every IOC fit of the workspace (bi-level, docs/methods.md sec. 6; single-level, sec. 6.1), each fitted weight "
             "with its 95 % bootstrap interval and what the data determine (sec. 6.3); the stages' own sections in "
             "docs/results.md give the details.", "",
             "| stage | method | convention | fit | D | time (s) | weight | fitted | 95 % interval | verdict |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    tests = []
    for stage, path in fits.items():
        doc = json.loads(Path(path).read_text())
        method = "single-level" if doc.get("method") == "single-level" else "bi-level"
        for k, r in (doc.get("fits") or {}).items():
            t = r.get("seconds")
            head = f"| {stage} | {method} | {doc.get('convention')} | {k} | {r['objective']:.4f} | {'–' if t is None else f'{t:.1f}'}"
            for n in r["spec"]["fitted"]:
                lines.append(f"{head} | {n} | {r['weights'][n]:.3g} | " + " | ".join(interval_cells(r.get("uncertainty"), n)) + " |")
        if doc.get("subjects_differ"):
            tests.append((stage, doc["subjects_differ"]))
    lines.append("")
    for stage, rows in tests:
        cells = [f"{r['weight']}: " + ("not tested (fewer than 2 subjects where it is determined)" if r.get("differ") is None else
                                       f"{'differ' if r['differ'] else 'do not differ'} (Q = {r['Q']:.3g}, {r['subjects']} subjects, "
                                       f"p (Holm) {'' if r['p_holm'] == 0 else '= '}{p_text(r['p_holm'])})") for r in rows]
        lines += [f"Do the subjects' weights differ ({stage}, Cochran's Q, docs/methods.md sec. 6.3)? " + "; ".join(cells) + ".", ""]
    return lines


def gauge_limit_lines(weights: dict[str, float], fitted, pace: dict | None) -> list[str]:
    """Markdown: the fitted weights the time gauge (a1..a3 x c^4, ``pace``) moved beyond the search limits
    ``ioc.LOG_BOUNDS``: fitted on a limit, they are written scaled off it (the tables show the written weights)."""
    from cobot_analysis.models.ioc.fit import LOG_BOUNDS
    from cobot_analysis.models.ioc.pace import ACCELERATION_WEIGHTS

    if not pace or not np.isfinite(pace.get("c", np.nan)):
        return []
    off = [n for n in fitted if n in ACCELERATION_WEIGHTS and not LOG_BOUNDS[0] <= np.log10(max(weights[n], 1e-300)) <= LOG_BOUNDS[1]]
    if not off:
        return []
    return [f"The weights written (and shown above) are the time gauge's, a1-a3 x c^4 = {pace['c'] ** 4:.4g}: "
            + ", ".join(f"{n} = {weights[n]:.3g}" for n in off)
            + f" lie{'s' if len(off) == 1 else ''} beyond the search limits 1e{LOG_BOUNDS[0]:g}..1e{LOG_BOUNDS[1]:g}, fitted on "
            f"{'a limit' if len(off) == 1 else 'limits'} and scaled off {'it' if len(off) == 1 else 'them'} (the verdicts' "
            "search limits are the fit's).", ""]


def _gauge_lines(line: str, targets, per_target: list[dict], pace: dict) -> list[str]:
    """The time-gauge calibration's summary and its per-target table (model beside subjects)."""
    M = np.asarray(pace["measured_T"], float)
    T0 = np.asarray(pace["model_T"], float)
    rows, speeds, errors = [], [], []
    for t, d, m in zip(targets, per_target, M):
        if not d.get("success"):
            rows.append(f"| {t.trial} | – | – | {m:.2f} | – | failed |")
            continue
        L = d.get("length", np.nan)
        sm = L / m if np.isfinite(m) else np.nan
        speeds.append((L / d["T"], sm))
        if np.isfinite(m):
            errors.append(d["T"] - m)
        rows.append(f"| {t.trial} | {d['T']:.2f} | {L / d['T']:.2f} | " + (f"{m:.2f} | {sm:.2f} |" if np.isfinite(m) else "– | – |")
                    + (" on a bound |" if d.get("T_at_bound", 0) else " |"))
    sp = np.array(speeds)
    sub = sp[np.isfinite(sp[:, 1])] if len(sp) else sp
    outside = int(np.sum((sp[:, 0] < 0.5) | (sp[:, 0] > 2.0))) if len(sp) else 0
    text = (f"**Time gauge fitted to the subjects' durations** (docs/methods.md sec. 6.4): the fitted weights walk each "
            f"path in c times the duration when a1, a2, a3 are multiplied by c^4 (the same time-normalised paths, the same D); "
            f"least squares of the model's durations against the subjects' ({pace['n_measured']} paths with a duration) "
            f"gives c = {pace['c']:.3f} (durations before: {np.nanmin(T0):.2f}-{np.nanmax(T0):.2f} s). The weights written are "
            f"the calibrated ones; re-solved there, D = {pace['D_after']:.4f} (before {pace['D_before']:.4f}), "
            f"rms duration error {np.sqrt(np.mean(np.square(errors))):.2f} s, model mean speed {sp[:, 0].min():.2f}-"
            f"{sp[:, 0].max():.2f} m/s against {np.nanmin(sub[:, 1]):.2f}-{np.nanmax(sub[:, 1]):.2f} m/s for the same paths "
            f"walked in the subjects' durations (the model's path length / the subjects' duration; the subjects' own "
            f"speeds, on their own paths, are generate's); {outside} of {len(sp)} model paths outside 0.5-2 m/s, "
            f"in the subjects' durations {int(np.sum((sub[:, 1] < 0.5) | (sub[:, 1] > 2.0)))} of {len(sub)}.")
    if pace.get("notes"):
        text += " **" + "; ".join(pace["notes"]) + ".**"
    return [line + ".", "", text, "",
            "| target | model T (s) | model mean speed (m/s) | subjects' T (s) | model path length / subjects' T (m/s) | flag |",
            "|---|---|---|---|---|---|", *rows, ""]


def goal_lines(comparison: pd.DataFrame, convention: str) -> list[str]:
    """Markdown: per compared model, how many of its paths end at their goal (``models.goal_check``: within
    ``GOAL_TOLERANCE``) and which did not; the subjects' rows (no goal) are left out."""
    from cobot_analysis.models import GOAL_TOLERANCE

    if "goal_reached" not in comparison:
        return []
    runs = comparison[comparison["goal_reached"].notna()]
    if runs.empty:
        return []
    parts = []
    for model, g in runs.groupby("model", sort=False):
        reached = g["goal_reached"].astype(bool)
        missed = g.loc[~reached, "trial"].astype(str).tolist()
        parts.append(f"{model} {int(reached.sum())} of {len(g)} paths at the goal"
                     + (f" (not: {', '.join(missed[:5])}{', ...' if len(missed) > 5 else ''})" if missed else ""))
    why = (" Under the continuous convention the goal at rest is a constraint (docs/methods.md sec. 5.5): a path that misses "
           "it is a run that did not converge, left out of the means above." if convention == "continuous" else
           " Under the published convention the goal is the terminal cost of the authors' models: a path may end near it, "
           "not on it; its distances are kept.")
    return [f"Goal reached (end within {GOAL_TOLERANCE[0] * 100:g} cm and {GOAL_TOLERANCE[1]:g} rad): " + "; ".join(parts)
            + "." + why, ""]


def fit_ioc_markdown(result, stage, *, optimizer: str, intervals: int, v_nominal: float, durations: pd.DataFrame | None,
                     other: dict | None = None, weigh: str = "trials") -> str:
    """The IOC's results fragment: the fits (D, evaluations, weights at the start and fitted), their flags,
    each weight's interval and verdict, the single-level fit beside the bi-level one (``other``: the
    workspace's bi-level weights.json), the model comparison with its statistics and figures (drawn into
    ``stage``); ``weigh``: how the means fitted were weighed (``average --weigh``)."""
    from cobot_analysis import conventions

    conv = conventions.get(result.convention)
    model, names, per = result.model, result.names, result.per
    spec, results, fits = result.spec, result.results, result.fits
    angle = spec.angle
    if conv.name == "published":
        lower = ("lower level: the published convention (docs/methods.md sec. 11): explicit Euler at the authors' node "
                 "step, costs summed per node, the authors' start and goal poses; each path's horizon chosen by the authors' "
                 "duration rule (Nelder-Mead on J/T) at the start weights and held during the fit, then the rule run again "
                 "at the fitted weights (the D fitted below); distances after arc-length resampling of both paths, to "
                 + ("the authors' mean block" if Path(result.means_source).parent.name == "import-published" else "the means")
                 + f" ({result.means_source})")
    else:
        lower = (f"lower level: OC with free duration on {intervals} intervals, the goal at rest a constraint (continuous "
                 "convention, docs/methods.md sec. 5.5, 11), from the solution at the best weights so far and from a rest "
                 "and a straight-line guess, the least cost kept")
    start_weights = result.start_label
    single = result.method == "single-level"
    if single:
        lower = lower.replace(", from the solution at the best weights so far and from a rest and a straight-line guess, the least cost kept",
                              ", its KKT conditions constraints of the NLP; the D reported re-solves it from the NLP's paths and from a "
                              "rest and a straight-line guess, the least cost kept")
    lines = [f"## Inverse optimal control ({model} model{', one fit per subject' if per == 'subject' else ''}, "
             f"{conv.name} convention, {'single-level' if single else 'bi-level'})", "",
             (f"Single-level IOC (docs/methods.md sec. 6.1): one NLP over ({', '.join(names)}), every path and the "
              f"multipliers of its lower level's KKT conditions, solved by a feasible path (trust-region steps in the weights, "
              f"each path's KKT conditions restored by Newton's method), the D reported from the lower level re-solved at the fitted weights; "
              if single else
              f"Bi-level IOC (docs/methods.md sec. 6): upper level {optimizer} over log10 of ({', '.join(names)}), ")
             + f"bounds 1e-7..1e3, the other weights held at their start value "
             f"({'neutral start: fitted weights 1' if start_weights == 'ones' else start_weights}); "
             f"{lower}; objective D = d_xy + 0.5 d_{angle} averaged over the trajectories (orientation required; "
             f"goal: {result.goal if conv.name == 'continuous' else 'the authors'})"
             + ((". gamma of the measured path: " + ("recorded in the data" if conv.comparison.measured_gamma == "data" else
                                                       "from the path (distances.gamma_from_path)") + "; of the model's path: from the path.")
                if angle == "gamma" else "; pair study: per-scenario means (the pooled 'all' means left out).")
             + (" Coupled model: scenario-3 forward and return means, Subject 2 as carrier 1 on returns." if model == "coupled" else "")
             + (f" The means are weighted by {weigh} (`average --weigh {weigh}`): the mean of each subject's (pair's) mean."
                if weigh != "trials" else ""),
             "",
             "| fit | paths | D start | D fitted | evaluations | not converged | " + " | ".join(names) + " |",
             "|---|---|---|---|---|---|" + "---|" * len(names)]
    w0, all_names = result.start_weights, result.all_names
    for k, r in results.items():
        lines.append(f"| {k}: start weights ({start_weights}) | {len(fits[k])} | {r.start_objective:.4f} |  |  |  | "
                     + " | ".join(f"{w0[all_names.index(n)]:.3g}" for n in names) + " |")
        lines.append(f"| {k}: fitted | {len(fits[k])} | {r.start_objective:.4f} | {r.objective:.4f} | {r.evaluations} | {r.failed} | "
                     + " | ".join(f"{r.weights[n]:.3g}" for n in names) + " |")
    lines.append("")
    for k, r in results.items():
        # with the curvature at hand, a weight at a search limit is judged by its verdict (below), not flagged
        lines += [("" if per == "all" else f"Fit {k}: ") + duration_flag(r.per_target, v_nominal, conv.name,
                                                                          None if model == "coupled" else conv.oc_rule(model).T_bounds)
                  + ("" if k in result.uncertainty else " " + weight_limit_flag(r.weights, names))
                  + (f" Optimiser: {r.message.strip()}" if per == "all" else ""), ""]
    lines += uncertainty_lines(result)
    if single:
        lines += methods_side_by_side(result, other)
    if conv.name == "published" and "a0" not in names and model != "coupled":
        lines += ["a0 is held at its start value under the published convention: a constant per node, it adds a0 N to J "
                  "on a held horizon and a0 / dt to the duration rule's J / T, so no path depends on it (docs/methods.md "
                  "sec. 11).", ""]
        if r.held_objective is not None:
            lines += [f"{'' if per == 'all' else f'Fit {k}: '}with the horizons held, D = {r.held_objective:.4f} at the "
                      f"fitted weights; the duration rule run again there moves the horizon of {r.horizons_changed} of "
                      f"{len(fits[k])} paths (D = {r.objective:.4f}).", ""]
    if conv.name == "continuous" and model != "coupled" and per == "all":
        lines += pace_lines(result.mean_keys, fits["all"], results["all"].per_target, durations, results["all"].pace)
        lines += gauge_limit_lines(results["all"].weights, names, results["all"].pace)
    if result.coupled is not None:
        lines += coupled_section(results["all"], result.coupled, result.mean_targets, stage, durations)
    if result.comparison is not None:
        comparison = result.comparison
        lines += [f"### Model comparison on the mean trajectories ({conv.name} convention)", "",
                  summary_table(comparison, angle, ddof=conv.comparison.sd_ddof), *goal_lines(comparison, conv.name),
                  "### Statistics", "", statistics(comparison, list(result.compared)[-1], angle)]
        stage.savefig(figure_boxplots(comparison, angle, comparison_title(model, conv.name)), "distances_boxplot")
        lines += ["![distances per model](distances_boxplot.png)", ""]
        stage.savefig(figure_paths(result.mean_targets, result.paths, paths_title(model, conv.name)), "paths")
        lines += ["![generated vs mean paths](paths.png)", ""]
        for k in result.paths:  # a converged path need not be a walker's: its heading, at both weights
            lines += [f"The model's paths at the {k} weights (as `generate` makes them, the figure's): "
                      + heading_line(result.model_paths(k)), ""]
        if result.turning is not None:
            lines += turning_lines(result.turning)
    return "\n".join(lines) + "\n"
