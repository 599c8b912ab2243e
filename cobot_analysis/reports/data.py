"""The results fragments of the data stages (docs/results.md): what ``import``, ``import-published`` and
``preprocess`` read, checked, kept and left out."""

from __future__ import annotations

from typing import Any

from cobot_analysis.lazy import pandas as pd

from cobot_analysis.design import POSITION_CODES
from cobot_analysis import refusals
from cobot_analysis.io.markers import ImportedTrial
from cobot_analysis.refusals import Refused
from cobot_analysis.io.published import END_ORIENTATION_TOLERANCE, GAMMA_CONSISTENCY, GAMMA_LIMIT
from cobot_analysis.io.protocol import Protocol
from cobot_analysis.preprocess.stage import Params


def import_summary(protocol: Protocol, imported: list[ImportedTrial], refused: list[Refused], limits: dict[str, float],
                   outside_files: list[str] = ()) -> str:
    """The stage's results.md: what was imported, with which pelvis markers, what was left out or
    skipped, and the files outside the protocol's folder (``allow_outside``)."""
    from collections import Counter

    pelvis = Counter(" ".join(m) for t in imported for m in t.pelvis.values())
    formats = Counter(t.source_format for t in imported)
    lines = ["## Import (raw markers)", "",
             f"{len(imported)} of {len(protocol.trials)} trials of `{protocol.path.name}` imported "
             f"({', '.join(f'{n} {k}' for k, n in sorted(formats.items()))}); positions checked against the lab extent "
             f"{limits['lab_extent']:g} m, the marker speed limit {limits['max_speed']:g} m/s and the spike limit "
             f"{limits['max_spike']:g} m.", "",
             "| pelvis markers | pelvis trajectories |", "|---|---|",
             *[f"| {k} | {n} |" for k, n in sorted(pelvis.items())], ""]
    if line := vertical_line(imported):
        lines += [line + ".", ""]
    notes = [n for t in imported for n in t.notes]
    if notes:
        lines += ["Notes:", "", *[f"- {n}" for n in notes], ""]
    lines += refusals.markdown(refused, len(protocol.trials))
    if outside_files:
        lines += [f"Files outside the protocol's folder (allow_outside: true): {', '.join(outside_files)}.", ""]
    return "\n".join(lines)


def vertical_line(imported, how: str | None = None) -> str:
    """'4 of 10 trials had y as their vertical axis (detected from the pelvis markers): rotated to z up', for the
    trials whose vertical axis is not z (``how``: only those found so: given, detected); '' when none."""
    from collections import Counter

    words = {"given": "given by --up", "detected": "detected from the pelvis markers"}
    axes = Counter((t.vertical, t.vertical_how) for t in imported if t.vertical != "z" and how in (None, t.vertical_how))
    parts = [f"{n} of {len(imported)} trials had {axis} as their vertical axis ({words[h]})" for (axis, h), n in sorted(axes.items())]
    return "; ".join(parts) + ": rotated to z up" if parts else ""


def walking_results_markdown(facts: dict[str, Any]) -> str:
    """results.md fragment of the walking-2020 import (counts found next to the README's)."""
    f = facts
    per_subject = " | ".join(f"{s}: {n}" for s, n in f["orientation_missing_per_subject"].items())
    implausible = " | ".join(f"{s}: {n}" for s, n in f["implausible_per_subject"].items())
    order = ("confirmed: each row matches the first/last sample of its condition's mean block "
             f"(largest difference {f['start_end_max_error'] * 1000:.3f} mm; the next-best condition is at least "
             f"{f['start_end_next_best'] * 1000:.0f} mm away)") if f["start_end_order_ok"] else \
        f"NOT confirmed: rows match other conditions: {f['start_end_mismatches']}"
    return "\n".join([
        "## Published data: walking-2020 (import)",
        "",
        "| fact | found by the pipeline | README |",
        "|---|---|---|",
        f"| subject trajectories | {f['n_subject']} | 400 |",
        f"| published means | {f['n_mean']} | 40 |",
        f"| subject trajectories without orientation (rows 4-5 all zero) | {f['orientation_missing_subject']} | 125 |",
        f"| means without orientation | {f['orientation_missing_mean']} ({', '.join(f['orientation_missing_means'])}) | 3 (O1500, O4000, O4015) |",
        f"| mean x, y = plain mean of the 10 subjects (max difference) | {f['mean_xy_is_plain_mean']:.2e} m | yes |",
        f"| mean &#124;gamma&#124; of subjects with orientation | {f['mean_abs_gamma_subject']:.2f} rad | about 0.86 rad |",
        "",
        f"Subject trajectories without orientation, per subject: {per_subject}.",
        "",
        f"StartAndEnd.dat order (position codes {', '.join(POSITION_CODES)}, each N, E, S, O): {order}.",
        "",
        f"Implausible gamma (flag `implausible_gamma`, values kept): over 20-80 % of the path, median "
        f"|gamma| > {f['gamma_limit']} rad, or gamma disagreeing with theta minus the CoM-path heading by a median "
        f"> {GAMMA_CONSISTENCY} rad. Flagged: {f['implausible_subject']} of {f['with_orientation_subject']} subject "
        f"trajectories with orientation ({f['implausible_too_large']} too large, {f['implausible_inconsistent']} "
        f"inconsistent with the path) and {f['implausible_mean']} of the means ({', '.join(f['implausible_means']) or 'none'}). "
        f"Median |gamma| over 20-80 % of the subject paths: {f['median_abs_gamma_subject']:.2f} rad. Per subject: {implausible}.",
        "",
        f"Gamma agrees with theta minus the heading of the CoM path in {f['with_orientation_subject'] - f['implausible_inconsistent']} "
        f"of {f['with_orientation_subject']} subject trajectories, so the large values come from theta (the pelvis orientation) "
        f"itself, not from how gamma was derived; consistently, the final theta of {f['end_heading_off']} of them is more than "
        f"{GAMMA_LIMIT} rad away from the goal heading pi/2. Analyses of orientation should treat flagged trajectories "
        "with caution (they are kept, and can be filtered on `quality`).",
        "",
    ])


# ---- pair-carriage-2022 ---------------------------------------------------------------------------


def pair_results_markdown(facts: dict[str, Any]) -> str:
    """results.md fragment of the pair-carriage-2022 import (counts found next to the README's)."""
    f = facts
    fwd_total = f["forward_sc1"] + f["forward_sc2"] + f["forward_sc3"]
    dur_fwd = f["durations_forward"]
    offsets = "; ".join(f"{g} {e} ({k}): {o:.3f} rad" for g, e, k, o in f["all_data_angle_offsets"]) or "none"
    return "\n".join([
        "## Published data: pair-carriage-2022 (import)",
        "",
        "| fact | found by the pipeline | README |",
        "|---|---|---|",
        f"| forward trials in the means (nb), scenarios 1 / 2 / 3 | {f['forward_sc1']} / {f['forward_sc2']} / {f['forward_sc3']} "
        f"(total {fwd_total}; All data {f['forward_all']}) | 179 / 180 / 180 (539) |",
        f"| return trials in the means (nb) | {f['return_all']} of 540 | 522 of 540 |",
        f"| mean paths per entity: forward sc1 / sc2 / sc3 / All data, return | {f['n_means']['forward_sc1']} / "
        f"{f['n_means']['forward_sc2']} / {f['n_means']['forward_sc3']} / {f['n_means']['forward_all']}, {f['n_means']['return']} | "
        "sc3: 13, return: 18 (docs/methods.md sec. 6) |",
        f"| pairs in the durations tables | {f['durations_pairs']} | 20 |",
        f"| forward durations, scenarios 1 / 2 / 3 | {dur_fwd.get(1, 0)} / {dur_fwd.get(2, 0)} / {dur_fwd.get(3, 0)} | 180 / 180 / 180 |",
        f"| return durations | {f['durations_return']} of 180 | 172 of 180 |",
        f"| durations on the 200 Hz grid (multiples of 0.005 s) | {'yes' if f['durations_on_200hz_grid'] else 'no'} | yes |",
        f"| All data x, y = nb-weighted mean of the scenario means (max difference) | {f['all_data_weighted_xy_error']:.1e} m | exactly |",
        f"| start_and_end.json leaves equal to the first/last sample of their mean | {f['start_end_matched']} of {f['start_end_checked']} "
        f"(max difference {f['start_end_worst']:.1e} m) | all |",
        "",
        f"Angles were averaged as plain numbers. Means whose table orientation at the end (forward) or start (return) is "
        f"more than {END_ORIENTATION_TOLERANCE} rad from their configuration key, modulo 2 pi, are flagged "
        f"`plain_angle_mean` (all three entities, values kept): {len(f['plain_angle_means'])} means: "
        f"{', '.join(f['plain_angle_means']) or 'none'}.",
        "",
        f"Global orientation of the pooled All data means vs the nb-weighted mean of the scenario means, modulo 2 pi: {offsets}.",
        "",
    ])


def _measured_ends(traj: pd.DataFrame) -> list[str]:
    """The results' paragraph on the forward carriages that took their end orientation from the table (flag
    ``end_orientation_measured``): how many, and how far the table ended from the orientation taken."""
    import numpy as np

    from cobot_analysis.angles import angle_diff
    from cobot_analysis.preprocess.pairs import END_TOLERANCE

    last = traj[traj["entity"].eq("table") & traj["sample"].eq(traj["sample"].max())]
    last = last[last["quality"].str.split(";").map(lambda f: "end_orientation_measured" in f)]
    if last.empty:
        return []
    off = np.abs(angle_diff(last["theta"].to_numpy(float), last["end_orientation"].to_numpy(float)))
    return [f"{len(last)} forward carriage{'s' if len(last) > 1 else ''} had no end_orientation in the trials table: each "
            "took the table's orientation at its end, snapped to the nearer of its configuration's two (flagged "
            f"`end_orientation_measured`; at most {np.nanmax(off):.3f} rad from it, refused beyond {END_TOLERANCE:.3f}), as "
            "returns take theirs.", ""]


def preprocess_summary(traj: pd.DataFrame, gap_df: pd.DataFrame, p: Params, n_recordings: int,
                     refused: list[Refused] = ()) -> str:
    """The stage's results.md fragment: what was processed, pelvis markers, gaps, quality flags and skipped trials."""
    per = traj.drop_duplicates(["trial", "entity"])
    flags = per["quality"].str.split(";").explode().value_counts()
    pelvis = per["pelvis_markers"].dropna().value_counts()
    lines = [
        "## Preprocessing (raw markers -> trajectories)", "",
        f"{n_recordings} recordings -> {per['trial'].nunique()} trials, {len(per)} trajectories of "
        f"{p.n_samples} samples. Filter: Butterworth low-pass order {p.order} ({p.order_convention} convention), "
        f"{p.cutoff:g} Hz, zero-phase; gaps up to {p.max_gap:g} s filled by cubic spline. Segmentation: pair "
        f"recordings where the table is {p.lift_threshold * 1000:g} mm above its resting height (median of the first "
        f"{p.floor_window:g} s{f'; lifts set down less than {p.min_set_down:g} s apart are one carriage' if p.min_set_down else ''}), walking trials where the CoM speed exceeds {p.speed_threshold:g} m/s for "
        f"{p.min_duration:g} s (extended to {p.rest_speed:g} m/s; a rest of {p.min_rest:g} s separates two walks). Orientation is reported missing for a trajectory "
        f"with a long gap on {'any pelvis marker' if p.orientation_markers == 'pelvis' else 'LASI or RASI'}.", "",
        f"Gaps in the pelvis/table markers: {len(gap_df)} ({int(gap_df['filled'].sum())} filled, "
        f"{int((~gap_df['filled']).sum())} left open; {gap_df['n_frames'].sum() if len(gap_df) else 0} frames).", "",
        "| entity | marker | recordings with gaps | gaps filled | gaps left open | missing frames left |",
        "|---|---|---|---|---|---|",
        *[f"| {e} | {m} | {g['trial'].nunique()} | {int(g['filled'].sum())} | {int((~g['filled']).sum())} | "
          f"{int(g.loc[~g['filled'], 'n_frames'].sum())} |" for (e, m), g in gap_df.groupby(["entity", "marker"])], "",
        "| pelvis markers (CoM = barycentre, SACR counted for both PSIS; theta from LASI-RASI) | trajectories |", "|---|---|",
        *[f"| {k.replace(',', ' ')} | {v} |" for k, v in pelvis.items()], "",
        "| quality flag | trajectories |", "|---|---|",
        *[f"| {k} | {v} |" for k, v in flags.items()], "",
        *([f"{int(flags['truncated'])} trajectories are `truncated`: they run off the start or end of the recording (or of "
           "the visible data) while moving, so their travel time and distance cover only the recorded part.", ""]
          if "truncated" in flags else []),
        *([f"{int(flags['later_walks'])} trajectories are `later_walks`: their recording holds more walks after the first "
           f"(standing still at least {p.min_rest:g} s between them, e.g. back to the start); the first is the trial, the "
           "later ones are left out.", ""] if "later_walks" in flags else []),
        *_measured_ends(traj),
        "| entity | direction | trajectories | travel time (s), median [IQR] | travelled distance (m), median |",
        "|---|---|---|---|---|",
    ]
    for (ent, dirn), g in per.fillna({"direction": "-"}).groupby(["entity", "direction"]):
        q = g["travel_time"].quantile([0.25, 0.5, 0.75]).to_numpy()
        lines.append(f"| {ent} | {dirn} | {len(g)} | {q[1]:.2f} [{q[0]:.2f}, {q[2]:.2f}] | "
                     f"{g['travelled_distance'].median():.2f} |")
    if refused:
        lines += ["", *refusals.markdown(list(refused), n_recordings + len(refused))]
    return "\n".join(lines) + "\n"
