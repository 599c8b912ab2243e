"""The measured trajectories an inverse-OC fit is made against (docs/methods.md sec. 6): one
walker (``Target``) or the two carriers of a pair (``PairTarget``), read from a trajectories or
means table.

Start and goal of each OC problem: the first and last measured poses (the goal heading given or
the last measured one). Under the published convention, a walking-study target takes the authors'
endpoints (docs/methods.md sec. 11): start and end positions truncated to the millimetre, the start
heading of the condition letter (N, E, S, O = pi/2, 0, -pi/2, pi) and the goal heading pi/2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.errors import InputError


@dataclass
class Target:
    """One measured trajectory the model is fitted to."""

    trial: str
    condition: str
    subject: str
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    goal_pose: tuple[float, float, float] | None = None  # None: the last measured pose
    start_pose: tuple[float, float, float] | None = None  # None: the first measured pose
    gamma: np.ndarray | None = None  # the measured local orientation when the data hold it (else from the path)
    orientation: str = ""  # the start orientation letter of its condition when that is a walking-2020 code, else ''

    @property
    def start(self) -> tuple[float, float, float]:
        if self.start_pose is not None:
            return tuple(float(v) for v in self.start_pose)
        return (float(self.x[0]), float(self.y[0]), float(self.theta[0]))

    @property
    def goal(self) -> tuple[float, float, float]:
        """The goal pose of the OC problem; its heading on the branch of the last measured theta."""
        if self.goal_pose is None:
            return (float(self.x[-1]), float(self.y[-1]), float(self.theta[-1]))
        gx, gy, gth = self.goal_pose
        k = round((self.theta[-1] - gth) / (2 * math.pi)) if np.isfinite(self.theta[-1]) else 0
        return (float(gx), float(gy), float(gth + 2 * math.pi * k))

    @property
    def global_distance(self) -> float:
        return math.hypot(self.x[-1] - self.x[0], self.y[-1] - self.y[0])


def published_endpoints(code, x: np.ndarray, y: np.ndarray):
    """The authors' start and goal poses of a path of the walking condition ``code`` (``design.WalkingCondition``,
    module docstring), or None for a label that is no walking-2020 code (None)."""
    from cobot_analysis.design import WALKING_GOAL

    if code is None:
        return None
    mm = lambda v: math.floor(float(v) * 1000) / 1000  # noqa: E731
    return (mm(x[0]), mm(y[0]), code.theta0), (mm(x[-1]), mm(y[-1]), WALKING_GOAL[2])


def targets_from_table(df: pd.DataFrame, *, path=None, entity: str = "walker", goal=None,
                       convention="continuous", unoriented: bool = False, codes: dict | None = None) -> list[Target]:
    """Targets from a long trajectories/means table (one per trial x entity); rows without
    orientation are left out (docs/methods.md sec. 6) unless ``unoriented`` (model comparisons: d_xy
    only, the start heading of the walking condition). NaN in positions is refused. ``goal``: the
    goal pose of every target (e.g. the walking study's (0, 0, pi/2)), None for the last measured
    pose; under the published convention walking conditions take ``published_endpoints`` instead.
    ``codes``: the labels that are walking-2020 codes (``design.table_codes``; default: judged on ``df``)."""
    from cobot_analysis import conventions
    from cobot_analysis.design import table_codes

    published = conventions.get(convention).name == "published"
    need = {"trial", "condition", "entity", "sample", "x", "y", "theta"}
    missing = sorted(need - set(df.columns))
    if missing:
        raise InputError(f"trajectory table lacks columns {missing}", path=path, remedy="pass a trajectories.parquet or means.parquet")
    df = df[df["entity"] == entity]
    codes = table_codes(df)[0] if codes is None else codes
    targets = []
    for trial, g in df.groupby("trial", sort=True):
        g = g.sort_values("sample")
        x, y, th = (g[c].to_numpy(float) for c in ("x", "y", "theta"))
        condition = str(g["condition"].iloc[0])
        code = codes.get(condition)
        oriented = not np.isnan(th).all()
        if not oriented and not (unoriented and code):
            continue  # no orientation: left out
        if not (np.isfinite(x).all() and np.isfinite(y).all() and (np.isfinite(th).all() or not oriented)):
            raise InputError(f"trajectory {trial!r} has NaN samples", path=path,
                             remedy="fill or drop the gaps in preprocessing (or re-run average) before fitting")
        subject = g["subject"].iloc[0] if "subject" in g and isinstance(g["subject"].iloc[0], str) else ""
        gamma = g["gamma"].to_numpy(float) if "gamma" in g and np.isfinite(g["gamma"]).all() else None
        ends = published_endpoints(code, x, y) if published or not oriented else None
        start_pose, goal_pose = ends if ends else (None, goal)
        if not oriented and not published:  # measured start and end, the condition's start heading
            start_pose = (float(x[0]), float(y[0]), ends[0][2])
            goal_pose = goal if goal is not None else (float(x[-1]), float(y[-1]), ends[1][2])
        targets.append(Target(str(trial), condition, subject, x, y, th, goal_pose, start_pose, gamma,
                              code.orientation if code else ""))
    return targets


@dataclass
class PairTarget:
    """A mean path of the two carriers (coupled model): carrier 1 and carrier 2 as ``Target``s."""

    trial: str
    condition: str
    carriers: tuple[Target, Target]
    subject: str = ""
    direction: str = ""  # forward or return

    @property
    def start(self):
        return np.array([c.start for c in self.carriers])

    @property
    def goal(self):
        return np.array([c.goal for c in self.carriers])

    @property
    def global_distance(self) -> float:
        return max(c.global_distance for c in self.carriers)


def pair_targets_from_table(df: pd.DataFrame, *, path=None, scenario: int = 3) -> list[PairTarget]:
    """Coupled-model targets: the scenario-``scenario`` forward and return means of Subject 1 and 2;
    on returns the roles are swapped (Subject 2 is carrier 1, docs/methods.md 5.6)."""
    need = {"trial", "condition", "entity", "sample", "x", "y", "theta", "direction", "scenario"}
    missing = sorted(need - set(df.columns))
    if missing:
        raise InputError(f"pair trajectory table lacks columns {missing}", path=path, remedy="pass the pair study's trajectories or means")
    sel = df[(df["scenario"] == scenario) & df["entity"].isin(["subject1", "subject2"])]
    out = []
    for trial, g in sel.groupby("trial", sort=True):
        ts = {t.trial: t for t in targets_from_table(g.assign(trial=g["entity"]), path=path, entity="subject1")
              + targets_from_table(g.assign(trial=g["entity"]), path=path, entity="subject2")}
        if set(ts) != {"subject1", "subject2"}:
            continue
        direction = str(g["direction"].iloc[0])
        order = ("subject2", "subject1") if direction == "return" else ("subject1", "subject2")
        out.append(PairTarget(str(trial), str(g["condition"].iloc[0]), (ts[order[0]], ts[order[1]]), direction=direction))
    return out
