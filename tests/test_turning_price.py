"""What walker-like paths cost a fit whose model paths spin (docs/methods.md sec. 5.5; models.turning_price):
model paths planted at a fit-like a3 of 1.1e-7, where some design starts spin, as the means."""

import math

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.design import WALKING_GOAL, walking_condition
from cobot_analysis.models import generate, spins
from cobot_analysis.models.ioc import Target
from cobot_analysis.models.presets import load_weights, names_for, weights_vector
from cobot_analysis.models.turning_price import a3_values, turning_price
from cobot_analysis.reports.models import turning_lines

W = {**dict(zip(names_for("improved"), map(float, weights_vector(load_weights("walking-2021", "improved"), "improved")))),
     "a2": 7.82, "a3": 1.12e-7, "a4": 2.34}  # the continuous walking fit's weights (make all, 2026-11-26)
CONDITIONS = ("S1500", "O4040", "E1500", "N0615")  # the first two spin at W, the others do not


def test_a3_values_are_the_decades_above_up_to_the_search_limit():
    assert a3_values(1.12e-7) == [10.0 ** k for k in range(-6, 4)]
    assert a3_values(1e-6)[0] == 1e-5 and a3_values(0.5)[:2] == [1.0, 10.0]
    assert a3_values(1e3) == [] and a3_values(999.0) == [] and a3_values(900.0) == [1e3]  # more than 1 % above


def test_turning_price_of_planted_spinning_paths():
    targets, spinning = [], 0
    for c in CONDITIONS:
        df = generate("improved", walking_condition(c).start, WALKING_GOAL, weights=W, n_samples=100, n_intervals=100,
                      convention="continuous")
        spinning += spins(df["theta"].to_numpy(float))
        targets.append(Target(c, c, "", df["x"].to_numpy(), df["y"].to_numpy(), df["theta"].to_numpy(), goal_pose=WALKING_GOAL,
                              start_pose=walking_condition(c).start))
    assert spinning == 2
    t = turning_price(targets, W, jobs=1)
    n = len(t)  # the fitted a3, then decades up to the first at which no path spins
    assert 2 <= n <= 11 and t["a3"].tolist() == [W["a3"], *a3_values(W["a3"])][:n]
    assert (t["paths"] == 4).all() and t["spinning"].iloc[0] == 2
    assert (t["spinning"].iloc[:-1] > 0).all() and t["spinning"].iloc[-1] == 0
    assert t["D"].iloc[0] < 1e-3  # the planted paths are the model's own at the fitted weights
    assert (t["D"].iloc[1:] > t["D"].iloc[0]).all()
    assert math.isnan(t["t"].iloc[0]) and not t["rejected"].iloc[0]
    assert np.isfinite(t["t"].iloc[1:]).all() and t["t_q"].iloc[1:].tolist() == pytest.approx([3.182] * (n - 1), abs=1e-3)  # t_3(0.975)
    # the same rows, one value at a time
    pd.testing.assert_frame_equal(turning_price(targets, W, batch=1, jobs=1), t)


def test_turning_lines_name_the_least_a3_without_spins_and_the_verdict():
    rows = pd.DataFrame({"a3": [1.1e-7, 1e-6, 1e-5], "paths": 37, "spinning": [10, 0, 0], "D": [0.45, 0.46, 0.50],
                         "t": [math.nan, 1.2, 3.3], "t_q": [math.nan, 2.03, 2.03], "rejected": [False, False, True]})
    text = "\n".join(turning_lines(rows))
    assert "| 1.1e-07 | 10 of 37 | 0.4500 |  | (the fitted weights) |" in text
    assert "| 1e-06 | 0 of 37 | 0.4600 | 1.2 (2.03) | no |" in text
    assert "The least a3 at which no path spins: 1e-06, D 0.4600 against 0.4500 (+2.2 %): the means do not reject it" in text
    text = "\n".join(turning_lines(rows.assign(rejected=[False, True, True])))
    assert "(+2.2 %): the means reject it" in text
    assert "Every a3 up to the search limit leaves some path spinning." in "\n".join(turning_lines(rows.assign(spinning=[10, 2, 1])))


def test_the_paired_test_against_a_fit_at_D_zero_rejects_any_significant_rise():
    """``profile.excess`` against noise-free paths (D = 0 at the fit): the 0.1 % floor is 0, the t test decides."""
    from cobot_analysis.models.ioc.profile import excess

    t, tq, crit = excess(np.array([0.1, 0.2, 0.15]), np.zeros(3))
    assert t == pytest.approx(0.15 / (0.05 / math.sqrt(3))) and crit == pytest.approx(t / tq)
    assert excess(np.zeros(3), np.zeros(3))[2] == 0.0


def test_fit_ioc_reports_the_turning_price_where_its_paths_spin(monkeypatch):
    """``fit_ioc`` computes the sweep where its fitted weights' model paths spin, and only there: on means planted
    at W (a2 fitted, 2 evaluations) its own paths need not spin after its time gauge (a3 x c^4: spins are chaotic
    this close to a3 = 0; none does on this machine); with ``spins`` made to say every path spins, the sweep from the
    fitted weights (its own spin count is the real one) and its table in results.md."""
    import cobot_analysis.api as ca
    import cobot_analysis.models as models
    from cobot_analysis.reports.models import fit_ioc_markdown
    from cobot_analysis.schema import TRAJECTORIES

    frames = []
    for c in CONDITIONS:
        df = generate("improved", walking_condition(c).start, WALKING_GOAL, weights=W, n_samples=100, n_intervals=100,
                      convention="continuous")
        frames.append(df[list(TRAJECTORIES.columns.keys() & set(df.columns))].assign(
            study="test-walking", trial=f"mean_{c}", condition=c, kind="mean", n_trials=1, subject=None))
    means = pd.concat(frames, ignore_index=True)

    def fit_it():
        return ca.fit_ioc(means, fit=["a2"], start_weights=W, intervals=20, max_evaluations=2, bootstrap=0, jobs=1)

    fit = fit_it()
    assert (fit.turning is None) == (not fit.spinning())  # here none spins (on this machine): no sweep
    monkeypatch.setattr(models, "spins", lambda theta: True)
    fit = fit_it()
    t = fit.turning
    assert t is not None and t["a3"].iloc[0] == fit.results["all"].weights["a3"] and (t["paths"] == len(CONDITIONS)).all()
    assert t["spinning"].iloc[0] == sum(spins(p["theta"].to_numpy(float)) for p in fit.paths["fitted"])  # the real count

    class Stage:
        def savefig(self, fig, name):
            import matplotlib.pyplot as plt
            plt.close(fig)

    text = fit_ioc_markdown(fit, Stage(), optimizer="powell", intervals=20, v_nominal=1.0, durations=None)
    assert "What walker-like paths would cost" in text and f"| {t['a3'].iloc[0]:.3g} | " in text
