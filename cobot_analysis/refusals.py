"""Bad trials named and skipped: what ``import`` and ``preprocess`` do when some trials are unusable.

Default (docs/protocol.md, "Bad trials"): the good trials go on; the refused ones are left out and
listed, each with its raw file, the reason and the remedy (given once when several trials share
it), in one short summary on the console, in the stage's ``results.md``, in its ``manifest.json``
(key ``refused``) and in the report. The command then exits with code 3 (``EXIT_CODE``: done, some
trials refused), also when the stage is skipped as up to date. ``--strict`` refuses the whole run
instead (exit code 2, nothing written), and so does a run where every trial is refused.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from cobot_analysis.errors import InputError

EXIT_CODE = 3


@dataclass
class Refused:
    """A refused trial: its id, its raw file, why (one line) and what to do."""

    trial: str
    path: Path
    reason: str
    remedy: str = ""
    text: str = ""  # the whole one-line error, as a run of this trial alone reports it

    @classmethod
    def of(cls, trial: str, path, exc: InputError) -> "Refused":
        """From the ``InputError`` of one trial: its message without the file or trial prefix."""
        reason = getattr(exc, "detail", None) or str(exc)
        for prefix in (f"trial {trial}: ", f"trial {trial} "):
            if reason.startswith(prefix):
                reason = reason[len(prefix):]
                break
        return cls(str(trial), Path(path) if path else Path(""), " ".join(reason.split()), getattr(exc, "remedy", "") or "",
                   str(exc))

    def record(self) -> dict:
        return {"trial": self.trial, "file": str(self.path), "reason": self.reason, "remedy": self.remedy}


def _shared_remedy(refused: list[Refused]) -> str | None:
    remedies = Counter(r.remedy for r in refused)
    return next(iter(remedies)) if len(remedies) == 1 else None


def summary(refused: list[Refused], n_trials: int, stage: str) -> list[str]:
    """The console summary: one head line, one line per refused trial (raw file and reason), the
    remedy once when the trials share it."""
    shared = _shared_remedy(refused)
    lines = [f"{stage}: {len(refused)} of {n_trials} trials refused and left out, the other {n_trials - len(refused)} went on "
             f"(exit code {EXIT_CODE}; --strict refuses the run instead):"]
    for r in refused:
        lines.append(f"  {r.trial} ({r.path.name or 'no file'}): {r.reason}" + ("" if shared is not None or not r.remedy else f"; {r.remedy}"))
    if shared:
        lines.append(f"  remedy: {shared}")
    return lines


def markdown(refused: list[Refused], n_trials: int) -> list[str]:
    """The ``results.md`` / report table of the refused trials."""
    if not refused:
        return []
    return [f"Refused and left out: {len(refused)} of {n_trials} trials (the others went on).", "",
            "| trial | raw file | reason | remedy |", "|---|---|---|---|",
            *[f"| {r.trial} | `{r.path.name}` | {r.reason.replace('|', '/')} | {r.remedy.replace('|', '/')} |" for r in refused], ""]


def error(refused: list[Refused], n_trials: int, stage: str) -> InputError:
    """The one error of a run that refuses (``--strict``, or every trial bad): the trials, their raw
    files and reasons, the remedy once."""
    if n_trials == 1 and len(refused) == 1:  # the error itself
        r = refused[0]
        return InputError(r.text) if r.text else InputError(r.reason, path=r.path, remedy=r.remedy or None)
    shared = _shared_remedy(refused)
    listing = "; ".join(f"{r.trial} ({r.path.name}): {r.reason}" + ("" if shared is not None or not r.remedy else f" ({r.remedy})")
                        for r in refused)
    what = "every trial refused" if len(refused) == n_trials else f"{len(refused)} of {n_trials} trials refused (--strict)"
    return InputError(f"{what}, nothing written: {listing}", remedy=shared or f"fix or leave out these trials, then re-run {stage}")


def exit_code(stage_dir: Path) -> int:
    """``EXIT_CODE`` when the stage's manifest lists refused trials, else 0 (the command's exit status)."""
    return EXIT_CODE if refused_trials(stage_dir) else 0


def refused_trials(stage_dir: Path) -> list[dict]:
    """The ``refused`` records of a stage's manifest (empty when none or no manifest)."""
    try:
        return list(json.loads((Path(stage_dir) / "manifest.json").read_text()).get("refused", []))
    except (OSError, ValueError):
        return []


def record(stage, refused: list[Refused], n_trials: int, name: str) -> None:
    """Put the refused trials in the manifest of ``stage`` (a ``workspace.Stage``) and print the summary."""
    from cobot_analysis.console import warn

    if refused:
        stage.manifest_extra["refused"] = records(refused)
        for line in summary(refused, n_trials, name):
            warn(line)


def records(refused: list[Refused]) -> list[dict]:
    """The manifest's ``refused`` list."""
    return [r.record() for r in refused]
