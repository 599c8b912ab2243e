"""Profile likelihoods of fitted weights (models/ioc/profile.py): the verdict rules on made-up profiles,
and profiles of recovered weights on paths generated at known weights (20 intervals, 6 paths)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from cobot_analysis.models.ioc import IOCSpec
from cobot_analysis.models.ioc.profile import excess, grid, verdict
from cobot_analysis.models.presets import load_weights, names_for, weights_vector

W = weights_vector(load_weights("walking-2021", "improved"), "improved")
SPEC = IOCSpec(model="improved", start_weights=tuple(W), n_intervals=20, fitted=("a2", "a4"))


def test_excess_is_the_paired_t_test_of_the_targets():
    """t = mean / (sd / sqrt(n)) of the per-target rises against t_(n-1)(0.975); a rise below 0.1 % of D is flat
    however consistent; no rise, or a fall, is never rejected."""
    D0 = np.full(10, 0.4)
    rise = np.array([0.01, 0.03] * 5)  # mean 0.02, sd 0.01054
    t, tq, e = excess(D0 + rise, D0)
    assert t == pytest.approx(0.02 / (np.std(rise, ddof=1) / math.sqrt(10))) and tq == pytest.approx(2.262157, rel=1e-5)
    assert e == pytest.approx(t / tq) and e > 1
    assert excess(D0 + 1e-5, D0)[2] == pytest.approx(1e-5 / 4e-4)  # consistent (t = inf) but 0.0025 % of D: flat
    assert excess(D0, D0)[2] == 0.0 and excess(D0 - rise, D0)[2] < 0


def test_grid_steps_out_to_the_search_limit():
    assert grid(0.5, 1) == pytest.approx([0.6, 0.8, 1.5, 3.0])  # 0.5 + 3 is beyond the limit 3: the limit instead
    assert grid(0.5, -1) == pytest.approx([0.4, 0.2, -0.5, -2.5, -7.0])
    assert grid(-7.0, -1) == [] and grid(2.995, 1) == []  # at the limit: nothing to walk


def _pt(y, e, D=1.0, **w):
    return {"y": y, "D": D, "excess": e, "weights": w, "switched": 0, "failed": 0, "error": ""}


def test_profile_verdicts_on_made_up_profiles():
    """Rejected on both sides: determined, the interval at the linearly interpolated crossings of excess = 1;
    nothing rejected up to a limit with a partner moving along (slope 1 in log10): its ratio; with nothing
    moving: not determined; a refit that failed: not judged; a branch change and a D below the fit's are reported."""
    y0 = {"a2": 0.0, "a4": 1.0}
    centre = _pt(0.0, 0.0, a4=10.0)
    down = [_pt(-0.1, 0.5, a4=10.0), _pt(-0.3, 1.5, a4=10.0)]
    up = [_pt(0.1, 0.2, a4=10.0), _pt(0.3, 2.2, a4=10.0)]
    v, (lo, hi) = verdict("a2", y0, centre, down, up, 1.0)
    assert v.startswith("determined (profile: the targets reject a2 below")
    assert lo == pytest.approx(10 ** -0.2) and hi == pytest.approx(10 ** (0.1 + 0.2 * 0.8 / 2.0))
    flat = [_pt(y, 0.5, a4=10.0 ** (1 + y)) for y in (0.1, 0.3, 1.0, 3.0)]
    v, iv = verdict("a2", y0, centre, down, flat, 1.0)
    assert v.startswith("only its ratio to a4 is determined (profile: no value rejected by the targets up to the search limit 1000 above")
    assert iv == (1e-7, 1e3)
    still = [_pt(y, 0.5, a4=10.0) for y in (0.1, 0.3, 1.0, 3.0)]
    assert verdict("a2", y0, centre, down, still, 1.0)[0].startswith("not determined by these data (profile: no value rejected")
    broken = [_pt(0.1, 0.1, a4=10.0), {**_pt(0.3, math.nan, D=math.nan), "error": "a lower level failed"}]
    assert verdict("a2", y0, centre, down, broken, 1.0)[0].startswith("not judged: the profile's refit failed at a2 2")
    unrefitted = "single-level: a lower-level solution at the start weights is not a regular KKT point"
    bound = still[:3] + [{**_pt(3.0, 0.5, a4=10.0), "error": unrefitted}]  # an upper bound of the profile, not rejected
    assert verdict("a2", y0, centre, down, bound, 1.0)[0].startswith("not determined by these data")
    bound[-1]["excess"] = 2.0  # rejected, but only an upper bound: no verdict
    assert verdict("a2", y0, centre, down, bound, 1.0)[0].startswith("not judged: the profile's refit failed at a2 1e+03")
    jump = [_pt(-0.1, 0.0, D=0.9, a4=10.0), {**_pt(-0.3, 3.0, D=1.3, a4=10.0), "switched": 3}]
    v = verdict("a2", y0, centre, jump, up, 0.9)[0]
    assert "change branch (a fold) at a2 0.501 (3)" in v and "D 0.9 at a2 0.794, below the fit's 1" in v


def test_profile_verdict_hook_and_category():
    """Where the curvature cannot judge, the profile's verdict is given, and its category is the plain one."""
    from cobot_analysis.models.ioc.uncertainty import verdict_category, verdicts

    w = {"a1": 1.0, "a2": 1.0}
    v = verdicts(("a1", "a2"), np.eye(2), 0.1, w, lack=0.3, profiled={"a1": "determined (profile: D crosses ...)"})
    assert v["a1"] == "determined (profile: D crosses ...)" and v["a2"].startswith("not judged")
    assert verdicts(("a1", "a2"), np.eye(2), 0.1, w, lack=0.05, profiled={"a1": "not determined"})["a1"] == "determined"
    assert verdict_category(v["a1"]) == "determined"


@pytest.mark.slow
def test_profiles_of_recovered_weights():
    """Paths generated at known weights (0.5 cm noise, 8 paths), fitted back from twice the truth: the targets
    reject a2 on both sides of the fit and its profile interval holds the truth (measured: 10.6 .. 39.1 around
    20.15); b1, the weight of the terminal heading error, which the goal constraint makes 0 on every path (docs/methods.md
    sec. 6), is rejected nowhere from the search limit 1e-7 to 1000: not determined."""
    from cobot_analysis.models.ioc.profile import profiles
    from cobot_analysis.models.ioc.recovery import synthetic_targets
    from cobot_analysis.models.ioc.single_level import fit_feasible_path

    names = names_for("improved")
    targets = synthetic_targets(SPEC, W, 8, noise=0.005)
    w = np.array(W, float)
    for n in SPEC.fitted:
        w[names.index(n)] *= 2
    r = fit_feasible_path(replace(SPEC, start_weights=tuple(w)), targets)
    out = profiles(SPEC, targets, r.weights, fitted=("a2",), paths=r.primals)
    assert out["D"] == pytest.approx(r.objective, rel=1e-6)
    v, (lo, hi) = out["verdicts"]["a2"], out["intervals"]["a2"]
    assert v.startswith("determined"), v
    assert lo < W[names.index("a2")] < hi and hi / lo < 10, (lo, hi)
    assert all(p["excess"] <= 1 for p in out["points"]["a2"] if lo < 10 ** p["y"] < hi)
    spec_b = replace(SPEC, fitted=("a2", "b1"))
    out = profiles(spec_b, targets, r.weights, fitted=("b1",), paths=r.primals)
    v = out["verdicts"]["b1"]
    assert v == "not determined by these data (profile: no value rejected by the targets up to the search limit 1e-07 below " \
                "and 1000 above)", v
    assert max(abs(p["D"] / out["D"] - 1) for p in out["points"]["b1"]) < 1e-6


def test_fit_ioc_refuses_an_unknown_profiles_choice(cli, tmp_path):
    code, out, err = cli("fit-ioc", "--out", tmp_path, "--profiles", "some", "--no-compare")
    assert code == 2 and "--profiles" in err and "means, all, none" in err and len(err.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())
