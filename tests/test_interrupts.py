"""Ctrl-C and SIGTERM during a stage, with real processes: every process ends, one line, exit code
130 / 143, no temporary directory, and a rerun works; what a SIGKILLed run leaves is removed by the
next run; a long call into C (an OC solve) does not delay an interrupt."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time

import psutil
import pytest

from cobot_analysis.interrupt import Interrupted, deferred, interruptible, signals

CLI = [sys.executable, "-m", "cobot_analysis"]
BOUND = 60.0  # s: generous bound for an interrupted process tree to be gone (required: 2 s)


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    """The import stage of a small synthetic walking study (60 trials)."""
    from cobot_analysis.cli import run

    ws = tmp_path_factory.mktemp("study")
    assert run(["-q", "synth", "walking", "--out", str(ws), "--subjects", "3", "--repetitions", "2", "--conditions", "10"]) == 0
    assert run(["-q", "import", str(ws / "synth-walking" / "protocol.yaml"), "--out", str(ws), "--jobs", "1"]) == 0
    return ws / "import"


def _preprocess(imported, tmp_path) -> tuple[subprocess.Popen, list[psutil.Process]]:
    """``preprocess --jobs 2`` in its own process group, once its two workers run."""
    ws = tmp_path / "ws"
    shutil.copytree(imported, ws / "import")
    p = subprocess.Popen([*CLI, "preprocess", "--out", str(ws), "--jobs", "2"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    main = psutil.Process(p.pid)
    deadline = time.monotonic() + 300
    while len(main.children()) < 2:
        assert p.poll() is None, p.communicate()
        assert time.monotonic() < deadline, "the workers never started"
        time.sleep(0.005)
    return p, main.children(recursive=True)


def _ended(p: subprocess.Popen, workers: list[psutil.Process]) -> tuple[int, str]:
    try:
        _, err = p.communicate(timeout=BOUND)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        pytest.fail("the interrupted command did not end")
    _, alive = psutil.wait_procs(workers, timeout=BOUND)
    assert not alive, f"workers still running: {alive}"
    return p.returncode, err


def _rerun_works(ws) -> None:
    from cobot_analysis.cli import run

    assert run(["-q", "preprocess", "--out", str(ws), "--jobs", "2"]) == 0
    assert (ws / "preprocess" / "trajectories.parquet").is_file()
    assert not list(ws.glob(".preprocess*"))


@pytest.mark.parametrize("sig, group, code", [(signal.SIGINT, True, 130), (signal.SIGTERM, False, 143)])
@pytest.mark.slow
def test_interrupt_ends_every_process_and_writes_nothing(imported, tmp_path, sig, group, code):
    """SIGINT to the process group (what Ctrl-C in a terminal does), SIGTERM to the command only."""
    p, workers = _preprocess(imported, tmp_path)
    (os.killpg if group else os.kill)(p.pid, sig)
    rc, err = _ended(p, workers)
    assert rc == code
    assert err.strip().splitlines()[-1] == f"error: interrupted ({signal.Signals(sig).name}); nothing written"
    assert "Traceback" not in err
    ws = tmp_path / "ws"
    assert sorted(x.name for x in ws.iterdir()) == ["import"]  # no stage, no temporary directory
    _rerun_works(ws)


@pytest.mark.slow
def test_leftovers_of_a_killed_run_are_removed_by_the_next(imported, tmp_path):
    p, workers = _preprocess(imported, tmp_path)
    os.kill(p.pid, signal.SIGKILL)
    _ended(p, workers)  # the workers die with their parent
    ws = tmp_path / "ws"
    (left,) = ws.glob(".preprocess.*.tmp")
    code = subprocess.run([*CLI, "preprocess", "--out", str(ws), "--jobs", "2"], capture_output=True, text=True)
    assert code.returncode == 0, code.stderr
    assert f"removed{left},leftbyaninterruptedrun" in "".join(code.stderr.split())  # wrapped at 80 columns
    assert not left.exists() and (ws / "preprocess" / "trajectories.parquet").is_file()


LONG_SOLVE = textwrap.dedent("""
    import os, sys
    import casadi as ca, numpy as np
    from cobot_analysis.interrupt import Interrupted, interruptible, signals

    n = 3000  # fatrop on a dense problem: minutes, and it never looks at signals
    x = ca.SX.sym("x", n)
    f = ca.sum1((x[1:] - x[:-1] ** 2) ** 2) + ca.sum1((1 - x) ** 2) + ca.sum1(ca.sin(x * x))
    solver = ca.nlpsol("s", "fatrop", {"x": x, "f": f}, {"print_time": False, "fatrop": {"print_level": 0}})
    with signals():
        try:
            print("solving", flush=True)
            interruptible(solver, x0=np.full(n, 3.0))
            print("solved", flush=True)
        except Interrupted as exc:
            print(f"interrupted {exc}", flush=True)
            os._exit(exc.exit_code)
""")


@pytest.mark.slow
def test_a_long_solve_in_c_is_interrupted(tmp_path):
    p = subprocess.Popen([sys.executable, "-c", LONG_SOLVE], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "solving"
    time.sleep(1.0)  # inside the solve
    p.send_signal(signal.SIGINT)
    try:
        out, _ = p.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        p.kill()
        pytest.fail("SIGINT did not end the solve")
    assert (p.returncode, out.strip()) == (130, "interrupted SIGINT")


def test_interruptible_returns_and_raises_like_a_direct_call():
    with signals():
        assert interruptible(divmod, 17, 5) == (3, 2)
        with pytest.raises(ZeroDivisionError):
            interruptible(divmod, 1, 0)


def test_a_signal_inside_a_deferred_section_is_raised_at_its_end():
    done = []
    with signals(), pytest.raises(Interrupted) as err:
        with deferred():
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)  # the handler runs here, and must not raise yet
            done.append(True)
    assert done == [True] and err.value.exit_code == 143


def test_the_message_names_the_stages_completed_before_the_interrupt(tmp_path):
    from cobot_analysis.interrupt import outcome
    from cobot_analysis.workspace import Stage

    with signals():
        assert outcome() == "nothing written"
        with Stage(tmp_path, "first") as stage:
            stage.path("a.txt").write_text("1\n")
        with pytest.raises(Interrupted), Stage(tmp_path, "second"):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1.0)  # interrupted here
        assert outcome() == f"kept: {tmp_path / 'first'}"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["first"]
    assert sorted(p.name for p in (tmp_path / "first").iterdir()) == ["a.txt", "manifest.json"]
