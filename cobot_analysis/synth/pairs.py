"""Synthetic pair-carriage study (design of pair-carriage-2022, docs/methods.md sec. 1.2).

``generate(directory)`` writes one C3D per pair x goal x scenario recording (20 x 9 x 3 = 540 by
default; 200 Hz, mm; labels ``S1:LASI`` ... ``S2:...`` (14 markers each) and ``Table:TAB1..TAB3``),
``protocol.yaml`` (commented, ``synth.protocol``) with ``trials.csv`` (trial, file, pair,
condition = goal stem, scenario, configuration = family, end_orientation = chosen end angle,
repetition), ``subjects.csv``, ``pairs.csv`` and the ground truth (``synth.truth``). World frame of the dataset: the table starts
at (0, 0) heading pi/2 (d1, d2) or pi (d3); goals at ``design.GOAL_POSITIONS``.

A recording: both subjects stand 0.5-1 s at 1-2 m from their ends of the table, walk to it
(walk_to_table), grasp it (0.5-1 s), lift it (0.3-0.5 s to 0.10-0.20 m), carry it to the goal in
the chosen end orientation (forward, in the recording's scenario), set it down, pause 1.5-3 s,
lift it and carry it back to the start pose (return, always scenario 3), set it down and stand
0.5-1 s. A carriage segment is exactly the time the table top is more than 5 mm above its rest
height. The table's long axis (TAB1 -> TAB2) points at Subject 1, who faces Subject 2 across the
table; each holds a short end with the pelvis ``HANDLE_OFFSET`` from the table centre.

Planted effects (module constants, also written per row in ``truth_trials.parquet``):

- carriage duration ``D = (L / CARRY_SPEED + CARRY_RAMP + lift + set-down) f_s exp(eps)``,
  ``f_s = SCENARIO_TIME_FACTOR[s]`` (scenario 3, and every return, about 10 % faster),
  ``eps ~ N(0, DURATION_NOISE_SD^2)``;
- end configuration drawn with ``P(c) = exp(-CONFIG_BETA D(c)) / sum_c' exp(-CONFIG_BETA D(c'))``,
  ``D(c) = D1 + D2`` the straight-line distances travelled by the two subjects if the table ends in
  configuration c (nominal handle positions): the distance-minimising configuration is favoured;
- table path variability ``TABLE_PATH_SD`` (x ``PATH_SD_FACTOR[s]``; scenarios 1 and 2 are more
  variable) is smaller than the subjects' (table + ``SUBJECT_REL_SD`` deviation at the table +
  gait sway);
- the return follows the forward path backwards (same geometry, small change ``RETURN_SD``), but
  its speed profile is front-loaded like every carriage (``CARRY_RAMP_FRACTIONS``): resampled by arc
  length, forward and reversed return match within a few cm (the table closer than the subjects);
  time-normalised they differ by about 0.3 m, as the published mean paths do. A return inherits
  the shape, hence the variability, of its own forward path (scenarios 1 and 2 included);
- nothing depends on the pair: every recording draws its behaviour from the same distributions
  (subjects differ only in anthropometry and marker placement), so "no pair effect" holds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.angles import wrap
from cobot_analysis.design import PAIR_GOALS, SCENARIOS, TABLE_SIZE
from cobot_analysis.io.protocol import PELVIS_MARKERS, SUBJECT_MARKERS, TABLE_MARKERS
from cobot_analysis.synth import body as bd
from cobot_analysis.synth import paths
from cobot_analysis.synth.c3d import write_c3d
from cobot_analysis.synth.protocol import write_protocol
from cobot_analysis.synth.truth import TRUTH, TRUTH_TRIALS
from cobot_analysis.synth.walking import draw_style, hold, truth_frame, walk

STUDY = "synthetic-pairs"
STAGE = "synth-pairs"
N_PAIRS = 20
HANDLE_OFFSET = TABLE_SIZE[0] / 2 + 0.35  # m: pelvis CoM to table centre along the long axis
LIFT_THRESHOLD = 0.005  # m above the rest height: carriage onset / offset
CARRY_SPEED = 0.7  # m/s, speed term of the carriage duration law (``carriage_duration``)
CARRY_RAMP = 1.5  # s, constant term of the carriage duration law
#: shares of a carriage's horizontal motion spent accelerating and decelerating: the table starts
#: briskly and is placed slowly on its marks, forward and return alike, as in the published mean
#: table trajectories (time-normalised). The return path is the forward path reversed, but its
#: speed profile is not: time-normalised forward / reversed-return distances are about 0.3 m, as
#: between the published means (0.35 m for the table).
CARRY_RAMP_FRACTIONS = (0.25, 0.45)
#: planted: factor on the carriage duration per scenario (the return is scenario 3).
SCENARIO_TIME_FACTOR = {1: 1.0, 2: 1.0, 3: 0.9}
DURATION_NOISE_SD = 0.08  # sd of the log-normal duration noise
#: planted: 1/m, preference for the end configuration that minimises D1 + D2.
CONFIG_BETA = 3.0
TABLE_PATH_SD = 0.04  # m, sd of the table path's lateral bulge across recordings (scenario 3)
PATH_SD_FACTOR = {1: 1.5, 2: 1.5, 3: 1.0}  # planted: paths are more variable when one subject leads
SUBJECT_REL_SD = 0.06  # m, sd of a subject's smooth lateral deviation from its place at the table
RETURN_SD = 0.02  # m, sd of the change of bulge between the forward path and the reversed return
P_LONG_GAP = 0.10  # share of recordings with a long gap on a pelvis marker (fewer than walking)
TABLE_REST_HEIGHT = TABLE_SIZE[2]
_SUBJECT_KEY, _RECORDING_KEY, _NOISE_KEY = 4, 3, 5
_ENTITIES = ("subject1", "subject2", "table")
_PREFIX = {"subject1": "S1", "subject2": "S2", "table": "Table"}
_N_SUBJECT_MARKERS = len(SUBJECT_MARKERS)
PROTOCOL_HEADER = ("Protocol of a synthetic pair-carriage study, written by `cobot-analysis synth pairs`. Import it "
                   "with `cobot-analysis import protocol.yaml`; every key is documented in docs/protocol.md.")
PROTOCOL_NOTES = {
    "study": "Study name, copied into the 'study' column of every output.",
    "rate": "Sampling rate (Hz), used only for a raw file that states none (these C3D files state 200 Hz).",
    "entities": ("Label prefix in the raw files -> entity (walker, subject1, subject2 or table). Each file holds "
                 "two people and a table: 'S1:LASI' is a marker of Subject 1 (who holds the same end of the table "
                 "in every trial), 'S2:LASI' one of Subject 2, 'Table:TAB1' a corner of the table. Labels that "
                 "carry the subjects' names instead (e.g. 'Daphnee:LASI') list every name here with its role."),
    "marker_map": ("Lab label -> canonical label: pelvis LASI RASI LPSI RPSI (required for each person), feet LHEE "
                   "LTOE LMT5 / RHEE RTOE RMT5, head LFHD RFHD LBHD RBHD, table corners TAB1 TAB2 TAB3 (required; "
                   "TAB1 -> TAB2 along a long side, TAB1 -> TAB3 along a short side). These files use the "
                   "canonical names after the prefix, so the map is empty; a lab with other names maps them here, "
                   "e.g. 'ASISr: RASI', 'Corner1: TAB1'."),
    "subjects": "Subjects (CSV beside this file): id, sex, weight (kg), height (m).",
    "pairs": "Pairs (CSV beside this file): id, subject1, subject2 (ids of the subjects table).",
    "trials": ("One row per recording (CSV beside this file): trial (unique id), file (path relative to this "
               "file), pair, condition (goal stem: start, goal position and configuration family, e.g. "
               "d1_p4_gris), scenario of the forward carriage (1: only Subject 1 knows the goal, 2: only "
               "Subject 2, 3: both; the return is always 3), configuration (family of the two end "
               "orientations: gris 0 or pi, jaune +-pi/2), end_orientation (rad, the table's orientation at the "
               "goal), repetition. Each recording holds a forward and a return carriage."),
}


@dataclass(frozen=True)
class PairSubject:
    id: str
    sex: str
    weight: float
    height: float
    body: bd.Body


def draw_subject(seed: int, index: int) -> PairSubject:
    """Subject ``index`` (0-based; pair k has subjects 2k and 2k + 1): anthropometry only."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, _SUBJECT_KEY, index]))
    female = bool(rng.random() < 0.5)
    height = float(rng.normal(1.66, 0.06) if female else rng.normal(1.78, 0.06))
    weight = float(np.clip(rng.normal(22.5, 2.2), 18.5, 30.0) * height**2)
    return PairSubject(f"S{index + 1:02d}", "F" if female else "M", round(weight, 1), round(height, 3),
                       bd.Body.draw(rng, height))


def pair_id(index: int) -> str:
    return f"P{index + 1:02d}"


def recording_id(pair: str, stem: str, scenario: int) -> str:
    return f"{pair}_{stem}_s{scenario}"


def rot(theta) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def handles(centre, theta: float) -> tuple[np.ndarray, np.ndarray]:
    """Nominal pelvis positions of Subject 1 (on +x of the table) and Subject 2 (on -x)."""
    axis = HANDLE_OFFSET * np.array([math.cos(theta), math.sin(theta)])
    return np.asarray(centre) + axis, np.asarray(centre) - axis


def pair_distance(start_pose, centre, theta: float) -> float:
    """``D1 + D2``: straight-line distances of both subjects if the table ends at (centre, theta)."""
    s1, s2 = handles(start_pose[:2], start_pose[2])
    e1, e2 = handles(centre, theta)
    return float(np.hypot(*(e1 - s1)) + np.hypot(*(e2 - s2)))


def choose_configuration(rng: np.random.Generator, goal) -> tuple[int, np.ndarray, np.ndarray]:
    """Draw the end orientation: ``P(c) ∝ exp(-CONFIG_BETA (D1 + D2)(c))`` -> (index, P, D)."""
    dist = np.array([pair_distance(goal.start_pose, goal.position, th) for th in goal.end_orientations])
    p = np.exp(-CONFIG_BETA * (dist - dist.min()))
    p /= p.sum()
    return int(rng.choice(2, p=p)), p, dist


@dataclass
class Carriage:
    """One carriage from lift start to set-down end, sampled per frame."""

    xy: np.ndarray  # table centre (k, 2)
    theta: np.ndarray  # table long-axis orientation (k,), unwrapped
    height: np.ndarray  # lift of the table top above its rest height (k,)
    progress: np.ndarray  # travelled fraction of the path (k,)


def carriage_duration(length: float, lift: float, setdown: float, scenario: int, eps: float) -> float:
    """``D = (L / CARRY_SPEED + CARRY_RAMP + lift + set-down) SCENARIO_TIME_FACTOR[s] exp(eps)`` (s)."""
    return (length / CARRY_SPEED + CARRY_RAMP + lift + setdown) * SCENARIO_TIME_FACTOR[scenario] * math.exp(eps)


@dataclass(frozen=True)
class Lift:
    """How the table is lifted and set down: height (m), durations (s), overlap with the motion."""

    height: float
    t_lift: float
    t_set: float
    q1: float  # the motion starts q1 * t_lift after the lift starts
    q2: float  # the set-down starts q2 * t_set before the motion ends

    @classmethod
    def draw(cls, rng: np.random.Generator) -> "Lift":
        return cls(rng.uniform(0.10, 0.20), rng.uniform(0.3, 0.5), rng.uniform(0.3, 0.5),
                   rng.uniform(0.6, 1.0), rng.uniform(0.0, 0.4))

    def reversed(self, rng: np.random.Generator) -> "Lift":
        """The time-reversed handling (lift <-> set-down), slightly changed: for the return."""
        return Lift(self.height * float(np.exp(rng.normal(0, 0.1))), self.t_set, self.t_lift,
                    1.0 - self.q2, 1.0 - self.q1)


def carry(points: np.ndarray, theta0: float, theta1: float, window: tuple[float, float], lift: Lift,
          scenario: int, eps: float, rate: float) -> Carriage:
    """Lift, move the table along ``points`` turning from ``theta0`` to ``theta1``, set it down.

    The table turns as it travels (s = travelled fraction of the path), half in proportion to the
    distance and half within the fraction ``window = (a, b)`` of the path:
    ``theta = theta0 + (theta1 - theta0) (s + S((s - a) / (b - a))) / 2``, so that the carriers'
    paths stay smooth (no orbiting around a table that turns on the spot). Lift and set-down follow
    ``H S(t / t_lift)``; horizontal motion starts ``q1`` into the lift and ends ``q2`` into the
    set-down. The speed profile accelerates over ``CARRY_RAMP_FRACTIONS[0]`` of the motion and
    decelerates over ``CARRY_RAMP_FRACTIONS[1]``.
    """
    lift_h, t_lift, t_set, q1, q2 = lift.height, lift.t_lift, lift.t_set, lift.q1, lift.q2
    length = float(np.hypot(*np.diff(points, axis=0).T).sum())
    target = carriage_duration(length, t_lift, t_set, scenario, eps)
    motion = max(target - t_lift * q1 - t_set * (1 - q2), 1.0)
    path = paths.along(points, motion, CARRY_RAMP_FRACTIONS[0] * motion, rate, CARRY_RAMP_FRACTIONS[1] * motion)
    m0 = int(round(t_lift * q1 * rate))
    n_motion = len(path.t)
    s0 = m0 + n_motion - 1 - int(round(t_set * q2 * rate))  # set-down start frame
    n = s0 + int(round(t_set * rate)) + 1
    t = np.arange(n) / rate
    height = lift_h * (paths.smoothstep(t / t_lift) - paths.smoothstep((t - s0 / rate) / t_set))
    xy = hold(path.xy, m0, n - m0 - n_motion)
    frac = np.cumsum(np.concatenate([[0.0], np.hypot(*np.diff(path.xy, axis=0).T)])) / max(path.length, 1e-12)
    progress = hold(frac, m0, n - m0 - n_motion)
    a, b = window
    theta = theta0 + (theta1 - theta0) * 0.5 * (progress + paths.smoothstep((progress - a) / (b - a)))
    return Carriage(xy, theta, height, progress)


def at_table(table_xy, table_theta, progress, sign: float, grip, amplitudes) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis pose of a carrier = table pose composed with its place at the table.

    Place in the table frame: ``x = sign HANDLE_OFFSET + dx + ax b``, ``y = dy + ay b``,
    ``theta = (pi if Subject 1 else 0) + dth + ath b`` with ``b = sin^2(pi s)`` (s the carriage
    progress): the grip offsets ``(dx, dy, dth)`` plus a smooth deviation that vanishes at both ends.
    ``amplitudes`` (frames, 3) are the ``(ax, ay, ath)`` of the carriage each frame belongs to.
    """
    dx, dy, dth = grip
    bump = np.sin(np.pi * np.asarray(progress)) ** 2
    rel_x = sign * HANDLE_OFFSET + dx + amplitudes[:, 0] * bump
    rel_y = dy + amplitudes[:, 1] * bump
    rel_th = (math.pi if sign > 0 else 0.0) + dth + amplitudes[:, 2] * bump
    c, s = np.cos(table_theta), np.sin(table_theta)
    return table_xy + np.column_stack([c * rel_x - s * rel_y, s * rel_x + c * rel_y]), table_theta + rel_th


def simulate_recording(task: tuple) -> tuple[list[dict], list[dict], dict]:
    """Make one recording and write its C3D: ``task = (directory, seed, pair index, goal index, scenario, raw)``.

    With ``raw`` false the C3D file is not written (truth only: fast statistical checks).

    Returns (truth columns, truth_trials rows, protocol row).
    """
    directory, seed, i_pair, i_goal, scenario, raw = task
    rate = bd.RATE
    goal = PAIR_GOALS[i_goal]
    pair = pair_id(i_pair)
    trial = recording_id(pair, goal.stem, scenario)
    subjects = [draw_subject(seed, 2 * i_pair), draw_subject(seed, 2 * i_pair + 1)]
    rng = np.random.default_rng(np.random.SeedSequence([seed, _RECORDING_KEY, i_pair, i_goal, scenario]))
    gaits = [bd.Gait.draw(rng), bd.Gait.draw(rng)]

    # -- the table's two carriages ----------------------------------------------------------------
    xs, ys, ths = goal.start_pose
    start = np.array([xs, ys]) + rng.normal(0, 0.02, 2)
    th_start = ths + rng.normal(0, 0.02)
    chosen, p_conf, dist = choose_configuration(rng, goal)
    th_end_nominal = goal.end_orientations[chosen]
    end = np.array(goal.position) + rng.normal(0, 0.03, 2)
    turn = float(wrap(th_end_nominal - ths))
    if abs(abs(turn) - math.pi) < 1e-9:  # half turn: rotate toward the side of the goal
        cross = math.cos(ths) * (end[1] - start[1]) - math.sin(ths) * (end[0] - start[0])
        turn = math.pi if cross >= 0 else -math.pi
    th_end = th_start + turn + rng.normal(0, 0.03)
    chord = end - start
    d = float(np.hypot(*chord))
    heading = math.atan2(chord[1], chord[0])
    bulge = rng.normal(0, TABLE_PATH_SD * PATH_SD_FACTOR[scenario])  # published table paths are nearly straight
    fwd_pts = paths.hermite(start, end, heading, heading, k=1.0, bulge=bulge)
    window = (rng.uniform(0.0, 0.2), rng.uniform(0.8, 1.0))
    eps_f, eps_r = rng.normal(0, DURATION_NOISE_SD, 2)
    handling = Lift.draw(rng)
    fwd = carry(fwd_pts, th_start, th_end, window, handling, scenario, eps_f, rate)
    # return: the forward path reversed, ending at the start marks, with a small change of bulge
    back = np.asarray(start) + rng.normal(0, 0.02, 2)
    u = np.linspace(0.0, 1.0, len(fwd_pts))[:, None]
    ret_pts = fwd_pts[::-1] + u * (back - start)
    normal = np.array([chord[1], -chord[0]]) / d  # left normal of the return chord
    ret_pts = ret_pts + rng.normal(0, RETURN_SD) * np.sin(np.pi * u) ** 2 * normal
    ret_window = (max(0.0, 1 - window[1] + rng.normal(0, 0.03)), min(1.0, 1 - window[0] + rng.normal(0, 0.03)))
    ret = carry(ret_pts, th_end, th_start + rng.normal(0, 0.02), ret_window, handling.reversed(rng), 3, eps_r, rate)

    # -- walking to the table ---------------------------------------------------------------------
    grips = [(rng.normal(0, 0.02), rng.normal(0, 0.03), rng.normal(0, 0.1)) for _ in range(2)]
    walks = []
    for k, sign in enumerate((1.0, -1.0)):
        dx0, dy0, dth0 = grips[k]
        hand = start + rot(th_start) @ np.array([sign * HANDLE_OFFSET + dx0, dy0])
        th_hand = th_start + (math.pi if sign > 0 else 0.0) + dth0
        r, alpha = rng.uniform(1.0, 2.0), rng.uniform(-0.7, 0.7)
        spot = hand + rot(th_start) @ (r * np.array([sign * math.cos(alpha), math.sin(alpha)]))
        to_table = math.atan2(*(hand - spot)[::-1])
        path, theta = walk(rng, draw_style(rng), spot, to_table + rng.normal(0, 0.3), hand, th_hand, rate)
        walks.append((path, theta, int(round(rng.uniform(0.0, 0.3) * rate))))

    # -- timeline (frames) ------------------------------------------------------------------------
    k_walk = int(round(rng.uniform(0.5, 1.0) * rate))
    k_lift1 = k_walk + max(delay + len(p.t) for p, _, delay in walks) + int(round(rng.uniform(0.5, 1.0) * rate))
    k_lift2 = k_lift1 + len(fwd.height) + int(round(rng.uniform(1.5, 3.0) * rate))
    n = k_lift2 + len(ret.height) + int(round(rng.uniform(0.5, 1.0) * rate))
    t = np.arange(n) / rate

    table_xy = np.empty((n, 2))
    table_th, raised = np.empty(n), np.zeros(n)
    spans = ((k_lift1, fwd), (k_lift2, ret))
    table_xy[:k_lift1], table_th[:k_lift1] = fwd.xy[0], fwd.theta[0]
    for i, (k0, car) in enumerate(spans):
        k1 = k0 + len(car.height)
        table_xy[k0:k1], table_th[k0:k1], raised[k0:k1] = car.xy, car.theta, car.height
        nxt = spans[i + 1][0] if i + 1 < len(spans) else n
        table_xy[k1:nxt], table_th[k1:nxt] = car.xy[-1], car.theta[-1]

    progress = np.zeros(n)
    for k0, car in spans:
        progress[k0:k0 + len(car.height)] = car.progress
    people = []
    for k, sign in enumerate((1.0, -1.0)):
        path, theta, delay = walks[k]
        amplitudes = np.zeros((n, 3))
        for k0, car in spans:  # each carriage its own deviation from the place at the table
            amplitudes[k0:k0 + len(car.height)] = rng.normal(0, [0.03, SUBJECT_REL_SD, 0.25])
        xy, th = at_table(table_xy, table_th, progress, sign, grips[k], amplitudes)
        w0, w1 = k_walk + delay, k_walk + delay + len(path.t) - 1
        xy[:w0], th[:w0] = path.xy[0], theta[0]
        xy[w0:w1 + 1], th[w0:w1 + 1] = path.xy, theta
        th = np.unwrap(th)  # the walk may end at the grip heading + 2 k pi
        speed = bd.speed_of(xy, rate)
        com, dz, theta_true = bd.oscillate(t, xy, th, speed, gaits[k])
        people.append((xy, com, dz, theta_true, speed, w0, w1))

    # -- gaps, then markers (noise from its own stream so that truth does not depend on ``raw``) --
    psi = np.pi * gaits[0].f_step * t + gaits[0].psi0
    z_top = TABLE_REST_HEIGHT + raised + 0.003 * bd.envelope(bd.speed_of(table_xy, rate)) * np.cos(2 * psi)
    labels = [f"{_PREFIX[e]}:{m}" for e in ("subject1", "subject2") for m in SUBJECT_MARKERS]
    labels += [f"Table:{m}" for m in TABLE_MARKERS]
    pelvis_cols = [k * _N_SUBJECT_MARKERS + SUBJECT_MARKERS.index(m) for k in range(2) for m in PELVIS_MARKERS]
    long = rng.random() < P_LONG_GAP
    k0, car = spans[int(rng.integers(2))]  # the long gap hides a pelvis marker during one carriage
    missing, gaps = bd.plan_gaps(rng, n, len(labels), long_markers=pelvis_cols if long else (),
                                 long_window=(k0, k0 + len(car.height)))
    if raw:
        xyz = np.concatenate([bd.subject_markers(t, com, dz, th, speed, subjects[k].body, gaits[k])
                              for k, (_, com, dz, th, speed, _, _) in enumerate(people)]
                             + [bd.table_markers(table_xy, table_th, z_top)], axis=1)
        noise = np.random.default_rng(np.random.SeedSequence([seed, _NOISE_KEY, i_pair, i_goal, scenario]))
        write_c3d(Path(directory) / "raw" / f"{trial}.c3d", labels, bd.add_noise(noise, xyz), rate, missing)

    # -- truth ------------------------------------------------------------------------------------
    above = (z_top - TABLE_REST_HEIGHT) > LIFT_THRESHOLD
    carried = [np.flatnonzero(above[k0:k0 + len(car.height)]) + k0 for k0, car in spans]
    segment = np.full(n, "rest", dtype=object)
    segment[carried[0][-1] + 1:carried[1][0]] = "pause"
    segment[carried[0][0]:carried[0][-1] + 1] = "forward"
    segment[carried[1][0]:carried[1][-1] + 1] = "return"
    frame = np.arange(n, dtype=np.int32)
    pieces, rows = [], []
    for k, entity in enumerate(_ENTITIES):
        if entity == "table":
            x, y, th, z = table_xy[:, 0], table_xy[:, 1], table_th, z_top
            seg, lost = segment, np.zeros(n, dtype=bool)
            occluded = missing[:, -3:].sum(axis=1)
            base = table_xy
        else:
            base, com, _, th, _, w0, w1 = people[k]
            x, y, z = com[:, 0], com[:, 1], np.full(n, np.nan)
            seg = segment.copy()
            seg[w0:w1 + 1] = "walk_to_table"
            cols = pelvis_cols[4 * k:4 * k + 4]
            lost = np.zeros(n, dtype=bool)
            for g in gaps:
                if g.marker in cols:
                    lost[g.start:g.stop] = True
            occluded = missing[:, cols].sum(axis=1)
        pieces.append({"trial": trial, "entity": entity, "frame": frame, "time": t, "x": x, "y": y, "theta": th,
                       "z": z, "segment": seg, "orientation_lost": lost, "pelvis_occluded": occluded.astype(np.int8)})
        segs = [("forward", carried[0], scenario, fwd, eps_f), ("return", carried[1], 3, ret, eps_r)]
        if entity != "table":
            segs.insert(0, ("walk_to_table", np.arange(people[k][5], people[k][6] + 1), np.nan, None, np.nan))
        for name, frames, scen, car, eps in segs:
            a, b = int(frames[0]), int(frames[-1])
            step = np.hypot(*np.diff(base[a:b + 1], axis=0).T)
            row = {"trial": trial, "entity": entity, "segment": name, "onset": a / rate, "offset": b / rate,
                   "travel_time": (b - a) / rate, "condition": goal.stem, "pair": pair, "scenario": scen,
                   "orientation_lost": bool(lost[a:b + 1].any()), "x0": x[a], "y0": y[a], "theta0": th[a],
                   "xf": x[b], "yf": y[b], "thetaf": th[b], "path_length": float(step.sum()),
                   "peak_speed": float(step.max() * rate) if len(step) else 0.0}
            if car is not None:
                row.update(configuration=goal.family, end_orientation=th_end_nominal,
                           time_factor=SCENARIO_TIME_FACTOR[scen], duration_noise=float(math.exp(eps)),
                           distance_chosen=float(dist[chosen]), distance_other=float(dist[1 - chosen]),
                           p_chosen=float(p_conf[chosen]), optimal=bool(dist[chosen] <= dist[1 - chosen] + 1e-9))
            rows.append(row)
    proto = {"trial": trial, "file": f"raw/{trial}.c3d", "pair": pair, "condition": goal.stem, "scenario": scenario,
             "configuration": goal.family, "end_orientation": th_end_nominal, "repetition": 1}
    return pieces, rows, proto


def generate(directory, seed: int = 0, n_pairs: int = N_PAIRS, goals: Sequence[str] | None = None,
             scenarios: Sequence[int] = (1, 2, 3), jobs: int | None = 1, scheduler: str | None = None,
             write_raw: bool = True) -> Path:
    """Write a synthetic pair-carriage study into ``directory``; return the path of ``protocol.yaml``.

    ``goals``: goal stems of ``design.PAIR_GOALS`` (default all 9); ``scenarios``: subset of 1, 2, 3.
    ``write_raw=False`` skips the C3D files (truth and protocol only; the protocol then names
    files that do not exist).
    """
    from cobot_analysis.parallel import map_tasks
    from cobot_analysis.schema import write_table

    if n_pairs < 1:
        raise ValueError("n_pairs must be >= 1")
    stems = [g.stem for g in PAIR_GOALS]
    goals = stems if goals is None else list(goals)
    for stem in goals:
        if stem not in stems:
            raise ValueError(f"unknown pair goal {stem!r}")
    if not scenarios or any(s not in SCENARIOS for s in scenarios):
        raise ValueError(f"scenarios must be a non-empty subset of {sorted(SCENARIOS)}")
    directory = Path(directory)
    (directory / "raw").mkdir(parents=True, exist_ok=True)
    tasks = [(str(directory), seed, i, stems.index(stem), s, write_raw) for i in range(n_pairs) for stem in goals
             for s in sorted(scenarios)]
    results = map_tasks(simulate_recording, tasks, jobs=jobs, scheduler=scheduler, description="synth pairs")
    truth = truth_frame([piece for r in results for piece in r[0]])
    trials_truth = pd.DataFrame([row for r in results for row in r[1]])
    for col in TRUTH_TRIALS.columns:
        if col not in trials_truth:
            trials_truth[col] = np.nan
    meta = {"study": STUDY, "seed": seed, "rate": bd.RATE,
            "planted": {"scenario_time_factor": SCENARIO_TIME_FACTOR, "duration_noise_sd": DURATION_NOISE_SD,
                        "config_beta": CONFIG_BETA, "table_path_sd": TABLE_PATH_SD, "path_sd_factor": PATH_SD_FACTOR,
                        "subject_rel_sd": SUBJECT_REL_SD, "return_sd": RETURN_SD}}
    write_table(truth, directory / "truth.parquet", TRUTH, **meta)
    write_table(trials_truth[list(TRUTH_TRIALS.columns)], directory / "truth_trials.parquet", TRUTH_TRIALS, **meta)
    subjects = [draw_subject(seed, i) for i in range(2 * n_pairs)]
    subj = pd.DataFrame({"id": [s.id for s in subjects], "sex": [s.sex for s in subjects],
                         "weight": [s.weight for s in subjects], "height": [s.height for s in subjects]})
    pairs = pd.DataFrame({"id": [pair_id(i) for i in range(n_pairs)],
                          "subject1": [subjects[2 * i].id for i in range(n_pairs)],
                          "subject2": [subjects[2 * i + 1].id for i in range(n_pairs)]})
    trials = pd.DataFrame([r[2] for r in results])
    (directory / "results.md").write_text(summary(trials_truth))
    return write_protocol(directory / "protocol.yaml", STUDY, trials, subjects=subj, pairs=pairs, rate=bd.RATE,
                          entities={_PREFIX[e]: e for e in _ENTITIES}, header=PROTOCOL_HEADER, notes=PROTOCOL_NOTES)


def summary(trials_truth: pd.DataFrame) -> str:
    """Markdown fragment describing the generated study (``results.md`` of the stage)."""
    table = trials_truth[trials_truth["entity"] == "table"]
    fwd = table[table["segment"] == "forward"]
    ret = table[table["segment"] == "return"]
    lines = ["## Synthetic pair-carriage study", "",
             f"{fwd['pair'].nunique()} pairs x {fwd['condition'].nunique()} goals x {fwd['scenario'].nunique()} "
             f"scenarios: {len(fwd)} recordings, {len(fwd) + len(ret)} carriages (C3D, 200 Hz, mm).", "",
             "| carriage | n | travel time (s) | planted factor | optimal configuration (%) |", "|---|---|---|---|---|"]
    for (seg, scen), g in table[table["segment"].isin(["forward", "return"])].groupby(["segment", "scenario"]):
        lines.append(f"| {seg} scenario {int(scen)} | {len(g)} | {g['travel_time'].mean():.2f} +- {g['travel_time'].std():.2f} "
                     f"| {SCENARIO_TIME_FACTOR[int(scen)]} | {100 * g['optimal'].mean():.0f} |")
    lost = trials_truth[trials_truth["entity"] != "table"].groupby("trial")["orientation_lost"].any()
    lines += ["", f"Orientation lost (long gap on a pelvis marker) in {int(lost.sum())} recordings "
                  f"({100 * lost.mean():.0f} %; planted share {100 * P_LONG_GAP:.0f} %).", ""]
    return "\n".join(lines)
