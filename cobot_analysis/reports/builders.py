"""Study reports: a Markdown file (README.md) embedding the tables and figures of a workspace.

``build_report(study, inputs, stage, out)`` reads what the workspace holds (trajectories, means,
distances, stats, reconstruction), draws the figures of ``reports.figures`` into the stage directory
(PNG + PDF) and writes README.md (the report) and results.md (a fragment for docs/results.md). Every
label, abbreviation and question id comes from the study file (``cobot_analysis.study``); a section
is drawn when the data support it (paths, distances by each factor, carriage analyses), whatever the
study's name.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.reports import figures
from cobot_analysis.schema import as_text

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
    for d in ioc_stages(out):  # the IOC fits' weights.json (a changed fit redoes the report)
        found[f"ioc:{d}"] = out / d / "weights.json"
    return found


def ioc_stages(out: Path) -> list[str]:
    """The workspace's IOC fit directories with a weights.json (the coupled fit has its own section), each
    bi-level fit followed by its single-level twin: fit-ioc, fit-ioc-published, fit-ioc-single, fit-ioc-subjects, ..."""
    from cobot_analysis import registry

    names = ("fit-ioc", "fit-ioc-single", "fit-ioc-subjects", "fit-ioc-subjects-single")
    dirs = [d.name for d in Path(out).glob("fit-ioc*") if registry.base_stage(d.name) in names and (d / "weights.json").is_file()]
    return sorted(dirs, key=lambda d: (names.index(registry.base_stage(d)), d))


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
    caption = caption[:1].upper() + caption[1:]
    stage.savefig(fig, stem)
    lines += [f"![{caption}]({stem}.png)", "", f"*{caption}* ([PDF]({stem}.pdf))", ""]


SCENARIO_STYLE = {1: "-", 2: "--", 3: ":"}


def _path_panels(ts, means, keys: list[str], title_of, select=None, scenario=None) -> list[dict]:
    """Path panels, one per distinct ``keys`` (sorted): trials as thin lines, means bold; a forward pair
    mean is drawn in its scenario's line style and named after the scenario (``scenario``: the
    study's scenario factor, for the level names)."""
    from cobot_analysis.study import COLUMNS

    scenario = scenario or COLUMNS["scenario"]
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
            if kind == "lines":  # named by subject (walking) or trial: figures.paths names a few of them
                who = m["subject"].iloc[i] if "subject" in m.columns and pd.notna(m["subject"].iloc[i]) else m["trial"].iloc[i]
                panels[key]["lines"].append((src.x[i], src.y[i], ent, str(who)))
            elif "frames_differ" in str(m["quality"].iloc[i] if "quality" in m.columns else ""):
                if "mean not drawn" not in panels[key]["title"]:  # averaging.frame_spread: no path anyone walked
                    panels[key]["title"] += "\n(mean not drawn: trials in different frames)"
            else:
                sc = m["scenario"].iloc[i] if "scenario" in m.columns and m["direction"].iloc[i] == "forward" else None
                meaning = scenario.levels.get(as_text(sc), "") if sc is not None and sc == sc else ""
                name = (f"mean of {scenario.level(sc, short=True)}" + (f" ({meaning})" if meaning else "")
                        if sc is not None and sc == sc else None)
                panels[key]["means"].append((src.x[i], src.y[i], src.theta[i], ent, SCENARIO_STYLE.get(sc, "-"), name))
    return [panels[k] for k in sorted(order, key=lambda k: tuple(str(v) for v in k))]


def _key(v):
    """A panel key value: floats rounded (end orientations), the rest as is."""
    return round(float(v), 3) if isinstance(v, float | np.floating) else v


def _end_title(key) -> str:
    """Pair panel title: goal stem and the table's end orientation in degrees."""
    goal, end = key
    return f"{goal}, table ends at {np.degrees(end):.0f}°" if end == end else str(goal)


def _stats_section(data: dict, study, lines: list[str]) -> None:
    from cobot_analysis.stats.analyses import markdown

    if "stats" in data:
        lines.append(markdown(data["stats"], "Statistics"))
        if not study.declared:
            lines += ["The study file declares no questions: these are the default descriptive statistics (each distance "
                      "and travel time described by each factor, Kruskal-Wallis where two levels have two values; "
                      "docs/statistics.md says how to declare questions).", ""]
    else:
        lines += ["## Statistics", "", "Not computed: run `cobot-analysis stats` first.", ""]


def _ticks(study, keys: tuple, columns: list[str]) -> str:
    """A box label: each key shown by its factor (short forms: "Subj. 1", "fwd", "sc1")."""
    from cobot_analysis.study import ENTITY_SHORT

    out = []
    for col, v in zip(columns, keys):
        if col == "entity":
            out.append(ENTITY_SHORT.get(v, str(v)))
        elif col == "direction":
            out.append({"forward": "fwd", "return": "ret"}.get(v, str(v)))
        else:
            out.append(study.factor(col).level(v, short=True))
    return "\n".join(out)


def _data_section(study, data: dict, lines: list[str], results: list[str]) -> None:
    ts = data.get("ts")
    if ts is None:
        return
    tr = ts.meta[ts.meta["kind"].eq("trial")]

    def by_entity(rows) -> str:
        return ", ".join(f"{e}: {n}" for e, n in rows["entity"].value_counts().sort_index().items())

    if len(tr):
        txt = [f"{len(tr)} trajectories ({by_entity(tr)})."]
    else:  # a study published as means only (pair-carriage-2022): say so rather than "0 trajectories"
        mn = ts.meta[ts.meta["kind"].eq("mean")]
        txt = [f"No individual trials in the data: {len(mn)} mean trajectories ({by_entity(mn)})."]
    missing = ~np.isfinite(ts.theta).all(axis=1)
    if "subject" in tr.columns and tr["subject"].notna().any():
        per_subject = pd.Series(missing[tr.index]).groupby(tr["subject"].to_numpy()).sum()
        mean_rows = ts.meta["kind"].eq("mean").to_numpy()
        txt.append(f"Trajectories without orientation: {int(missing[tr.index].sum())} of {len(tr)} subject trajectories "
                   f"({', '.join(f'{k}: {int(v)}' for k, v in per_subject.items())})"
                   + (f"; {int(missing[mean_rows].sum())} of {int(mean_rows.sum())} published means." if mean_rows.any() else "."))
    lines += ["## Data", "", *txt, ""]
    results += [f"## {study.title}: data", "", *txt, ""]


def _paths_section(study, data: dict, stage, lines: list[str]) -> None:
    ts, means = data.get("ts"), data.get("means")
    if ts is None and means is None:
        return
    meta = (ts if ts is not None else means).meta
    pairs = "direction" in meta.columns and meta["direction"].notna().any() and "scenario" in meta.columns
    if pairs:
        goal = study.factor("configuration")
        legend = "; ".join(f"{k} = {v}" for k, v in goal.levels.items())
        for direction in ("forward", "return"):
            panels = _path_panels(ts, means, ["condition", "end_orientation"], _end_title,
                                  select=lambda m, d=direction: (m["direction"].eq(d) & m["scenario"].notna()).to_numpy(),
                                  scenario=study.factor("scenario"))
            if panels:
                what = "scenarios in line styles" if direction == "forward" else "scenario 3"
                _fig(stage, figures.paths(panels, ncols=6, arrows=6, size=2.8,
                                          title=f"{direction.capitalize()} carriage paths per goal and end orientation of the table "
                                                f"({what})", names={"lines": "individual trials"}),
                     f"paths_{direction}", f"{direction.capitalize()} paths per {study.label('condition')} and end orientation: "
                     "individual trials, means and orientation arrows" + (f" (goal code dK_pJ_<{goal.label}>: start K, goal "
                                                                         f"position J, then {' or '.join(goal.levels)}, see the codes above)" if legend else ""), lines)
        return
    from cobot_analysis.stats.sources import start_orientations

    cond = study.factor("condition")
    codes = {c for _, c in start_orientations(ts if ts is not None else means)}  # walking-2020 codes the paths agree with
    panels = _path_panels(ts, means, ["condition"], lambda k: figures.walking_title(str(k[0])) if str(k[0]) in codes
                          else cond.level(k[0]) + (f" ({cond.levels[as_text(k[0])]})" if as_text(k[0]) in cond.levels else ""))
    grid = figures.walking_grid([p["key"][0] for p in panels], codes)
    names = {"means": "mean of the trials (recomputed)"}
    if grid is not None:  # start positions (rows, by distance to the goal) x start orientations (columns)
        for p in panels:
            p["cell"] = grid[p["key"][0]]
        cols = [o for o in figures.WALKING_COLUMNS if any(str(p["key"][0])[0] == o for p in panels)]
        fig = figures.paths(panels, share="row", size=2.4, col_titles=[figures.WALKING_COLUMNS[o] for o in cols], names=names,
                            title="Walking paths to the goal (0, 0), facing +y: one row per start position (by distance), "
                                  "one column per start orientation")
        caption = ("Individual paths, recomputed mean and its orientation per start condition (code: start orientation "
                   "N, E, S or O = facing north +y, east +x, south -y, west (ouest) -x, then the start grid position)")
    else:
        fig = figures.paths(panels, ncols=min(6, max(1, len(panels))), title=f"Paths per {study.label('condition')}",
                            names=names, share=True)
        caption = f"Individual paths, mean and its orientation per {study.label('condition')} (one scale for all panels)"
    _fig(stage, fig, "paths", caption, lines)


def _distance_section(study, data: dict, stage, lines: list[str]) -> None:
    from cobot_analysis.stats.sources import distances_source, start_orientations
    from cobot_analysis.study import data_factors

    dist = data.get("distances")
    if dist is None or not len(dist):
        return
    from cobot_analysis.compare import DISTANCES

    d = distances_source(dist.assign(**{c: np.nan for c in DISTANCES.columns if c not in dist.columns}),
                         start_orientations(data.get("ts")))
    ind = d[d["comparison"].eq("individual-mean") & d["kind"].fillna("trial").eq("trial")]
    if not len(ind):
        return
    lines += ["## Variability: individual vs mean", ""]
    entities = sorted(ind["entity"].dropna().unique(), key=lambda e: ENTITY_ORDER.index(e) if e in ENTITY_ORDER else 9)
    several = len(entities) > 1
    for f in data_factors(study, ind):
        keys = (["entity"] if several else []) + [f.column]
        for col, unit in (("d_xy", "m"), ("d_theta", "rad"), ("d_gamma", "rad")):
            if col != "d_xy" and (several or not ind[col].notna().any() or f is not data_factors(study, ind)[0]):
                continue  # angular distances by the first factor only, single-entity studies
            g, colors = {}, []
            for k, v in ind.groupby(keys):
                g[_ticks(study, k if isinstance(k, tuple) else (k,), keys)] = v[col].dropna().to_numpy()
                colors.append(figures.COLORS.get(k[0] if several else entities[0], "#9ecae1"))
            _fig(stage, figures.boxplots(g, f"{col} individual vs mean ({unit})", f"{col} by {f.label}", colors,
                                         xlabel=(("entity, " if several else "") + f.label)),
                 f"box_{col}_{f.column}", study.cite(f"individual vs mean {col} by {f.label}",
                                                     source="distances", value=col, group=f.column), lines)
    if ind["global_distance"].dropna().nunique() > 1:
        _fig(stage, figures.scatter_r({e: (v["global_distance"], v["d_xy"]) for e, v in ind.groupby("entity")},
                                      "global distance (m)", "d_xy individual vs mean (m)",
                                      "Individual vs mean d_xy against the global distance"), "scatter_d_xy_global",
             study.cite("individual vs mean d_xy against the global distance (start-goal distance)", source="distances",
                        value="d_xy", group="global_distance"), lines)
    if "orientation_change" in ind and ind["orientation_change"].fillna(0).abs().gt(1e-9).any() and several:
        _fig(stage, figures.scatter_r({e: (v["orientation_change"], v["d_xy"]) for e, v in ind.groupby("entity")},
                                      "change of orientation |theta_end - theta_start| (rad)", "d_xy individual vs mean (m)",
                                      "Individual vs mean d_xy against the change of orientation"), "scatter_d_xy_turn",
             "Individual vs mean d_xy against the change of orientation", lines)
    model = d[d["comparison"].eq("model")]
    if len(model):  # rows of `compare --against generated.parquet --comparison model`
        _fig(stage, figures.boxplots({"subjects vs mean": ind["d_xy"].to_numpy(), "model vs mean": model["d_xy"].to_numpy()},
                                     "d_xy (m)", "Model error and subject variability", xlabel="comparison"), "box_model",
             study.cite("model vs mean and subject vs mean d_xy", source="distances", value="d_xy", group="comparison"), lines)
        groups = {}
        so = study.factor("start_orientation")
        for o, v in model.groupby("start_orientation"):
            groups[f"start {o}"] = v["d_xy"].to_numpy()
        gd = model["global_distance"].astype(float)
        if gd.notna().any():
            groups.update({"< 3 m": model.loc[gd < 3, "d_xy"].to_numpy(), "> 3 m": model.loc[gd >= 3, "d_xy"].to_numpy()})
        if groups:
            _fig(stage, figures.boxplots(groups, "model d_xy (m)", f"Model error by {so.label} and global distance",
                                         xlabel=f"{so.label}, global distance"),
                 "box_model_conditions", "Model error by start orientation (N, E, S, O: facing north +y, east +x, south -y, "
                 "west -x) and by global distance", lines)


def _carriage_section(study, data: dict, stage, lines: list[str]) -> None:
    """What pair (carriage) data allow: travel time, scenarios, symmetry, end configuration choices, returns."""
    from cobot_analysis.stats.sources import build_sources

    ts, dist = data.get("ts"), data.get("distances")
    if dist is None or ts is None and "durations" not in data:
        return
    if not ("direction" in dist.columns and dist["direction"].notna().any()) and "durations" not in data:
        return  # no carriage in these data
    sources = build_sources(ts, dist, data.get("durations"), only={"durations", "choices", "patterns", "return_variability"})
    dur = sources["durations"]
    sc = study.factor("scenario")
    if len(dur) and dur["scenario"].notna().any():
        g = {_ticks(study, k, ["direction", "scenario"]): v["duration"].to_numpy() for k, v in dur.groupby(["direction", "scenario"])}
        _fig(stage, figures.boxplots(g, "travel time (s)", "Travel time by direction and scenario",
                                     xlabel="direction (fwd forward, ret return), scenario"), "box_travel_time",
             study.cite("travel time by direction and scenario", source="durations", value="duration"), lines)
    ind = dist[dist["comparison"].eq("individual-mean") & dist["kind"].eq("trial")]
    if len(ind) and ind["scenario"].notna().any():
        g, colors = {}, []
        for k, v in ind.groupby(["entity", "direction", "scenario"]):
            g[_ticks(study, k, ["entity", "direction", "scenario"])] = v["d_xy"].to_numpy()
            colors.append(figures.COLORS.get(k[0], "#9ecae1"))
        _fig(stage, figures.boxplots(g, "d_xy individual vs mean (m)", "Variability by entity, direction and scenario", colors,
                                     xlabel="entity, direction (fwd forward, ret return), scenario"),
             "box_d_xy", study.cite("individual vs mean d_xy by entity, direction and scenario", source="distances", value="d_xy",
                                    comparison="individual-mean"), lines)
    trial_level = dist["comparison"].eq("scenario-scenario").any()
    between = dist[dist["comparison"].eq("scenario-scenario" if trial_level else "scenario-scenario-mean")]
    if len(between):
        g, colors = {}, []
        b = between.assign(sp=[(int(min(a, c)), int(max(a, c))) for a, c in zip(between["scenario"], between["b_scenario"])])
        for (ent, sp), v in b.groupby(["entity", "sp"]):
            g[f"{_ticks(study, (ent,), ['entity'])}\n{sc.level(sp[0], True)}-{sc.level(sp[1], True)}"] = v["d_xy"].to_numpy()
            colors.append(figures.COLORS.get(ent, "#9ecae1"))
        what = "forward paths of one pair in two scenarios" if trial_level else "mean paths of two scenarios"
        _fig(stage, figures.boxplots(g, "d_xy (m)", f"Distance between {what} (same end orientation)", colors,
                                     xlabel="entity, scenarios compared"),
             "box_scenarios", study.cite(f"distance between {what}, per entity and scenario pair", source="distances",
                                         value="d_xy", group="scenario_pair"), lines)
    sym = dist[dist["comparison"].isin(["symmetry", "symmetry-mean"])]
    sym = sym[sym["comparison"].eq("symmetry")] if sym["comparison"].eq("symmetry").any() else sym
    if len(sym):
        _fig(stage, figures.boxplots({_ticks(study, (e,), ["entity"]): v["d_xy"].to_numpy() for e, v in sym.groupby("entity")},
                                     "d_xy forward vs reversed return (m)", "Forward/return symmetry",
                                     [figures.COLORS.get(e, "#9ecae1") for e in sorted(sym["entity"].unique())], xlabel="entity"),
             "box_symmetry", study.cite("forward vs time-reversed return distance per entity", source="distances", value="d_xy",
                                        comparison="symmetry"), lines)
    charts, chance = {}, {}
    if len(sources["patterns"]):
        counts = sources["patterns"]["pattern"].value_counts()
        expected = next((a.expected for a in (study.config.analyses if study.config else [])
                         if a.source == "patterns" and a.expected), {})
        cats = list(expected) + [k for k in counts.index if k not in expected]  # every declared pattern, also when absent
        name = "same end configuration in"
        charts[name] = {k.replace("S", "sc"): int(counts.get(k, 0)) for k in cats}
        if expected and len(set(expected.values())) == 1:
            chance[name] = float(next(iter(expected.values())))
    ch = sources["choices"]
    for who, name in (("s1", "optimal for Subj. 1"), ("s2", "optimal for Subj. 2"), ("pair", "optimal for the pair")):
        if len(ch):
            v = ch[f"optimal_{who}"].astype(bool)
            charts[name] = {"optimal": int(v.sum()), "not optimal": int((~v).sum())}
            chance[name] = float(pd.to_numeric(ch[f"chance_{who}"], errors="coerce").mean())
    if charts:
        _fig(stage, figures.proportions(charts, "End configuration choices (share with its 95 % interval; dashed: the share "
                                                "expected by chance)", chance), "bars_configuration",
             study.cite("configuration patterns across scenarios (scK = scenario K) and optimality of the chosen end "
                        "configuration, shares with 95 % Wilson intervals", source="choices"), lines)
    rv = sources["return_variability"]
    if len(rv):
        counts = {_ticks(study, (e,), ["entity"]): {"p < 0.05": int(v["significant"].astype(bool).sum()),
                                                    "p >= 0.05": int((~v["significant"].astype(bool)).sum())}
                  for e, v in rv.groupby("entity")}
        _fig(stage, figures.proportions(counts, "Returns from one goal differ within the pair (Kruskal)"), "bars_returns",
             study.cite("share of (pair, goal) whose returns differ (Kruskal p < 0.05), per entity, with 95 % Wilson intervals",
                        source="return_variability"), lines)


def build_report(study, inputs: dict, stage, out: Path) -> None:
    """Write README.md (report), figures and results.md into ``stage`` for ``study``
    (``cobot_analysis.study.Study``: its labels, abbreviations and questions)."""
    data = _load(inputs)
    where = (f"the study file `{study.path}`" if study.path else
             "no study file (labels from the data; docs/statistics.md says how to write one)")
    lines = [f"# {study.title}: report", "", "Generated by `cobot-analysis report`; every number and figure comes from the workspace "
             f"files: {', '.join(f'`{p.parent.name}/{p.name}`' for p in inputs.values())}. Study description: {where}; "
             + ("questions declared there." if study.declared else "no questions declared: default descriptive statistics."), ""]
    abbreviations = study.abbreviations()
    if abbreviations:
        lines += ["Abbreviations and codes (one meaning each in this report):", "", *[f"- {a}" for a in abbreviations], ""]
    results: list[str] = []
    refused = refused_section(out)
    lines += refused
    _data_section(study, data, lines, results)
    _paths_section(study, data, stage, lines)
    _distance_section(study, data, stage, lines)
    _carriage_section(study, data, stage, lines)
    for name in ("average", "compare", "reconstruct", "fit-ioc-coupled"):
        frag = Path(out) / name / "results.md"
        if frag.is_file():
            lines += [frag.read_text(), ""]
            for fig in [*frag.parent.glob("*.png"), *frag.parent.glob("*.pdf")]:  # the fragment's figure links
                if not stage.path(fig.name).exists():
                    shutil.copy2(fig, stage.path(fig.name))
    _stats_section(data, study, lines)
    from cobot_analysis.reports.models import ioc_overview

    lines += ioc_overview({k.split(":", 1)[1]: p for k, p in inputs.items() if k.startswith("ioc:")})
    stage.path("README.md").write_text("\n".join(lines) + "\n")
    stage.path("results.md").write_text("\n".join(results) + "\n" if results else
                                        f"## {study.title}: report\n\nSee README.md in the report stage (and the --to directory of `report`).\n")


def refused_section(out: Path) -> list[str]:
    """The trials refused by import and preprocess (their manifests' ``refused`` lists), as report lines."""
    from cobot_analysis.refusals import refused_trials

    rows = [(stage, r) for stage in ("import", "preprocess") for r in refused_trials(Path(out) / stage)]
    if not rows:
        return []
    lines = ["## Refused trials", "", f"{len(rows)} trial(s) were left out; the other trials went on.", "",
             "| stage | trial | raw file | reason | remedy |", "|---|---|---|---|---|"]
    for stage, r in rows:
        lines.append(f"| {stage} | {r['trial']} | `{Path(r.get('file') or '').name}` | {r['reason'].replace('|', '/')} | "
                     f"{r.get('remedy', '').replace('|', '/')} |")
    return lines + [""]
