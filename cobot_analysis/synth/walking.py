"""Synthetic single-walking study (design of walking-2020, docs/methods.md sec. 1.1).

``generate(directory)`` writes, for n subjects x start conditions x repetitions, one C3D file per
trial (200 Hz, mm, the 14 markers of ``io.protocol.SUBJECT_MARKERS``, labels without prefix),
``protocol.yaml`` (commented, ``synth.protocol``) with ``trials.csv`` (trial, file, subject,
condition, repetition) and ``subjects.csv`` (id, sex, weight, height), and the ground truth ``truth.parquet`` /
``truth_trials.parquet`` (``synth.truth``). Coordinates are in the goal frame of the study: goal
pose (0, 0, pi/2), start near ``walking_condition(code).start``.

A trial: the subject stands still 0.5-1.0 s at the start pose, walks to the goal along a smooth
base path (``synth.paths``: Hermite geometry, trapezoidal speed profile peaking at 1.0-1.3 m/s),
turning the pelvis toward the direction of travel early in the walk and to the goal heading at
the end, then stands 0.8-1.3 s at the goal. Gait oscillation, noise and gaps: ``synth.body``.
A subject keeps the same style (peak speed, path bulge, turning habits, start offset) in every
trial; trial-to-trial noise is added on top.

Determinism: every random draw comes from ``SeedSequence([seed, ...])`` keyed by the subject index,
the condition's index in ``design.WALKING_CONDITIONS`` and the repetition, so a subset of the
study reproduces exactly the same trials as the full study.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from cobot_analysis.angles import wrap
from cobot_analysis.design import WALKING_CONDITIONS, WALKING_GOAL, walking_condition
from cobot_analysis.io.protocol import PELVIS_MARKERS, SUBJECT_MARKERS
from cobot_analysis.synth import body as bd
from cobot_analysis.synth import paths
from cobot_analysis.synth.c3d import write_c3d
from cobot_analysis.synth.protocol import write_protocol
from cobot_analysis.synth.truth import TRUTH, TRUTH_TRIALS

STUDY = "synthetic-walking"
STAGE = "synth-walking"
N_SUBJECTS = 10
N_TRIALS = 3
#: share of trials with one long gap on a pelvis marker (walking-2020 lost orientation in 125/400).
P_LONG_GAP = 0.28
#: where subjects stand relative to the nominal start of ``design.walking_condition(code).start``:
#: shifted by START_SHIFT (m) and START_BEHIND (m) behind the start orientation. Fitted by eye to
#: the first samples of the published mean trajectories of walking-2020 (mean offsets per start
#: orientation N (0.0, 0.02), E (-0.11, 0.16), S (0.01, 0.27), O (0.12, 0.16) m).
START_SHIFT = (0.0, 0.145)
START_BEHIND = 0.12
_PELVIS_COLS = tuple(SUBJECT_MARKERS.index(m) for m in PELVIS_MARKERS)
PROTOCOL_HEADER = ("Protocol of a synthetic walking study, written by `cobot-analysis synth walking`. Import it with "
                   "`cobot-analysis import protocol.yaml`; every key is documented in docs/protocol.md.")
PROTOCOL_NOTES = {
    "study": "Study name, copied into the 'study' column of every output.",
    "rate": "Sampling rate (Hz), used only for a raw file that states none (these C3D files state 200 Hz).",
    "entities": ("Label prefix in the raw files -> entity (walker, subject1, subject2 or table). The labels of this "
                 "study have no prefix (LASI, RASI, ...), so every marker belongs to the walker and nothing needs "
                 "declaring. A single-person file whose labels carry the subject's name (Vicon: 'S01:LASI') needs "
                 "nothing either: an undeclared prefix is dropped. A file holding several people or a table "
                 "declares its prefixes, e.g. 'S1: subject1'."),
    "marker_map": ("Lab label -> canonical label: pelvis LASI RASI LPSI RPSI (required), feet LHEE LTOE LMT5 / RHEE "
                   "RTOE RMT5, head LFHD RFHD LBHD RBHD, table corners TAB1 TAB2 TAB3. These files use the canonical "
                   "labels, so the map is empty; a lab that names the iliac spines otherwise maps them here, e.g. "
                   "'L_ASIS: LASI' (or, for one prefixed label only, 'S01:L_ASIS: LASI')."),
    "subjects": "Subjects (CSV beside this file): id, sex, weight (kg), height (m).",
    "trials": ("One row per raw file (CSV beside this file): trial (unique id), file (path relative to this file), "
               "subject (an id of the subjects table), condition (start condition code: orientation letter N E S O "
               "and start grid position, e.g. E4015), repetition."),
}
_SUBJECT_KEY, _TRIAL_KEY, _NOISE_KEY = 1, 2, 6  # first words of the SeedSequence entropy, per use


@dataclass(frozen=True)
class Style:
    """How one subject walks (constant across the subject's trials)."""

    v_peak: float  # m/s, peak speed of the base path
    t_ramp: float  # s, acceleration / deceleration time
    start_bias: tuple[float, float]  # m, where the subject tends to stand at the start marks
    bulge: float  # m, lateral bulge of the path (+ = left of the chord), for a 3 m walk
    k: float  # Hermite tangent length, relative to the start-goal distance
    alpha_start: float  # share of the start orientation kept by the initial walking direction
    alpha_end: float  # share of the goal heading taken by the final walking direction
    turn_start: float  # share of the duration spent turning the pelvis toward the path at the start
    turn_end: float  # share of the duration spent turning to the goal heading at the end
    theta_end_bias: float  # rad, final heading offset
    turn_sign: float  # +1 / -1: preferred turning direction when starting facing away


@dataclass(frozen=True)
class Subject:
    id: str
    sex: str
    weight: float
    height: float
    body: bd.Body
    gait: bd.Gait
    style: Style


def draw_style(rng: np.random.Generator) -> Style:
    """A walking style: peak speed 1.0-1.3 m/s, ramps 1.0-1.4 s, start offset, bulge, turning habits."""
    return Style(
        v_peak=float(np.clip(rng.normal(1.15, 0.08), 1.0, 1.3)),
        t_ramp=float(rng.uniform(1.0, 1.4)),
        start_bias=(float(rng.normal(0, 0.08)), float(rng.normal(0, 0.08))),
        bulge=float(rng.normal(0, 0.05)),
        k=float(rng.uniform(0.8, 1.1)),
        alpha_start=float(rng.uniform(0.1, 0.3)),
        alpha_end=float(rng.uniform(0.1, 0.3)),
        turn_start=float(rng.uniform(0.2, 0.35)),
        turn_end=float(rng.uniform(0.2, 0.3)),
        theta_end_bias=float(rng.normal(0, 0.05)),
        turn_sign=float(rng.choice([-1.0, 1.0])),
    )


def draw_subject(seed: int, index: int) -> Subject:
    """Subject ``index`` (0-based) of the study with ``seed``: anthropometry, gait and style."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, _SUBJECT_KEY, index]))
    female = index % 5 == 2  # 2 women out of 10, as in walking-2020
    height = float(rng.normal(1.65, 0.05) if female else rng.normal(1.77, 0.06))
    weight = float(np.clip(rng.normal(22.5, 2.0), 18.5, 29.0) * height**2)
    style = draw_style(rng)
    return Subject(f"S{index + 1:02d}", "F" if female else "M", round(weight, 1), round(height, 3),
                   bd.Body.draw(rng, height), bd.Gait.draw(rng), style)


def walk(rng: np.random.Generator, style: Style, start, theta0: float, goal, thetaf: float, rate: float):
    """One walk between two poses -> (BasePath, pelvis theta along it (unwrapped)).

    Initial walking direction ``phi0 = c + alpha_start wrap(theta0 - c)`` and final one
    ``phi1 = c + alpha_end wrap(thetaf - c)`` (c the start->goal chord heading); the pelvis turns
    from ``theta0`` toward the path and ends at ``thetaf`` (``paths.turn_profile``).
    """
    start, goal = np.asarray(start, dtype=float), np.asarray(goal, dtype=float)
    chord = goal - start
    d = float(np.hypot(*chord))
    c = math.atan2(chord[1], chord[0])
    phi0 = c + style.alpha_start * float(wrap(theta0 - c))
    phi1 = c + style.alpha_end * float(wrap(thetaf - c))
    bulge = (style.bulge + rng.normal(0, 0.04)) * min(1.0, d / 3.0)
    pts = paths.hermite(start, goal, phi0, phi1, k=style.k * float(np.exp(rng.normal(0, 0.05))), bulge=bulge)
    length = float(np.hypot(*np.diff(pts, axis=0).T).sum())
    v_peak = style.v_peak * float(np.exp(rng.normal(0, 0.04)))
    duration = paths.motion_duration(length, v_peak, style.t_ramp)
    path = paths.along(pts, duration, style.t_ramp, rate)
    h0, hf = path.heading[0], path.heading[-1]
    d0 = float(wrap(theta0 - h0))
    if abs(d0) > math.pi - 0.35:  # facing away: turn the subject's preferred way
        d0 = style.turn_sign * abs(d0)
    df = float(wrap(thetaf - hf))
    T = path.duration
    ts = min(max(0.6, style.turn_start * T), 0.5 * T)
    te = min(max(0.6, style.turn_end * T), 0.5 * T)
    theta = paths.turn_profile(path.t, T, path.heading, h0 + d0, hf + df, ts, te)
    return path, theta


def hold(values: np.ndarray, before: int, after: int) -> np.ndarray:
    """Pad a motion with ``before`` / ``after`` copies of its first / last sample (standing still)."""
    pad = [(before, after)] + [(0, 0)] * (values.ndim - 1)
    return np.pad(values, pad, mode="edge")


def trial_id(subject: str, condition: str, repetition: int) -> str:
    return f"{subject}_{condition}_{repetition}"


def simulate_trial(task: tuple) -> tuple[dict, dict]:
    """Make one trial and write its C3D: ``task = (directory, seed, subject index, condition, repetition, raw)``.

    With ``raw`` false the C3D file is not written (truth only).

    Returns (truth columns as arrays, truth_trials row).
    """
    directory, seed, i_subject, code, repetition, raw = task
    rate = bd.RATE
    subject = draw_subject(seed, i_subject)
    rng = np.random.default_rng(np.random.SeedSequence(
        [seed, _TRIAL_KEY, i_subject, WALKING_CONDITIONS.index(code), repetition]))
    cond = walking_condition(code)
    x0, y0, th0 = cond.start
    behind = -START_BEHIND * np.array([math.cos(th0), math.sin(th0)])
    start = np.array([x0, y0]) + START_SHIFT + behind + subject.style.start_bias + rng.normal(0, 0.06, 2)
    theta0 = th0 + rng.normal(0, 0.08)
    goal = np.array(WALKING_GOAL[:2]) + rng.normal(0, 0.03, 2)
    thetaf = WALKING_GOAL[2] + subject.style.theta_end_bias + rng.normal(0, 0.04)
    path, theta = walk(rng, subject.style, start, theta0, goal, thetaf, rate)

    before, after = int(round(rng.uniform(0.5, 1.0) * rate)), int(round(rng.uniform(0.8, 1.3) * rate))
    m = len(path.t) - 1
    n = before + m + 1 + after
    t = np.arange(n) / rate
    base_xy, base_theta = hold(path.xy, before, after), hold(theta, before, after)
    speed = np.pad(path.speed, (before, after))
    com, dz, theta_true = bd.oscillate(t, base_xy, base_theta, speed, subject.gait)
    long = rng.random() < P_LONG_GAP
    missing, gaps = bd.plan_gaps(rng, n, len(SUBJECT_MARKERS), long_markers=_PELVIS_COLS if long else (),
                                 long_window=(before, before + m))
    trial = trial_id(subject.id, code, repetition)
    if raw:  # noise from its own stream, so that the truth does not depend on ``raw``
        noise = np.random.default_rng(np.random.SeedSequence(
            [seed, _NOISE_KEY, i_subject, WALKING_CONDITIONS.index(code), repetition]))
        xyz = bd.add_noise(noise, bd.subject_markers(t, com, dz, theta_true, speed, subject.body, subject.gait))
        write_c3d(Path(directory) / "raw" / f"{trial}.c3d", SUBJECT_MARKERS, xyz, rate, missing)

    lost = np.zeros(n, dtype=bool)
    for g in gaps:
        lost[g.start:g.stop] = True
    segment = np.full(n, "rest", dtype=object)
    segment[before:before + m + 1] = "walk"
    truth = {"trial": trial, "entity": "walker", "frame": np.arange(n, dtype=np.int32), "time": t,
             "x": com[:, 0], "y": com[:, 1], "theta": theta_true, "z": np.full(n, np.nan), "segment": segment,
             "orientation_lost": lost, "pelvis_occluded": missing[:, list(_PELVIS_COLS)].sum(axis=1).astype(np.int8)}
    k0, k1 = before, before + m
    row = {"trial": trial, "entity": "walker", "segment": "walk", "onset": k0 / rate, "offset": k1 / rate,
           "travel_time": m / rate, "condition": code, "subject": subject.id, "orientation_lost": bool(lost.any()),
           "x0": com[k0, 0], "y0": com[k0, 1], "theta0": theta_true[k0], "xf": com[k1, 0], "yf": com[k1, 1],
           "thetaf": theta_true[k1], "path_length": path.length, "peak_speed": float(path.speed.max())}
    return truth, row


def truth_frame(pieces: Sequence[dict]) -> pd.DataFrame:
    """Concatenate per-recording truth columns into the TRUTH table (labels as categories)."""
    cols = {}
    sizes = [len(p["frame"]) for p in pieces]
    for name in TRUTH.columns:
        values = [p[name] for p in pieces]
        if np.isscalar(values[0]) or isinstance(values[0], str):
            cols[name] = pd.Categorical(np.repeat(np.array(values, dtype=object), sizes))
        else:
            cols[name] = np.concatenate(values)
    df = pd.DataFrame(cols)
    df["segment"] = pd.Categorical(df["segment"])
    return df


def generate(directory, seed: int = 0, n_subjects: int = N_SUBJECTS, n_trials: int = N_TRIALS,
             conditions: Sequence[str] | None = None, jobs: int | None = 1, scheduler: str | None = None,
             write_raw: bool = True) -> Path:
    """Write a synthetic walking study into ``directory``; return the path of ``protocol.yaml``.

    ``conditions``: start-condition codes (default: all 40 of ``design.WALKING_CONDITIONS``).
    ``write_raw=False`` skips the C3D files (truth and protocol only).
    """
    from cobot_analysis.parallel import map_tasks
    from cobot_analysis.schema import write_table

    if n_subjects < 1 or n_trials < 1:
        raise ValueError("n_subjects and n_trials must be >= 1")
    conditions = list(WALKING_CONDITIONS if conditions is None else conditions)
    for code in conditions:
        if code not in WALKING_CONDITIONS:
            raise ValueError(f"unknown walking condition {code!r}")
    directory = Path(directory)
    (directory / "raw").mkdir(parents=True, exist_ok=True)
    tasks = [(str(directory), seed, i, code, r, write_raw) for i in range(n_subjects) for code in conditions
             for r in range(1, n_trials + 1)]
    results = map_tasks(simulate_trial, tasks, jobs=jobs, scheduler=scheduler, description="synth walking")
    truth = truth_frame([r[0] for r in results])
    trials_truth = pd.DataFrame([r[1] for r in results])
    for col in TRUTH_TRIALS.columns:
        if col not in trials_truth:
            trials_truth[col] = np.nan
    meta = {"study": STUDY, "seed": seed, "rate": bd.RATE}
    write_table(truth, directory / "truth.parquet", TRUTH, **meta)
    write_table(trials_truth[list(TRUTH_TRIALS.columns)], directory / "truth_trials.parquet", TRUTH_TRIALS, **meta)
    subjects = [draw_subject(seed, i) for i in range(n_subjects)]
    subj = pd.DataFrame({"id": [s.id for s in subjects], "sex": [s.sex for s in subjects],
                         "weight": [s.weight for s in subjects], "height": [s.height for s in subjects]})
    trials = pd.DataFrame({"trial": [r[1]["trial"] for r in results],
                           "file": [f"raw/{r[1]['trial']}.c3d" for r in results],
                           "subject": [r[1]["subject"] for r in results],
                           "condition": [r[1]["condition"] for r in results],
                           "repetition": [t[4] for t in tasks]})
    (directory / "results.md").write_text(summary(trials_truth))
    return write_protocol(directory / "protocol.yaml", STUDY, trials, subjects=subj, rate=bd.RATE,
                          header=PROTOCOL_HEADER, notes=PROTOCOL_NOTES)


def summary(trials_truth: pd.DataFrame) -> str:
    """Markdown fragment describing the generated study (``results.md`` of the stage)."""
    tt = trials_truth
    lost = int(tt["orientation_lost"].sum())
    return (
        "## Synthetic walking study\n\n"
        f"{tt['subject'].nunique()} subjects x {tt['condition'].nunique()} start conditions: {len(tt)} trials "
        f"(C3D, 200 Hz, mm). Travel time {tt['travel_time'].mean():.2f} +- {tt['travel_time'].std():.2f} s, "
        f"peak speed {tt['peak_speed'].mean():.2f} +- {tt['peak_speed'].std():.2f} m/s, path length "
        f"{tt['path_length'].min():.2f}-{tt['path_length'].max():.2f} m. Orientation lost (long gap on a "
        f"pelvis marker) in {lost} trials ({100 * lost / len(tt):.0f} %; planted share {100 * P_LONG_GAP:.0f} %).\n"
    )
