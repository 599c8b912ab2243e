"""Trust in the compiled-solver cache: native code and serialised solvers are loaded only from a
private directory, and only when they match a digest recorded when this package wrote them.

The cache (``problem.cache_dir()``) holds shared libraries that are loaded into the process
(``dlopen``) and casadi solvers serialised beside them; anyone who can write there can run code in
every analysis. So (docs/cache.md):

1. the directory must be a real directory (not a symbolic link) owned by the user and not
   writable by group or others, and none of its ancestors may be writable by another user
   (writable by others without the sticky bit, or owned by another user than root) -- else the
   cache is not used at all (``untrusted_reason`` says why, the caller warns once and solves with
   casadi's virtual machine: same NLP, about 2x slower). It is created with mode 0700;
2. every artefact (library, serialised solver) has its SHA-256 recorded in a separate file,
   ``digests/<name>.sha256``, written by this package after it wrote the artefact; an artefact is
   used only when its content matches (``verified``). A library or solver without a digest, or
   that differs from it (planted, damaged, half-written), is rebuilt, never loaded.

The digest alone catches damage; with 1 it also catches tampering by anyone but the user (who
could as well edit the package). Compilation runs in a fresh temporary directory of the cache
with a relative source name, so the same source gives the same library bytes.
"""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

DIGESTS = "digests"


def untrusted_reason(directory: Path) -> str | None:
    """Why ``directory`` (created with mode 0700 when absent) cannot hold code to load, or None."""
    try:
        if not os.path.lexists(directory):
            directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        st = os.lstat(directory)
    except OSError as exc:
        return f"it cannot be created or read ({exc.strerror or type(exc).__name__})"
    uid = os.getuid()
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISDIR(st.st_mode):
        return "it is a symbolic link or not a directory"
    if st.st_uid != uid:
        return f"it is owned by another user (uid {st.st_uid})"
    if st.st_mode & 0o022:
        return f"it is writable by group or others (mode {stat.S_IMODE(st.st_mode):o})"
    for parent in directory.resolve().parents:
        try:
            pst = os.stat(parent)
        except OSError:
            return f"its parent {parent} cannot be read"
        if pst.st_uid not in (uid, 0):
            return f"its parent {parent} is owned by another user (uid {pst.st_uid})"
        if pst.st_mode & 0o002 and not pst.st_mode & stat.S_ISVTX:
            return f"its parent {parent} is writable by others"
    return None


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def digest_file(artefact: Path) -> Path:
    return artefact.parent / DIGESTS / f"{artefact.name}.sha256"


def verified(artefact: Path) -> bool:
    """True when ``artefact`` exists and matches the digest recorded when it was written."""
    try:
        return digest_file(artefact).read_text().strip() == sha256(artefact)
    except OSError:
        return False


def record(artefact: Path, digest: str | None = None) -> None:
    """Record the SHA-256 of ``artefact`` (written by this package) in ``digests/`` (atomically)."""
    target = digest_file(artefact)
    target.parent.mkdir(mode=0o700, exist_ok=True)
    tmp = target.with_name(f"{target.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text((digest or sha256(artefact)) + "\n")
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)


def install(built: Path, target: Path) -> None:
    """Move a freshly built artefact to ``target`` and record its digest (the digest of what was
    built, so that a file swapped in meanwhile does not match)."""
    digest = sha256(built)
    os.replace(built, target)
    record(target, digest)
