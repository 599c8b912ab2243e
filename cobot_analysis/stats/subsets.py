"""Largest subset of groups (subjects, pairs) whose values are statistically indistinguishable.

"Indistinguishable" = Kruskal-Wallis across the groups of the subset gives p > alpha.
Exact search when there are at most ``max_exact`` groups: subsets are tried from the largest size
down and, at the first size where some subset qualifies, the one with the largest p is returned.
With more groups (2^20 subsets for 20 pairs would be too many) a greedy search removes, one at a
time, the group whose removal gives the largest p, until p > alpha. The method used is returned.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np


@dataclass
class SubsetResult:
    members: list
    p: float
    statistic: float
    method: str  # "exact (k subsets tried)" or "greedy"


def _kruskal(values: list[np.ndarray]) -> tuple[float, float]:
    from scipy import stats

    if len(values) < 2:
        return float("nan"), 1.0
    allv = np.concatenate(values)
    if np.ptp(allv) == 0:  # all values identical: nothing distinguishes the groups
        return 0.0, 1.0
    h, p = stats.kruskal(*values)
    return float(h), float(p)


def largest_subset(groups: dict, alpha: float = 0.05, max_exact: int = 12) -> SubsetResult:
    """The largest subset of ``groups`` (label -> values) with Kruskal p > alpha (see module doc)."""
    labels = sorted(groups, key=str)
    vals = {k: np.asarray(groups[k], float) for k in labels}
    if len(labels) <= max_exact:
        tried = 0
        for size in range(len(labels), 1, -1):
            best = None
            for combo in itertools.combinations(labels, size):
                tried += 1
                h, p = _kruskal([vals[k] for k in combo])
                if p > alpha and (best is None or p > best[2]):
                    best = (list(combo), h, p)
            if best is not None:
                return SubsetResult(best[0], best[2], best[1], f"exact ({tried} subsets tried)")
        return SubsetResult(labels[:1], 1.0, float("nan"), f"exact ({tried} subsets tried; no two groups agree)")
    members = list(labels)
    h, p = _kruskal([vals[k] for k in members])
    while p <= alpha and len(members) > 2:
        trials = []
        for k in members:
            rest = [m for m in members if m != k]
            trials.append((_kruskal([vals[m] for m in rest])[1], k))
        _, drop = max(trials, key=lambda t: (t[0], str(t[1])))
        members.remove(drop)
        h, p = _kruskal([vals[k] for k in members])
    if p <= alpha:
        members = members[:1]
        h, p = float("nan"), 1.0
    return SubsetResult(members, p, h, "greedy (backward elimination of the group whose removal maximises p)")
