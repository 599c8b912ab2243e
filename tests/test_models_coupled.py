"""Coupled OC model of two carriers and its IOC (docs/methods.md 5.6, 6): recovery of planted paths,
the kink-free barriers, the fit's own stage (the table fit is not clobbered), the T-at-bound flag."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from cobot_analysis.models.oc import resample
from cobot_analysis.models.ioc import IOCSpec, PairTarget, Target, duration_terms, fit
from cobot_analysis.models.oc.problem import OCPSolution
from cobot_analysis.models.presets import PRESETS, weights_vector
from cobot_analysis.schema import TRAJECTORIES, write_table

W = weights_vector(PRESETS["pair-2022"], "coupled")
NAMES = list(PRESETS["pair-2022"])
START = np.array([(0.0, 0.9, -math.pi / 2), (0.0, -0.9, math.pi / 2)])  # table at the origin, carriers facing it
GOALS = [np.array([(-2.17, -2.25, math.pi), (-3.97, -2.25, 0.0)]),  # table turned by 90 degrees
         np.array([(-1.5, -1.3, -math.pi / 2), (-1.5, -3.2, math.pi / 2)])]  # table translated
N = 60  # samples per carrier path


def _carriers(sol, n=N):
    out = []
    for i in range(2):
        part = OCPSolution(sol.X[:, 6 * i:6 * i + 6], sol.U[:, 3 * i:3 * i + 3], sol.T, sol.cost, True, "", "", 0, sol.primal)
        out.append(resample(part, n))
    return out


def _planted(weights, intervals=20):
    from cobot_analysis.models.oc.coupled import solve_pair

    return [solve_pair(START, g, weights, n_intervals=intervals).check() for g in GOALS]


def test_coupled_fit_recovers_planted_paths():
    """Paths generated with a1 = 10, a7 = 1 (published 2.29, 10.42); the fit of (a1, a7) from the
    published weights finds paths within 2 mm of the planted ones (goal = generating goal)."""
    planted = W.copy()
    planted[NAMES.index("a1")], planted[NAMES.index("a7")] = 10.0, 1.0
    targets = []
    for j, (g, sol) in enumerate(zip(GOALS, _planted(planted))):
        cs = tuple(Target(f"c{i}", "g", "", p["x"], p["y"], p["theta"], tuple(g[i])) for i, p in enumerate(_carriers(sol)))
        targets.append(PairTarget(f"t{j}", "g", cs, direction="forward"))
    spec = IOCSpec(model="coupled", start_weights=tuple(W), fitted=("a1", "a7"), n_intervals=20, max_evaluations=60)
    r = fit(spec, targets)
    assert r.start_objective > 0.1  # the published weights do not explain the planted paths
    assert r.objective < 0.005 and r.failed == 0
    assert max(d[f"d_xy_{i}"] for d in r.per_target for i in (1, 2)) < 0.002
    assert r.weights["a1"] == pytest.approx(10.0, rel=0.05) and r.weights["a7"] == pytest.approx(1.0, rel=0.05)
    assert all(d["T_at_bound"] == 0 for d in r.per_target)


def test_barriers_are_the_published_chi_and_xi_at_the_optimum():
    """The slacks s, t1, t2 equal max(0, d - 2.1, 1.6 - d) and max(0, |bearing| - pi/3) at every interval."""
    from cobot_analysis.models.oc.coupled import BAND, FACING, get_coupled_ocp
    from cobot_analysis.models.oc.problem import OCPShape

    ocp = get_coupled_ocp(OCPShape(20, free_time=True))
    w = W.copy()
    w[NAMES.index("a9")] = 5.0  # a stronger barrier: the distance band is active on part of the path
    sol = ocp.solve(START, GOALS[0], w, 4.7, guess="line").check()
    s = sol.primal[ocp._si]
    X = sol.X[:-1]
    d = np.hypot(X[:, 0] - X[:, 6], X[:, 1] - X[:, 7])

    def bearing(a, b):
        dx, dy = X[:, b] - X[:, a], X[:, b + 1] - X[:, a + 1]
        return np.arctan2(-np.sin(X[:, a + 2]) * dx + np.cos(X[:, a + 2]) * dy, np.cos(X[:, a + 2]) * dx + np.sin(X[:, a + 2]) * dy)

    assert np.abs(s[:, 0] - np.maximum.reduce([np.zeros_like(d), d - BAND[1], BAND[0] - d])).max() < 1e-6
    for k, (a, b) in enumerate(((0, 6), (6, 0))):
        assert np.abs(s[:, 1 + k] - np.maximum(0, np.abs(bearing(a, b)) - FACING)).max() < 1e-6


def test_duration_at_bound_is_detected():
    assert duration_terms(0.4 * 5.0, 5.0)["T_at_bound"] == -1
    assert duration_terms(2.5 * 3.0 * (1 + 1e-5), 3.0)["T_at_bound"] == 1
    assert duration_terms(1.3 * 3.0, 3.0)["T_at_bound"] == 0


def _pair_means(sols):
    """A means table of the pair study (scenario 3): forward, and the same paths as a return with
    the subjects' labels swapped; the table between the carriers."""
    frames = []
    for j, sol in enumerate(sols):
        c = _carriers(sol)
        table = {"x": (c[0]["x"] + c[1]["x"]) / 2, "y": (c[0]["y"] + c[1]["y"]) / 2, "theta": c[1]["theta"]}
        for direction, labels in (("forward", ("subject1", "subject2")), ("return", ("subject2", "subject1"))):
            for entity, p in ((labels[0], c[0]), (labels[1], c[1]), ("table", table)):
                frames.append(pd.DataFrame({
                    "study": "test-pairs", "trial": f"g{j}_{direction}_sc3", "kind": "mean", "n_trials": 3,
                    "condition": f"g{j}", "direction": direction, "scenario": 3, "entity": entity, "sample": np.arange(N),
                    "phase": np.linspace(0, 100, N), "time": np.linspace(0, sol.T, N), "x": p["x"], "y": p["y"],
                    "theta": p["theta"], "travel_time": sol.T, "travelled_distance": 1.0, "quality": "ok"}))
    return pd.concat(frames, ignore_index=True)


@pytest.mark.slow
def test_coupled_fit_has_its_own_stage_and_every_report_flags_T_at_its_bound(tmp_path, cli):
    src = write_table(_pair_means(_planted(W)), tmp_path / "means.parquet", TRAJECTORIES)
    out = tmp_path / "ws"
    fast = {**PRESETS["table-2022"], "a0": 1e7}  # time is very expensive: T on its lower bound (0.1 T0)
    wfile = tmp_path / "fast.json"
    wfile.write_text(json.dumps({"weights": fast}))
    # means without their durations: no time-gauge calibration to the subjects' pace (models/ioc/pace.py),
    # which would move T off the bound the test needs
    unpaced = write_table(_pair_means(_planted(W)).assign(travel_time=np.nan), tmp_path / "unpaced.parquet", TRAJECTORIES)
    code, _, err = cli("fit-ioc", "--out", out, "--model", "table", "--means", unpaced, "--start-weights", wfile, "--fit", "a1",
                       "--max-evaluations", "1", "--intervals", "20", "--no-compare", "-j", "1")
    assert code == 0, err
    table_weights = (out / "fit-ioc" / "weights.json").read_text()
    text = (out / "fit-ioc" / "results.md").read_text()
    assert "**Warning: fitted duration T at its bound** (0.1, 10) x T0" in text and "4 of 4 paths (4 at the lower, 0 at the upper" in text
    code, _, err = cli("fit-ioc", "--out", out, "--model", "coupled", "--means", src, "--fit", "a1",
                       "--max-evaluations", "1", "--intervals", "20", "-j", "1")
    assert code == 0, err
    assert (out / "fit-ioc" / "weights.json").read_text() == table_weights  # the table fit is untouched
    fit_ = json.loads((out / "fit-ioc-coupled" / "weights.json").read_text())
    assert fit_["model"] == "coupled" and fit_["fits"]["all"]["failed"] == 0
    # the targets are the model's own paths at the published weights, but the OC goal is the measured
    # end pose (soft terminal cost: not the generating goal), so not exactly zero
    assert fit_["fits"]["all"]["start_objective"] < 0.1
    text = (out / "fit-ioc-coupled" / "results.md").read_text()
    assert "Paths: 2 forward + 2 return scenario-3 mean paths" in text and "| a9 | held | 0.5 | 0.5 | 0.5 |" in text
    assert "Fitted duration T inside its bounds" in text and (out / "fit-ioc-coupled" / "pair_paths.png").is_file()
    from cobot_analysis.models.outputs import IOC_DISTANCES
    from cobot_analysis.schema import read_table

    dist = read_table(out / "fit-ioc-coupled" / "distances.parquet", IOC_DISTANCES)
    assert len(dist) == 2 * 4 * 2  # weight sets x paths x carriers
    ret = dist[(dist.direction == "return") & (dist.carrier == 1)]
    assert set(ret.subject) == {"subject2"}  # roles swapped on returns
    fwd = dist[dist.direction == "forward"].sort_values(["model", "condition", "carrier"])["d_xy"].to_numpy()
    rev = dist[dist.direction == "return"].sort_values(["model", "condition", "carrier"])["d_xy"].to_numpy()
    assert np.allclose(fwd, rev, atol=1e-9)  # same problem after the swap


def test_coupled_fit_refuses_means_without_both_carriers(tmp_path, cli):
    df = _pair_means(_planted(W)[:1])
    src = write_table(df[df.entity != "subject2"], tmp_path / "one_carrier.parquet", TRAJECTORIES)
    out = tmp_path / "ws"
    code, _, err = cli("fit-ioc", "--out", out, "--model", "coupled", "--means", src, "--max-evaluations", "1", "-j", "1")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "one_carrier.parquet: no scenario-3 mean path with both carriers" in err
    assert not (out / "fit-ioc-coupled").exists() and not list(out.glob(".fit-ioc-coupled*"))  # no stage, no checkpoint
