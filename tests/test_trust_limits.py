"""Issue 21: inputs that raised internal errors (exit 1) or got the process killed are refused,
exit 2, one line, before any work, nothing left in the workspace."""

from __future__ import annotations

import socket
import sys
import time
from pathlib import Path

import pytest

from cobot_analysis.errors import InputError

sys.path.insert(0, str(Path(__file__).parent))
from test_import import assert_rejected, person, write_qtm_tsv, write_vicon_csv  # noqa: E402
from test_preprocess import trials_row, walking_trial, write_workspace  # noqa: E402
from test_trust_inputs import one_trial_protocol  # noqa: E402


def _one_line_refusal(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("preprocess ━")]
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


@pytest.mark.parametrize("writer, name", [(write_vicon_csv, "a.csv"), (write_qtm_tsv, "a.tsv")])
def test_a_20_mb_line_in_a_marker_file_is_refused_before_reading(tmp_path, cli, writer, name):
    f = writer(tmp_path / name, person(30))
    lines = f.read_text().split("\n")
    lines.insert(len(lines) - 5, "1," * (10 << 20))  # 20 MB, inside the data rows
    f.write_text("\n".join(lines))
    t0 = time.perf_counter()
    assert_rejected(cli, tmp_path / "ws", [one_trial_protocol(tmp_path, f)], f"{name}: line", "is longer than 1024 kB: not a marker export")
    assert time.perf_counter() - t0 < 30  # was a MemoryError after 66 s (generous bound: the machine is shared)


def test_a_data_row_wider_than_its_header_is_refused(tmp_path, cli):
    f = write_vicon_csv(tmp_path / "a.csv", person(30))
    lines = f.read_text().split("\n")
    lines[13] += ",1" * 5000
    f.write_text("\n".join(lines))
    assert_rejected(cli, tmp_path / "ws", [one_trial_protocol(tmp_path, f)], "a.csv: data row at line 14 has 5017 cells, the header 17")


def test_a_yaml_protocol_nested_5000_deep(tmp_path, cli):
    p = tmp_path / "protocol.yaml"
    p.write_text("study: x\ntrials: " + "[" * 5000 + "]" * 5000 + "\n")
    assert_rejected(cli, tmp_path / "ws", [p], "protocol.yaml: not a protocol: its YAML is nested too deeply")


@pytest.fixture()
def walking_ws(tmp_path):
    ws = tmp_path / "ws"
    write_workspace(ws, walking_trial("W1"), [trials_row("W1", subject="S01")])
    return ws


def test_absurd_samples_are_refused_before_allocating(walking_ws, cli):
    """At 1e8 the process grew to 22 GB and was killed, leaving a .tmp folder."""
    code, _, err = cli("preprocess", "--out", walking_ws, "--jobs", "1", "--samples", str(10**12))
    assert code == 2
    line = _one_line_refusal(err)
    assert "--samples 1000000000000 would need about" in line and "GB of memory available" in line, line
    assert not (walking_ws / "preprocess").exists() and not list(walking_ws.glob(".preprocess*"))


@pytest.mark.parametrize("option", ["--max-gap", "--min-duration", "--cutoff", "--speed-threshold"])
def test_infinite_durations_are_refused(walking_ws, cli, option):
    """--max-gap inf and --min-duration inf raised OverflowError (exit 1); NaN is a usage error of the CLI already."""
    code, _, err = cli("preprocess", "--out", walking_ws, "--jobs", "1", option, "inf")
    assert code == 2, err
    assert f"{option} inf is not a finite number {'> 0' if option == '--cutoff' else '>= 0'}" in _one_line_refusal(err)
    assert not (walking_ws / "preprocess").exists()


def test_params_are_validated_in_the_library():
    from cobot_analysis.preprocess.stage import Params

    with pytest.raises(InputError, match="--max-gap inf is not a finite number >= 0"):
        Params(max_gap=float("inf"))
    with pytest.raises(InputError, match="--min-duration nan is not a finite number >= 0"):
        Params(min_duration=float("nan"))
    with pytest.raises(InputError, match="--samples 1 is not an integer >= 2"):
        Params(n_samples=1)
    assert Params().memory_bytes(10) == 500 * 10 * Params().memory_bytes(1) // 500


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed once the socket is


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:{port}", "127.0.0.1:{port}"])
def test_a_scheduler_on_a_closed_port_fails_fast(walking_ws, cli, address):
    """Was an OSError after 32 s."""
    address = address.format(port=_closed_port())
    t0 = time.perf_counter()
    code, _, err = cli("preprocess", "--out", walking_ws, "--scheduler", address)
    assert code == 2, err
    assert time.perf_counter() - t0 < 15
    line = _one_line_refusal(err)
    assert f"--scheduler {address}: no Dask scheduler answers at 127.0.0.1:" in line and "Connection refused" in line, line
    assert not (walking_ws / "preprocess").exists() and not list(walking_ws.glob(".preprocess*"))


def test_a_malformed_scheduler_address():
    from cobot_analysis.parallel import check_scheduler

    with pytest.raises(InputError, match="--scheduler 'tcp://host:port' is not a scheduler address"):
        check_scheduler("tcp://host:port")
