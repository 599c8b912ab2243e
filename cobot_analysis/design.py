"""Designs of the CoBot studies (docs/methods.md sec. 1): conditions, start poses, goals, scenarios.

Shared by the synthetic generator, the published-data importers, the statistics and the models so
that every part of the pipeline names conditions the same way.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

# ---- walking-2020 ---------------------------------------------------------------------------------
#: start orientation letter -> theta0 (rad). N, E, S, O(uest) as in the published file names.
ORIENTATIONS = {"N": math.pi / 2, "E": 0.0, "S": -math.pi / 2, "O": math.pi}
#: position codes in the order of StartAndEnd.dat (each with N, E, S, O).
POSITION_CODES = ("1500", "4000", "-0615", "0615", "1515", "4015", "-0640", "0640", "1540", "4040")
#: the 40 start conditions, e.g. "E4015", in the published order (position-major).
WALKING_CONDITIONS = tuple(f"{o}{p}" for p in POSITION_CODES for o in "NESO")
#: goal pose in the goal frame.
WALKING_GOAL = (0.0, 0.0, math.pi / 2)
GLOBAL_DISTANCE_SPLIT = 3.0  # m: "< 3 m" vs "> 3 m" groups of docs/methods.md sec. 4

_CODE = re.compile(r"^([NESO])(-?)(\d)(\d)(\d)(\d)$")


@dataclass(frozen=True)
class WalkingCondition:
    code: str  # e.g. "E4015"
    orientation: str  # N, E, S, O
    a: float  # grid coordinates written in the code (m)
    b: float

    @property
    def theta0(self) -> float:
        return ORIENTATIONS[self.orientation]

    @property
    def start(self) -> tuple[float, float, float]:
        """Nominal start pose in the goal frame: (x, y) = (-b, 0.6 - a), heading theta0 (+-0.2 m in the data)."""
        return (-self.b, 0.6 - self.a, self.theta0)

    @property
    def global_distance(self) -> float:
        x, y, _ = self.start
        return math.hypot(x - WALKING_GOAL[0], y - WALKING_GOAL[1])


def walking_condition(code: str) -> WalkingCondition:
    """Parse a start-condition code: ``E4015`` -> E, a = 4.0, b = 1.5; ``S-0640`` -> a = -0.6, b = 4.0."""
    m = _CODE.match(code)
    if not m:
        raise ValueError(f"not a walking start-condition code: {code!r} (expected e.g. E4015 or S-0640)")
    letter, sign, a1, a2, b1, b2 = m.groups()
    a = float(f"{a1}.{a2}") * (-1 if sign else 1)
    return WalkingCondition(code, letter, a, float(f"{b1}.{b2}"))


#: how far (m) a condition's measured start may lie from its code's nominal start, both taken from the goal (the
#: median over its paths of each start from its own end), for the label to be that code (docs/methods.md sec. 1.1:
#: walking-2020 0.39 at most, the synthetic study 0.23; the design's nearest two starts lie 0.9 m apart)
CODE_TOLERANCE = 0.6


def design_codes(conditions, starts, ends) -> tuple[dict[str, WalkingCondition], str]:
    """The labels of one study's paths that are walking-2020 start-condition codes, and '' or why its code-like
    labels are not. ``conditions``: a label per path; ``starts``, ``ends``: (n, 2) first and last measured
    positions. A label such as "S1020" (a lab's session 1, trial 020) parses as a code; it counts as one only when
    every code-like label of the study agrees with its data (``CODE_TOLERANCE``), else none does (a study's labels
    are its design's or its own)."""
    import numpy as np

    parsed = {}
    for c in dict.fromkeys(map(str, conditions)):
        try:
            parsed[c] = walking_condition(c)
        except ValueError:
            pass
    if not parsed:
        return {}, ""
    labels = np.asarray(list(map(str, conditions)))
    rel = np.asarray(starts, float) - np.asarray(ends, float)
    off = {}
    for c, w in parsed.items():
        d = np.hypot(*(rel[labels == c] - np.subtract(w.start[:2], WALKING_GOAL[:2])).T)
        if np.isfinite(d).any():  # a label whose paths have no measured start or end is not judged
            off[c] = float(np.median(d[np.isfinite(d)]))
    worst = max(off, key=off.get, default=None)
    if worst is None or off[worst] <= CODE_TOLERANCE:
        return parsed, ""
    x, y, _ = parsed[worst].start
    return {}, (f"its label {worst} reads as the walking-2020 code of a start at ({x + 0.0:g}, {y + 0.0:g}) from the goal, but its "
                f"paths start {off[worst]:.2f} m from there (over {CODE_TOLERANCE:g} m): the labels are the study's own")


def table_codes(df) -> tuple[dict[str, WalkingCondition], str]:
    """``design_codes`` of one study's long trajectories or means table (trial, sample, condition, x, y)."""
    if "condition" not in df or not any(_CODE.match(str(c)) for c in df["condition"].unique()):
        return {}, ""
    paths = df.sort_values("sample").groupby("trial", sort=False) if "sample" in df else df.groupby("trial", sort=False)
    first, last = paths[["condition", "x", "y"]].first(), paths[["x", "y"]].last()  # first / last measured
    return design_codes(first["condition"], first[["x", "y"]].to_numpy(float), last[["x", "y"]].to_numpy(float))


# ---- pair-carriage-2022 ---------------------------------------------------------------------------
SCENARIOS = {1: "S1 leader", 2: "S2 leader", 3: "both know the goal"}
TABLE_SIZE = (1.22, 0.80, 0.77)  # length (x, long axis), width, height (m)
#: approximate goal positions of the table centre in the world frame (README of the dataset).
GOAL_POSITIONS = {"p4": (-3.07, -2.25), "p5": (-1.53, -2.28), "p6": (-3.0, -4.5), "p7": (0.0, -4.6)}
#: configuration family -> the two end orientations of the table (rad).
CONFIGURATIONS = {"gris": (0.0, math.pi), "jaune": (math.pi / 2, -math.pi / 2)}


@dataclass(frozen=True)
class PairGoal:
    stem: str  # e.g. "d1_p4_gris": start dK, goal position pJ, configuration family
    start_pose: tuple[float, float, float]  # table start (x, y, theta)
    position: tuple[float, float]
    family: str

    @property
    def end_orientations(self) -> tuple[float, float]:
        return CONFIGURATIONS[self.family]


def _pair_goal(stem: str) -> PairGoal:
    d, p, family = stem.split("_")
    start = (0.0, 0.0, math.pi if d == "d3" else math.pi / 2)
    return PairGoal(stem, start, GOAL_POSITIONS[p], family)


#: the 9 goals (goal position x configuration family) of the pair study.
PAIR_GOALS = tuple(_pair_goal(s) for s in (
    "d1_p4_gris", "d1_p4_jaune", "d1_p5_gris", "d1_p5_jaune", "d1_p6_gris", "d1_p6_jaune",
    "d2_p7_gris", "d2_p7_jaune", "d3_p7_gris"))
