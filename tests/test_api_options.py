"""The API as a notebook meets it: options given as the command line's text or as Python lists, bad options
and misplaced tables refused with one ``InputError`` naming the option (never a ``TypeError`` from deep
inside pandas or numpy, never a silent empty or wrong result), and the published pair study's relative pose
taken as ``import_published`` gives it."""

from __future__ import annotations

from pathlib import Path

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


def test_predict_takes_lists_and_single_names():
    """``predictors=["cv"]`` was an AttributeError ('list' object has no attribute 'split'), ``entities="walker"``
    a TypeError from pandas' isin."""
    walk = walking_table(n_subjects=1, n_conditions=1, n_trials=1, missing_theta=0)
    a = ca.predict(walk, settings="10:20", predictors="cv,ctrv", jobs=1)
    b = ca.predict(walk, settings=[(10, 20)], predictors=["cv", "ctrv"], entities="walker", studies="synthetic-walking", jobs=1)
    pd.testing.assert_frame_equal(a.predictions, b.predictions, check_exact=True)


@pytest.mark.parametrize("call, message", [
    (lambda w, m: ca.average(w, max_spread=-1.0), r"^--max-spread must be >= 0, got -1"),
    (lambda w, m: ca.predict(w, settings="10:20", predictors="cv", every=0), r"^--every must be >= 1, got 0"),
    (lambda w, m: ca.predict(w, settings="10:20", predictors="cv", limit=0), r"^--limit must be >= 1, got 0"),
    (lambda w, m: ca.predict(w, settings="10:20", predictors="oc", g0=-1.0), r"^--g0 must be >= 0, got -1"),
    (lambda w, m: ca.generate("clothoid", start=(-1.5, -3.4, 0.0), samples=1), r"^--samples must be >= 2, got 1"),
    (lambda w, m: ca.generate("improved", start=(-1.5, -3.4, 0.0), v_nominal=0.0), r"^--v-nominal must be >= 0.01, got 0"),
    (lambda w, m: ca.generate("improved", start=(-1.5, -3.4, 0.0), duration="fixed", convention="continuous"),
     r"^unknown --duration 'fixed'; use one of free, search, grid"),
    (lambda w, m: ca.generate("improved", start="-1.5,-3.4,0"), r"^--start must be a pose \(x, y, theta\)"),
    (lambda w, m: ca.generate("clothoid", cases=[("E1500", (0.0, -0.9), (0.0, 0.0, 1.57))]), r"^start must be a pose"),
    (lambda w, m: ca.generate("clothoid", cases=[("E1500", (0.0, -0.9, 0.0))]), r"^a case is \(condition, start, goal\)"),
    (lambda w, m: ca.walking_cases("published"), r"^the published convention takes the authors' start and goal poses"),
    (lambda w, m: ca.walking_cases("publish"), r"^--convention 'publish' is not a convention"),
    (lambda w, m: ca.fit_ioc(m, goal="ends", bootstrap=0), r"^unknown --goal 'ends'; use one of auto, design, end"),
    (lambda w, m: ca.fit_ioc(m, per="subjects", bootstrap=0), r"^unknown --per 'subjects'; use one of all, subject"),
    (lambda w, m: ca.fit_ioc(m, max_evaluations=0, bootstrap=0), r"^--max-evaluations must be >= 1, got 0"),
    (lambda w, m: ca.fit_ioc(m, intervals=5, bootstrap=0), r"^--intervals must be >= 10, got 5"),
    (lambda w, m: ca.fit_ioc(w, bootstrap=0), r"^no mean walker trajectory \(kind = mean\) with orientation; pass the means"),
    (lambda w, m: ca.import_published("walking-2020", "nowhere", gamma_limit=-0.5), r"^--gamma-limit must be >= 0"),
    (lambda w, m: ca.preprocess("nowhere/markers.parquet"), r"^nowhere/markers.parquet: file not found"),
])
def test_bad_options_are_one_line_input_errors(walks, means, call, message):
    """Each was a ZeroDivisionError, IndexError, ValueError, a scipy error or a silent default before."""
    with pytest.raises(InputError, match=message):
        call(walks, means)


def test_fit_names_take_the_command_lines_text(means):
    """``fit="a2,a3"`` was split into letters (``--fit names ['a', '2', ',', ...]``)."""
    fit = ca.fit_ioc(means, fit="a2,a3", intervals=20, max_evaluations=2, bootstrap=0, compare=False, jobs=1)
    assert fit.names == ("a2", "a3")


def test_velocity_commands_bounds():
    """``rate=0`` was a ZeroDivisionError; ``v_max=-1`` gave commands saturated at -1 m/s, silently."""
    path = ca.generate("clothoid", start=(-1.5, -3.4, 0.0), samples=50, jobs=1).generated
    with pytest.raises(InputError, match=r"^--rate must be >= 0.1, got 0"):
        ca.velocity_commands(path, rate=0.0)
    with pytest.raises(InputError, match=r"^--v-max must be >= 0, got -1"):
        ca.velocity_commands(path, v_max=-1.0)


def test_tables_of_the_wrong_kind_are_refused(walks, means):
    """An unknown ``kind`` gave 0 means silently; a table in millimetres gave distances 1000 x too large, in "m";
    means of another N a numpy broadcast error; the trajectories as distances a KeyError; a list a TypeError."""
    with pytest.raises(InputError, match=r"^trajectory table has kind 'recording'"):
        ca.average(walks.assign(kind="recording"))
    with pytest.raises(InputError, match=r"value\(s\) outside \[-100, 100\] m .*lengths in metres, not millimetres"):
        ca.compare(walks.assign(x=1000 * walks["x"], y=1000 * walks["y"]), means)
    short = ca.average(walking_table(n_subjects=3, n_conditions=2, n_trials=2, n=20)).means
    with pytest.raises(InputError, match=r"^the means have 20 samples per trajectory, the trajectories 40"):
        ca.compare(walks, short)
    with pytest.raises(InputError, match=r"^the distances table lacks column\(s\)"):
        ca.statistics(walks, means)
    with pytest.raises(InputError, match=r"^trajectories must be a DataFrame or the path of a Parquet file, not a list"):
        ca.average([walks])
    with pytest.raises(InputError, match=r"^means must be a DataFrame or the path of a Parquet file, not None"):
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


def test_fit_distances_have_the_documented_columns(means):
    """docs/schemas.md (``IOC_DISTANCES``) did not list ``converged`` and ``convention``, which every fit's
    distances table (and fit-ioc's distances.parquet) holds."""
    from cobot_analysis.models.outputs import IOC_DISTANCES, ioc_distances_schema

    dist = ca.fit_ioc(means, intervals=20, max_evaluations=2, bootstrap=0, compare=False, jobs=1).distances
    documented = list(IOC_DISTANCES.columns)
    assert [c for c in dist.columns if c not in documented] == []
    assert [c for c, col in IOC_DISTANCES.columns.items() if col.required and c not in dist.columns] == []
    assert ioc_distances_schema() is IOC_DISTANCES
    assert list(ioc_distances_schema(coupled=True).columns)[-6:] == ["direction", "carrier", "T", "T_at_bound", "converged",
                                                                      "convention"]


def test_a_result_stands_for_its_table(walks, means):
    """``compare(walks, average(walks))`` (the result, not its ``means``) was a TypeError from pathlib, as was a
    result given to statistics, fit_ioc, predict or velocity_commands; each now takes the result's table."""
    averaged = ca.average(walks)
    published = ca.PublishedResult("synthetic", Path("."), walks, {})
    compared = ca.compare(published, averaged)
    pd.testing.assert_frame_equal(compared.distances, ca.compare(walks, means).distances, check_exact=True)
    pd.testing.assert_frame_equal(ca.average(published).means, means, check_exact=True)
    pd.testing.assert_frame_equal(ca.statistics(published, compared).table, ca.statistics(walks, compared.distances).table,
                                  check_exact=True)
    fit = ca.fit_ioc(averaged, intervals=20, max_evaluations=2, bootstrap=0, compare=False, jobs=1)
    assert fit.results["all"].weights == ca.fit_ioc(means, intervals=20, max_evaluations=2, bootstrap=0, compare=False,
                                                    jobs=1).results["all"].weights
    walk = walking_table(n_subjects=1, n_conditions=1, n_trials=1)
    one = ca.PublishedResult("synthetic", Path("."), walk, {})
    pd.testing.assert_frame_equal(ca.predict(one, settings="10:20", predictors="cv", jobs=1).predictions,
                                  ca.predict(walk, settings="10:20", predictors="cv", jobs=1).predictions, check_exact=True)
    path = ca.generate("clothoid", start=(-1.5, -3.4, 0.0), samples=50, jobs=1)
    pd.testing.assert_frame_equal(ca.velocity_commands(path).commands, ca.velocity_commands(path.generated).commands,
                                  check_exact=True)


@pytest.mark.slow
def test_reconstruct_takes_the_published_relative_pose_as_the_stage_does(datasets):
    """The dataset's directory (``--wrt-table``), its import's table and the import's result give one reconstruction."""
    folder = datasets / "pair-carriage-2022"
    pairs = ca.import_published("pair-carriage-2022", folder)
    from_dir = ca.reconstruct(pairs.trajectories, relative_pose=folder).reconstruction
    from_result = ca.reconstruct(pairs, relative_pose=pairs).reconstruction
    pd.testing.assert_frame_equal(from_dir, from_result, check_exact=True)
    assert len(from_dir) == 62 and set(from_dir["relative_pose"]) == {"published"}


def test_paths_generated_without_a_study_are_explained(walks, means):
    """Paths generated without ``study=`` (study 'model') matched no mean: the message now says how to name it."""
    cases = [c for c in ca.walking_cases("continuous") if c[0] in ("N1500", "E1500")]
    paths = ca.generate("clothoid", cases=cases, jobs=1).generated
    with pytest.raises(InputError, match=r"study model \(means: synthetic-walking\).*generate them with study=\"synthetic-walking\"$"):
        ca.compare(walks, means, against=paths, comparison="model")
    named = ca.generate("clothoid", cases=cases, study="synthetic-walking", jobs=1).generated
    assert (ca.compare(walks, means, against=named, comparison="model").distances["comparison"] == "model").sum() == 2


def test_study_of_a_table(walks):
    """``study_of(walks)`` (a DataFrame, not a TrajectorySet) was an AttributeError."""
    assert ca.study_of(walks) == ca.study_of(ca.trajectory_set(walks)) == "synthetic-walking"


def test_predict_takes_the_goal_options_of_the_command_line(tmp_path):
    """``predict --goal --candidates --horizons`` had no API counterpart (``ca.predict(..., goal=...)`` a TypeError);
    the API now gives what the stage writes."""
    from cobot_analysis.models.prediction.sweep import PREDICTIONS
    from cobot_analysis.schema import TRAJECTORIES, read_table, write_table
    from cobot_analysis.stages.predict import predict as predict_stage

    walk = walking_table(n_subjects=1, n_conditions=1, n_trials=1, missing_theta=0)
    path = write_table(walk, tmp_path / "trajectories.parquet", TRAJECTORIES)
    options = dict(settings="10:20", predictors="goal,cv", convention="continuous", goal=(0.0, 0.0, 1.5708), horizons="5,all")
    api = ca.predict(walk, jobs=1, **options)
    done = predict_stage(tmp_path / "ws", trajectories=path, jobs=1, **options)
    keep = ["trial", "predictor", "n0", "n_oc", "n_windows", "delta_xy", "delta_theta", "d_pred", "ade", "fde"]
    written = read_table(done.directory / "predictions.parquet", PREDICTIONS)
    pd.testing.assert_frame_equal(api.predictions[keep].reset_index(drop=True), written[keep].reset_index(drop=True),
                                  check_exact=True, check_dtype=False)
    assert sorted(api.horizon_errors["horizon"].unique().tolist()) == [-1, 5]


def test_statistics_takes_anthropometrics_and_durations_as_the_command_line(tmp_path):
    """``anthropometrics`` was documented as the subjects' weight and height but had to be a per-pair table of
    differences (a subjects table was a KeyError 'pair' in a merge); the directory ``--anthropometrics`` takes is now
    read as the stage reads it, and a table without the per-pair columns is refused."""
    from cobot_analysis.stats.sources import read_anthropometrics

    pairs = pair_table(n_pairs=2, goals=1)
    distances = ca.compare(pairs, ca.average(pairs).means).distances
    pd.DataFrame({"id": ["A", "B", "C", "D"], "weight": [60.0, 80.0, 70.0, 71.0],
                  "height": [1.6, 1.8, 1.7, 1.75]}).to_csv(tmp_path / "subjects.csv", index=False)
    pd.DataFrame({"id": ["P01", "P02"], "subject1": ["A", "C"], "subject2": ["B", "D"]}).to_csv(tmp_path / "pairs.csv", index=False)
    table = read_anthropometrics(tmp_path)
    assert table["weight_diff"].tolist() == [20.0, 1.0]
    from_dir = ca.statistics(pairs, distances, anthropometrics=tmp_path).table
    from_table = ca.statistics(pairs, distances, anthropometrics=table).table
    pd.testing.assert_frame_equal(from_dir, from_table, check_exact=True)
    with pytest.raises(InputError, match=r"^the anthropometrics table lacks column\(s\) \['pair', 'weight_diff', 'height_diff'\]"):
        ca.statistics(pairs, distances, anthropometrics=pd.read_csv(tmp_path / "subjects.csv"))
    with pytest.raises(InputError, match=r"no subjects.csv and pairs.csv here"):
        ca.statistics(pairs, distances, anthropometrics=tmp_path / "nowhere")
    with pytest.raises(InputError, match=r"^the durations table lacks a duration column"):
        ca.statistics(pairs, distances, durations=distances)


@pytest.mark.slow
def test_statistics_takes_the_published_durations_as_a_file(datasets, tmp_path):
    """The pair study's durations as the import gives them, as its result, or as its durations.parquet: one table."""
    from cobot_analysis.io.published import DURATIONS
    from cobot_analysis.schema import write_table

    pairs = ca.import_published("pair-carriage-2022", datasets / "pair-carriage-2022")
    distances = ca.compare(pairs, ca.average(pairs)).distances
    config = Path(__file__).parents[1] / "pipelines" / "pair-carriage-2022.toml"
    path = write_table(pairs.durations, tmp_path / "durations.parquet", DURATIONS)
    tables = [ca.statistics(pairs, distances, config=config, durations=d).table for d in (pairs.durations, pairs, path)]
    for other in tables[1:]:
        pd.testing.assert_frame_equal(tables[0], other, check_exact=True)
    assert (tables[0]["status"] == "ok").sum() == 13


def test_a_lab_extent_beyond_what_later_stages_accept_is_refused_before_any_work(tmp_path, cli):
    """import --lab-extent above 100 m would import positions that every later stage refuses (the trajectory tables'
    limit, schema.LAB_EXTENT): refused at once, in one line, nothing written."""
    with pytest.raises(InputError, match=r"--lab-extent 200 m is beyond the 100 m"):
        ca.import_markers(tmp_path / "missing.yaml", lab_extent=200.0)
    code, _, err = cli("import", tmp_path / "missing.yaml", "--out", tmp_path / "ws", "--lab-extent", "200")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "at most 100" in err
    assert not (tmp_path / "ws").exists()


def test_the_statistics_summary_counts_tests_apart_from_descriptive_summaries(walks, means):
    """A ``describe`` row has no p: the summary counted it among the "tests run" (docs/results.md: 17 tests run for 14
    tests and 3 summaries on walking-2020)."""
    distances = ca.compare(walks, means).distances
    ask = {"source": "distances", "filter": {"comparison": "individual-mean"}, "value": "d_xy", "group": "subject",
           "family": "study"}
    config = {"study": "synthetic-walking", "analysis": [{**ask, "id": "A", "description": "test", "test": "kruskal"},
                                                        {**ask, "id": "B", "description": "summary", "test": "describe"}]}
    result = ca.statistics(walks, distances, config=config)
    assert result.table["status"].tolist() == ["ok", "ok"]
    assert result.summary().startswith("1 test run (and 1 descriptive summary), 0 skipped (reason in the table); ")


def test_compare_against_leaves_out_model_paths_that_did_not_converge(walks, means, caplog):
    """A generated table whose solver stopped on a path (``generate --study`` keeps it, ``converged`` false, the reason
    in ``status``): before, compare --against measured that last iterate as the model's path, without a word. Now it
    is left out, named in one warning line, the others compared; none converged is refused."""
    cases = [c for c in ca.walking_cases("continuous") if c[0] in ("N1500", "E1500")]
    named = ca.generate("clothoid", cases=cases, study="synthetic-walking", jobs=1).generated
    stopped = named.assign(converged=named["trial"].ne("clothoid_E1500"))
    d = ca.compare(walks, means, against=stopped, comparison="model").distances
    assert list(d.loc[d["comparison"] == "model", "condition"]) == ["N1500"]
    assert "the against table: 1 model path(s) left out, their solver did not converge or they miss their goal " \
           "(clothoid_E1500); re-run generate with a higher --max-iter" in caplog.text
    with pytest.raises(InputError, match=r"none of its 2 model paths converged; re-run generate with a higher --max-iter"):
        ca.compare(walks, means, against=named.assign(converged=False), comparison="model")
