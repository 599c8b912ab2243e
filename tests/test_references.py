"""The package, docs/ and README.md refer only to documents that exist in the repository.

Users get the repository, not the project's private specification: a citation of METHODS.md,
SOLVER-NOTES.md or anything under ../shared/ other than the datasets (their documented,
overridable default location) is an error, as is a link or a ``docs/NAME.md`` to a missing file.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: documents outside the repository (the datasets' default location ../shared/datasets is allowed)
OUTSIDE = re.compile(r"METHODS\.md|\bMETHODS(?= (?:sec\.|section|\d))|SOLVER-NOTES|shared/spec|\.\./shared/(?!datasets\b)\S+")
DOCS_MD = re.compile(r"(?<![\w.-])docs/([\w.-]+\.md)")
MD_LINK = re.compile(r"\]\(([^)\s]+)\)")


def scanned() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "cobot_analysis").rglob("*.py"))]


def slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def broken_references(path: Path) -> list[str]:
    """``file:line: reference`` for every reference of ``path`` to a document that does not exist."""
    text = path.read_text(encoding="utf-8")
    anchors = {slug(m) for m in re.findall(r"^#+ (.+)$", text, re.M)} if path.suffix == ".md" else set()
    found = []
    for n, line in enumerate(text.splitlines(), 1):
        refs = [m.group(0) for m in OUTSIDE.finditer(line)]
        refs += [f"docs/{m}" for m in DOCS_MD.findall(line) if not (ROOT / "docs" / m).is_file()]
        if path.suffix == ".md":
            for target in MD_LINK.findall(line):
                if target.startswith("#"):
                    if target[1:] not in anchors:
                        refs.append(target)
                elif target.endswith(".md") and "://" not in target and not (path.parent / target).is_file():
                    refs.append(target)
        found += [f"{path.relative_to(ROOT)}:{n}: {ref}" for ref in refs]
    return found


def test_no_reference_to_documents_outside_the_repository():
    files = scanned()
    assert len(files) > 50 and ROOT / "docs" / "methods.md" in files
    broken = [ref for path in files for ref in broken_references(path)]
    assert not broken, "references to documents that are not in the repository:\n" + "\n".join(broken)


def test_the_checker_finds_what_it_must(tmp_path):
    bad = tmp_path / "bad.md"
    bad.write_text("# Title\nSee METHODS.md sec. 5.5, METHODS 5.6 and ../shared/spec/SOLVER-NOTES.md.\n"
                   "Data: ../shared/datasets/walking-2020 (allowed). [x](#title) [y](#nowhere) [z](missing.md)\n"
                   "docs/methods.md exists, docs/nothing.md does not.\n")
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        (tmp_path / "docs").mkdir()
        (tmp_path / "docs" / "methods.md").write_text("# Methods\n")
        refs = [r.split(": ", 1)[1] for r in broken_references(bad)]
    finally:
        ROOT = saved
    assert refs == ["METHODS.md", "METHODS", "../shared/spec/SOLVER-NOTES.md.", "#nowhere", "missing.md", "docs/nothing.md"]
