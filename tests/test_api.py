"""The public API (docs/api.md): what a notebook user imports behaves as the command line does."""

from __future__ import annotations

import subprocess
import sys

import pytest

import cobot_analysis.api as ca
from cobot_analysis.errors import InputError
from cobot_analysis.synth.tables import walking_table


def test_importing_the_package_loads_no_heavy_library():
    code = "import sys, cobot_analysis, cobot_analysis.api; print(sorted({'pandas', 'scipy', 'casadi', 'matplotlib'} & set(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "[]"


def test_every_export_resolves():
    for name, module in ca.EXPORTS.items():
        assert getattr(ca, name).__module__ == f"cobot_analysis.api.{module}"
    with pytest.raises(AttributeError):
        ca.no_such_function  # noqa: B018


def test_generate_defaults_to_the_convention_of_the_weights_as_the_cli_does():
    from cobot_analysis.models import generate

    preset = generate("improved", (-1.0, -1.5, 0.0), (0.0, 0.0, 1.5707963), weights="walking-2021")
    assert preset["convention"].iloc[0] == "published"  # the papers' weights mean what they mean under it
    mapping = generate("improved", (-1.0, -1.5, 0.0), (0.0, 0.0, 1.5707963), weights=dict(a1=1.0, b0=10.0, b1=10.0))
    assert mapping["convention"].iloc[0] == "continuous"  # weights of unknown convention: ours
    unicycle = generate("unicycle", (-1.0, -1.5, 0.0), (0.0, 0.0, 1.5707963), weights="walking-2021")
    assert unicycle["convention"].iloc[0] == "continuous"  # the published convention has no unicycle
    assert ca.generate("improved", start=(-1.0, -1.5, 0.0), weights="walking-2021").convention == "published"


def test_fitted_weights_are_used_in_the_convention_they_were_fitted_in(tmp_path):
    """A weights.json of fit-ioc, as a file or as the fit's ``weights_json()`` mapping, runs under the convention
    recorded in it, in models.generate and api.generate alike (the CLI's rule); asked for, another one wins."""
    import json

    from cobot_analysis.models import generate
    from cobot_analysis.models.presets import PRESETS

    start, goal = (-1.0, -1.5, 0.0), (0.0, 0.0, 1.5707963)
    for convention in ("continuous", "published"):
        fitted = {"model": "improved", "convention": convention, "weights": dict(PRESETS["walking-2021"])}
        path = tmp_path / f"{convention}.json"
        path.write_text(json.dumps(fitted))
        for weights in (path, str(path), fitted):
            assert generate("improved", start, goal, weights=weights)["convention"].iloc[0] == convention, weights
        assert ca.generate("improved", start=start, weights=fitted).convention == convention
    assert generate("improved", start, goal, weights=fitted, convention="continuous")["convention"].iloc[0] == "continuous"
    with pytest.raises(InputError, match="is not a convention"):
        generate("improved", start, goal, weights=dict(fitted, convention="discrete"))


def test_compare_refuses_generated_paths_given_as_trials():
    walks = walking_table(n_subjects=2, n_conditions=1, n_trials=2)
    means = ca.average(walks).means
    with pytest.raises(InputError, match="generated paths"):
        ca.compare(walks.assign(kind="model"), means)
    d = ca.compare(walks, means).distances
    assert len(d) == 4 and (d["comparison"] == "individual-mean").all() and (d["d_xy"] > 0).all()


def test_generate_summary_states_the_time_law_beside_the_subjects():
    """The summary line a user sees: how many paths walk outside 0.5-2 m/s, the subjects' own count on the same
    conditions, and under the published convention that its duration rule is no human pace."""
    import pandas as pd

    from cobot_analysis.api.models import GenerateResult

    ends = pd.DataFrame({"trial": ["m_a", "m_b", "m_c"], "condition": ["a", "b", "c"], "goal_reached": [True, True, False],
                         "mean_speed": [0.4, 0.8, 2.5]})
    cases = [(c, (-1.0, -1.0, 0.0), (0.0, 0.0, 1.0)) for c in "abc"]  # the subjects' pace is per case (trial m_<case>)
    r = GenerateResult(ends, ["m"], None, cases, "continuous", 500, 100, {"a": (3.0, 0.45), "b": (2.0, 0.9)})
    assert r.summary() == ("3 trajectories, 1 not reaching their goal (status in .generated), mean speed 0.4-2.5 m/s "
                           "(2 of 3 outside 0.5-2 m/s; the subjects' 1 of 2)")  # from Python: no results.md was written
    assert r.summary(where="ws/generate/results.md").startswith("3 trajectories, 1 not reaching their goal (ws/generate/results.md)")
    published = GenerateResult(ends.iloc[:1], ["m"], "walking-2021", [], "published", 500, 100)
    assert published.summary() == ("1 trajectory, all at their goal, mean speed 0.4 m/s (the published duration rule: "
                                   "no human pace; velocity-commands refuses it)")


def test_import_summary_says_where_the_refused_trials_are():
    """The summary said "(listed above and in results.md)" from Python too, where nothing was listed above and no
    results.md was written: from Python it names the result's ``refused``, the command line its own places."""
    from pathlib import Path

    import pandas as pd

    from cobot_analysis.api.data import ImportResult
    from cobot_analysis.refusals import Refused

    r = ImportResult(None, None, pd.DataFrame({"trial": ["t1", "t2"]}), {}, [Refused("t3", Path("t3.c3d"), "LASI never visible")],
                     [], n_samples=200, n_occluded=3)
    assert r.summary() == "2 trials, 1 refused (why: .refused), 200 marker samples (1.5% occluded)"
    assert r.summary(where="listed above and in ws/import/results.md").startswith("2 trials, 1 refused (listed above and in ws/")
