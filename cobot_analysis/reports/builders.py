"""Study reports: a Markdown file (README.md) embedding the tables and figures of a workspace.

``build_report("walking" | "pairs", inputs, stage)`` reads what the workspace holds (trajectories,
means, distances, stats, reconstruction), draws the figures of ``reports.figures`` into the stage
directory (PNG + PDF) and writes README.md (the report) and results.md (a fragment for
docs/results.md). Sections whose data are absent say so instead of failing.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.reports import figures

ENTITY_ORDER = ["walker", "subject1", "subject2", "table"]


def report_inputs(out: Path) -> dict[str, Path]:
    """The workspace files a report can use (only those that exist)."""
    cands = {
        "trajectories": [out / "preprocess" / "trajectories.parquet", out / "import-published" / "trajectories.parquet"],
        "means": [out / "average" / "means.parquet"],
        "distances": [out / "compare" / "distances.parquet"],
        "stats": [out / "stats" / "stats.parquet"],
        "reconstruction": [out / "reconstruct" / "reconstruction.parquet"],
        "durations": [out / "import-published" / "durations.parquet"],
        "coupled_ioc": [out / "fit-ioc-coupled" / "results.md"],  # fragment included as is (a changed fit redoes the report)
    }
    found = {}
    for name, paths in cands.items():
        for p in paths:
            if p.is_file():
                found[name] = p
                break
    return found


def _load(inputs: dict) -> dict:
    from cobot_analysis.compare import DISTANCES, read_trajectory_set
    from cobot_analysis.reconstruct import RECONSTRUCTION
    from cobot_analysis.schema import read_table
    from cobot_analysis.stats.analyses import STATS

    def read(key, schema):
        df = read_table(inputs[key], schema)
        df.attrs = {}  # pandas deep-copies attrs on every operation
        return df

    data = {}
    if "trajectories" in inputs:
        data["ts"] = read_trajectory_set(inputs["trajectories"], ("trajectories",))
    if "means" in inputs:
        data["means"] = read_trajectory_set(inputs["means"], ("means",))
    for key, schema in (("distances", DISTANCES), ("stats", STATS), ("reconstruction", RECONSTRUCTION)):
        if key in inputs:
            data[key] = read(key, schema)
    if "durations" in inputs:
        data["durations"] = pd.read_parquet(inputs["durations"])
    return data


def _fig(stage, fig, stem: str, caption: str, lines: list[str]) -> None:
    stage.savefig(fig, stem)
    lines += [f"![{caption}]({stem}.png)", "", f"*{caption}* ([PDF]({stem}.pdf))", ""]


SCENARIO_STYLE = {1: "-", 2: "--", 3: ":"}
SHORT = {"subject1": "Subj. 1", "subject2": "Subj. 2", "table": "table"}  # box labels


def _path_panels(ts, means, keys: list[str], title_of, select=None) -> list[dict]:
    """Path panels, one per distinct ``keys`` (sorted): trials as thin lines, means bold; a forward pair
    mean is drawn in its scenario's line style and named after the scenario."""
    from cobot_analysis.design import SCENARIOS

    panels = {}
    order = []
    for src, kind in ((ts, "lines"), (means, "means")):
        if src is None:
            continue
        m = src.meta
        rows = np.flatnonzero(select(m)) if select else np.arange(len(m))
        if kind == "lines":
            rows = rows[m["kind"].to_numpy()[rows] == "trial"]
        for i in rows:
            key = tuple(_key(m[k].iloc[i]) for k in keys)
            if key not in panels:
                panels[key] = {"title": title_of(key), "lines": [], "means": [], "key": key}
                order.append(key)
            ent = m["entity"].iloc[i]
            if kind == "lines":
                panels[key]["lines"].append((src.x[i], src.y[i], ent))
            else:
                sc = m["scenario"].iloc[i] if "scenario" in m.columns and m["direction"].iloc[i] == "forward" else None
                name = f"mean of scenario {sc:g} ({SCENARIOS.get(int(sc), '')})" if sc is not None and sc == sc else None
                panels[key]["means"].append((src.x[i], src.y[i], src.theta[i], ent, SCENARIO_STYLE.get(sc, "-"), name))
    return [panels[k] for k in sorted(order, key=lambda k: tuple(str(v) for v in k))]


def _key(v):
    """A panel key value: floats rounded (end orientations), the rest as is."""
    return round(float(v), 3) if isinstance(v, float | np.floating) else v


def _end_title(key) -> str:
    """Pair panel title: goal stem and the table's end orientation in degrees."""
    goal, end = key
    return f"{goal}, table ends at {np.degrees(end):.0f}°" if end == end else str(goal)


def _stats_section(data: dict, lines: list[str]) -> None:
    from cobot_analysis.stats.analyses import markdown

    if "stats" in data:
        lines.append(markdown(data["stats"], "Statistics"))
    else:
        lines += ["## Statistics", "", "Not computed: run `cobot-analysis stats` first.", ""]


def _walking(data: dict, stage, lines: list[str], results: list[str]) -> None:
    ts, means, dist = data.get("ts"), data.get("means"), data.get("distances")
    if ts is not None:
        tr = ts.meta[ts.meta["kind"].eq("trial")]
        missing = ~np.isfinite(ts.theta).all(axis=1)
        per_subject = pd.Series(missing[tr.index]).groupby(tr["subject"].to_numpy()).sum()
        mean_rows = ts.meta["kind"].eq("mean").to_numpy()
        txt = (f"Trajectories without orientation: {int(missing[tr.index].sum())} of {len(tr)} subject trajectories "
               f"({', '.join(f'{k}: {int(v)}' for k, v in per_subject.items())})"
               + (f"; {int(missing[mean_rows].sum())} of {int(mean_rows.sum())} published means." if mean_rows.any() else "."))
        lines += ["## Data", "", txt, ""]
        results += ["## Walking study: data", "", txt, ""]
    if ts is not None or means is not None:
        panels = _path_panels(ts, means, ["condition"], lambda k: figures.walking_title(str(k[0])))
        grid = figures.walking_grid([p["key"][0] for p in panels])
        if grid is not None:  # 10 start positions (rows, by distance to the goal) x 4 start orientations (columns)
            for p in panels:
                p["cell"] = grid[p["key"][0]]
            cols = [o for o in figures.WALKING_COLUMNS if any(str(p["key"][0])[0] == o for p in panels)]
            fig = figures.paths(panels, share="row", size=2.4, col_titles=[figures.WALKING_COLUMNS[o] for o in cols],
                                names={"means": "mean of the subjects (recomputed)"},
                                title="Walking paths to the goal (0, 0), facing +y: one row per start position (by distance), "
                                      "one column per start orientation")
        else:
            fig = figures.paths(panels, ncols=8, title="Paths per start condition", names={"means": "mean of the subjects (recomputed)"})
        _fig(stage, fig, "paths", "Individual paths, recomputed mean and its orientation per start condition", lines)
    if dist is not None:
        ind = dist[dist["comparison"].eq("individual-mean")]
        if len(ind):
            for col, unit in (("d_xy", "m"), ("d_gamma", "rad")):
                g = {s: v[col].dropna().to_numpy() for s, v in ind.groupby("subject")}
                _fig(stage, figures.boxplots(g, f"{col} individual vs mean ({unit})", f"{col} by subject", xlabel="subject"),
                     f"box_{col}_subject", f"W1.{1 if col == 'd_xy' else 2}: individual vs mean {col} by subject", lines)
            g = {o: v["d_xy"].to_numpy() for o, v in ind.groupby(ind["condition"].astype(str).str[0])}
            _fig(stage, figures.boxplots(g, "d_xy individual vs mean (m)", "d_xy by start orientation", xlabel="start orientation"), "box_d_xy_orientation",
                 "W1.5: individual vs mean d_xy by start orientation", lines)
            _fig(stage, figures.scatter_r({"walker": (ind["global_distance"], ind["d_xy"])}, "global distance (m)", "d_xy (m)"),
                 "scatter_d_xy_global", "W1.6: individual vs mean d_xy against the global distance", lines)
        model = dist[dist["comparison"].eq("model")]
        if len(model):  # rows of `compare --against generated.parquet --comparison model`
            _fig(stage, figures.boxplots({"subjects vs mean": ind["d_xy"].to_numpy(), "model vs mean": model["d_xy"].to_numpy()},
                                         "d_xy (m)", "Model error and subject variability", xlabel="comparison"), "box_model",
                 "W2: model vs mean and subject vs mean d_xy", lines)
            orient = model["condition"].astype(str).str[0]
            gd = model["global_distance"].astype(float)
            groups = {**{f"start {o}": v["d_xy"].to_numpy() for o, v in model.groupby(orient)},
                      "< 3 m": model.loc[gd < 3, "d_xy"].to_numpy(), "> 3 m": model.loc[gd >= 3, "d_xy"].to_numpy()}
            _fig(stage, figures.boxplots(groups, "model d_xy (m)", "Model error by start orientation and global distance",
                                         xlabel="start orientation, global distance"),
                 "box_model_conditions", "W3 / W4: model error by start orientation and by global distance", lines)


def _pairs(data: dict, stage, lines: list[str], results: list[str]) -> None:
    from cobot_analysis.stats.sources import build_sources

    ts, means, dist = data.get("ts"), data.get("means"), data.get("distances")
    for direction in ("forward", "return"):
        panels = _path_panels(ts, means, ["condition", "end_orientation"], _end_title,
                              select=lambda m, d=direction: (m["direction"].eq(d) & m["scenario"].notna()).to_numpy())  # no pooled means
        if panels:
            what = "scenarios in line styles" if direction == "forward" else "scenario 3"
            _fig(stage, figures.paths(panels, ncols=6, arrows=6, size=2.8,
                                      title=f"{direction.capitalize()} carriage paths per goal and end orientation of the table "
                                            f"({what})", names={"lines": "individual trials"}),
                 f"paths_{direction}", f"{direction.capitalize()} paths per goal and end orientation: individual trials, means "
                 "and orientation arrows", lines)
    if dist is None:
        return
    sources = build_sources(ts, dist, data.get("durations"), only={"durations", "choices", "patterns", "return_variability"})
    dur = sources["durations"]
    if len(dur):
        g = {f"{d} S{s:g}": v["duration"].to_numpy() for (d, s), v in dur.groupby(["direction", "scenario"])}
        _fig(stage, figures.boxplots(g, "travel time (s)", "Travel time by direction and scenario", xlabel="direction and scenario"), "box_travel_time",
             "Q1.1 / Q2.2: travel time by direction and scenario", lines)
    ind = dist[dist["comparison"].eq("individual-mean") & dist["kind"].eq("trial")]
    if len(ind):
        g, colors = {}, []
        for (ent, d, s), v in ind.groupby(["entity", "direction", "scenario"]):
            g[f"{SHORT.get(ent, ent)}\n{d[:3]} sc{s:g}"] = v["d_xy"].to_numpy()
            colors.append(figures.COLORS[ent])
        _fig(stage, figures.boxplots(g, "d_xy individual vs mean (m)", "Variability by entity, direction and scenario", colors,
                                     xlabel="entity, direction (fwd forward, ret return), scenario"),
             "box_d_xy", "Q4.1: individual vs mean d_xy by entity, direction and scenario", lines)
        _fig(stage, figures.scatter_r({e: (v["global_distance"], v["d_xy"]) for e, v in ind.groupby("entity")},
                                      "global distance (m)", "d_xy (m)"), "scatter_d_xy_global",
             "Individual vs mean d_xy against the global distance", lines)
        pairs = ind[ind["entity"].ne("table")]
        if pairs["pair"].notna().any():
            _fig(stage, figures.boxplots({p: v["d_xy"].to_numpy() for p, v in pairs.groupby("pair")}, "d_xy individual vs mean (m)",
                                         "Subjects' variability per pair", xlabel="pair"), "box_d_xy_pair",
                 "Q4.2: individual vs mean d_xy of the subjects, per pair", lines)
        _fig(stage, figures.scatter_r({e: (v["orientation_change"], v["d_xy"]) for e, v in ind.groupby("entity")},
                                      "change of orientation |theta_end - theta_start| (rad)", "d_xy (m)"), "scatter_d_xy_turn",
             "Q4.4: individual vs mean d_xy against the change of orientation", lines)
    trial_level = dist["comparison"].eq("scenario-scenario").any()
    between = dist[dist["comparison"].eq("scenario-scenario" if trial_level else "scenario-scenario-mean")]
    if len(between):
        b = between.assign(sp=[f"S{int(min(a, c))}-S{int(max(a, c))}" for a, c in zip(between["scenario"], between["b_scenario"])])
        g, colors = {}, []
        for (ent, sp), v in b.groupby(["entity", "sp"]):
            g[f"{SHORT.get(ent, ent)}\n{sp.replace('S', 'sc')}"] = v["d_xy"].to_numpy()
            colors.append(figures.COLORS[ent])
        what = "forward paths of one pair in two scenarios" if trial_level else "mean paths of two scenarios"
        _fig(stage, figures.boxplots(g, "d_xy (m)", f"Distance between {what} (same end orientation)", colors,
                                     xlabel="entity, scenarios compared"),
             "box_scenarios", f"Q1.3: distance between {what}, per entity and scenario pair", lines)
    sym = dist[dist["comparison"].isin(["symmetry", "symmetry-mean"])]
    sym = sym[sym["comparison"].eq("symmetry")] if sym["comparison"].eq("symmetry").any() else sym
    if len(sym):
        _fig(stage, figures.boxplots({e: v["d_xy"].to_numpy() for e, v in sym.groupby("entity")}, "d_xy forward vs reversed return (m)",
                                     "Forward/return symmetry", [figures.COLORS[e] for e in sorted(sym["entity"].unique())],
                                     xlabel="entity"),
             "box_symmetry", "Q2.1: forward vs time-reversed return distance per entity", lines)
    charts = {}
    if len(sources["patterns"]):
        charts["same configuration"] = sources["patterns"]["pattern"].value_counts().to_dict()
    ch = sources["choices"]
    for who, name in (("s1", "optimal for S1"), ("s2", "optimal for S2"), ("pair", "optimal for the pair")):
        if len(ch):
            v = ch[f"optimal_{who}"].astype(bool)
            charts[name] = {"optimal": int(v.sum()), "not optimal": int((~v).sum())}
    if charts:
        _fig(stage, figures.pies(charts, "End configuration choices"), "pies_configuration",
             "Q1.2 / Q3: configuration patterns across scenarios and optimality of the chosen configuration", lines)
    rv = sources["return_variability"]
    if len(rv):
        counts = {e: {"p < 0.05": int(v["significant"].astype(bool).sum()), "p >= 0.05": int((~v["significant"].astype(bool)).sum())}
                  for e, v in rv.groupby("entity")}
        _fig(stage, figures.pies(counts, "Returns from one goal differ within the pair (Kruskal)"), "pies_returns",
             "Q4.3: share of (pair, goal) whose 3 returns differ (Kruskal p < 0.05), per entity", lines)


def build_report(study: str, inputs: dict, stage, out: Path) -> None:
    """Write README.md (report), figures and results.md into ``stage``."""
    data = _load(inputs)
    title = {"walking": "Single walking study", "pairs": "Pair carriage study"}[study]
    lines = [f"# {title}: report", "", "Generated by `cobot-analysis report`; every number and figure comes from the workspace "
             f"files: {', '.join(f'`{p.parent.name}/{p.name}`' for p in inputs.values())}.", ""]
    results: list[str] = []
    (_walking if study == "walking" else _pairs)(data, stage, lines, results)
    for name in ("average", "compare", "reconstruct", "fit-ioc-coupled"):
        frag = Path(out) / name / "results.md"
        if frag.is_file():
            lines += [frag.read_text(), ""]
            for fig in [*frag.parent.glob("*.png"), *frag.parent.glob("*.pdf")]:  # the fragment's figure links
                if not stage.path(fig.name).exists():
                    shutil.copy2(fig, stage.path(fig.name))
    _stats_section(data, lines)
    stage.path("README.md").write_text("\n".join(lines) + "\n")
    stage.path("results.md").write_text("\n".join(results) + "\n" if results else f"## {title}: report\n\nSee README.md in the report stage (and the --to directory of `report`).\n")
