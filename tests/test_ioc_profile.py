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


def test_profile_verdict_walks_from_the_least_D():
    """A fit stopped short of its minimum (the wiring test's bi-level fit after 6 evaluations: a2 34.7, D 0.0031;
    the profile finds D 0.0011 at a2 17.4, and the targets reject the fit against it): the interval is walked
    from the least-D point and excludes the fit; a profile none of whose points the targets accept against a lower D
    found on another weight's profile is not judged."""
    y0 = {"a2": math.log10(34.75), "a4": 1.0}
    centre = {**_pt(y0["a2"], 1.07, D=0.003128, a4=10.0), "y": y0["a2"]}
    down = [_pt(math.log10(27.6), 1.12, D=0.001929, a4=10.0), _pt(math.log10(17.4), 0.0, D=0.001073, a4=10.0),
            _pt(math.log10(3.475), 1.12, D=0.02979, a4=10.0)]
    up = [_pt(math.log10(43.7), 1.11, D=0.004001, a4=10.0)]
    v, (lo, hi) = verdict("a2", y0, centre, down, up, 0.001073)
    assert v.startswith("determined (profile: the targets reject a2 below") and "which the targets reject" in v
    assert 3.475 < lo < 17.4 < hi < 27.6  # the truth (20.15) inside, the fit (34.7) outside
    v, (lo, hi) = verdict("a2", y0, centre, [{**p, "excess": 1.5} for p in down[:1]], up, 0.0009)
    assert v.startswith("not judged: the fit is not at a minimum of D") and (lo, hi) == (1e-7, 1e3)


def test_profile_verdict_hook_and_category():
    """Where the curvature cannot judge, the profile's verdict is given, and its category is the plain one."""
    from cobot_analysis.models.ioc.uncertainty import judged, verdict_category, verdicts

    w = {"a1": 1.0, "a2": 1.0}
    curv = verdicts(("a1", "a2"), np.eye(2), 0.1, w, lack=0.3)
    v, by = judged(curv, curv, w, 0.3, {"a1": "determined (profile: D crosses ...)"})
    assert v["a1"] == "determined (profile: D crosses ...)" and v["a2"].startswith("not judged") and by == {"a1": "profile", "a2": "curvature"}
    assert verdict_category(v["a1"]) == "determined"


# An analytic D whose truth is known (no lower level): per target i, in y = log10 w,
#   D_i = 1 + (y1 - 1 + e_i)^2 + (y2 - y3 + f_i)^2   (e, f: centred, sd 0.3; y4 absent),
# so a1 is determined (10), only the ratio of a2 to a3 is determined, and a4 is not determined.
NAMES = ("a1", "a2", "a3", "a4")
_rng = np.random.default_rng(1)
E, F = (lambda x: 0.3 * (x - x.mean()) / x.std())(_rng.normal(size=30)), (lambda x: 0.3 * (x - x.mean()) / x.std())(_rng.normal(size=30))
Y0 = np.array([1.0, 0.0, 0.0, 0.0])


def _Di(y):
    return 1 + (y[0] - 1 + E) ** 2 + (y[1] - y[2] + F) ** 2


def _curvature(shift=0.0):
    """The exact per-target D_i, gradient and Hessian at the fit (the curvature's and bootstrap's input)."""
    from cobot_analysis.models.ioc.uncertainty import Curvature

    n = len(E)
    gi = np.column_stack([2 * E, 2 * F, -2 * F, np.zeros(n)])
    Hi = np.tile(2 * np.array([[1, 0, 0, 0], [0, 1, -1, 0], [0, -1, 1, 0], [0, 0, 0, 0.0]]), (n, 1, 1))
    return Curvature(NAMES, Y0.copy(), _Di(Y0), gi, Hi, 0, shift)


def _profile(j):
    """The weight's profile as ``profile.profiles`` walks it: its grid each side, the others re-fitted exactly,
    each chain stopped after its first point the targets reject (``profile.excess``)."""
    from cobot_analysis.models.ioc.profile import excess, grid, verdict

    D0i = _Di(Y0)
    chains = {}
    for side in (-1, 1):
        chain = []
        for yj in grid(Y0[j], side):
            y = Y0.copy()
            y[j] = yj
            if j in (1, 2):  # the other of the pair re-fitted: y2 - y3 = -mean(F) = 0
                y[3 - j] = yj
            Di = _Di(y)
            chain.append({"y": yj, "D": float(Di.mean()), "excess": excess(Di, D0i)[2], "switched": 0, "failed": 0, "error": "",
                          "weights": {n: 10.0 ** y[k] for k, n in enumerate(NAMES) if k != j}})
            if chain[-1]["excess"] > 1:
                break
        chains[side] = chain
    centre = {"y": Y0[j], "D": float(D0i.mean()), "excess": 0.0, "switched": 0, "failed": 0, "error": "",
              "weights": {n: 10.0 ** Y0[k] for k, n in enumerate(NAMES) if k != j}}
    return verdict(NAMES[j], dict(zip(NAMES, Y0)), centre, chains[-1], chains[1], centre["D"])


def test_both_analyses_judge_a_known_truth_alike():
    """On the analytic D (truth known): the curvature with the bootstrap and the profile likelihoods give the same
    verdicts (a1 determined, a2 and a3 only as a ratio, a4 not determined), whichever ``judged`` takes; the profile
    interval of a1 holds the truth 10 and is the one the targets' paired t test gives: dy^2 / (2 |dy| 0.3 / sqrt(30))
    > t_29(0.975) = 2.045 for |dy| > 0.224 (0.228 interpolated between the grid's 0.1 and 0.3)."""
    from cobot_analysis.models.ioc.uncertainty import bootstrap, interval_verdicts, judged, verdict_category, verdicts

    c = _curvature()
    w = {n: 10.0 ** y for n, y in zip(NAMES, Y0)}
    curv = verdicts(NAMES, c.H, c.D, w, lack=c.lack_of_fit)
    boot = interval_verdicts(curv, bootstrap(c)["intervals"], bootstrap(c)["held"])
    prof = {n: _profile(j) for j, n in enumerate(NAMES)}
    by_curvature, src = judged(curv, boot, w, 0.0)
    by_profile, src_p = judged(curv, boot, w, 0.0, {n: v for n, (v, _) in prof.items()})
    expect = {"a1": "determined", "a2": "ratio to a3", "a3": "ratio to a2", "a4": "not determined"}
    assert {n: verdict_category(v) for n, v in by_curvature.items()} == expect and set(src.values()) == {"curvature"}
    assert {n: verdict_category(v) for n, v in by_profile.items()} == expect and set(src_p.values()) == {"profile"}
    lo, hi = prof["a1"][1]
    assert 10 ** (1 - 0.26) < lo < 10 ** (1 - 0.2) and 10 ** (1 + 0.2) < hi < 10 ** (1 + 0.26)


def test_the_profile_judges_what_the_bootstrap_overturns():
    """A weight the curvature determines and the bootstrap does not (the search box holds its quadratic refit in a few
    resamples) is disputed and judged by its profile: determined when the targets reject it on both sides (the box's
    resamples are the quadratic's extrapolation, the profile evaluates D), not determined when its profile is flat;
    a profile that could not judge leaves the bootstrap's verdict when D is smooth, and stays "not judged" when not."""
    from cobot_analysis.models.ioc.uncertainty import disputed, judged

    w = {"a2": 7.8, "a3": 1e-7, "a4": 2.3}
    curv = {n: "determined" for n in w}
    held = "not determined by these data (the search box holds its refit in 11 of 200 resamples: ...)"
    boot = {"a2": held, "a3": held, "a4": "determined"}
    assert disputed(0.05, curv, boot) == ("a2", "a3") and disputed(0.15, curv, boot) == ("a2", "a3", "a4")
    prof = {"a2": "determined (profile: the targets reject a2 below 4.69 and above 12.1)",
            "a3": "not determined by these data (profile: no value rejected by the targets up to the search limit 1e-07 below)"}
    v, by = judged(curv, boot, w, 0.05, prof)
    assert v["a2"] == prof["a2"] and v["a4"] == "determined" and by == {"a2": "profile", "a3": "profile", "a4": "curvature"}
    assert v["a3"] == prof["a3"] + " (at the search limit 1e-07)"
    failed = {"a2": "not judged: the profile's refit failed at a2 1e+03"}
    v, by = judged(curv, boot, w, 0.05, failed)
    assert v["a2"] == held and by["a2"] == "bootstrap"
    v, by = judged({n: "not judged: D is not smooth at the fit" for n in w}, {n: "not judged: D is not smooth at the fit" for n in w}, w, 0.15, failed)
    assert v["a2"] == failed["a2"] and by["a2"] == "profile" and by["a4"] == "curvature"


def test_a_fit_short_of_a_minimum_is_not_judged_by_its_curvature():
    """D concave along a direction beyond the sloppiness (a fit stopped by its budget: the wiring test's bi-level fit
    after 6 evaluations, eigenvalues -0.021 and 0.46 at D 0.0031): the weights in it are not judged by the curvature
    (they came out "not determined" before) and are disputed, so their profiles judge them; a concave direction
    within the sloppiness (the regression's walking fit: -0.00079 at D 0.446) stays sloppy."""
    from cobot_analysis.models.ioc.uncertainty import disputed, verdicts

    w = {"a2": 34.7, "a4": 10.0}
    H = np.array([[-0.021, 0.0], [0.0, 0.46]])
    v = verdicts(("a2", "a4"), H, 0.0031, w)
    assert v["a2"].startswith("not judged: the fit is not at a minimum of D") and v["a4"] == "determined"
    assert disputed(0.03, v, v) == ("a2",)
    v = verdicts(("a2", "a4"), np.diag([-0.00079, 0.46]), 0.446, w)
    assert v["a2"] == "not determined by these data" and disputed(0.03, v, v) == ()


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
