"""The API as a notebook meets it: options given as the command line's text or as Python lists, bad options
and misplaced tables refused with one ``InputError`` naming the option (never a ``TypeError`` from deep
inside pandas or numpy, never a silent empty or wrong result), and the published pair study's relative pose
taken as ``import_published`` gives it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import cobot_analysis.api as ca
from cobot_analysis.errors import InputError
from cobot_analysis.synth.tables import pair_table, walking_table


@pytest.fixture(scope="module")
def walks():
    return walking_table(n_subjects=3, n_conditions=2, n_trials=2)


@pytest.fixture(scope="module")
def means(walks):
    return ca.average(walks).means


def test_list_options_take_a_list_or_the_command_lines_text(walks, means):
    """``by="condition"`` was split into its letters (``--by names unknown column(s) ['c', 'o', ...]``)."""
    as_text = ca.average(walks, by="condition,entity").means
    as_list = ca.average(walks, by=["condition", "entity"]).means
    pd.testing.assert_frame_equal(as_text, as_list, check_exact=True)
    d_text = ca.compare(walks, means, any_vs_any="condition").distances
    d_list = ca.compare(walks, means, any_vs_any=["condition"]).distances
    pd.testing.assert_frame_equal(d_text, d_list, check_exact=True)
    assert (d_text["comparison"] == "any-any").sum() == 2 * 15  # 6 trials per condition: 15 pairs each
    with pytest.raises(InputError, match=r"^--any-vs-any names unknown column\(s\) \['speed'\]"):
        ca.compare(walks, means, any_vs_any="speed")


def test_tables_of_the_wrong_kind_are_refused(walks, means):
    """An unknown ``kind`` gave 0 means silently; a table in millimetres gave distances 1000 x too large, in "m";
    means of another N a numpy broadcast error; the trajectories as distances a KeyError; a list a TypeError."""
    with pytest.raises(InputError, match=r"^trajectory table has kind 'recording'"):
        ca.average(walks.assign(kind="recording"))
    with pytest.raises(InputError, match=r"beyond the lab \(100 m\); give x and y in metres"):
        ca.compare(walks.assign(x=1000 * walks["x"], y=1000 * walks["y"]), means)
    short = ca.average(walking_table(n_subjects=3, n_conditions=2, n_trials=2, n=20)).means
    with pytest.raises(InputError, match=r"^the means have 20 samples per trajectory, the trajectories 40"):
        ca.compare(walks, short)
    with pytest.raises(InputError, match=r"^the distances table lacks column\(s\)"):
        ca.statistics(walks, means)
    with pytest.raises(InputError, match=r"^trajectories must be a DataFrame or the path of a Parquet file, not a list"):
        ca.average([walks])
    with pytest.raises(InputError, match=r"^trajectories must be a DataFrame or the path of a Parquet file, not a NoneType"):
        ca.compare(walks, None)


def test_reconstruct_takes_the_relative_pose_as_imported():
    """``import_published(...).subject_wrt_table`` (a DataFrame) was a ValueError ("truth value of a DataFrame is
    ambiguous"); it is now the same relative pose as the mapping ``reconstruct.read_wrt_table`` gives."""
    import cobot_analysis.reconstruct as rc
    from cobot_analysis.api import trajectory_set

    pairs = pair_table(n_pairs=2, goals=1)
    pose = rc.relative_pose(trajectory_set(pairs), 3, "trial")
    table = pd.DataFrame([{"entity": e, "direction": d, "sample": k, "x_rel": x[k], "y_rel": y[k], "theta_rel": t[k]}
                          for (e, d), (x, y, t) in pose.items() for k in range(len(x))])
    from_table = ca.reconstruct(pairs, relative_pose=table).reconstruction
    from_dict = ca.reconstruct(pairs, relative_pose=pose).reconstruction
    pd.testing.assert_frame_equal(from_table, from_dict, check_exact=True)
    published = from_table[from_table["relative_pose"] == "published"]
    assert len(published) == 16 and np.isfinite(published["d_xy"]).all()
    with pytest.raises(InputError, match=r"^the relative pose lacks column\(s\) \['x_rel'\]"):
        ca.reconstruct(pairs, relative_pose=table.drop(columns="x_rel"))


def test_localise_takes_one_bag_and_names_unknown_options(tmp_path):
    """A single path was iterated ('r: no such file', or "'PosixPath' object is not iterable"); an unknown
    option was a TypeError, a tuple ``delay_window`` an AttributeError."""
    from cobot_analysis.localisation import synth

    bag = synth.write_ros1(synth.make_run(synth.SynthParams(n_goals=1, stop=3.0, speed=0.3)), tmp_path / "run.bag")
    one = ca.localise(str(bag), delay=0.55, delay_window=(0.0, 1.5))
    listed = ca.localise([bag], delay=0.55)
    pd.testing.assert_frame_equal(one.runs, listed.runs, check_exact=True)
    with pytest.raises(InputError, match=r"^unknown localise option\(s\) \['tol'\]"):
        ca.localise(bag, tol=0.1)
    with pytest.raises(InputError, match=r"^--min-samples must be >= 3, got 0"):
        ca.localise(bag, min_samples=0)


def test_a_study_dict_of_another_study_is_refused(walks, means):
    """A dict (or loaded study file) of another study ran its questions on the data silently; a path was refused."""
    question = {"id": "W1.1", "description": "d_xy across subjects", "source": "distances",
                "filter": {"comparison": "individual-mean"}, "value": "d_xy", "group": "subject", "test": "kruskal",
                "family": "study"}
    distances = ca.compare(walks, means).distances
    with pytest.raises(InputError, match=r"^study file of study 'walking-2020', but the trajectories are of study 'synthetic-walking'"):
        ca.statistics(walks, distances, config={"study": "walking-2020", "analysis": [question]})
    table = ca.statistics(walks, distances, config={"study": "synthetic-walking", "analysis": [question]}).table
    assert table["id"].tolist() == ["W1.1"] and table["status"].tolist() == ["ok"]
