"""The protocol file of a synthetic study, every key preceded by a comment that explains it.

``write_protocol`` lets ``io.protocol.save_protocol`` write the CSV tables (and a plain YAML),
then rewrites ``protocol.yaml`` key by key with comments, always with ``entities`` and
``marker_map`` (empty mappings included), and checks that the commented file loads to the same
document. The keys are documented in docs/protocol.md.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pandas as pd

from cobot_analysis.io.protocol import save_protocol

#: order of the keys in a written protocol.
KEYS = ("study", "rate", "entities", "marker_map", "subjects", "pairs", "trials")
WIDTH = 100


def _comment(text: str) -> list[str]:
    return ["# " + line for line in textwrap.wrap(text, WIDTH - 2, break_on_hyphens=False)]


def _value(key: str, value) -> str:
    import yaml

    if isinstance(value, dict) and not value:
        return f"{key}: {{}}"
    return yaml.safe_dump({key: value}, sort_keys=False, default_flow_style=False, allow_unicode=True).rstrip()


def write_protocol(path, study: str, trials: pd.DataFrame, *, header: str, notes: dict[str, str], rate: float,
                   entities: dict[str, str] | None = None, marker_map: dict[str, str] | None = None,
                   subjects: pd.DataFrame | None = None, pairs: pd.DataFrame | None = None) -> Path:
    """Write ``protocol.yaml`` (and its CSV tables) with ``header`` on top and ``notes[key]`` above each key."""
    import yaml

    path = save_protocol(path, study, trials, subjects=subjects, pairs=pairs, rate=rate)
    plain = yaml.safe_load(path.read_text())
    doc = {"study": plain["study"], "rate": plain["rate"], "entities": dict(entities or {}),
           "marker_map": dict(marker_map or {})}
    doc.update({k: plain[k] for k in ("subjects", "pairs", "trials") if k in plain})
    lines = _comment(header)
    for key in KEYS:
        if key in doc:
            lines += [""] + (_comment(notes[key]) if key in notes else []) + [_value(key, doc[key])]
    text = "\n".join(lines) + "\n"
    if yaml.safe_load(text) != doc:  # the comments must not change what the file says
        raise RuntimeError(f"commented protocol of {study} does not load back to its document")
    path.write_text(text)
    return path
