"""Largest subset of groups (subjects, pairs) whose values are statistically indistinguishable.

Two definitions (docs/methods.md sec. 4, walking analyses), side by side:

- ``largest_subset`` (ours): "indistinguishable" = Kruskal-Wallis across the groups of the subset
  gives p > alpha. Exact search when there are at most ``max_exact`` groups: subsets are tried from
  the largest size down and, at the first size where some subset qualifies, the one with the largest
  p is returned. With more groups (2^20 subsets for 20 pairs would be too many) a greedy search
  removes, one at a time, the group whose removal gives the largest p, until p > alpha.
- ``pairwise_subset`` (the walking thesis's figure, sec. 11): "indistinguishable" = every pair of
  groups of the subset has a two-sided Mann-Whitney p > alpha. Starting from all groups, the group
  whose median lies furthest from the pooled median of the remaining groups is dropped, one at a
  time, until every pair qualifies; the subset's Kruskal-Wallis H and p are reported. The authors'
  public code holds no subset search: this is the definition that gives their figure (6 of 10
  subjects at p = 0.31) on the published data, stated so that it can be checked. The largest sets
  with every pair indistinguishable (exact, ``pairwise_cliques``) are reported beside it.

The method used is returned with each result.
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


def _pairwise_p(vals: dict) -> dict:
    """Two-sided Mann-Whitney p of every pair of groups (1 when all their values are identical)."""
    from scipy import stats

    out = {}
    for a, b in itertools.combinations(vals, 2):
        both = np.concatenate([vals[a], vals[b]])
        out[a, b] = out[b, a] = 1.0 if np.ptp(both) == 0 else float(stats.mannwhitneyu(vals[a], vals[b]).pvalue)
    return out


def pairwise_cliques(groups: dict, alpha: float = 0.05) -> list[SubsetResult]:
    """Every largest set of groups in which each pair has Mann-Whitney p > alpha (Bron-Kerbosch with
    pivot on the graph "pair indistinguishable"), in label order, with its Kruskal H and p."""
    labels = sorted(groups, key=str)
    vals = {k: np.asarray(groups[k], float) for k in labels}
    p = _pairwise_p(vals)
    near = {k: {m for m in labels if m != k and p[k, m] > alpha} for k in labels}
    found: list[list] = []

    def expand(r: list, cand: set, done: set) -> None:
        if not cand and not done:
            found.append(sorted(r, key=str))
            return
        pivot = max(cand | done, key=lambda k: len(near[k] & cand))
        for k in sorted(cand - near[pivot], key=str):
            expand(r + [k], cand & near[k], done & near[k])
            cand = cand - {k}
            done = done | {k}

    expand([], set(labels), set())
    top = max((len(c) for c in found), default=0)
    out = []
    for c in sorted((c for c in found if len(c) == top), key=lambda c: [str(k) for k in c]):
        h, pk = _kruskal([vals[k] for k in c])
        out.append(SubsetResult(c, pk, h, "exact (Bron-Kerbosch)"))
    return out


def pairwise_subset(groups: dict, alpha: float = 0.05) -> SubsetResult:
    """Drop the group with the median furthest from the pooled median of the others left, until every
    remaining pair has Mann-Whitney p > alpha (module doc); Kruskal H and p of what is left."""
    labels = sorted(groups, key=str)
    vals = {k: np.asarray(groups[k], float) for k in labels}
    p = _pairwise_p(vals)
    members, dropped = list(labels), []
    while len(members) > 1 and any(p[a, b] <= alpha for a, b in itertools.combinations(members, 2)):
        pooled = np.median(np.concatenate([vals[k] for k in members]))
        drop = max(members, key=lambda k: (abs(np.median(vals[k]) - pooled), -labels.index(k)))
        members.remove(drop)
        dropped.append(drop)
    h, pk = _kruskal([vals[k] for k in members]) if len(members) > 1 else (float("nan"), 1.0)
    order = ", ".join(map(str, dropped)) or "none"
    return SubsetResult(members, pk, h, f"pairwise elimination (every pair Mann-Whitney p > {alpha}; dropped, most "
                                        f"atypical median first: {order})")
