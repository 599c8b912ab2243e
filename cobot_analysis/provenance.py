"""Provenance of outputs: content hashes of files, the versions of the packages that made them and
the git commit of the source tree (recorded in every stage's manifest and in docs/results.md)."""

from __future__ import annotations

import hashlib
import platform
import subprocess
from pathlib import Path

_VERSIONED = ("numpy", "scipy", "pandas", "pyarrow", "casadi", "ezc3d", "rosbags", "statsmodels", "dask", "matplotlib")


def file_sha256(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def package_versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

    from cobot_analysis import __version__

    versions = {"python": platform.python_version(), "cobot_analysis": __version__}
    for name in _VERSIONED:
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            pass
    return versions


def git_commit() -> str | None:
    """Commit of the source tree the package runs from, with '-dirty' if it has local changes."""
    src = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=src, capture_output=True, text=True, timeout=5)
        if sha.returncode != 0:
            return None
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "."], cwd=src, capture_output=True, text=True, timeout=5)
        return sha.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return None
