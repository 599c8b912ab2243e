"""What walker-like paths cost a fit whose model paths spin (docs/methods.md sec. 5.5).

a3 is the only price of the turning rate's changes; near zero, omega can alternate in sign from node to node at
almost no cost and the heading spins (``models.spins``) on a path that still converges at its goal. At weights
whose model paths spin, a3 is raised by decades from its fitted value (the other weights as fitted) until no path
spins or the search limit, and at each value the model paths on the means (``comparison.compare_models_keeping``:
generate's grid) give the paths that spin and D = d_xy + w_angle d_angle per mean, compared with the fitted
weights' D by the profile likelihood's paired test (``ioc.profile.excess``: rejected when the per-mean rises are
significant at 95 % and above 0.1 % of D). The least a3 at which no path spins says what a walker's heading costs
in fit.
"""

from __future__ import annotations

import math

import numpy as np
from cobot_analysis.lazy import pandas as pd

from cobot_analysis.models import spins
from cobot_analysis.models.comparison import compare_models_keeping
from cobot_analysis.models.ioc.fit import LOG_BOUNDS
from cobot_analysis.models.ioc.profile import excess
from cobot_analysis.models.ioc.targets import Target


def a3_values(a3: float) -> list[float]:
    """The decades above ``a3`` up to the search limit, 10^k > a3 (more than 1 % above it).

        >>> a3_values(1.12e-07)[:3], a3_values(1.12e-07)[-1], a3_values(1e3)
        ([1e-06, 1e-05, 0.0001], 1000.0, [])
    """
    first = math.floor(math.log10(a3 * 1.01)) + 1
    return [10.0 ** k for k in range(first, int(LOG_BOUNDS[1]) + 1)]


def turning_price(targets: list[Target], weights: dict[str, float], *, model: str = "improved", angle: str = "gamma",
                  angle_weight: float = 0.5, convention: str = "continuous", batch: int = 2, jobs=None,
                  scheduler=None) -> pd.DataFrame:
    """One row per a3 (the fitted value first, then ``a3_values`` up to the first at which no path spins; ``batch``
    values solved side by side): ``a3``, ``paths``, ``spinning`` (model paths that spin), ``D`` (mean over the means
    with a finite D at every value), ``t`` and ``t_q`` (the paired test against the fitted weights), ``rejected``
    (module docstring); NaN test cells on the fitted row."""
    todo = [float(weights["a3"]), *a3_values(float(weights["a3"]))]
    frames, spinning, values = [], [], []

    def settled() -> bool:  # the last value reported has no spinning path: no larger a3 is needed
        return bool(spinning) and spinning[-1] == 0

    while todo and not settled():
        chunk, todo = todo[:batch], todo[batch:]
        models = {f"a3={v:.6g}": (model, {**weights, "a3": v}) for v in chunk}
        df, kept = compare_models_keeping(targets, models, tuple(models), angle=angle, angle_weight=angle_weight, jobs=jobs,
                                          scheduler=scheduler, convention=convention)
        frames.append(df.pivot_table(index="trial", columns="model", values="D", aggfunc="first", dropna=False)[list(models)])
        for label, v in zip(models, chunk):
            if settled():
                break  # the batch's values past the first at which none spins: not reported
            values.append(v)
            spinning.append(sum(spins(p["theta"].to_numpy(float)) for p in kept[label].values() if p is not None))
    D = pd.concat(frames, axis=1).iloc[:, :len(values)]  # D per mean (rows) and a3 (columns)
    finite = D.notna().all(axis=1)
    fitted = D.loc[finite].iloc[:, 0].to_numpy(float)
    rows = []
    for i, (v, n) in enumerate(zip(values, spinning)):
        Di = D.loc[finite].iloc[:, i].to_numpy(float)
        t, tq, crit = excess(Di, fitted) if i else (math.nan, math.nan, math.nan)
        rows.append({"a3": v, "paths": len(targets), "spinning": n, "D": float(np.mean(Di)) if len(Di) else math.nan,
                     "t": t, "t_q": tq, "rejected": bool(crit > 1)})
    return pd.DataFrame(rows)
