"""The study file (cobot_analysis.study), its documentation, the default questions, the describe
row, refused trials and averages of trials that do not share a frame."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from cobot_analysis import refusals, study as st
from cobot_analysis.errors import InputError
from cobot_analysis.stats import analyses, tests as T
from cobot_analysis.stats.config import Analysis, StudyConfig

DOC = Path(__file__).resolve().parents[1] / "docs" / "statistics.md"


def doc_examples() -> list[str]:
    return re.findall(r"```toml\n(.*?)```", DOC.read_text(), flags=re.S)


def test_every_documented_example_loads_and_every_test_kind_has_one(tmp_path):
    tests = set()
    for n, text in enumerate(doc_examples()):
        path = tmp_path / f"example{n}.toml"
        path.write_text(text)
        s = st.load(path)
        assert s.name in ("lab-gait", "lab-pairs") and s.declared
        tests |= {a.test for a in s.config.analyses} | {a.parametric for a in s.config.analyses if a.parametric}
    assert tests == set(T.TESTS)


def test_documented_sources_are_the_real_ones():
    from cobot_analysis.stats.sources import SOURCE_COLUMNS

    text = DOC.read_text()
    assert all(f"| `{name}` |" in text for name in SOURCE_COLUMNS)


@pytest.mark.parametrize("doc, message", [
    ({"colour": "red"}, "unknown key(s) ['colour']"),
    ({"factor": [{"label": "x"}]}, "factor #1 needs column"),
    ({"factor": [{"column": "scenario", "short": "x"}, {"column": "pair", "short": "x"}]}, "abbreviation 'x' already means scenario"),
    ({"factor": [{"column": "subject", "short": "Subj. 1"}]}, "already means subject1"),
    ({"factor": [{"column": "subject", "colour": 1}]}, "unknown key(s) ['colour']"),
    ({"entities": ["robot"]}, "entities must be a list of"),
    ({"analysis": [{"id": "A", "source": "nowhere", "value": "d_xy", "test": "kruskal", "family": "f"}]}, "unknown source"),
])
def test_bad_study_files_are_one_line(doc, message):
    with pytest.raises(InputError) as e:
        st.parse(doc, Path("study.toml"))
    assert message in str(e.value) and "\n" not in str(e.value)


def test_study_file_is_found_beside_the_protocol_and_must_name_the_data(tmp_path):
    import json

    lab = tmp_path / "lab"
    lab.mkdir()
    (lab / "protocol.yaml").write_text("trials: []\n")
    ws = tmp_path / "ws"
    (ws / "import").mkdir(parents=True)
    (ws / "import" / "manifest.json").write_text(json.dumps({"inputs": [{"path": str(lab / "protocol.yaml")}]}))
    assert st.resolve(ws, "lab-gait").path is None  # nothing declared: described from the data
    st.write(lab / "study.toml", "lab-gait", "Gait", ["walker"], [st.Factor("condition", "floor", short="fl")])
    s = st.resolve(ws, "lab-gait")
    assert s.path == lab / "study.toml" and s.label("condition") == "floor" and not s.declared
    assert s.factor("condition").level(2, short=True) == "fl2" and s.factor("condition").level(2) == "floor 2"
    with pytest.raises(InputError, match="study file of study 'lab-gait', but the trajectories are of study 'other'"):
        st.resolve(ws, "other")
    with pytest.raises(InputError, match="study file not found"):
        st.resolve(ws, "lab-gait", lab / "missing.toml")
    assert st.locate(tmp_path / "nowhere", "walking-2020") == st.PIPELINES / "walking-2020.toml"  # published data: by name


def test_our_studies_use_the_same_mechanism():
    for name in ("walking-2020", "pair-carriage-2022", "synthetic-pairs", "synthetic-walking"):
        s = st.load(st.PIPELINES / f"{name}.toml")
        assert s.name == name and s.declared and s.factors
    pairs = st.load(st.PIPELINES / "synthetic-pairs.toml")
    assert pairs.factor("configuration").levels["gris"] == "the table ends at 0 or pi (grey marks)" and pairs.factor("scenario").short == "sc"
    assert any(a.startswith("Subj. 1 = Subject 1") for a in pairs.abbreviations())


def test_a_study_file_based_on_another(tmp_path):
    s = st.load(st.PIPELINES / "synthetic-walking.toml")
    walking = st.load(st.PIPELINES / "walking-2020.toml")
    assert s.name == "synthetic-walking" and s.factors == walking.factors
    assert [a.id for a in st.questions(s, {}).analyses] == [a.id for a in walking.config.analyses]
    assert st.questions(s, {}).study == "synthetic-walking"
    (tmp_path / "a.toml").write_text('based_on = "b.toml"\n')
    (tmp_path / "b.toml").write_text('based_on = "a.toml"\n')
    with pytest.raises(InputError, match="based_on makes a cycle"):
        st.load(tmp_path / "a.toml")


def test_synth_writes_a_study_file(tmp_path):
    from cobot_analysis.stages.data import synth_walking

    synth_walking(tmp_path, subjects=1, repetitions=1, conditions=["E4015"], jobs=1)
    s = st.load(tmp_path / "synth-walking" / "study.toml")
    assert s.name == "synthetic-walking" and [a.id for a in s.config.analyses] == [a.id for a in st.load(
        st.PIPELINES / "walking-2020.toml").config.analyses]


def test_default_questions_describe_by_each_factor_and_test_what_the_design_allows():
    rng = np.random.default_rng(1)
    rows = [{"comparison": "individual-mean", "kind": "trial", "entity": "walker", "subject": s, "condition": c,
             "d_xy": rng.gamma(2, 0.05)} for s in ("A", "B", "C") for c in ("x", "y") for _ in range(3)]
    rows += [{"comparison": "individual-mean", "kind": "trial", "entity": "walker", "subject": "D", "condition": "z",
              "d_xy": 0.1}]
    dist = pd.DataFrame(rows)
    s = st.Study("lab", "lab", [], [st.Factor("subject", "participant"), st.Factor("condition", "floor")], None)
    qs = st.default_analyses(s, {"distances": dist, "trials": None})
    assert [(a.id, a.group, a.test) for a in qs] == [("D0", None, "describe"), ("D1", "subject", "describe"),
                                                    ("D1-test", "subject", "kruskal"), ("D2", "condition", "describe"),
                                                    ("D2-test", "condition", "kruskal")]
    assert st.questions(s, {"distances": dist}).analyses == qs
    one = dist[dist["subject"].eq("D")]  # a single level: described, not tested
    two = pd.concat([one, one.assign(subject="E")])  # two subjects of one value each: described, not tested
    assert [a.id for a in st.default_analyses(s, {"distances": two})] == ["D0", "D1"]


def test_describe_of_a_numeric_column_is_its_distribution_not_value_counts():
    a = Analysis(id="FW", description="", source="distances", value="d_xy", test="describe", family="d", group="g")
    df = pd.DataFrame({"g": ["a", "a", "b"], "d_xy": [0.7538013844222866, 0.5, 0.25]})
    row = analyses._run_one(a, df, {"a": df["d_xy"][:2].to_numpy(), "b": df["d_xy"][2:].to_numpy()}, 0.05)
    assert row["summary"] == "a: 0.627 [0.563, 0.69], 0.627 +- 0.179; b: 0.25 (n = 1)"  # one value: no spread
    codes = analyses._run_one(a, df, {"a": np.array([1, 1, 3]), "b": np.array([2])}, 0.05)
    assert codes["summary"] == "a: 1: 2, 3: 1; b: 2: 1"  # integer codes (scenarios): counts


def test_refused_trials_summary_names_the_raw_file_and_gives_the_remedy_once():
    def exc(t):
        return InputError(f"trial {t}: nobody walks", path="ws/import/markers.parquet", remedy="leave it out of the protocol")

    r = [refusals.Refused.of("t1", "/lab/a.c3d", exc("t1")), refusals.Refused.of("t2", "/lab/b.csv", exc("t2"))]
    assert r[0].reason == "nobody walks" and r[0].remedy == "leave it out of the protocol"
    lines = refusals.summary(r, 5, "preprocess")
    assert lines[0].startswith("preprocess: 2 of 5 trials refused and left out, the other 3 went on (exit code 3")
    assert lines[1:] == ["  t1 (a.c3d): nobody walks", "  t2 (b.csv): nobody walks", "  remedy: leave it out of the protocol"]
    err = str(refusals.error(r, 2, "preprocess"))
    assert err.count("leave it out") == 1 and "markers.parquet" not in err and "a.c3d" in err and len(err) < 200
    assert "| t1 | `a.c3d` | nobody walks | leave it out of the protocol |" in refusals.markdown(r, 5)


def trajectory_set(starts: list[tuple[float, float]], condition="walk"):
    from cobot_analysis.compare import TrajectorySet

    s = np.linspace(0, 1, 20)
    x = np.array([x0 + 3 * s for x0, _ in starts])
    y = np.array([y0 + 0 * s for _, y0 in starts])
    meta = pd.DataFrame({"study": "lab", "trial": [f"t{i}" for i in range(len(starts))], "kind": "trial", "n_trials": 1,
                         "condition": condition, "entity": "walker"})
    return TrajectorySet(meta, x, y, np.zeros_like(x), np.zeros_like(x))


def test_means_of_trials_in_different_frames_are_flagged_and_not_compared():
    from cobot_analysis import averaging
    from cobot_analysis.compare import TrajectorySet, comparable_means, excluded_means, individual_vs_mean

    one_lab = trajectory_set([(0, 0), (0.1, 0.1), (-0.1, 0)])
    labs = trajectory_set([(0, 0), (4, 1), (-2, 3)], condition="far")
    assert averaging.spread_warnings(one_lab, ["condition", "entity"]) == []
    assert averaging.spread_warnings(labs, ["condition"], max_spread=5.0) == []  # a stated limit, --max-spread
    assert set(averaging.mean_trajectories(labs, ["condition", "entity"], max_spread=5.0)["quality"]) == {"ok"}
    (warning,) = averaging.spread_warnings(labs, ["condition", "entity"])
    assert "far|walker of 3 trajectories: starts spread" in warning and "> 1 m" in warning
    sp = averaging.frame_spread(labs, ["condition"])
    assert sp["start_spread"].iloc[0] == pytest.approx(np.hypot(4, 0), rel=1e-9)  # median start (0, 1)
    both = TrajectorySet(pd.concat([one_lab.meta, labs.meta.assign(trial=["u0", "u1", "u2"])], ignore_index=True),
                         *(np.vstack([getattr(one_lab, k), getattr(labs, k)]) for k in ("x", "y", "theta", "gamma")))
    single = trajectory_set([(0, 0)], condition="alone")
    allt = TrajectorySet(pd.concat([both.meta, single.meta.assign(trial="v0")], ignore_index=True),
                         *(np.vstack([getattr(both, k), getattr(single, k)]) for k in ("x", "y", "theta", "gamma")))
    means = averaging.mean_trajectories(allt, ["condition", "entity"])
    first = means[means["sample"].eq(0)].set_index("condition")
    assert first.loc["far", "quality"] == "frames_differ" and first.loc["walk", "quality"] == "ok"
    meta = first.reset_index()
    assert list(comparable_means(meta)) == [c == "walk" for c in meta["condition"]]
    mset = TrajectorySet(first.reset_index(), *(np.vstack([means[means["trial"].eq(t)][k].to_numpy() for t in first["trial"]])
                                                for k in ("x", "y", "theta", "gamma")))
    d = individual_vs_mean(allt, mset, ["condition", "entity"])
    assert sorted(d["trial"]) == ["t0", "t1", "t2"]  # neither the far-apart labs nor the mean of one trial
    assert excluded_means(allt, mset, ["condition", "entity"]) == {"single": 1, "frames": 3}


def test_default_report_questions_run(tmp_path):
    """The default questions go through the statistics like declared ones."""
    rng = np.random.default_rng(2)
    dist = pd.DataFrame([{"comparison": "individual-mean", "kind": "trial", "entity": "walker", "subject": s,
                          "condition": "walk", "d_xy": rng.gamma(2, 0.05)} for s in ("A", "B") for _ in range(4)])
    from cobot_analysis.stats.sources import SOURCE_COLUMNS, distances_source

    full = dist.assign(**{c: np.nan for c in ("study", "global_distance", "b_scenario", "scenario") if c not in dist})
    sources = {k: pd.DataFrame(columns=v) for k, v in SOURCE_COLUMNS.items()}
    sources["distances"] = distances_source(full)
    s = st.Study("lab", "lab", [], [], None)
    cfg = st.questions(s, sources)
    assert isinstance(cfg, StudyConfig) and [a.id for a in cfg.analyses] == ["D0", "D1", "D1-test"]
    table = analyses.run(cfg, sources)
    assert table.loc[table["id"].str.startswith("D1-test"), "status"].eq("ok").all()


def test_progress_prints_plain_lines_when_the_output_is_not_a_terminal(monkeypatch):
    import io
    import time

    from rich.console import Console

    from cobot_analysis import console as c

    buffer = io.StringIO()
    monkeypatch.setattr(c, "console", Console(file=buffer, force_terminal=False, width=200))
    monkeypatch.setattr(c, "PLAIN_EVERY", 0.0)
    monkeypatch.setattr(c, "_level", 1)  # normal verbosity (an earlier -q run may have lowered it)
    assert list(c.track(range(3), "IOC all")) == [0, 1, 2]
    lines = buffer.getvalue().splitlines()
    assert [line.split(",")[0] for line in lines] == ["IOC all: 0/3 (0 %)", "IOC all: 1/3 (33 %)", "IOC all: 2/3 (67 %)",
                                                      "IOC all: 3/3 (100 %)"]
    monkeypatch.setattr(c, "PLAIN_EVERY", 3600.0)  # work quicker than PLAIN_EVERY says nothing (before: its start and end)
    buffer.truncate(0), buffer.seek(0)
    list(c.track(range(50), "preprocess"))
    assert buffer.getvalue() == ""
    monkeypatch.setattr(c, "PLAIN_EVERY", 0.05)  # work that has run PLAIN_EVERY: its lines, the end's included

    def slow(n):
        for i in range(n):
            time.sleep(0.06)
            yield i

    buffer.truncate(0), buffer.seek(0)
    list(c.track(slow(2), "fit", total=2))
    assert [line.split(",")[0] for line in buffer.getvalue().splitlines()] == ["fit: 1/2 (50 %)", "fit: 2/2 (100 %)"]
    # a search's budget (fit-ioc's evaluations): counted up to a most, no time left foreseen; its end as a count
    buffer.truncate(0), buffer.seek(0)
    with c.progress() as bar:
        task = bar.add_task("IOC all", total=2000, status="", budget=True)
        for n in (1, 2):
            time.sleep(0.06)
            bar.update(task, completed=n, status=f"D = 0.{n}")
        bar.update(task, total=2, completed=2)
    lines = buffer.getvalue().splitlines()
    assert lines[0].startswith("IOC all: 1 of at most 2000, 0:00:00; D = 0.1") and "left" not in buffer.getvalue()
    assert lines[-1].startswith("IOC all: 2/2 (100 %)")
