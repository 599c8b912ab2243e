"""The single-level IOC under the published convention, at held horizons (docs/methods.md sec. 6.1;
cobot_analysis.models.ioc.single_level_published)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from cobot_analysis.distances import gamma_from_path, resample_arclength, resample_time
from cobot_analysis.errors import InputError
from cobot_analysis.models.ioc.fit import IOCSpec, solve_target
from cobot_analysis.models.ioc.single_level import check_spec
from cobot_analysis.models.ioc.single_level_published import HeldBranch, fit_held_horizons
from cobot_analysis.models.ioc.targets import Target
from cobot_analysis.models.presets import names_for

TRUE = (7.87, 4.0, 20.15, 1e-06, 10.0, 0.0, 0.0, 10.0, 10.0, 0.38, 3.36)  # a0..a6, b0..b3: the published walker's
GOAL = (0.0, 0.0, math.pi / 2)
STARTS = [(-0.6, -1.0, 1.2), (0.5, -1.0, 1.9), (0.0, -1.3, 1.57)]


def published_targets(spec: IOCSpec, weights, starts=STARTS) -> list[Target]:
    """Paths of the published lower level at ``weights`` (the duration rule's horizon, one sample per node),
    with the gamma the published D compares them by: a model path at these weights is at D = 0."""
    out = []
    for i, s in enumerate(starts):
        a = np.linspace(0.0, 1.0, 10)  # a placeholder path (the solve needs only the endpoints)
        t = Target(f"p{i}", "synthetic", "", s[0] * (1 - a), s[1] * (1 - a), s[2] + a * (GOAL[2] - s[2]), goal_pose=GOAL,
                   start_pose=s)
        sol = solve_target(spec, np.asarray(weights, float), t, None)[1].check("synthetic published path")
        x, y, th = sol.X[:, 0].copy(), sol.X[:, 1].copy(), sol.X[:, 2].copy()
        xr, yr = resample_arclength(x, y, len(x))
        gamma = gamma_from_path(xr, yr, resample_time(th, len(x), authors=True))
        out.append(Target(f"p{i}", "synthetic", "", x, y, th, goal_pose=GOAL, start_pose=s, gamma=gamma))
    return out


SPEC = IOCSpec(model="improved", start_weights=TRUE, fitted=("a1", "a2"), convention="published", max_iter=100)


def test_published_spec_is_accepted_only_with_held_horizons():
    check_spec(SPEC, 3)
    with pytest.raises(InputError, match="holds each path's horizon"):
        check_spec(replace(SPEC, hold_duration=False), 3)
    with pytest.raises(InputError, match="cannot determine"):
        check_spec(SPEC, 1)
    with pytest.raises(InputError, match="single-level fit covers"):
        check_spec(replace(SPEC, model="coupled", fitted=("a1",)), 3)


def test_held_branch_gradient_matches_re_solved_paths():
    """dD/dy from the linear predictor (central differences) against D on the KKT points corrected at
    w +- dw (the lower level's own solutions there): the same to a few per cent."""
    targets = published_targets(SPEC, TRUE, STARTS[:1])
    names = names_for("improved")
    fi = [names.index(n) for n in SPEC.fitted]
    w = np.array(TRUE)
    w[fi] *= 1.5  # off the truth: D > 0 and its gradient not 0
    sol = solve_target(SPEC, w, targets[0], None)[1]
    b = HeldBranch(SPEC, targets[0], sol.U.shape[0], fi)
    r = b.correct(np.concatenate([sol.primal, np.zeros(b.ocp.n_cons)]), w, 1e-8, False)
    assert r is not None and r["residual"] < 1e-8
    assert r["D"] == pytest.approx(b.D(sol.primal), abs=1e-6)  # the branch is the lower level's own solution
    h = 0.02
    for j, i in enumerate(fi):
        D = []
        for sign in (1, -1):
            w2 = w.copy()
            w2[i] *= 10 ** (sign * h)
            D.append(b.correct(r["v"] + r["S"] @ (w2[fi] - w[fi]), w2, 1e-8, False)["D"])
        assert r["g"][j] == pytest.approx((D[0] - D[1]) / (2 * h), rel=0.05, abs=1e-5)


def test_noise_free_recovery_under_the_published_convention():
    """Paths of the published lower level at known weights, the fit started with a1 and a2 x 1.5: both come
    back within 1 %, D falls to ~0 and the duration rule at the fitted weights keeps every horizon."""
    targets = published_targets(SPEC, TRUE)
    names = names_for("improved")
    w0 = np.array(TRUE)
    for n in SPEC.fitted:
        w0[names.index(n)] *= 1.5
    r = fit_held_horizons(replace(SPEC, start_weights=tuple(w0)), targets)
    assert r.start_objective > 1e-4
    for n in SPEC.fitted:
        assert r.weights[n] == pytest.approx(TRUE[names.index(n)], rel=0.01)
    assert r.held_objective < 1e-5 and r.objective < 1e-5 and "kept" not in r.message
    assert r.horizons_changed == 0 and r.failed == 0


def test_a_fit_whose_rule_check_ends_above_its_start_keeps_the_start(monkeypatch):
    """When D by the duration rule at the fitted weights is not below the start's, the fit keeps the start (its
    weights, D, terms and the rule's solutions there) and says so. Here the rule's check at the fitted weights
    is made to cost 1 more per path than it does."""
    import cobot_analysis.models.ioc.single_level_published as published

    targets = published_targets(SPEC, TRUE)
    names = names_for("improved")
    w0 = np.array(TRUE)
    for n in SPEC.fitted:
        w0[names.index(n)] *= 1.5
    spec = replace(SPEC, start_weights=tuple(w0))
    check = published.rule_check_chunk
    monkeypatch.setattr(published, "rule_check_chunk", lambda task: [({**d, "D": d["D"] + 1.0}, s) for d, s in check(task)])
    r = fit_held_horizons(spec, targets)
    assert "the start's weights are kept" in r.message, r.message
    assert r.objective == r.held_objective == r.start_objective > 1e-4 and r.horizons_changed == 0
    assert all(r.weights[n] == w0[i] for i, n in enumerate(names)), r.weights
    assert float(np.mean([d["D"] for d in r.per_target])) == r.start_objective and len(r.solutions) == len(targets)
    # the same fit with the check as it is: test_noise_free_recovery_under_the_published_convention (D ~ 0, not kept)


def test_a_rounding_step_is_a_repeated_point_of_the_arclength_resampling():
    """A path whose second node sits 1e-16 m from the first (an OC solution's rounding at a start at rest)
    resamples as the path without it: the spline through both would overshoot by metres."""
    s = np.linspace(0.0, 1.0, 60)
    x, y = np.sin(2 * s), s**2
    xr, yr = resample_arclength(np.r_[x[0], x], np.r_[y[0] + 1e-16, y], 60)
    x0, y0 = resample_arclength(x, y, 60)
    assert np.abs(xr - x0).max() < 1e-9 and np.abs(yr - y0).max() < 1e-9


def test_duration_rule_started_at_a_held_horizon_checks_it():
    """The published fit's last duration rule is a check of the held horizon, with the held solution as
    its solve there (``oc.solve_model``'s ``start_horizon``): where that horizon is the rule's choice from the
    authors' T_guess, it is kept and its solution returned as is; 40 nodes short of it, with a solution of that
    horizon, the criterion is lower a node further on and the search moves to the rule's choice."""
    from cobot_analysis.conventions import PUBLISHED
    from cobot_analysis.models.oc import solve_model

    w = np.asarray(TRUE, float)
    start = STARTS[0]
    full = solve_model("improved", start, GOAL, w, convention=PUBLISHED, warm=True)
    T = full.U.shape[0]
    kept = solve_model("improved", start, GOAL, w, convention=PUBLISHED, warm=True, seed=full, start_horizon=T)
    assert kept.U.shape[0] == T and np.allclose(kept.X, full.X, atol=1e-12)
    short = solve_model("improved", start, GOAL, w, convention=PUBLISHED, horizon=T - 40)
    moved = solve_model("improved", start, GOAL, w, convention=PUBLISHED, warm=True, seed=short, start_horizon=T - 40)
    assert moved.U.shape[0] == T and abs(moved.cost - full.cost) < 1e-6 * abs(full.cost)


def test_curvature_takes_the_fits_rule_solutions_as_its_centre(monkeypatch):
    """The published curvature's centre given as the duration rule's solutions at the weights (the fit's last
    rule, ``IOCResult.solutions``): no rule is run again (every stencil task seeds held horizons), and D_i, g_i, H_i
    are the same, bit for bit, as with the centre solved again."""
    from cobot_analysis.models.ioc import uncertainty

    targets = published_targets(SPEC, TRUE, STARTS[:2])
    names = names_for("improved")
    w = np.array(TRUE)
    w[names.index("a2")] *= 1.3  # off the truth: D > 0
    weights = dict(zip(names, map(float, w)))
    solved = uncertainty.curvature(SPEC, targets, weights)
    rules = [solve_target(replace(SPEC, hold_duration=False), w, t, None)[1] for t in targets]
    seeds = []
    chunk = uncertainty.stencil_chunk
    monkeypatch.setattr(uncertainty, "stencil_chunk", lambda task: seeds.extend(g for _, g in task[2]) or chunk(task))
    given = uncertainty.curvature(SPEC, targets, weights, centre=rules)
    assert seeds and all(hasattr(g, "X") for g in seeds)  # held horizons only: no duration rule
    for a in ("Di", "gi", "Hi"):
        np.testing.assert_array_equal(getattr(given, a), getattr(solved, a))
    assert given.lack_of_fit == solved.lack_of_fit and given.failed == solved.failed == 0


def test_bilevel_fit_checks_its_held_horizons_at_the_end(monkeypatch):
    """The bi-level fit's duration rule at the fitted weights is a check of the held horizons, the held solutions
    its solves there (``fit.rule_check_chunk``): the rule searches from the authors' T_guess only at the start
    weights, at the end it starts at each held horizon and keeps it; the D reported is the held D and the
    solutions returned (the curvature's centre) are on the held horizons."""
    from cobot_analysis.models.ioc.fit import fit
    from cobot_analysis.models.oc import duration

    targets = published_targets(SPEC, TRUE, STARTS[:2])
    names = names_for("improved")
    w0 = np.array(TRUE)
    w0[names.index("a2")] *= 1.3
    starts = []
    rule = duration.nelder_mead_duration
    monkeypatch.setattr(duration, "nelder_mead_duration", lambda solve, start=None: starts.append(start) or rule(solve, start))
    r = fit(replace(SPEC, start_weights=tuple(w0), max_evaluations=3), targets)
    horizons = [s.U.shape[0] for s in r.solutions]
    assert starts == [None, None, *horizons]  # the reference rule from T_guess, then the check at the held horizons
    assert r.horizons_changed == 0 and r.failed == 0 and r.evaluations > 1
    assert r.objective == pytest.approx(r.held_objective, rel=1e-12, abs=0)
    assert [d["T"] for d in r.per_target] == pytest.approx([h * 0.1 for h in horizons], rel=1e-12)


def test_steps_from_another_fits_weights_start_at_its_D(recwarn):
    """``continued_from``: the single-level steps started at another fit's weights (a1, a2 x 1.5 here). Its start D
    is the one the bi-level fit evaluates there (``fit.solve_target``: the duration rule from the authors' guess),
    its end the truth within 1 % (D ~ 0); continuous fits are refused (their candidates differ: ``cross_check``)."""
    from cobot_analysis.models.ioc.single_level_published import continued_from

    targets = published_targets(SPEC, TRUE)
    names = names_for("improved")
    w0 = np.array(TRUE)
    for n in SPEC.fitted:
        w0[names.index(n)] *= 1.5
    bilevel_D = float(np.mean([solve_target(SPEC, w0, t, None)[0]["D"] for t in targets]))
    r = continued_from(SPEC, targets, dict(zip(names, map(float, w0))))
    assert bilevel_D > 1e-4 and r["start_objective"] == pytest.approx(bilevel_D, rel=1e-9)
    assert r["objective"] < 1e-5 and r["seconds"] > 0 and "feasible-path steps accepted" in r["message"]
    for n in SPEC.fitted:
        assert r["weights"][n] == pytest.approx(TRUE[names.index(n)], rel=0.01)
    assert not [w for w in recwarn if "kept" in str(w.message)]
    with pytest.raises(ValueError, match="published convention"):
        continued_from(replace(SPEC, convention="continuous"), targets, dict(zip(names, map(float, w0))))


def test_steps_that_cannot_start_at_the_other_weights_say_why(monkeypatch):
    """A lower level that does not converge at the bi-level weights: no row of numbers, the reason instead (NaN D,
    no metric), and the stage keeps its own fit."""
    import cobot_analysis.models.ioc.single_level_published as published
    from types import SimpleNamespace

    from cobot_analysis.metrics.models import fit_ioc as fit_metrics
    from cobot_analysis.metrics.records import collect
    from cobot_analysis.reports.models import methods_side_by_side

    def fails(*args, **kwargs):
        raise RuntimeError("single-level (published): a lower level did not converge at the start weights")

    monkeypatch.setattr(published, "fit_held_horizons", fails)
    w = dict(zip(names_for("improved"), TRUE))
    c = published.continued_from(SPEC, published_targets(SPEC, TRUE)[:1], w)
    assert math.isnan(c["objective"]) and c["weights"] == w
    assert c["message"] == "not run: single-level (published): a lower level did not converge at the start weights"
    result = SimpleNamespace(names=("a1",), results={"all": SimpleNamespace(objective=0.49, weights={"a1": 8.1})},
                             seconds={"all": 1.0}, cross_checked={}, uncertainty={}, continued={"all": c})
    other = {"path": "w.json", "fits": {"all": {"objective": 0.48, "seconds": 2.0, "weights": {"a1": 6.2}}}}
    text = "\n".join(methods_side_by_side(result, other))
    assert f"| all | single-level, started at the bi-level weights: {c['message']} | – | {c['seconds']:.1f} | – |" in text
    doc = {"fits": {"all": {"per_target": [], "objective": 0.49, "spec": {"fitted": []}, "from_bilevel": c}}}
    assert not [k for k in collect("fit-ioc-single-published", fit_metrics, doc, None).as_dict() if "from_bilevel" in k]


def test_steps_from_the_bilevel_weights_are_reported_and_recorded():
    """The side-by-side table's row 'single-level, started at the bi-level weights' and the metric
    ``D.single_level_from_bilevel`` carry ``FitResult.continued`` as weights.json holds it; without it, no row."""
    from types import SimpleNamespace

    from cobot_analysis.metrics.models import fit_ioc as fit_metrics
    from cobot_analysis.metrics.records import collect
    from cobot_analysis.reports.models import methods_side_by_side

    names = ("a1", "a2")
    fit = SimpleNamespace(objective=0.49, weights={"a1": 8.1, "a2": 8.0})
    cont = {"objective": 0.4724, "start_objective": 0.4785, "weights": {"a1": 8.17, "a2": 8.14}, "seconds": 21.5, "message": ""}
    result = SimpleNamespace(names=names, results={"all": fit}, seconds={"all": 20.3}, cross_checked={}, uncertainty={},
                             continued={"all": cont})
    other = {"path": "fit-ioc-published/weights.json",
             "fits": {"all": {"objective": 0.4785, "seconds": 545.0, "weights": {"a1": 6.15, "a2": 6.21}}}}
    text = "\n".join(methods_side_by_side(result, other))
    rows = [ln for ln in text.splitlines() if ln.startswith("| all |")]
    assert rows[:3] == ["| all | bi-level | 0.4785 | 545.0 | 6.15 | 6.21 |",
                        "| all | single-level, started at the bi-level weights | 0.4724 | 21.5 | 8.17 | 8.14 |",
                        "| all | single-level | 0.4900 | 20.3 | 8.1 | 8 |"]
    assert "stopped short of a minimum of D" in text and "re-solved also from the single-level paths" not in text
    assert "started at the bi-level" not in "\n".join(methods_side_by_side(SimpleNamespace(**{**vars(result), "continued": {}}), other))
    doc = {"fits": {"all": {"per_target": [], "start_objective": 0.52, "objective": 0.49, "evaluations": 0, "failed": 0,
                            "spec": {"fitted": []}, "from_bilevel": cont}}}
    got = collect("fit-ioc-single-published", fit_metrics, doc, None).as_dict()
    assert got["fit-ioc-single.all.D.single_level_from_bilevel"] == 0.4724


def test_the_single_level_report_compares_with_a_bilevel_fit_of_its_own_model_only(tmp_path):
    """A pair workspace whose fit-ioc/ holds the walker's bi-level fit: no comparison, no cross-checks for the table's
    single-level fit (another model's weights are no start for it), and the report names the fit to run."""
    import json
    from types import SimpleNamespace

    from cobot_analysis.reports.models import methods_side_by_side
    from cobot_analysis.stages.models import _bilevel_fit

    (tmp_path / "fit-ioc").mkdir()
    (tmp_path / "fit-ioc" / "weights.json").write_text(json.dumps({"model": "improved", "fits": {"all": {"objective": 0.4}}}))
    assert _bilevel_fit(tmp_path, "fit-ioc", "table") is None
    assert _bilevel_fit(tmp_path, "fit-ioc", "improved")["fits"] == {"all": {"objective": 0.4}}
    assert _bilevel_fit(tmp_path, "fit-ioc-published", "improved") is None
    text = methods_side_by_side(SimpleNamespace(model="table", convention="published"), None)[0]
    assert text == ("No bi-level fit of the table model in this workspace to compare with (run fit-ioc --model table "
                    "--convention published without --method first).")
