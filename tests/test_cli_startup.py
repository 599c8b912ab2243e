"""Start-up of the command line (issue 22): ``--help`` and a stage that refuses a missing input or a bad option
import none of the heavy libraries (the model and data stages: numpy only; their cost is measured by
benchmarks/bench_startup.py, never asserted here), and the command line, not the library, chooses Arrow's
allocator."""

from __future__ import annotations

import json
import os
import subprocess
import sys

HEAVY = ("pandas", "pyarrow", "numpy", "scipy", "casadi", "matplotlib")

PROBE = """
import json, sys
from cobot_analysis.cli import run
for argv in json.loads(sys.argv[1]):  # one process for all: each command is checked before the next runs
    code = run(argv)
    print(json.dumps({"argv": argv, "code": code, "heavy": [m for m in %r if m in sys.modules]}), flush=True)
""" % (HEAVY,)


def test_help_and_a_refused_input_import_no_heavy_library(tmp_path):
    ws = str(tmp_path)
    commands = [(["--help"], 0), (["localisation", "--help"], 0), (["average", "--out", ws], 2), (["compare", "--out", ws], 2),
                (["stats", "--out", ws], 2), (["reconstruct", "--out", ws], 2),
                (["localisation", f"{ws}/missing.bag", "--out", ws], 2)]
    out = subprocess.run([sys.executable, "-c", PROBE, json.dumps([argv for argv, _ in commands])], capture_output=True,
                         text=True, check=True).stdout
    results = [json.loads(line) for line in out.splitlines() if line.startswith('{"argv"')]
    assert [(r["argv"], r["code"], r["heavy"]) for r in results] == [(argv, code, []) for argv, code in commands]
    assert not any(tmp_path.iterdir())  # the refusals wrote nothing


def test_the_other_stages_check_their_options_and_inputs_before_pandas(tmp_path):
    # numpy may come first (models' option checks use it: about 0.1 s), pandas and the rest only after the checks
    ws = str(tmp_path)
    commands = [["predict", "--out", ws], ["predict", "--out", ws, "--settings", "50-100"],
                ["predict", "--out", ws, "--predictors", "oc,kalman"], ["generate", "--out", ws],
                ["generate", "--out", ws, "--model", "bogus"], ["generate", "--out", ws, "--start", "1", "1", "0", "--goal", "1", "1", "0"],
                ["fit-ioc", "--out", ws], ["fit-ioc", "--out", ws, "--model", "bogus"], ["velocity-commands", "--out", ws],
                ["import", f"{ws}/missing.yaml", "--out", ws], ["import", f"{ws}/missing.yaml", "--out", ws, "--map", "LASI"],
                ["import-published", "walking-2020", f"{ws}/missing", "--out", ws], ["preprocess", "--out", ws],
                ["report", "--out", ws], ["bag-info", f"{ws}/missing.bag"]]
    out = subprocess.run([sys.executable, "-c", PROBE, json.dumps(commands)], capture_output=True, text=True, check=True).stdout
    results = [json.loads(line) for line in out.splitlines() if line.startswith('{"argv"')]
    assert [(r["argv"], r["code"], [m for m in r["heavy"] if m != "numpy"]) for r in results] == [(argv, 2, []) for argv in commands]
    assert not any(tmp_path.iterdir())


def test_the_lazy_pandas_imports_pandas_at_its_first_use_and_is_pandas_then():
    code = ("import sys\nfrom cobot_analysis.lazy import pandas as pd\nbefore = 'pandas' in sys.modules\n"
            "frame = pd.DataFrame({'x': [1.0]})\nimport pandas\n"
            "print(before, pd.DataFrame is pandas.DataFrame, pd.concat is pandas.concat, isinstance(frame, pandas.DataFrame))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "True", "True", "True"]


def test_main_chooses_the_system_allocator_for_arrow_and_the_library_does_not():
    env = {k: v for k, v in os.environ.items() if k != "ARROW_DEFAULT_MEMORY_POOL"}

    def backend(code: str) -> list[str]:
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout.split()

    default = backend("import pyarrow as pa; print(pa.default_memory_pool().backend_name)")
    # what a localisation run does to its process before reading a bag leaves Arrow's allocator alone
    run = backend("import pyarrow as pa; from cobot_analysis.localisation.analysis import _return_freed_memory; "
                  "_return_freed_memory(); print(pa.default_memory_pool().backend_name)")
    assert run == default
    # main() ends the process (os._exit after the exit handlers): the check runs as an exit handler
    main = backend("import atexit, os, sys; from cobot_analysis import cli; sys.argv = ['cobot-analysis', '--help']\n"
                   "def report():\n    import pyarrow as pa\n"
                   "    print(os.environ['ARROW_DEFAULT_MEMORY_POOL'], pa.default_memory_pool().backend_name)\n"
                   "atexit.register(report)\ncli.main()\n")
    assert main[-2:] == ["system", "system"]


def test_a_run_builds_only_the_command_it_runs_and_the_group_is_typers(tmp_path, monkeypatch):
    import typer.main

    from cobot_analysis.cli import app, click_group, run

    lazy, eager = click_group(app), typer.main.get_command(app)
    assert list(lazy.commands) == list(eager.commands)
    for name in eager.commands:
        assert [(p.name, p.opts, p.default) for p in lazy.commands[name].params] == \
            [(p.name, p.opts, p.default) for p in eager.commands[name].params]
    built = []
    build = typer.main.get_command_from_info
    monkeypatch.setattr(typer.main, "get_command_from_info", lambda info, **kw: built.append(info.name) or build(info, **kw))
    assert run(["-q", "localisation", str(tmp_path / "missing.bag"), "--out", str(tmp_path)]) == 2
    assert built == ["localisation"]


def test_the_packages_version_is_read_when_asked_for():
    code = ("import sys, cobot_analysis\nbefore = 'importlib.metadata' in sys.modules\n"
            "import importlib.metadata as md\nprint(before, cobot_analysis.__version__ == md.version('cobot-analysis'))")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split() == ["False", "True"]


def test_localisation_runs_on_one_openblas_thread_unless_the_user_chose(tmp_path):
    code = ("import os\nfrom cobot_analysis.cli import run\n"
            f"code = run(['-q', 'localisation', {str(tmp_path / 'missing.bag')!r}, '--out', {str(tmp_path)!r}])\n"
            "print(code, os.environ.get('OPENBLAS_NUM_THREADS'))")
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    for given, expected in ((None, "1"), ("2", "2")):
        run_env = env if given is None else {**env, "OPENBLAS_NUM_THREADS": given}
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=run_env).stdout.split()
        assert out == ["2", expected]


def test_an_in_process_localisation_run_leaves_the_garbage_collector_on(cli, tmp_path):
    import gc

    assert gc.isenabled()
    assert cli("-q", "localisation", str(tmp_path / "missing.bag"), "--out", str(tmp_path))[0] == 2
    assert gc.isenabled()
