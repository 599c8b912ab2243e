"""The papers' model figures beside ours under both conventions (docs/methods.md sec. 11): one table
per study for docs/results.md, read from the stage outputs of a workspace (nothing is recomputed
but the convention switches that explain a difference, on paths the stages wrote).

Each row: the paper's mean +- sd, ours under the published convention, ours under the continuous
convention (mean +- sd over the same trajectories, the convention's sd), whether the published
convention reproduces the paper (within ``TOLERANCE`` of its mean), and a one-line account.
Besides means (``kind`` "mean"), a row can read one statistic of the stats stage ("value": its
p, or "members": the size of its subset) or a Pearson r of a distance with the start-goal distance
("pearson"); a paper value stated as a bound ("p < 1e-5", ``bound``) is reproduced when ours
is within it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from cobot_analysis.lazy import pandas as pd

TOLERANCE = 0.15  # "reproduced": within 15 % of the published mean


@dataclass(frozen=True)
class Figure:
    """One published figure and where the stages put ours."""

    what: str  # the row label
    paper: tuple[float, float | None]  # mean, sd (None: not published)
    unit: str
    stage: str  # stage directory under the continuous convention ("-published" is appended for the other)
    table: str  # file in the stage directory
    select: dict  # column -> value of the rows to average
    column: str  # the value averaged
    note: str  # the paper's source and what it averaged over
    kind: str = "mean"  # mean | value (one stats row) | members (size of a stats row's subset) | pearson
    bound: str = ""  # "<": the paper states an upper bound (e.g. p < 1e-5)
    versus: str = "global_distance"  # x of a pearson row


#: walking thesis ch. 1 sec. 1.4.4: the subjects' variability and the model error vs the start-goal distance
SUBJECTS_GAMMA = Figure("subjects vs their mean (trajectories with orientation): d_gamma", (0.4842, None), "rad", "compare",
                        "distances.parquet", {"comparison": "individual-mean", "entity": "walker"}, "d_gamma",
                        "thesis ch. 1 sec. 1.4.4")
SUBJECTS_KRUSKAL = Figure("subjects vs their mean, d_gamma: Kruskal-Wallis across the 10 subjects, p", (1e-5, None), "-",
                          "stats", "stats.parquet", {"id": "W1.2"}, "p", "thesis ch. 1 sec. 1.4.4", kind="value", bound="<")
SUBSET_SIZE = Figure("largest subset of indistinguishable subjects (d_xy): subjects", (6, None), "subjects", "stats",
                     "stats.parquet", {"id": "W1.3-pairwise"}, "levels", "thesis ch. 1 sec. 1.4.4", kind="members")
SUBSET_P = Figure("largest subset of indistinguishable subjects (d_xy): Kruskal-Wallis p", (0.31, None), "-", "stats",
                  "stats.parquet", {"id": "W1.3-pairwise"}, "p", "thesis ch. 1 sec. 1.4.4", kind="value")
MODEL_R_XY = Figure("improved OC, walking-2021 weights, vs the 40 means: Pearson r of d_xy with the start-goal distance",
                    (0.63, None), "r", "fit-ioc", "distances.parquet", {"model": "improved OC (published)"}, "d_xy",
                    "thesis ch. 1 sec. 1.4.4", kind="pearson")
MODEL_R_GAMMA = Figure("improved OC: Pearson r of d_gamma with the start-goal distance (37 means with orientation)",
                       (-0.81, None), "r", "fit-ioc", "distances.parquet", {"model": "improved OC (published)"}, "d_gamma",
                       "thesis ch. 1 sec. 1.4.4", kind="pearson")

WALKING = (
    Figure("improved OC, walking-2021 weights, vs the 40 means: d_xy", (0.0767, 0.0450), "m", "fit-ioc", "distances.parquet",
           {"model": "improved OC (published)"}, "d_xy", "thesis ch. 2 / CMBBE 2021"),
    Figure("improved OC, walking-2021 weights: d_gamma (37 means with orientation)", (0.3786, 0.1336), "rad", "fit-ioc",
           "distances.parquet", {"model": "improved OC (published)"}, "d_gamma", "thesis ch. 2 / CMBBE 2021"),
    Figure("Mombaur-form OC (mombaur-2010): d_xy", (0.188, 0.104), "m", "fit-ioc", "distances.parquet",
           {"model": "Mombaur OC"}, "d_xy", "thesis Table 1.1 (IROS 2020)"),
    Figure("Mombaur-form OC (mombaur-2010): d_theta", (0.874, 0.530), "rad", "fit-ioc", "distances.parquet",
           {"model": "Mombaur OC"}, "d_theta", "thesis Table 1.1 (IROS 2020)"),
    Figure("clothoid: d_xy", (0.605, 0.628), "m", "fit-ioc", "distances.parquet", {"model": "clothoid"}, "d_xy",
           "thesis Table 1.1 (IROS 2020)"),
    Figure("clothoid: d_theta", (0.521, 0.279), "rad", "fit-ioc", "distances.parquet", {"model": "clothoid"}, "d_theta",
           "thesis Table 1.1 (IROS 2020)"),
    Figure("subjects vs their mean (400 trajectories): d_xy", (0.1073, 0.0652), "m", "compare", "distances.parquet",
           {"comparison": "individual-mean", "entity": "walker"}, "d_xy", "thesis ch. 2 / CMBBE 2021"),
    Figure("prediction, 400 subject trajectories, (N0, N_OC) = (50, 100): delta_xy", (0.08, 0.02), "m", "predict",
           "predictions.parquet", {"predictor": "oc", "n0": 50, "n_oc": 100, "kind": "trial"}, "delta_xy",
           "thesis ch. 2 / RA-L 2021"),
    Figure("prediction (50, 100): delta_theta", (0.28, 0.01), "rad", "predict", "predictions.parquet",
           {"predictor": "oc", "n0": 50, "n_oc": 100, "kind": "trial"}, "delta_theta", "thesis ch. 2 / RA-L 2021"),
    Figure("prediction (50, 100): d_pred", (0.48, 0.17), "m", "predict", "predictions.parquet",
           {"predictor": "oc", "n0": 50, "n_oc": 100, "kind": "trial"}, "d_pred", "thesis ch. 2 / RA-L 2021"),
    SUBJECTS_GAMMA, SUBJECTS_KRUSKAL, SUBSET_SIZE, SUBSET_P, MODEL_R_XY, MODEL_R_GAMMA,
)

PAIRS = (
    Figure("table OC, table-2022 weights: d_xy (the paper: individual trials; here the published table means)", (0.12, 0.12),
           "m", "fit-ioc", "distances.parquet", {"model": "table OC (published)"}, "d_xy", "thesis ch. 5 / Humanoids 2022"),
    Figure("table OC, table-2022 weights: d_theta (means, see above)", (0.36, None), "rad", "fit-ioc", "distances.parquet",
           {"model": "table OC (published)"}, "d_theta", "thesis ch. 5 / Humanoids 2022"),
    Figure("table prediction (50, 100): delta_xy (the paper: individual trials; here the table means)", (0.04, 0.02), "m",
           "predict", "predictions.parquet", {"predictor": "oc", "n0": 50, "n_oc": 100, "entity": "table"}, "delta_xy",
           "thesis ch. 5 / Humanoids 2022"),
)

FIGURES = {"walking-2020": WALKING, "pair-carriage-2022": PAIRS}

#: the one-line accounts of a remaining difference, measured by switching a convention element (docs/results.md)
ACCOUNTS: dict[str, dict[str, str]] = {
    "walking-2020": {
        WALKING[1].what: "the authors' final scripts' d_eta: the local angle of the resampled model path (its theta by "
                         "time) against the gamma recorded in the mean block, each wrapped on its own, 499 samples",
        WALKING[6].what: "both paths resampled by arc length, as the authors' script; pointwise on time (continuous) the "
                         "distance is smaller: the time laws of a subject and its mean differ more than their paths",
        WALKING[7].what: "the differences are measured in the predict-published section (which orientations are tracked, "
                         "the rest start, the node step); the OC predictor loses to constant velocity under both conventions",
        WALKING[8].what: "see the predict-published section; constant velocity has the same delta_theta: the measured theta "
                         "varies that much",
        WALKING[9].what: "d_pred is a distance covered in N_OC - N0 samples: it follows the samples' duration, which the "
                         "time-normalised published data do not hold (predict-published section)",
        SUBJECTS_GAMMA.what: "the 275 trajectories with orientation; the authors' script also compared the 125 marker-loss "
                             "trajectories, whose files hold gamma = 0 (stats source gamma_as_files)",
        SUBJECTS_KRUSKAL.what: "without the marker-loss trajectories; kept as the authors' files hold them (gamma = 0): "
                               "rows W1.2-files (Kruskal) and W1.2-files-anova (the authors' public script's test)",
        SUBSET_SIZE.what: "the authors' public code holds no subset search; definition: every pair Mann-Whitney p > 0.05, "
                          "the most atypical median dropped first (row W1.3-pairwise); ours, W1.3: the largest set with "
                          "Kruskal p > 0.05",
        SUBSET_P.what: "see the row above",
        MODEL_R_XY.what: "the authors' public code computes no correlation; over the 40 means and their measured start-goal "
                         "distance",
        MODEL_R_GAMMA.what: "see the row above",
    },
    "pair-carriage-2022": {
        PAIRS[0].what: "the paper fitted and compared individual trials, which are not published; here the 83 table means "
                       "of the published data",
        PAIRS[2].what: "means, not trials (the differences the conventions explain: predict-published section); the OC "
                       "predictor loses to constant velocity on the means",
    },
}


def measured(ws: Path, fig: Figure, convention: str) -> tuple[float, float, int] | None:
    """Our value of ``fig`` under ``convention`` as (value, sd, n), or None when the workspace has no
    such output. mean: mean, sd (the convention's ddof), n of the selected rows; value: the one
    selected stats row's ``column`` and n (sd NaN); members: the number of levels of that row;
    pearson: r of ``column`` with ``versus`` over the selected rows (sd NaN), n pairs."""
    from scipy import stats

    from cobot_analysis.conventions import get
    from cobot_analysis.registry import directory

    conv = get(convention)
    path = ws / directory(fig.stage, conv.name) / fig.table
    if not path.is_file():
        return None
    df = pd.read_parquet(path)
    for col, value in fig.select.items():
        if col not in df.columns:
            return None
        df = df[df[col] == value]
    if fig.column not in df.columns or df.empty:
        return None
    if fig.kind in ("value", "members"):
        r = df.iloc[0]
        if fig.kind == "members":  # the subset's size, and n = the number of groups it was drawn from
            return (float(len([m for m in str(r[fig.column]).split(", ") if m])), float("nan"),
                    len([g for g in str(r["n_groups"]).split("; ") if g]))
        return (float(r[fig.column]), float("nan"), int(r["n"])) if pd.notna(r[fig.column]) else None
    if fig.kind == "pearson":
        xy = df[[fig.versus, fig.column]].apply(pd.to_numeric, errors="coerce").dropna() if fig.versus in df else df.iloc[0:0]
        if len(xy) < 3:
            return None
        return float(stats.pearsonr(xy[fig.versus], xy[fig.column])[0]), float("nan"), len(xy)
    v = df[fig.column].dropna().to_numpy(float)
    if not len(v):
        return None
    return float(v.mean()), float(v.std(ddof=conv.comparison.sd_ddof)) if len(v) > 1 else float("nan"), len(v)


def _cell(value, fig: Figure) -> str:
    if value is None:
        return "not run"
    m, sd, n = value
    if fig.kind == "value":
        return f"{m:.3g} (n = {n})"
    if fig.kind == "members":
        return f"{m:.0f} of {n}"
    if fig.kind == "pearson":
        return f"r = {m:.3f} (n = {n})"
    return f"{m:.4f} ± {sd:.4f} (n = {n})"


def _paper(paper: tuple[float, float | None]) -> str:
    m, sd = paper
    return f"{m:g}" + (f" ± {sd:g}" if sd is not None else "")


def verdict(paper: tuple[float, float | None], ours, bound: str = "") -> str:
    """'yes' within ``TOLERANCE`` of the paper's mean (or, for a paper bound "<", below it), else
    the relative difference (or how far above the bound)."""
    if ours is None:
        return "–"
    if bound == "<":
        return "yes" if ours[0] < paper[0] else f"no ({ours[0] / paper[0]:.2g} x the bound)"
    rel = (ours[0] - paper[0]) / abs(paper[0])
    return "yes" if abs(rel) <= TOLERANCE else f"no ({rel:+.0%})"


def table(ws: Path, study: str, accounts: dict[str, str] | None = None) -> list[str]:
    """Markdown lines: the study's published figures, ours under both conventions, the accounts."""
    accounts = accounts or {}
    lines = [f"| figure ({study}) | paper | ours, published convention | ours, continuous convention | reproduced | account |",
             "|---|---|---|---|---|---|"]
    for fig in FIGURES[study]:
        pub, cont = measured(ws, fig, "published"), measured(ws, fig, "continuous")
        lines.append(f"| {fig.what} ({fig.unit}; {fig.note}) | {fig.bound}{_paper(fig.paper)} | {_cell(pub, fig)} | "
                     f"{_cell(cont, fig)} | {verdict(fig.paper, pub, fig.bound)} | {accounts.get(fig.what, '')} |")
    return lines


def comparison_switches(ws: Path) -> dict[str, float] | None:
    """d_xy of the published-convention improved-OC paths of the walking means (generate-published) to
    the means, compared three ways: both paths resampled by arc length (the published convention), the
    model path only (the authors' other script version), pointwise on time (sec. 3). None when the
    workspace has no such paths."""
    from cobot_analysis.conventions import Comparison
    from cobot_analysis.distances import path_distances

    gen_path, mean_path = ws / "generate-published" / "generated.parquet", ws / "import-published" / "trajectories.parquet"
    if not (gen_path.is_file() and mean_path.is_file()):
        return None
    gen, means = pd.read_parquet(gen_path), pd.read_parquet(mean_path)
    gen = gen[gen["model"] == "improved"]
    means = means[(means["kind"] == "mean") & (means["entity"] == "walker")]
    ways = {"both": Comparison("arclength", True, "each", "data", 0), "model only": Comparison("arclength", False, "each", "data", 0),
            "time": Comparison("time", False, "wrapped", "path", 0)}
    out = {k: [] for k in ways}
    for cond, g in gen.groupby("condition"):
        m = means[means["condition"] == cond].sort_values("sample")
        if m.empty:
            continue
        g = g.sort_values("sample")
        for k, c in ways.items():
            out[k].append(path_distances((m["x"], m["y"], m["theta"]), (g["x"], g["y"], g["theta"]), c)["d_xy"])
    return {k: float(np.mean(v)) for k, v in out.items() if v} or None


#: the start-goal distance of each start position code as the authors' distance.py / distance_ioc.py list it (m)
AUTHORS_START_GOAL = {"1500": 0.9, "4000": 3.4, "-0615": float(np.hypot(1.2, 1.5)), "0615": 1.5,
                      "1515": float(np.hypot(0.9, 1.5)), "4015": float(np.hypot(3.4, 1.5)), "-0640": float(np.hypot(1.2, 4.0)),
                      "0640": 4.0, "1540": float(np.hypot(0.9, 4.0)), "4040": float(np.hypot(3.4, 4.0))}


def _rel(value: float, paper: float) -> str:
    return f"{(value - paper) / abs(paper):+.0%}"


def _stats_row(ws: Path, stage: str, qid: str) -> pd.Series | None:
    path = ws / stage / "stats.parquet"
    if not path.is_file():
        return None
    s = pd.read_parquet(path)
    s = s[(s["id"] == qid) & (s["status"] == "ok")]
    return s.iloc[0] if len(s) else None


def subjects_accounts(ws: Path) -> dict[str, str]:
    """Accounts of the subjects' variability rows (thesis ch. 1 sec. 1.4.4), measured in ``ws``: the
    authors' subject-vs-mean d_gamma with the marker-loss rows as their files hold them, the Kruskal
    and ANOVA p of those rows, and the two subset definitions."""
    from cobot_analysis.compare import read_trajectory_set
    from cobot_analysis.stats.sources import gamma_as_files_source

    out = {}
    traj = ws / "import-published" / "trajectories.parquet"
    g = gamma_as_files_source(read_trajectory_set(traj, ("trajectories",))) if traj.is_file() else pd.DataFrame()
    if len(g):
        kept, lost = g.loc[~g["orientation_missing"], "d_gamma"], int(g["orientation_missing"].sum())
        paper = SUBJECTS_GAMMA.paper[0]
        out[SUBJECTS_GAMMA.what] = (
            f"the authors' script on the published files (subject gamma vs the mean block's gamma, by time, each "
            f"wrapped) keeps the {lost} marker-loss trajectories, whose files hold gamma = 0: "
            f"{g['d_gamma'].mean():.4f} over {len(g)} ({_rel(g['d_gamma'].mean(), paper)}); those rows at distance 0 "
            f"instead: {g['d_gamma_loss_zero'].mean():.4f} ({_rel(g['d_gamma_loss_zero'].mean(), paper)}); without "
            f"them {kept.mean():.4f} over {len(kept)} ({_rel(kept.mean(), paper)}, ours); no definition in the "
            "authors' public code gives 0.4842")
    for stage, name in (("stats-published", "published"), ("stats", "continuous")):
        k, a, ours = (_stats_row(ws, stage, q) for q in ("W1.2-files", "W1.2-files-anova", "W1.2"))
        if k is not None and a is not None and ours is not None:
            most = ""
            if len(g):
                per = g.groupby("subject")["orientation_missing"].agg(["sum", "size"])
                top = per["sum"].idxmax()
                most = f"; {per.loc[top, 'sum']} of {top}'s {per.loc[top, 'size']}"
            bound = SUBJECTS_KRUSKAL.paper[0]
            below = "both below" if max(k["p"], a["p"]) < bound else "not both below"
            out[SUBJECTS_KRUSKAL.what] = (
                f"the marker-loss trajectories decide it: kept as the authors' files hold them (gamma = 0{most}) "
                f"Kruskal p = {k['p']:.2g}, one-way ANOVA (the authors' public script's test) p = {a['p']:.2g}, "
                f"{below} {bound:g}; without them ({name} convention, ours) p = {ours['p']:.2g}: the subjects do not "
                "differ in orientation, the marker loss does")
            break
    parts, pair = [], None
    for stage, name in (("stats-published", "published"), ("stats", "continuous")):
        mine, theirs = _stats_row(ws, stage, "W1.3"), _stats_row(ws, stage, "W1.3-pairwise")
        if theirs is not None:
            pair = pair or (name, theirs)
            n = len(str(theirs["levels"]).split(", "))
            parts.append(f"{name}: {n} subjects at p = {theirs['p']:.3g}" + (
                f", ours {len(str(mine['levels']).split(', '))} at p = {mine['p']:.3g}" if mine is not None else ""))
    if pair:
        name, r = pair
        sets = str(r["note"]).split("largest such sets: ")[-1]
        out[SUBSET_SIZE.what] = (
            "the authors' public code holds no subset search; the thesis's figure is what this definition gives: every "
            "pair of subjects Mann-Whitney p > 0.05, the subject with the median furthest from the pooled one dropped "
            f"first (row W1.3-pairwise; {'; '.join(parts)}; ours, W1.3, is the largest set with Kruskal p > 0.05); "
            f"the largest sets with every pair indistinguishable ({name}): {sets}")
    return out


def model_distance_accounts(ws: Path) -> dict[str, str]:
    """Accounts of the Pearson rows: r over the 40 means against the measured start-goal distance
    (the row), against the authors' listed distances (``AUTHORS_START_GOAL``), over the 10 start
    positions' means, and with the compare stage's d_gamma (our recomputed means' gamma)."""
    from scipy import stats

    dist = ws / "fit-ioc-published" / "distances.parquet"
    if not dist.is_file():
        return {}
    df = pd.read_parquet(dist)
    df = df[df["model"] == MODEL_R_XY.select["model"]].copy()
    if df.empty:
        return {}
    df["position"] = df["condition"].astype(str).str[1:]
    df["listed"] = df["position"].map(AUTHORS_START_GOAL)
    out = {}
    for fig in (MODEL_R_XY, MODEL_R_GAMMA):
        d = df.dropna(subset=[fig.column, "global_distance"])
        if len(d) < 3:
            continue
        r = lambda x, y: float(stats.pearsonr(x, y)[0])  # noqa: E731
        per = d.groupby("position").agg(v=(fig.column, "mean"), gd=("global_distance", "mean"), listed=("listed", "first"))
        rho = float(stats.spearmanr(d["global_distance"], d[fig.column])[0])
        text = (f"published convention, switches: against the authors' listed start-goal distances r = "
                f"{r(d['listed'], d[fig.column]):.3f}; over the 10 start positions' means (the scatter of their "
                f"distance.py) r = {r(per['gd'], per['v']):.3f}; Spearman rho {rho:.3f}")
        cmp = ws / "compare-published" / "distances.parquet"
        if fig is MODEL_R_GAMMA and cmp.is_file():
            c = pd.read_parquet(cmp)
            c = c[c["comparison"] == "model"].dropna(subset=["d_gamma", "global_distance"])
            if len(c) >= 3:
                text += (f"; with the gamma of our recomputed means (compare-published) r = "
                         f"{r(c['global_distance'], c['d_gamma']):.3f}")
        out[fig.what] = text + "; none reaches the paper's value (the public code computes no correlation, so the thesis's definition is not known)"
    return out


def accounts(ws: Path, study: str) -> dict[str, str]:
    """The one-line accounts of the study's rows, with the numbers measured in ``ws`` where a switch
    of one convention element shows what it explains."""
    if study == "pair-carriage-2022":
        out = dict(ACCOUNTS[study])
        dist = ws / "fit-ioc-published" / "distances.parquet"
        if dist.is_file():
            df = pd.read_parquet(dist)
            v = df.loc[df["model"] == "table OC (published)", "d_theta"].dropna()
            seam = v[v > np.pi]
            if len(v):
                out[PAIRS[1].what] = (f"means, not trials; the authors' comparison wraps each angle on its own, so a heading "
                                      f"near +-pi counts the seam as up to 2 pi: {len(seam)} of {len(v)} means above pi "
                                      f"(up to {v.max():.2f}); without them {v[v <= np.pi].mean():.3f}, median of all "
                                      f"{v.median():.3f}")
        return out
    if study != "walking-2020":
        return dict(ACCOUNTS.get(study, {}))
    out = dict(ACCOUNTS["walking-2020"])
    dist = ws / "fit-ioc-published" / "distances.parquet"
    if dist.is_file():
        df = pd.read_parquet(dist)
        for fig in WALKING:
            model = fig.select.get("model")
            if fig.column != "d_theta" or model not in ("Mombaur OC", "clothoid") or "d_theta_tangent" not in df:
                continue
            v = df.loc[df["model"] == model, "d_theta_tangent"].dropna()
            if len(v):
                out[fig.what] = (f"the paper's Table 1.1 is the IROS 2020 comparison, on orientations of the authors' data "
                                 f"that were not published (their DataIROS); against the walking-2020 means' path tangent "
                                 f"(theta - gamma) instead of their theta the same paths give {v.mean():.3f} ± {v.std(ddof=0):.3f}; "
                                 "the positions agree (d_xy above)")
    out.update(subjects_accounts(ws))
    out.update(model_distance_accounts(ws))
    sw = comparison_switches(ws)
    if sw:
        out[WALKING[0].what] = (f"same published-convention paths compared three ways: both resampled by arc length "
                                f"{sw['both']:.4f} (the authors' final scripts), the model path only {sw['model only']:.4f}, "
                                f"pointwise on time {sw['time']:.4f}; continuous: the same weights with integrated costs and a "
                                "free duration weigh the running cost 10 times less and fit worse (sec. 11)")
    return out


def study_of(ws: Path) -> str | None:
    """The published dataset a workspace analyses (its import-published stage), or None."""
    import json

    try:
        return json.loads((ws / "import-published" / "manifest.json").read_text())["params"]["dataset"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def section(workspaces: list[Path]) -> list[str]:
    """The reproduction tables of every workspace of a published study (empty when there is none)."""
    lines = []
    for ws in workspaces:
        study = study_of(ws)
        if study not in FIGURES:
            continue
        if not lines:
            lines = ["## The papers' model figures, reproduced", "",
                     "Each published figure beside ours under the published convention (the authors' discrete choices, "
                     "docs/methods.md sec. 11) and under the continuous one (ours), mean ± sd over the same trajectories "
                     f"(the convention's sd); 'reproduced' = within {TOLERANCE:.0%} of the paper's mean. The weights are "
                     "the published ones throughout; nothing was tuned.", ""]
        lines += table(ws, study, accounts(ws, study)) + [""]
    return lines
