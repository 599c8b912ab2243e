"""Ground truth of the synthetic studies, kept beside the raw C3D files.

``truth.parquet`` (``TRUTH``): the true pose of every entity at every frame of every recording,
so that a test can measure how well the pipeline recovers it from the noisy, gappy markers.
``truth_trials.parquet`` (``TRUTH_TRIALS``): per recording, entity and segment, the true motion
onset / offset and the parameters that were planted (scenario time factor, configuration
choice probabilities, ...).
"""

from __future__ import annotations

from cobot_analysis.schema import Column, TableSchema

#: segment labels of ``TRUTH.segment`` (per entity and frame).
SEGMENTS = ("rest", "walk", "walk_to_table", "forward", "pause", "return")

TRUTH = TableSchema(
    name="truth",
    version=1,
    description=(
        "Synthetic studies: true pose of each entity per recording and frame (before noise and "
        "gaps). Recording frames are those of the C3D file (time = frame / rate)."
    ),
    columns={
        "trial": Column("string", "", "recording id (protocol trials.csv)"),
        "entity": Column("string", "", "walker, subject1, subject2 or table"),
        "frame": Column("int", "-", "frame index from 0 (as in the C3D file)"),
        "time": Column("float", "s", "frame / rate, time in the recording"),
        "x": Column("float", "m", "true pelvis CoM (barycentre of the 4 true pelvis markers) or table centre"),
        "y": Column("float", "m", "true pelvis CoM (barycentre of the 4 true pelvis markers) or table centre"),
        "theta": Column("float", "rad", "true pelvis forward normal / table long axis (TAB1->TAB2) orientation, unwrapped"),
        "z": Column("float", "m", "table: height of the table top (0.77 m on the floor); NaN for people"),
        "segment": Column("string", "", "rest, walk, walk_to_table, forward, pause or return"),
        "orientation_lost": Column("bool", "", "a long gap (>= 0.3 s) hides a pelvis marker at this frame"),
        "pelvis_occluded": Column("int", "-", "number of pelvis markers (table: corner markers) missing (NaN) in "
                                             "the C3D at this frame, short gaps included", required=False),
    },
)

TRUTH_TRIALS = TableSchema(
    name="truth_trials",
    version=1,
    description=(
        "Synthetic studies: one row per recording, entity and moving segment with the true onset / "
        "offset of the motion and the planted parameters (NaN where a parameter does not apply)."
    ),
    columns={
        "trial": Column("string", "", "recording id (protocol trials.csv)"),
        "entity": Column("string", "", "walker, subject1, subject2 or table"),
        "segment": Column("string", "", "walk, walk_to_table, forward or return"),
        "onset": Column("float", "s", "start of the motion in the recording (carriage: table top rises above 5 mm)"),
        "offset": Column("float", "s", "end of the motion (carriage: table top back below 5 mm)"),
        "travel_time": Column("float", "s", "offset - onset"),
        "condition": Column("string", "", "walking start condition or pair goal stem"),
        "subject": Column("string", "", "walking: subject id", required=False),
        "pair": Column("string", "", "pairs: pair id", required=False),
        "scenario": Column("int", "-", "pairs: 1, 2 or 3 (return carriage: always 3)", required=False),
        "configuration": Column("string", "", "pairs: configuration family of the goal", required=False),
        "end_orientation": Column("float", "rad", "pairs: chosen end orientation of the table at the goal", required=False),
        "orientation_lost": Column("bool", "", "a long gap hides a pelvis marker during this segment"),
        "x0": Column("float", "m", "true start position (onset)"),
        "y0": Column("float", "m", "true start position (onset)"),
        "theta0": Column("float", "rad", "true start orientation"),
        "xf": Column("float", "m", "true end position (offset)"),
        "yf": Column("float", "m", "true end position (offset)"),
        "thetaf": Column("float", "rad", "true end orientation (unwrapped, continuing theta0)"),
        "path_length": Column("float", "m", "true arc length of the base path (without gait sway)"),
        "peak_speed": Column("float", "m/s", "peak speed of the base path"),
        "time_factor": Column("float", "-", "pairs: planted scenario factor on the carriage duration", required=False),
        "duration_noise": Column("float", "-", "pairs: multiplicative log-normal noise on the carriage duration", required=False),
        "distance_chosen": Column("float", "m", "pairs: D1 + D2 (nominal) for the chosen end orientation", required=False),
        "distance_other": Column("float", "m", "pairs: D1 + D2 (nominal) for the other end orientation", required=False),
        "p_chosen": Column("float", "-", "pairs: probability with which the chosen configuration was drawn", required=False),
        "optimal": Column("bool", "", "pairs: the chosen configuration minimises D1 + D2", required=False),
    },
)
