"""Input checks of `compare --against` and `stats`: a table matching no mean, a filter value
matching no row, a configuration of another study, values of the wrong type, a binary file."""

from __future__ import annotations

import sys
from pathlib import Path

import pandas as pd
import pytest

from cobot_analysis.errors import InputError
from cobot_analysis.schema import TRAJECTORIES, read_table, write_table
from cobot_analysis.stats.analyses import STATS

sys.path.insert(0, str(Path(__file__).parent))
from cobot_analysis.synth.tables import walking_table  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def ws(tmp_path_factory):
    """A small synthetic walking study: trajectories, means and distances (4 conditions)."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("walk") / "ws"
    write_table(walking_table(seed=3, n_subjects=4, n_conditions=4, n_trials=2, missing_theta=0.0),
                ws / "preprocess" / "trajectories.parquet", TRAJECTORIES)
    for args in (["average"], ["compare"]):
        assert run(["-q", *args, "--out", str(ws)]) == 0
    return ws


def _line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return " ".join(lines[0].split())


def _model(ws, tmp_path, **changes) -> Path:
    """The means shifted by 5 cm as a 'model' table, with some columns changed."""
    means = pd.read_parquet(ws / "average" / "means.parquet")
    model = means.assign(x=means["x"] + 0.05, kind="model", trial="model:" + means["trial"])
    for col, fn in changes.items():
        model[col] = fn(model)
    model.to_parquet(tmp_path / "model.parquet")
    return tmp_path / "model.parquet"


# ---- compare --against --------------------------------------------------------------------------------
def test_against_table_matching_no_mean_is_refused(ws, tmp_path, cli):
    before = (ws / "compare" / "manifest.json").read_text()
    path = _model(ws, tmp_path, study=lambda m: "walking-2020")
    code, _, err = cli("compare", "--out", ws, "--against", path, "--comparison", "model")
    assert code == 2 and _line(err) == (f"error: {path}: none of its 4 trajectories matches a mean on study, condition, "
                                        "entity: study walking-2020 (means: synthetic-walking); compare with the means of the "
                                        "same study and grouping (--by, --means), or fix those columns")
    assert (ws / "compare" / "manifest.json").read_text() == before  # the previous output is left as it was


def test_against_table_matching_some_means_is_warned(ws, tmp_path, cli):
    import shutil

    ws = shutil.copytree(ws, tmp_path / "ws")  # the module's workspace stays as it was
    first = sorted(pd.read_parquet(ws / "average" / "means.parquet")["condition"].unique())[:2]
    path = _model(ws, tmp_path, condition=lambda m: m["condition"].where(~m["condition"].isin(first), "X9999"))
    code, _, err = cli("compare", "--out", ws, "--against", path, "--comparison", "model", "--force")
    assert code == 0, err
    assert (f"{path}: 2 of its 4 trajectories match no mean on study, condition, entity and are not compared: condition "
            "X9999 (means:") in " ".join(err.split())
    d = pd.read_parquet(ws / "compare" / "distances.parquet")
    model = d[d["comparison"].eq("model")]
    assert len(model) == 2 and model["d_xy"].round(9).eq(0.05).all() and not model["condition"].isin(first).any()


def test_against_table_of_a_model_that_spins_is_compared(ws, tmp_path, cli):
    """A model's path may turn any number of times: `generate --study walking-2020` at the fitted weights wrote paths
    that spin to theta -18.86 rad, beyond the 3 turns a measured heading is held to (schema.TURNS), and `make walking`
    stopped at `compare --against` on 'degrees?'. The generated table's theta is any finite number: compared."""
    import shutil

    import numpy as np

    ws = shutil.copytree(ws, tmp_path / "ws")
    path = _model(ws, tmp_path, theta=lambda m: m["theta"] - 8 * np.pi * m["sample"] / m["sample"].max())
    assert pd.read_parquet(path)["theta"].min() < -6 * np.pi
    code, _, err = cli("compare", "--out", ws, "--against", path, "--comparison", "model", "--force")
    assert code == 0, err
    model = pd.read_parquet(ws / "compare" / "distances.parquet").query("comparison == 'model'")
    assert len(model) == 4 and model["d_xy"].round(9).eq(0.05).all() and (model["d_theta"] > 1).all()


def test_a_spinning_model_table_is_a_trajectory_set_and_a_measured_one_is_refused():
    """In memory as from a file: a model's path may turn past schema.TURNS (api.trajectory_set checks model rows as
    generate's table), a measured heading that far is refused as degrees."""
    import numpy as np

    from cobot_analysis.api import trajectory_set

    walk = walking_table(n_subjects=2, n_conditions=1, n_trials=1)
    spun = walk.assign(theta=walk["theta"] - 8 * np.pi * walk["sample"] / walk["sample"].max())
    assert trajectory_set(spun.assign(kind="model")).theta.min() < -6 * np.pi
    with pytest.raises(InputError, match=r"column 'theta': 16 value\(s\) outside \[-18.8496, 18.8496\] rad .*degrees\?"):
        trajectory_set(spun)


# ---- stats --------------------------------------------------------------------------------------------
def _config(tmp_path, text: str) -> Path:
    cfg = tmp_path / "stats.toml"
    cfg.write_text(text)
    return cfg


QUESTION = '''
[[analysis]]
id = "T1"
source = "distances"
filter = {{ comparison = "{comparison}" }}
value = "d_xy"
group = "subject"
test = "kruskal"
family = "f"
'''


def test_filter_value_matching_nothing_names_the_value_and_the_values(ws, tmp_path, cli):
    cfg = _config(tmp_path, 'study = "synthetic-walking"\n' + QUESTION.format(comparison="individual-maen"))
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 0, err
    assert ("1 filter value(s) match no row, their analyses are skipped (stats.md says why): T1: comparison = "
            "'individual-maen' (values of distances.comparison: individual-mean)") in " ".join(err.split())
    row = read_table(ws / "stats" / "stats.parquet", STATS).set_index("id").loc["T1"]
    assert row["status"] == "skipped: no row with comparison = 'individual-maen' (values of comparison there: individual-mean)"
    cfg.write_text('study = "synthetic-walking"\n' + QUESTION.format(comparison="individual-mean"))
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 0 and "warning" not in err
    assert read_table(ws / "stats" / "stats.parquet", STATS).set_index("id").loc["T1", "status"] == "ok"


def test_configuration_of_another_study_is_refused(ws, cli):
    cfg = ROOT / "pipelines" / "pair-carriage-2022.toml"
    code, _, err = cli("stats", "--out", ws, "--config", cfg, "--force")
    assert code == 2 and _line(err) == (f"error: {cfg}: study file of study 'pair-carriage-2022', but the trajectories "
                                        "are of study 'synthetic-walking'; set study = \"synthetic-walking\" in it, or pass the "
                                        "study file of the data (stats --config, report --study-file)")


@pytest.mark.parametrize("text, message", [
    ('alpha = "five percent"\n' + QUESTION.format(comparison="individual-mean"),
     "alpha must be a number, not a string 'five percent'; e.g. alpha = 0.05"),
    (QUESTION.format(comparison="individual-mean") + 'min_size = "3"\n',
     "analysis T1: min_size must be a number, not a string '3'"),
    (QUESTION.format(comparison="individual-mean") + "per = 3\n",
     "analysis T1: per must be a column name or a list of them, not a number 3"),
    (QUESTION.format(comparison="individual-mean").replace('"individual-mean"', "{ a = 1 }"),
     "analysis T1: filter comparison must be a value or a list of values"),
    ("analysis = 3\n", "no [[analysis]] entries"),
])
def test_values_of_the_wrong_type_are_one_line(ws, tmp_path, cli, text, message):
    cfg = _config(tmp_path, text)
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 2 and _line(err).startswith(f"error: {cfg}: ") and message in _line(err)


def test_binary_configuration_is_one_line(ws, tmp_path, cli):
    cfg = tmp_path / "stats.toml"
    cfg.write_bytes(bytes(range(256)) * 4)
    code, _, err = cli("stats", "--out", ws, "--config", cfg)
    assert code == 2 and _line(err) == (f"error: {cfg}: not a text file (a study file is UTF-8 TOML); pass the study's "
                                        "TOML file (docs/statistics.md)")
    code, _, err = cli("stats", "--out", ws, "--config", tmp_path)
    assert code == 2 and "cannot read the study file" in _line(err)


def test_distances_without_rows_are_refused_unless_compare_said_why(ws, tmp_path, cli):
    """An empty distances table made every question 'skipped' and exited 0: an empty result, not an answer. A
    compare that left every trial out (e.g. means whose trials do not share a frame) records why in the file
    (``excluded``), and that table goes on (tests/test_realdata_study.py: three labs, nothing compared)."""
    from cobot_analysis.api import distances_table, statistics
    from cobot_analysis.compare import DISTANCES
    from cobot_analysis.schema import table_metadata

    assert table_metadata(ws / "compare" / "distances.parquet")["excluded"] == {"single": 0, "frames": 0}
    empty = tmp_path / "distances.parquet"
    write_table(read_table(ws / "compare" / "distances.parquet", DISTANCES).iloc[:0], empty, DISTANCES)
    message = ("the distances table has no rows and does not say why; re-run compare on these trajectories and their means "
               "(cobot-analysis compare --force with the same --out) and pass what it writes")
    code, _, err = cli("stats", "--out", ws, "--distances", empty, "--force")
    assert code == 2 and _line(err) == f"error: {empty}: {message}"
    with pytest.raises(InputError) as refused:
        statistics(ws / "preprocess" / "trajectories.parquet", read_table(empty, DISTANCES))
    assert str(refused.value) == message
    said = tmp_path / "none-compared.parquet"
    write_table(read_table(empty, DISTANCES), said, DISTANCES, excluded={"single": 0, "frames": 3})
    assert distances_table(said).empty
    code, _, err = cli("stats", "--out", ws, "--distances", said, "--force")
    assert code == 0, err
