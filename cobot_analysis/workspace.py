"""The workspace (``--out DIR``): one directory per stage, each with its outputs and a manifest.

A stage runs inside ``Stage(...)``: outputs are written to a hidden temporary directory that
replaces ``DIR/<stage>`` only when the stage succeeds, so a failed run leaves no partial output
(and leaves the previous complete output in place). ``manifest.json`` records the inputs with
their content hashes, the parameters, package versions, the git commit and the timing. A stage
whose inputs, parameters and package version are unchanged is skipped unless ``force``.

Reuse is verified: a skip checks every output against the manifest (size and modification time,
then the SHA-256 when either differs); an output changed since the stage wrote it (edited by hand,
damaged) makes the stage run again, and says so, as a changed input would. A stage whose input
is another stage's output checks it against that stage's manifest the same way: an edited table
is refused, naming the file, rather than computed from (to use an edited table on purpose, pass
it from outside the workspace).

One run per stage and workspace at a time: a stage holds the lock ``DIR/.<stage>.lock``
(``flock``; the file is removed when the stage ends, and a killed run's is reused) from its start
to its commit; a second run of that stage into the same workspace is
refused with one line (never a silent last-writer-wins). The lock is released by the system when
the process ends, however it ends.

Interrupted or killed runs: the temporary directory ``.<stage>.<random>.tmp`` holds a lock file
that its process keeps locked (``flock``); an interrupt (Ctrl-C, SIGTERM) removes it, and the next
run of the stage removes those a killed process left (their lock is free). Directories are created
with the user's umask; those of ``--out`` that a run created are removed again, while still empty, when it keeps nothing.

    with Stage(out, "preprocess", inputs=[markers], params=params, force=force) as stage:
        if stage.skipped:
            return stage.final_dir
        write_table(df, stage.path("trajectories.parquet"), TRAJECTORIES)
"""

from __future__ import annotations

import errno
import json
import os
import platform
import secrets
import shutil
import sys
import time
from collections.abc import Iterable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import cobot_analysis
from cobot_analysis import registry
from cobot_analysis.console import info, warn
from cobot_analysis.errors import InputError
from cobot_analysis.interrupt import deferred, keep, seen
from cobot_analysis.provenance import file_sha256, git_commit, package_versions

try:
    import fcntl
except ImportError:  # not POSIX: leftovers are left alone
    fcntl = None

DEFAULT_OUT = Path("cobot-out")
MANIFEST = "manifest.json"
LOCK = ".lock"  # in a running stage's temporary directory, locked by its process
STAGE_LOCK = ".{}.lock"  # in the workspace: held by the run of that stage
PREVIOUS = ".previous"  # the replaced output, moved into the new one while it is committed
STALE_AFTER = 60.0  # s: a temporary directory without a lock file (older versions) older than this is abandoned
COMMAND: list[str] = []  # the command line being run (set by cli.run; sys.argv otherwise), for the manifests


RACY_NS = 20_000_000  # a file modified less than this before it was hashed is hashed again next time (file times are coarse)
_HASHED: dict[tuple[int, int, int, int, int], str] = {}


def content_sha256(f: Path) -> str:
    """``file_sha256`` of ``f``, computed once per version of the file in this process: an output hashed for its
    stage's manifest and read as the next stage's input (``import --preprocess``: markers.parquet, 0.3 s for
    480 trials) is not read again. A version is its device, inode, size, modification and status-change times:
    any write (and any reset of the modification time) changes the status-change time. As in git's racy-entry
    rule, a file modified within ``RACY_NS`` before the hash started is not remembered (file times are
    kernel ticks)."""
    import time

    st = f.stat()
    key = (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
    if key in _HASHED:
        return _HASHED[key]
    start = time.time_ns()
    sha = file_sha256(f)
    if max(st.st_mtime_ns, st.st_ctime_ns) < start - RACY_NS:
        _HASHED[key] = sha
    return sha


def describe_inputs(paths: Iterable[str | os.PathLike], known: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """Content hashes of input files; a directory counts as all the files under it. ``known``: hashes already
    computed (``{resolved path: SHA-256}``), not computed again. A missing or unreadable input raises
    ``InputError`` (naming the command that wrote it, when known)."""
    known = known or {}
    described = []
    for p in sorted({Path(p).resolve() for p in paths}):
        if not p.exists():
            raise InputError("input file not found", path=p, remedy=_rerun_remedy(p))
        try:
            files = sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
            for f in files:
                described.append({"path": str(f), "sha256": known.get(str(f)) or content_sha256(f), "bytes": f.stat().st_size})
        except OSError as exc:
            raise InputError(f"cannot read the input ({exc.strerror or type(exc).__name__})", path=exc.filename or p,
                             remedy="check its permissions, or re-create it") from None
    return described


def _rerun_remedy(path: Path) -> str:
    """How to re-create a missing stage output: the command recorded in its stage's manifest."""
    try:
        command = json.loads((path.parent / MANIFEST).read_text())["command"]
        return f"re-run the command that wrote it: `{' '.join(['cobot-analysis', *command[1:]])}`"
    except (OSError, ValueError, KeyError, TypeError):
        return "check the path, or re-run the stage that writes it"


def find_input(out: str | os.PathLike, filename: str, stages: Iterable[str], option: str) -> Path:
    """The first ``out/<stage>/<filename>`` that exists, in the order of ``stages``.

    Raises ``InputError`` naming the stages to run (or the option to pass) when none exists.
    """
    stages = list(stages)
    check_workspace(out)
    for stage in stages:
        candidate = Path(out) / stage / filename
        if candidate.is_file():
            return candidate
    raise InputError(f"no {filename} in the workspace (looked in {', '.join(stages)})", path=out,
                     remedy=f"run `cobot-analysis {stages[0]}` first with the same --out, or pass {option}")


def check_workspace(out: str | os.PathLike) -> None:
    """``out`` must be a directory, or not exist yet."""
    if Path(out).exists() and not Path(out).is_dir():
        raise InputError("is not a directory", path=out, remedy="pass a workspace directory (new or existing) with --out")


def check_destination(path: str | os.PathLike, option: str, *, directory: bool) -> Path:
    """Where a command writes outside the workspace (``report --to``: a directory, ``results --to``: a file),
    refused before any work when it cannot be written: a file where a directory is needed (``path`` or one
    of its parents), or a directory where the file should be."""
    path = Path(path)
    parent = next((p for p in path.parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise InputError("is a file, not a directory", path=parent, remedy=f"give {option} a path whose parents are directories")
    if directory and path.exists() and not path.is_dir():
        raise InputError("is a file, not a directory", path=path, remedy=f"give {option} a directory (new or existing)")
    if not directory and path.is_dir():
        raise InputError("is a directory", path=path, remedy=f"give {option} a file name, e.g. {path / 'results.md'}")
    return path


def _abandoned(d: Path) -> bool:
    """A temporary stage directory whose run is over: its lock is free, or (no lock file) it is old."""
    try:
        fd = os.open(d / LOCK, os.O_RDWR)
    except FileNotFoundError:
        try:
            return time.time() - d.stat().st_mtime > STALE_AFTER
        except OSError:
            return False
    except OSError:
        return False
    try:
        if fcntl is None:  # cannot tell: left alone
            return False
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return True
    except OSError:  # locked: its process is running (or no locks on this file system)
        return False
    finally:
        os.close(fd)


def changed_outputs(stage_dir: Path, manifest: dict[str, Any]) -> list[str]:
    """The outputs of a stage (relative paths) that are missing or differ from its manifest: size
    and modification time first, the SHA-256 when either differs (or the manifest has no time)."""
    changed = []
    for o in manifest.get("outputs", []):
        f = stage_dir / o["path"]
        try:
            st = f.stat()
        except OSError:
            changed.append(o["path"])
            continue
        if st.st_size != o.get("bytes") or (st.st_mtime_ns != o.get("mtime_ns") and content_sha256(f) != o.get("sha256")):
            changed.append(o["path"])
    return changed


def check_upstream(inputs: list[dict[str, Any]]) -> None:
    """Refuse an input that is another stage's output changed since that stage wrote it (its
    SHA-256 differs from the one in the manifest beside it, or one directory up)."""
    manifests: dict[Path, tuple[dict, dict[str, dict]] | None] = {}  # directory -> (manifest, its outputs by path)
    for i in inputs:
        f = Path(i["path"])
        for d in (f.parent, f.parent.parent):
            if d not in manifests:
                try:
                    m = json.loads((d / MANIFEST).read_text())
                    outputs = m.get("outputs", []) if isinstance(m, dict) else []
                    manifests[d] = (m, {o.get("path"): o for o in reversed(outputs) if isinstance(o, dict)}) if isinstance(m, dict) else None
                except (OSError, ValueError, AttributeError, TypeError):
                    manifests[d] = None
            known = manifests[d]
            if known is None or f.name == MANIFEST:
                continue
            m, listed_by_path = known
            listed = listed_by_path.get(str(f.relative_to(d)))
            if listed is None:
                continue
            if listed.get("sha256") != i["sha256"]:
                stage = str(m.get("stage", d.name))  # a stage directory moved or renamed keeps its manifest's name
                raise InputError(f"changed since stage {stage} wrote it (its SHA-256 differs from {d.name}/{MANIFEST})", path=f,
                                 remedy=f"re-run `cobot-analysis {registry.command(stage)}` with its --out (it redoes the "
                                        f"stage), or copy the edited file out of "
                                        f"the workspace and pass it as an option to use it on purpose")
            break


def _canonical(params: dict[str, Any]) -> Any:
    return json.loads(json.dumps(params, sort_keys=True, default=str))


def _open_figures() -> list[int]:
    """The numbers of the open pyplot figures ([] when pyplot was never imported: not imported here)."""
    plt = sys.modules.get("matplotlib.pyplot")
    return list(plt.get_fignums()) if plt is not None else []


def _close_figures(numbers: Iterable[int]) -> None:
    """Close the pyplot figures ``numbers``: those a stage opened and left open (a stage's figures are its
    files; pyplot would keep them in memory for the rest of the process, a notebook or a long run)."""
    plt = sys.modules.get("matplotlib.pyplot")
    for n in numbers:
        plt.close(n)


class Stage:
    """One pipeline stage writing into ``out/name`` atomically, with a manifest and skip logic."""

    def __init__(self, out: str | os.PathLike, name: str, *, inputs: Iterable[str | os.PathLike] = (),
                 params: dict[str, Any] | None = None, force: bool = False, hashed_by_run: Iterable[str | os.PathLike] = ()):
        """``hashed_by_run``: input files (among ``inputs``) that the stage's own work reads and hashes (the raw
        files an import's workers read): when the stage cannot be skipped (no manifest of an earlier run, or
        ``force``) they are not hashed on entering; the run gives their hashes with ``inputs_hashed``, which
        also checks them against the stage that wrote them (``check_upstream``) before the manifest is written."""
        self.out = Path(out)
        self.name = name
        self.final_dir = self.out / name
        self.input_paths = [Path(p) for p in inputs]
        self._hashed_by_run = {Path(p) for p in hashed_by_run}  # as given in ``inputs``
        self._pending = False  # inputs left for the run to hash (``inputs_hashed``)
        self.params = _canonical(params or {})
        self.force = force
        self.skipped = False
        self.manifest_extra: dict[str, Any] = {}  # further manifest keys (e.g. "refused": the trials left out)
        self.dir: Path = self.final_dir
        self._inputs: list[dict[str, Any]] = []
        self._t0 = 0.0
        self._started = ""
        self._lock: int | None = None
        self.outputs: dict[str, Any] = {}  # what the stage wrote, kept in memory: its metrics are computed from it
        self.result: Any = None  # the API result of the run: its own numbers (.metrics()) are the stage's metrics.json
        self._stage_lock: int | None = None
        self._figures: set[int] = set()  # pyplot figure numbers open on entering (the caller's: left open)
        self._new: list[Path] = []  # the workspace's directories that did not exist on entering, deepest first

    @property
    def input_hashes(self) -> dict[str, str]:
        """``{resolved path: SHA-256}`` of the input files, as hashed on entering the stage (for the manifest):
        a stage that records its inputs' hashes elsewhere reuses them instead of hashing the files again
        (the inputs ``hashed_by_run`` are missing when the run hashes them)."""
        return {i["path"]: i["sha256"] for i in self._inputs}

    def inputs_hashed(self, hashes: dict[str, str]) -> None:
        """The run's hashes of the inputs ``hashed_by_run`` (``{resolved path: SHA-256}``; any it does not give
        are hashed here): every input described as on entering, and refused if another stage wrote it and
        it has changed since."""
        if self._pending:
            self._inputs = describe_inputs(self.input_paths, known={**self.input_hashes, **hashes})  # none hashed twice
            check_upstream(self._inputs)
            self._pending = False

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
            and old.get("versions", {}).get("cobot_analysis") == cobot_analysis.__version__
            and [(i["path"], i["sha256"]) for i in old.get("inputs", [])] == [(i["path"], i["sha256"]) for i in self._inputs]
        )
        if not same:
            return False
        changed = changed_outputs(self.final_dir, old)
        if changed:
            warn(f"{self.name}: {', '.join(changed[:3])}{' ...' if len(changed) > 3 else ''} changed since the stage "
                 f"wrote {'them' if len(changed) > 1 else 'it'} (not as its manifest records): running it again")
            return False
        return True

    # -- context --------------------------------------------------------------------------------
    def __enter__(self) -> "Stage":
        check_workspace(self.out)
        self._new = [d for d in (self.out, *self.out.parents) if not d.exists()]
        try:
            return self._enter()
        except BaseException:
            self._remove_new()
            raise

    def _enter(self) -> "Stage":
        if self.final_dir.exists() and not self.final_dir.is_dir():
            raise InputError("exists and is not a stage directory", path=self.final_dir,
                             remedy=f"move or delete it (stage {self.name} writes the directory {self.final_dir}), or pass another --out")
        self._t0 = time.perf_counter()
        self._started = datetime.now(timezone.utc).isoformat(timespec="seconds")
        self._figures = set(_open_figures())
        self._pending = bool(self._hashed_by_run) and (self.force or self._previous_manifest() is None)
        self._inputs = describe_inputs([p for p in self.input_paths if p not in self._hashed_by_run]
                                       if self._pending else self.input_paths)
        check_upstream(self._inputs)
        self._acquire()
        try:
            up_to_date = not self.force and self._up_to_date()
        except BaseException:
            self._release()
            raise
        if up_to_date:
            self._release()
            self.skipped = True
            info(f"[green]{self.name}[/green]: up to date, skipped (--force redoes it) -> {self.final_dir}")
            return self
        with deferred():
            try:
                self.out.mkdir(parents=True, exist_ok=True)
                self._clean_leftovers()
                self.dir = self._temporary()
            except OSError as exc:
                self._unlock()
                self._release()
                raise InputError(f"cannot write the workspace ({exc.strerror or type(exc).__name__})", path=exc.filename or self.out,
                                 remedy="pass a writable directory with --out") from None
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        seen(exc)
        if self.skipped:
            return False
        try:
            if exc_type is None:
                self.inputs_hashed({})  # the inputs the run did not hash (if any): before anything is kept
                self._write_metrics()
                self._write_manifest()
                with deferred():
                    self._commit()
        finally:
            _close_figures(set(_open_figures()) - self._figures)  # a figure drawn and not saved (e.g. a failed run)
            kept = self.dir == self.final_dir
            if not kept:  # failed or interrupted: nothing of this run is kept
                with deferred():
                    shutil.rmtree(self.dir, ignore_errors=True)
                    self._unlock()
            self._release()
            if not kept:
                self._remove_new()
        return False

    def _remove_new(self) -> None:
        """Remove the directories of ``--out`` that this run created, where they are still empty (a refused
        run into a new workspace leaves no empty workspace behind; another run's files keep theirs)."""
        for d in self._new:
            try:
                d.rmdir()
            except OSError:  # not empty (another run's), or already gone
                return

    def _acquire(self) -> None:
        """Take the stage's workspace lock, or refuse (one line) when another run holds it. The lock
        file is removed on release; a lock taken on a file removed meanwhile is taken again."""
        if fcntl is None:
            return
        path = self.out / STAGE_LOCK.format(self.name)
        retries = 3  # the new workspace removed by another run's ``_remove_new`` between mkdir and open: again
        while True:
            try:
                self.out.mkdir(parents=True, exist_ok=True)
                fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o666)
            except OSError as exc:
                if isinstance(exc, FileNotFoundError) and retries:
                    retries -= 1
                    continue
                raise InputError(f"cannot write the workspace ({exc.strerror or type(exc).__name__})", path=exc.filename or self.out,
                                 remedy="pass a writable directory with --out") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):  # no locks on this file system
                    os.close(fd)
                    return
                holder = os.read(fd, 64).decode(errors="replace").strip()
                os.close(fd)
                raise InputError(f"stage {self.name} is being run into this workspace by another process"
                                 f"{f' (pid {holder})' if holder else ''}", path=self.out,
                                 remedy="wait for it to finish, or pass another --out") from None
            try:
                same = os.stat(path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # released and removed by its holder between our open and our lock: again
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._stage_lock = fd

    def _release(self) -> None:
        fd, self._stage_lock = self._stage_lock, None
        if fd is not None:
            (self.out / STAGE_LOCK.format(self.name)).unlink(missing_ok=True)
            os.close(fd)

    def _temporary(self) -> Path:
        """A new hidden directory beside the stage's, created with the umask and locked by this process."""
        while True:
            d = self.out / f".{self.name}.{secrets.token_hex(4)}.tmp"
            try:
                d.mkdir()
            except FileExistsError:
                continue
            try:
                self._lock = os.open(d / LOCK, os.O_CREAT | os.O_RDWR, 0o666)
            except OSError:
                d.rmdir()
                raise
            try:
                if fcntl is not None:
                    fcntl.flock(self._lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:  # no locks on this file system: the directory is never taken for a leftover
                pass
            return d

    def _unlock(self) -> None:
        if self._lock is not None:
            os.close(self._lock)
            self._lock = None

    def _clean_leftovers(self) -> None:
        """Remove what killed runs of this stage left: temporary directories, a replaced output."""
        shutil.rmtree(self.final_dir / PREVIOUS, ignore_errors=True)
        for d in sorted(self.out.glob(f".{self.name}.*")):
            if d.is_dir() and (d.suffix == ".tmp" or d.name.startswith(f".{self.name}.old.")) and _abandoned(d):
                shutil.rmtree(d, ignore_errors=True)
                info(f"[green]{self.name}[/green]: removed {d}, left by an interrupted run")

    def _commit(self) -> None:
        """The temporary directory becomes the stage's (the replaced output is moved into it first)."""
        if self.final_dir.exists():
            os.replace(self.final_dir, self.dir / PREVIOUS)
        os.replace(self.dir, self.final_dir)
        self.dir = self.final_dir
        shutil.rmtree(self.final_dir / PREVIOUS, ignore_errors=True)
        (self.final_dir / LOCK).unlink(missing_ok=True)
        self._unlock()
        keep(self.final_dir)

    # -- outputs --------------------------------------------------------------------------------
    def path(self, relative: str) -> Path:
        """Where to write an output (inside the stage's temporary directory while it runs)."""
        p = self.dir / relative
        p.parent.mkdir(parents=True, exist_ok=True)
        return p

    def write_table(self, relative: str, df, schema, **metadata: Any) -> Path:
        """Write ``df`` as the Parquet table ``schema`` (``schema.write_table``) and keep it for the metrics."""
        from cobot_analysis.schema import to_arrow, write_table

        table = to_arrow(df, schema, **metadata)
        self.outputs[relative] = table
        return write_table(table, self.path(relative))

    def write_json(self, relative: str, data: Any, default=float) -> Path:
        """Write ``data`` as indented JSON (``default`` converts what JSON lacks) and keep the text for the metrics."""
        text = json.dumps(data, indent=2, default=default) + "\n"
        self.outputs[relative] = text
        p = self.path(relative)
        p.write_text(text)
        return p

    def savefig(self, fig, stem: str, formats: tuple[str, ...] = ("png", "pdf")) -> list[Path]:
        """Save a matplotlib figure as ``stem.png`` and ``stem.pdf`` (``plotting.save``: 150 dpi, tight, one
        layout for both) and close it."""
        import matplotlib.pyplot as plt

        from cobot_analysis.plotting import save

        paths = [self.path(f"{stem}.{fmt}") for fmt in formats]
        try:
            save(fig, paths, dpi=150)
        finally:  # pyplot keeps every figure until closed: a library that saves one must close it
            plt.close(fig)
        return paths

    def _write_metrics(self) -> None:
        """``metrics.json``: the stage's headline numbers (its ``result``'s, else read from its outputs), for
        ``cobot-analysis metrics check``."""
        from cobot_analysis.regression.extract import write_stage_metrics

        write_stage_metrics(self.name, self.dir, self.params, self.outputs, self.result)

    def _write_manifest(self) -> None:
        outputs = [
            {"path": str(f.relative_to(self.dir)), "sha256": content_sha256(f), "bytes": f.stat().st_size,
             "mtime_ns": f.stat().st_mtime_ns}
            for f in sorted(self.dir.rglob("*")) if f.is_file() and f.name != LOCK
        ]
        manifest = {
            "stage": self.name,
            "command": COMMAND or sys.argv,
            "started": self._started,
            "duration_s": round(time.perf_counter() - self._t0, 3),
            "inputs": self._inputs,
            "params": self.params,
            "outputs": outputs,
            "versions": package_versions(),
            "git_commit": git_commit(),
            "machine": {"platform": platform.platform(), "cpus": os.cpu_count()},
            **self.manifest_extra,
        }
        (self.dir / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
