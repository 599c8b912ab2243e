"""The study file: what a study is and what to test in it (docs/statistics.md).

One TOML file names the study, its entities, its grouping factors (a metadata column each, with a
label, a meaning, an abbreviation and the meaning of its levels) and the questions to test (the
``[[analysis]]`` tables of ``stats.config``). ``report``, ``stats`` and the figures read every label
from it, so they work for any study so described. Without questions, ``default_analyses`` gives a
descriptive set (distances and travel times by each factor, and the tests the design allows).

Where the file is found (``locate``), first match wins:

1. the file given on the command line (``stats --config``, ``report --study-file``);
2. ``study.toml`` beside the protocol imported into the workspace (``import/manifest.json``);
3. ``pipelines/<study>.toml`` in the current directory or the source tree, ``<study>`` being the
   data's ``study`` column (how the published datasets, imported without a protocol, find theirs);
4. none: the study is described from the data alone (factor labels from ``COLUMNS``), and the
   report says so.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from cobot_analysis.errors import InputError
from cobot_analysis.schema import as_text

STUDY_FILE = "study.toml"
PIPELINES = Path(__file__).resolve().parents[1] / "pipelines"
ENTITIES = ("walker", "subject1", "subject2", "table")
#: top-level keys of a study file (``analysis`` and ``factor`` are arrays of tables).
KEYS = ("study", "title", "entities", "alpha", "based_on", "factor", "analysis")
FACTOR_KEYS = ("column", "label", "meaning", "short", "levels")


@dataclass
class Factor:
    """A grouping factor: a metadata column with its label, meaning, abbreviation and level meanings."""

    column: str
    label: str
    meaning: str = ""
    short: str = ""  # prefix of a level on crowded axes: "sc" -> "sc1"
    levels: dict[str, str] = field(default_factory=dict)  # level (as text) -> meaning

    def level(self, value, short: bool = False) -> str:
        """A level as figures show it: ``sc1`` (short) or ``scenario 1`` / the level itself."""
        text = as_text(value)
        if short and self.short:
            return f"{self.short}{text}"
        return f"{self.label} {text}" if text.replace(".", "").replace("-", "").isdigit() else text

    def legend(self) -> str:
        """One line explaining the factor and its levels (for captions and the abbreviation list)."""
        lv = "; ".join(f"{(self.short + k) if self.short else k} = {v}" for k, v in self.levels.items())
        return f"{self.label}" + (f" ({self.meaning})" if self.meaning else "") + (f": {lv}" if lv else "")


#: labels of the metadata columns any study may use as factors; a study file overrides them.
COLUMNS = {
    "subject": Factor("subject", "subject", "the person recorded"),
    "pair": Factor("pair", "pair", "the two subjects carrying together"),
    "condition": Factor("condition", "condition", "the start condition or goal of the trial"),
    "direction": Factor("direction", "direction", "carriage to the goal or back",
                        levels={"forward": "to the goal", "return": "back to the start"}),
    "scenario": Factor("scenario", "scenario", "who knows the goal", short="sc"),
    "configuration": Factor("configuration", "end configuration", "family of the table's end orientations"),
    "end_orientation": Factor("end_orientation", "end orientation", "the table's orientation at the goal, the direction TAB1 -> TAB2 (rad)"),
    "repetition": Factor("repetition", "repetition", "repetition number within the condition", short="rep"),
    "entity": Factor("entity", "entity", "who or what moves",
                     levels={"walker": "the walking subject", "subject1": "Subject 1", "subject2": "Subject 2",
                             "table": "the carried table"}),
    "start_orientation": Factor("start_orientation", "start orientation", "heading at the start"),
    "distance_class": Factor("distance_class", "global distance", "start-goal distance class"),
}
#: how figures name the entities (one meaning per abbreviation: "Subj. 1" is always Subject 1).
ENTITY_SHORT = {"walker": "walker", "subject1": "Subj. 1", "subject2": "Subj. 2", "table": "table"}




@dataclass
class Study:
    name: str
    title: str
    entities: list[str]
    factors: list[Factor]
    config: object | None  # stats.config.StudyConfig of the declared questions (None: none declared)
    path: Path | None = None
    alpha: float = 0.05

    @property
    def declared(self) -> bool:
        """Whether the questions come from the study file (else: the default descriptive set)."""
        return self.config is not None and bool(self.config.analyses)

    def factor(self, column: str) -> Factor:
        for f in self.factors:
            if f.column == column:
                return f
        return COLUMNS.get(column, Factor(column, column.replace("_", " ")))

    def label(self, column: str) -> str:
        return self.factor(column).label

    def questions(self, source: str, value: str | None = None, group: str | None = None, comparison: str | None = None) -> list[str]:
        """Ids of the declared questions on ``source`` (and ``value``, ``group``, filter ``comparison``)."""
        if self.config is None:
            return []
        out = []
        for a in self.config.analyses:
            if a.source != source or (value and a.value != value) or (group and a.group != group):
                continue
            if comparison and a.filter.get("comparison") not in (None, comparison):
                continue
            out.append(a.id)
        return out

    def cite(self, text: str, **what) -> str:
        """``text`` preceded by the ids of the questions it shows ("W1.1: ..."), when any."""
        ids = self.questions(**what)
        return f"{' / '.join(ids[:3])}: {text}" if ids else text

    def abbreviations(self) -> list[str]:
        """Every abbreviation the figures of this study use, with its one meaning."""
        out = [f"{s} = {ENTITY_SHORT_MEANING[e]}" for e, s in ENTITY_SHORT.items() if s != e and e in self.entities]
        if any(f.column == "direction" for f in self.factors):
            out += ["fwd = forward carriage (to the goal)", "ret = return carriage (back to the start)"]
        for f in self.factors:
            if f.short or f.levels:
                out.append(f.legend())
        return out


ENTITY_SHORT_MEANING = {"walker": "the walking subject", "subject1": "Subject 1", "subject2": "Subject 2", "table": "the table"}


def _factor(raw, path: Path, n: int) -> Factor:
    if not isinstance(raw, dict) or not isinstance(raw.get("column"), str):
        raise InputError(f"factor #{n} needs column = \"<metadata column>\"", path=path,
                         remedy='declare each factor as [[factor]] with column = "subject" (docs/statistics.md)')
    unknown = sorted(set(raw) - set(FACTOR_KEYS))
    if unknown:
        raise InputError(f"factor {raw['column']}: unknown key(s) {unknown}", path=path, remedy=f"use only {', '.join(FACTOR_KEYS)}")
    base = COLUMNS.get(raw["column"], Factor(raw["column"], raw["column"].replace("_", " ")))
    levels = raw.get("levels", base.levels)
    if not isinstance(levels, dict):
        raise InputError(f"factor {raw['column']}: levels must be a table level = \"meaning\"", path=path,
                         remedy='e.g. levels = { N = "facing north" }')
    for key in ("label", "meaning", "short"):
        if key in raw and not isinstance(raw[key], str):
            raise InputError(f"factor {raw['column']}: {key} must be a string", path=path, remedy=f'e.g. {key} = "..."')
    meaning = raw.get("meaning", "" if "label" in raw else base.meaning)  # a relabelled column is another factor
    return Factor(raw["column"], raw.get("label", base.label), meaning, raw.get("short", base.short),
                  {str(k): str(v) for k, v in levels.items()})


def parse(data: dict, path: Path | None = None) -> Study:
    """Validate a parsed study file (module doc, docs/statistics.md) -> ``Study``."""
    from cobot_analysis.stats import config as cfg

    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise InputError(f"unknown key(s) {unknown}", path=path, remedy=f"use only {', '.join(KEYS)} (docs/statistics.md)")
    name = data.get("study", "")
    title = data.get("title", "")
    if not isinstance(name, str) or not isinstance(title, str):
        raise InputError("study and title must be strings", path=path, remedy='e.g. study = "lab-gait"')
    entities = data.get("entities", [])
    if not isinstance(entities, list) or not set(entities) <= set(ENTITIES):
        raise InputError(f"entities must be a list of {', '.join(ENTITIES)}, not {entities!r}", path=path,
                         remedy='e.g. entities = ["walker"]')
    raw_factors = data.get("factor", [])
    if not isinstance(raw_factors, list):
        raise InputError("factor must be an array of tables", path=path, remedy="declare each factor as [[factor]]")
    factors = [_factor(raw, path, n) for n, raw in enumerate(raw_factors, 1)]
    seen: dict[str, str] = {}
    for f in factors:
        if f.column in [g.column for g in factors if g is not f]:
            raise InputError(f"factor {f.column} declared twice", path=path, remedy="declare each column once")
        if f.short:  # one meaning per abbreviation in every report
            clash = seen.get(f.short) or next((e for e, s in ENTITY_SHORT.items() if s == f.short), None)
            if clash:
                raise InputError(f"factor {f.column}: abbreviation {f.short!r} already means {clash}", path=path,
                                 remedy="give each factor its own short")
            seen[f.short] = f.column
    config = cfg.parse(data, path, require=False) if data.get("analysis") else None
    alpha = config.alpha if config else cfg.parse({**data, "analysis": []}, path, require=False).alpha
    return Study(name, title or name, list(entities), factors, config, path, alpha)


def load(path: str | Path, _seen: tuple = ()) -> Study:
    """Read and validate a study file; ``based_on = "other.toml"`` (relative to it) takes the
    entities, factors, alpha and questions of that file unless this one declares them."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise InputError("study file not found", path=path, remedy="pass the study's TOML file (docs/statistics.md)") from None
    except UnicodeDecodeError:
        raise InputError("not a text file (a study file is UTF-8 TOML)", path=path,
                         remedy="pass the study's TOML file (docs/statistics.md)") from None
    except OSError as exc:
        raise InputError(f"cannot read the study file ({exc.strerror or type(exc).__name__})", path=path,
                         remedy="pass the study's TOML file (docs/statistics.md)") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML ({exc})", path=path, remedy="fix the syntax") from None
    base = data.get("based_on")
    if base is not None:
        if not isinstance(base, str):
            raise InputError("based_on must be the path of another study file", path=path, remedy='e.g. based_on = "walking-2020.toml"')
        other = (path.parent / base).resolve()
        if other in _seen:
            raise InputError(f"based_on makes a cycle through {other.name}", path=path, remedy="remove one based_on")
        parent = load(other, (*_seen, path.resolve()))
        own = parse({k: v for k, v in data.items() if k != "based_on"}, path)
        return Study(own.name or parent.name, data.get("title") or parent.title,
                     own.entities or parent.entities, own.factors or parent.factors,
                     own.config if own.declared else parent.config, path,
                     own.alpha if "alpha" in data else parent.alpha)
    return parse(data, path)


def protocol_of(out: Path) -> Path | None:
    """The protocol imported into workspace ``out`` (from ``import/manifest.json``), if any."""
    manifest = Path(out) / "import" / "manifest.json"
    try:
        inputs = json.loads(manifest.read_text()).get("inputs", [])
    except (OSError, ValueError):
        return None
    for item in inputs:
        p = Path(item.get("path", ""))
        if p.suffix.lower() in (".yaml", ".yml"):
            return p
    return None


def locate(out: Path, study_name: str, given: Path | None = None) -> Path | None:
    """The study file of workspace ``out`` whose data are of study ``study_name`` (module doc), or None."""
    if given is not None:
        return Path(given)
    protocol = protocol_of(out)
    if protocol is not None and (protocol.parent / STUDY_FILE).is_file():
        return protocol.parent / STUDY_FILE
    for base in (Path.cwd() / "pipelines", PIPELINES):
        if (base / f"{study_name}.toml").is_file():
            return base / f"{study_name}.toml"
    return None


def resolve(out: Path, study_name: str, given: Path | None = None) -> Study:
    """The workspace's study: its study file (``locate``), checked against the data's study name,
    or a description from the data alone (no factors declared, no questions)."""
    path = locate(out, study_name, given)
    if path is None:
        return Study(study_name, study_name, [], [], None, None)
    study = load(path)
    if study.name and study.name != study_name:
        raise InputError(f"study file of study {study.name!r}, but the trajectories are of study {study_name!r}", path=path,
                         remedy=f'set study = "{study_name}" in it, or pass the study file of the data (stats --config, report --study-file)')
    study.name = study.name or study_name
    return study


def data_factors(study: Study, df, exclude=("entity",)) -> list[Factor]:
    """The factors to show for table ``df``: the declared ones present in it, else every metadata
    column of ``COLUMNS`` present; only those with at least two levels."""
    cols = [f.column for f in study.factors] or [c for c in COLUMNS if c not in ("end_orientation",)]
    out = []
    for c in cols:
        if c in exclude or c not in df.columns:
            continue
        if df[c].dropna().nunique() >= 2:
            out.append(study.factor(c))
    return out


def default_analyses(study: Study, sources: dict) -> list:
    """The descriptive questions of a study without declared ones: per factor (``data_factors`` of
    the individual-vs-mean distances), d_xy described, and Kruskal-Wallis across its levels per
    entity where at least two levels have two values; travel time described per factor."""
    from cobot_analysis.stats.config import Analysis
    from cobot_analysis.stats.tests import MIN_SIZE

    out = []
    dist = sources.get("distances")
    if dist is not None and len(dist):
        ind = dist[dist["comparison"].eq("individual-mean") & dist["kind"].eq("trial")]
        out.append(Analysis(id="D0", description="Individual vs mean d_xy, all trials", source="distances",
                            filter={"comparison": "individual-mean", "kind": "trial"}, value="d_xy", test="describe",
                            family="descriptive", per=["entity"]))
        for n, f in enumerate(data_factors(study, ind), 1):
            base = dict(source="distances", filter={"comparison": "individual-mean", "kind": "trial"}, value="d_xy",
                        group=f.column, per=["entity"], family="descriptive")
            out.append(Analysis(id=f"D{n}", description=f"Individual vs mean d_xy by {f.label}", test="describe", **base))
            sizes = ind.groupby(["entity", f.column])["d_xy"].count()
            if (sizes >= MIN_SIZE["kruskal"]).groupby(level=0).sum().max() >= 2:
                out.append(Analysis(id=f"D{n}-test", description=f"Individual vs mean d_xy across {f.label} levels (Kruskal-Wallis)",
                                    test="kruskal", **base))
    trials = sources.get("trials")
    if trials is not None and len(trials) and trials["travel_time"].notna().any():
        out.append(Analysis(id="T0", description="Travel time, all trajectories", source="trials", value="travel_time",
                            test="describe", family="descriptive", per=["entity"]))
        for n, f in enumerate(data_factors(study, trials), 1):
            out.append(Analysis(id=f"T{n}", description=f"Travel time by {f.label}", source="trials", value="travel_time",
                                group=f.column, test="describe", family="descriptive", per=["entity"]))
    return out


def questions(study: Study, sources: dict):
    """The ``StudyConfig`` to run: the declared questions, else ``default_analyses``."""
    from cobot_analysis.stats.config import StudyConfig

    if study.declared:
        return StudyConfig(study.name, study.config.alpha, study.config.analyses, study.path)
    return StudyConfig(study.name, study.alpha, default_analyses(study, sources), study.path)


def write(path: Path, study: str, title: str, entities: list[str], factors: list[Factor], questions: str = "",
          header: str = "") -> Path:
    """Write a study file (``synth`` writes one beside each protocol); ``questions`` is TOML text of
    ``[[analysis]]`` tables (empty: the default descriptive report). The file is loaded back to check it."""
    def q(s: str) -> str:
        return json.dumps(s, ensure_ascii=False)

    lines = [f"# {line}" for line in header.splitlines()] + [
        f"study = {q(study)}", f"title = {q(title)}", f"entities = [{', '.join(q(e) for e in entities)}]", "alpha = 0.05", ""]
    for f in factors:
        lines += ["[[factor]]", f"column = {q(f.column)}", f"label = {q(f.label)}"]
        if f.meaning:
            lines.append(f"meaning = {q(f.meaning)}")
        if f.short:
            lines.append(f"short = {q(f.short)}")
        if f.levels:
            lines.append("levels = { " + ", ".join(f"{q(k)} = {q(v)}" for k, v in f.levels.items()) + " }")
        lines.append("")
    path = Path(path)
    path.write_text("\n".join(lines) + ("\n" + questions.strip() + "\n" if questions.strip() else ""))
    load(path)
    return path


def write_synthetic(directory: Path, study: str, template: str) -> Path:
    """``synth walking`` / ``synth pairs``: the study file beside the protocol, from the study file of
    the design the synthetic study imitates (``pipelines/<template>.toml``)."""
    header = (f"Study file of the synthetic study {study}, written by `cobot-analysis synth`: the factors and\n"
              f"questions of {template} (docs/statistics.md). `report` and `stats` find it beside protocol.yaml.")
    return derive(PIPELINES / f"{template}.toml", Path(directory) / STUDY_FILE, study, header,
                  title=None if study == template else f"Synthetic study ({template} design)")


def derive(template: Path, dest: Path, study: str, header: str = "", title: str | None = None) -> Path:
    """Write the study file ``dest`` for study ``study`` from the study file ``template`` (its factors
    and questions, e.g. the synthetic walking study from walking-2020's), ``header`` as comments on top."""
    import re

    text = Path(template).read_text(encoding="utf-8")
    text, n = re.subn(r'(?m)^study\s*=.*$', f"study = {json.dumps(study)}", text, count=1)
    if not n:
        text = f"study = {json.dumps(study)}\n" + text
    if title is not None:
        text = re.sub(r'(?m)^title\s*=.*$', f"title = {json.dumps(title)}", text, count=1)
    dest = Path(dest)
    dest.write_text("".join(f"# {line}\n" for line in header.splitlines()) + text, encoding="utf-8")
    load(dest)
    return dest
