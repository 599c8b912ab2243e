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


def test_the_synthetic_studies_are_in_the_api(tmp_path):
    """``synth walking|pairs|localisation`` had no API function (``ca.synth_walking`` was an AttributeError): each
    writes what the command writes into a directory, and its result names what the next function takes."""
    study = ca.synth_walking(tmp_path / "walk", subjects=1, repetitions=1, conditions="E4015", jobs=1)
    assert study.summary() == "1 trials" and study.protocol == tmp_path / "walk" / "protocol.yaml"
    assert (tmp_path / "walk" / "study.toml").is_file() and len(list((tmp_path / "walk" / "raw").glob("*.c3d"))) == 1
    assert ca.import_markers(study.protocol, jobs=1).trials["condition"].tolist() == ["E4015"]
    pairs = ca.synth_pairs(tmp_path / "pairs", pairs=1, goals=1, scenarios="3", jobs=1)
    assert pairs.summary() == "1 recordings" and sorted(pairs.truth_trials["scenario"].dropna().unique()) == [3]
    robot = ca.synth_localisation(tmp_path / "robot", goals_per_lap=1, stop=3.0, speed=0.3, formats=["mcap"])
    assert robot.bags == [tmp_path / "robot" / "run.mcap"] and robot.run.params.delay == 0.55
    with pytest.raises(InputError, match=r"^--goals-per-lap must be a whole number in \[1, 6\], got 7; e.g. --goals-per-lap 1$"):
        ca.synth_localisation(tmp_path / "bad", goals_per_lap=7)
    assert not (tmp_path / "bad").exists()  # refused before anything is written


@pytest.mark.parametrize("args, message", [
    (("--goals-per-lap", "7"), "--goals-per-lap must be a whole number in [1, 6], got 7; e.g. --goals-per-lap 1"),
    (("--speed", "0"), "--speed must be >= 0.01, got 0; e.g. --speed 0.12"),
    (("--delay", "-1"), "--delay must be >= 0, got -1; e.g. --delay 0.55"),
    (("--formats", "bag"), "unknown format(s) ['bag']; use --formats ros1,ros2,mcap (or some of them)"),
])
def test_synth_localisation_options_are_checked_by_the_api(cli, tmp_path, args, message):
    """The ranges typer checked (min=, max=) are the API's checks: the same exit code 2, one line naming the option."""
    code, _, err = cli("synth", "localisation", "--out", tmp_path / "ws", *args)
    assert code == 2 and err.splitlines() == [f"error: {message}"]
    assert not (tmp_path / "ws" / "synth-localisation").exists()
