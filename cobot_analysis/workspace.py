"""The workspace (``--out DIR``): one directory per stage, each with its outputs and a manifest.

A stage runs inside ``Stage(...)``: outputs are written to a hidden temporary directory that
replaces ``DIR/<stage>`` only when the stage succeeds, so a failed run leaves no partial output
(and leaves the previous complete output in place). ``manifest.json`` records the inputs with
their content hashes, the parameters, package versions, the git commit and the timing. A stage
whose inputs, parameters and package version are unchanged is skipped unless ``force``.

    with Stage(out, "preprocess", inputs=[markers], params=params, force=force) as stage:
        if stage.skipped:
            return stage.final_dir
        write_table(df, stage.path("trajectories.parquet"), TRAJECTORIES)
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from cobot_analysis import __version__
from cobot_analysis.console import info

DEFAULT_OUT = Path("cobot-out")
MANIFEST = "manifest.json"
_VERSIONED = ("numpy", "scipy", "pandas", "pyarrow", "casadi", "ezc3d", "rosbags", "statsmodels", "dask", "matplotlib")


def file_sha256(path: Path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def describe_inputs(paths: Iterable[str | os.PathLike]) -> list[dict[str, Any]]:
    """Content hashes of input files; a directory counts as all the files under it."""
    described = []
    for p in sorted({Path(p).resolve() for p in paths}):
        files = sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
        for f in files:
            described.append({"path": str(f), "sha256": file_sha256(f), "bytes": f.stat().st_size})
    return described


def package_versions() -> dict[str, str]:
    from importlib.metadata import PackageNotFoundError, version

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


def find_input(out: str | os.PathLike, filename: str, stages: Iterable[str], option: str) -> Path:
    """The first ``out/<stage>/<filename>`` that exists, in the order of ``stages``.

    Raises ``InputError`` naming the stages to run (or the option to pass) when none exists.
    """
    from cobot_analysis.errors import InputError

    stages = list(stages)
    for stage in stages:
        candidate = Path(out) / stage / filename
        if candidate.is_file():
            return candidate
    raise InputError(f"no {filename} in the workspace (looked in {', '.join(stages)})", path=out,
                     remedy=f"run `cobot-analysis {stages[0]}` first with the same --out, or pass {option}")


def _canonical(params: dict[str, Any]) -> Any:
    return json.loads(json.dumps(params, sort_keys=True, default=str))


class Stage:
    """One pipeline stage writing into ``out/name`` atomically, with a manifest and skip logic."""

    def __init__(self, out: str | os.PathLike, name: str, *, inputs: Iterable[str | os.PathLike] = (),
                 params: dict[str, Any] | None = None, force: bool = False):
        self.out = Path(out)
        self.name = name
        self.final_dir = self.out / name
        self.input_paths = [Path(p) for p in inputs]
        self.params = _canonical(params or {})
        self.force = force
        self.skipped = False
        self.dir: Path = self.final_dir
        self._inputs: list[dict[str, Any]] = []
        self._t0 = 0.0
        self._started = ""

    # -- skip logic -----------------------------------------------------------------------------
    def _previous_manifest(self) -> dict[str, Any] | None:
        try:
            return json.loads((self.final_dir / MANIFEST).read_text())
        except (OSError, ValueError):
            return None

    def _up_to_date(self) -> bool:
        old = self._previous_manifest()
        if old is None:
            return False
        same = (
            old.get("params") == self.params
            and old.get("versions", {}).get("cobot_analysis") == __version__
            and [(i["path"], i["sha256"]) for i in old.get("inputs", [])] == [(i["path"], i["sha256"]) for i in self._inputs]
        )
        return same and all((self.final_dir / o["path"]).is_file() for o in old.get("outputs", []))

    # -- context --------------------------------------------------------------------------------
    def __enter__(self) -> "Stage":
        self._t0 = time.perf_counter()
        self._started = datetime.now(timezone.utc).isoformat(timespec="seconds")
        self._inputs = describe_inputs(self.input_paths)
        if not self.force and self._up_to_date():
            self.skipped = True
            info(f"[green]{self.name}[/green]: up to date, skipped (use --force to redo): {self.final_dir}")
            return self
        self.out.mkdir(parents=True, exist_ok=True)
        self.dir = Path(tempfile.mkdtemp(prefix=f".{self.name}.", suffix=".tmp", dir=self.out))
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if self.skipped:
            return False
        if exc_type is not None:
            shutil.rmtree(self.dir, ignore_errors=True)
            return False
        self._write_metrics()
        self._write_manifest()
        trash = self.out / f".{self.name}.old.{os.getpid()}"
        if self.final_dir.exists():
            os.replace(self.final_dir, trash)
        os.replace(self.dir, self.final_dir)
        shutil.rmtree(trash, ignore_errors=True)
        self.dir = self.final_dir
        return False

    # -- outputs --------------------------------------------------------------------------------
    def path(self, relative: str) -> Path:
        """Where to write an output (inside the stage's temporary directory while it runs)."""
        p = self.dir / relative
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def savefig(self, fig, stem: str, formats: tuple[str, ...] = ("png", "pdf")) -> list[Path]:
        """Save a matplotlib figure as ``stem.png`` and ``stem.pdf`` and close it."""
        import matplotlib.pyplot as plt

        paths = []
        for fmt in formats:
            p = self.path(f"{stem}.{fmt}")
            fig.savefig(p, dpi=150, bbox_inches="tight")
            paths.append(p)
        plt.close(fig)
        return paths

    def _write_metrics(self) -> None:
        """``metrics.json``: the stage's headline numbers, for ``cobot-analysis metrics check``."""
        from cobot_analysis.regression.extract import write_stage_metrics

        write_stage_metrics(self.name, self.dir, self.params)

    def _write_manifest(self) -> None:
        outputs = [
            {"path": str(f.relative_to(self.dir)), "sha256": file_sha256(f), "bytes": f.stat().st_size}
            for f in sorted(self.dir.rglob("*")) if f.is_file()
        ]
        manifest = {
            "stage": self.name,
            "command": sys.argv,
            "started": self._started,
            "duration_s": round(time.perf_counter() - self._t0, 3),
            "inputs": self._inputs,
            "params": self.params,
            "outputs": outputs,
            "versions": package_versions(),
            "git_commit": git_commit(),
            "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
        }
        (self.dir / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
