"""The tables of the localisation stage (docs/methods.md sec. 9), in metres, radians and seconds:
``localisation.parquet`` one row per run (like the published per-experiment table), ``errors.parquet``
one row per associated ICP sample, ``goals.parquet`` one row per commanded goal.
"""

from __future__ import annotations

from cobot_analysis.schema import Column, TableSchema

_AXIS_UNIT = {"x": "m", "y": "m", "z": "m", "yaw": "rad"}


def _err_cols() -> dict[str, Column]:
    cols = {}
    for a, u in _AXIS_UNIT.items():
        cols[f"err_{a}_mean"] = Column("float", u, f"mean of |error| on {a}")
        cols[f"err_{a}_sd"] = Column("float", u, f"sd of |error| on {a}")
        cols[f"err_{a}_rmse"] = Column("float", u, f"root mean square error on {a}")
        cols[f"err_{a}_max"] = Column("float", u, f"max |error| on {a}")
    return cols


RUNS = TableSchema(
    name="localisation-runs",
    version=1,
    description="Localisation accuracy per run (ICP vs motion capture, docs/methods.md sec. 9).",
    columns={
        "run": Column("string", "", "run label"),
        "file": Column("string", "", "bag file or directory; DIR/run_0.bag+run_1.bag for the pieces of a split recording read as one (--join)"),
        "map": Column("string", "", "map label given on the command line (e.g. architectural, scanned)"),
        "truth": Column("string", "", "truth stream (topic or tf:PARENT->CHILD)"),
        "icp": Column("string", "", "ICP stream (topic or tf:PARENT->CHILD)"),
        "time_base": Column("string", "", "'header' stamps or bag 'record' time"),
        "up_truth": Column("string", "", "vertical axis of the truth frame and how it was found (given, detected, assumed); "
                                         "poses, errors and offsets are in the frame levelled to it (z up)"),
        "up_icp": Column("string", "", "vertical axis of the ICP frame, likewise"),
        "duration": Column("float", "s", "motion-capture span"),
        "n_truth": Column("int", "-", "motion-capture poses"),
        "n_icp": Column("int", "-", "ICP poses"),
        "n": Column("int", "-", "ICP poses associated with the truth (the samples of the errors)"),
        "distance": Column("float", "m", "travelled distance (planar path length of the smoothed truth)"),
        "delay": Column("float", "s", "delay of the ICP behind the truth (estimated or given)"),
        "delay_sd": Column("float", "s", "standard error of the delay (0 when given, NaN at the window edge)"),
        "delay_method": Column("string", "", "how the delay was obtained"),
        "delay_at_edge": Column("bool", "", "the delay estimate is on an end of its search window (no minimum; sd NaN)"),
        "max_gap": Column("float", "s", "longest truth gap interpolated across (--max-gap, default twice the truth's median sample spacing, at least 0.05 s)"),
        "alignment": Column("string", "", "offset removal: mean (per-axis mean difference), se3 (Umeyama), yaw (4 DoF), none"),
        "association": Column("string", "", "interpolate (truth at the ICP stamps) or nearest (nearest stamp)"),
        "offset_x": Column("float", "m", "structural offset, ICP minus truth (mean method); se3/yaw: translation of the rigid transform truth -> ICP frame"),
        "offset_y": Column("float", "m", "structural offset, ICP minus truth (mean method); se3/yaw: translation of the rigid transform truth -> ICP frame"),
        "offset_z": Column("float", "m", "structural offset, ICP minus truth (mean method); se3/yaw: translation of the rigid transform truth -> ICP frame"),
        "offset_yaw": Column("float", "rad", "structural offset, ICP minus truth (mean method); se3/yaw: rotation about z of the rigid transform truth -> ICP frame"),
        **_err_cols(),
        "ape_rmse": Column("float", "m", "RMSE of the 3-D position error (evo APE, translation part)"),
        "ape_mean": Column("float", "m", "mean 3-D position error"),
        "ape_median": Column("float", "m", "median 3-D position error"),
        "ape_std": Column("float", "m", "population sd of the 3-D position error"),
        "ape_max": Column("float", "m", "max 3-D position error"),
        "ape_min": Column("float", "m", "min 3-D position error"),
        "drift": Column("float", "m/m", "slope of the planar position error against the travelled distance; NaN (said in warnings) when the compared poses span less than 1 m of it"),
        "drift_sd": Column("float", "m/m", "standard error of the slope"),
        "drift_intercept": Column("float", "m", "intercept of that line"),
        "jumps": Column("int", "-", "jumps of the ICP against the truth (relocalisations: steps of their difference between "
                                    "consecutive poses of at least 0.1 m or 0.1 rad and 10 times the median step)"),
        "warnings": Column("string", "", "what to read with care, ' | '-separated (frame not z-up, delay at the window edge, "
                                         "dropped messages, ICP poses not compared, ...); empty when none"),
        "goals_commanded": Column("int", "-", "commanded goals", required=False),
        "goals_found": Column("int", "-", "goals matched to a detected stop", required=False),
        "goals_within_tolerance": Column("int", "-", "goals reached within the stop tolerances", required=False),
        **{f"goal_err_{a}_{s}": Column("float", "rad" if a == "yaw" else "m", f"{'mean' if s == 'mean' else 'sd'} of |reached - goal| on {a}", required=False)
           for a in ("x", "y", "xy", "yaw") for s in ("mean", "sd")},
    },
)

ERRORS = TableSchema(
    name="localisation-errors",
    version=1,
    description="One row per associated ICP sample: truth, raw and aligned ICP pose, signed errors.",
    columns={
        "run": Column("string", "", "run label"),
        "t": Column("float", "s", "ICP stamp"),
        "t_truth": Column("float", "s", "t minus the delay: where the truth was taken"),
        "distance": Column("float", "m", "travelled distance at t_truth"),
        **{f"{k}_{a}": Column("float", u, f"{d} {a}") for k, d in (("truth", "truth"), ("icp", "raw ICP"), ("aligned", "ICP after offset removal"))
           for a, u in _AXIS_UNIT.items()},
        **{f"err_{a}": Column("float", u, f"signed error aligned minus truth on {a}") for a, u in _AXIS_UNIT.items()},
        "err_xyz": Column("float", "m", "3-D position error"),
    },
)

GOALS = TableSchema(
    name="localisation-goals",
    version=1,
    description="One row per commanded goal and run: matched stop, reached pose (truth, in the goal frame), errors.",
    columns={
        "run": Column("string", "", "run label"),
        "goal": Column("int", "-", "goal number in command order"),
        "goal_x": Column("float", "m", "commanded goal"), "goal_y": Column("float", "m", "commanded goal"),
        "goal_yaw": Column("float", "rad", "commanded goal"),
        "found": Column("bool", "", "a stop was matched to the goal"),
        "t_start": Column("float", "s", "stop start (truth time)", required=False),
        "t_end": Column("float", "s", "stop end", required=False),
        "duration": Column("float", "s", "stop duration", required=False),
        "reached_x": Column("float", "m", "mean truth pose over the stop, goal frame", required=False),
        "reached_y": Column("float", "m", "mean truth pose over the stop, goal frame", required=False),
        "reached_yaw": Column("float", "rad", "mean truth pose over the stop, goal frame", required=False),
        "dx": Column("float", "m", "reached minus goal", required=False),
        "dy": Column("float", "m", "reached minus goal", required=False),
        "dyaw": Column("float", "rad", "reached minus goal, wrapped", required=False),
        "err_xy": Column("float", "m", "planar distance reached to goal", required=False),
        "within_tolerance": Column("bool", "", "err_xy <= tol_xy and |dyaw| <= tol_yaw"),
        "icp_x": Column("float", "m", "mean ICP pose over the stop (delay removed)", required=False),
        "icp_y": Column("float", "m", "mean ICP pose over the stop", required=False),
        "icp_yaw": Column("float", "rad", "mean ICP pose over the stop", required=False),
        "loc_err_xy": Column("float", "m", "planar distance ICP to reached pose at the stop", required=False),
        "loc_err_yaw": Column("float", "rad", "|ICP yaw - reached yaw| at the stop", required=False),
    },
)
