"""Issue 21: the compiled-solver cache loads no code it has not verified. A library planted in the
cache (it would write a file when loaded) is rebuilt and never loaded; in a directory others can
write, the cache is not used at all. Real compiles and loads, in subprocesses where loading is
the point (a process keeps what it dlopened)."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from cobot_analysis.models.oc import cache

ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
SHAPE = "OCPShape(n_intervals=10)"
SOLVE = textwrap.dedent(f"""
    import math, sys
    from cobot_analysis.models.oc.problem import N_WEIGHTS, WalkerOCP, OCPShape, compiled_library
    ocp = WalkerOCP({SHAPE})
    sol = ocp.solve((-2.0, 0.5, 0.0), (0.0, 0.0, math.pi / 2), [1.0] * N_WEIGHTS, 2.0)
    print("library", compiled_library(ocp))
    print("solved", sol.success, sol.solver, round(float(sol.X[-1, 0]), 3), round(float(sol.X[-1, 1]), 3))
""")


def _cc() -> str:
    cc = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler: the cache holds no library")
    return cc


def _planted(tmp_path: Path, marker: Path) -> Path:
    """A shared library that writes ``marker`` when it is loaded (what planted code would do)."""
    src = tmp_path / "evil.c"
    src.write_text(textwrap.dedent(f"""
        #include <stdio.h>
        __attribute__((constructor)) static void planted(void) {{
            FILE *f = fopen("{marker}", "w"); if (f) {{ fputs("loaded", f); fclose(f); }}
        }}
    """))
    out = tmp_path / "evil.so"
    subprocess.run([_cc(), "-shared", "-fPIC", str(src), "-o", str(out)], check=True)
    return out


def _run(cache_root: Path) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-c", SOLVE], capture_output=True, text=True, timeout=600,
                       env={**ENV, "COBOT_ANALYSIS_CACHE": str(cache_root), "COBOT_ANALYSIS_OCP_COMPILE": "1"})
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A private cache with the library and serialised solver of a 10-interval OCP."""
    root = tmp_path_factory.mktemp("cache")
    r = _run(root)
    assert "solved True fatrop" in r.stdout, r.stdout
    library = Path(next(ln.split()[1] for ln in r.stdout.splitlines() if ln.startswith("library")))
    assert library.parent == root / "ocp" and cache.verified(library)
    return root, library, r.stdout


def test_the_planted_library_would_run_code_when_loaded(tmp_path):
    """Control: loading the planted library writes its marker (so its absence below means 'not loaded')."""
    marker = tmp_path / "marker"
    evil = _planted(tmp_path, marker)
    subprocess.run([sys.executable, "-c", f"import ctypes; ctypes.CDLL({str(evil)!r})"], check=True)
    assert marker.read_text() == "loaded"


def test_a_planted_library_is_rebuilt_and_never_loaded(built, tmp_path):
    root, library, first = built
    marker = tmp_path / "marker"
    evil = _planted(tmp_path, marker)
    shutil.copy(evil, library)  # same name: what a name-only cache returned and loaded
    r = _run(root)
    assert not marker.exists(), "the planted library was loaded"
    assert cache.verified(library) and cache.sha256(library) != cache.sha256(evil)
    assert r.stdout == first  # same library path, same solution


def test_a_planted_serialised_solver_is_not_deserialised(built):
    """The SHA-256 inside the file caught damage, not tampering: the digest now lives outside it."""
    import casadi as ca

    root, library, first = built
    (solver,) = library.parent.glob(f"{library.stem}_fatrop_*.casadi")
    x = ca.SX.sym("x")
    solver.write_text(ca.Function("planted", [x], [2 * x]).serialize())
    r = _run(root)
    assert r.stdout == first
    assert cache.verified(solver) and "planted" not in solver.read_text()


def test_a_cache_others_can_write_is_not_used(built, tmp_path):
    """Planted library and a matching digest (whoever can write the directory can write both):
    the directory itself is refused, said in one warning, and the solve runs without the cache."""
    root, library, first = built
    shared = tmp_path / "shared"
    shutil.copytree(root, shared)
    marker = tmp_path / "marker"
    planted = shared / "ocp" / library.name
    shutil.copy(_planted(tmp_path, marker), planted)
    cache.record(planted)
    os.chmod(shared / "ocp", 0o777)
    r = _run(shared)
    assert not marker.exists(), "the planted library was loaded"
    assert "library None" in r.stdout and "solved True fatrop" in r.stdout
    assert r.stdout.splitlines()[-1] == first.splitlines()[-1]  # the same solution, from casadi's virtual machine
    warning = " ".join(r.stderr.split())
    assert f"the solver cache {shared / 'ocp'} is not used: it is writable by group or others (mode 777)" in warning, warning


@pytest.mark.parametrize("make, reason", [
    (lambda d: d.mkdir(mode=0o777) or os.chmod(d, 0o777), "it is writable by group or others (mode 777)"),
    (lambda d: d.mkdir(mode=0o770) or os.chmod(d, 0o770), "it is writable by group or others (mode 770)"),
    (lambda d: (d.parent / "real").mkdir(mode=0o700) or d.symlink_to(d.parent / "real"), "it is a symbolic link or not a directory"),
    (lambda d: d.write_text("x"), "it is a symbolic link or not a directory"),
    (lambda d: None, None),  # created private
])
def test_untrusted_reason(tmp_path, make, reason):
    d = tmp_path / "ocp"
    make(d)
    assert cache.untrusted_reason(d) == reason
    if reason is None:
        assert (os.stat(d).st_mode & 0o777) == 0o700


def test_an_ancestor_others_can_write_makes_the_cache_untrusted(tmp_path):
    parent = tmp_path / "open"
    parent.mkdir()
    os.chmod(parent, 0o777)  # no sticky bit: anyone may rename the cache away and put theirs
    assert cache.untrusted_reason(parent / "ocp") == f"its parent {parent} is writable by others"
    os.chmod(parent, 0o1777)  # like /tmp: others cannot move our directory
    assert cache.untrusted_reason(parent / "ocp") is None


@pytest.mark.skipif(os.getuid() != 0, reason="needs root to give the directory to another user")
def test_a_cache_owned_by_another_user_is_untrusted(tmp_path):
    d = tmp_path / "ocp"
    d.mkdir(mode=0o700)
    os.chown(d, 65534, 65534)
    assert cache.untrusted_reason(d) == "it is owned by another user (uid 65534)"


def test_the_digest_is_of_what_was_built(tmp_path):
    d = tmp_path / "ocp"
    cache.untrusted_reason(d)
    built_file, target = d / "new.so", d / "lib.so"
    built_file.write_bytes(b"library bytes")
    cache.install(built_file, target)
    assert cache.verified(target) and cache.digest_file(target).read_text().strip() == hashlib.sha256(b"library bytes").hexdigest()
    target.write_bytes(b"library bytez")  # damaged or replaced after it was recorded
    assert not cache.verified(target)
