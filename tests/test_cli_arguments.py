"""Bad arguments and inputs at the command line: one line naming what is wrong, and a non-zero exit."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from mav_motor_health.cli import main

SITL_LOGS = Path(__file__).resolve().parents[1] / "sitl_logs"
CSV = str(SITL_LOGS / "flight_F4.1_calm.csv")


def _run(capsys, argv: list[str]) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own errors
        code = int(exc.code or 0)
    return code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["replay", CSV, "--params", "{folder}", "--out", "{tmp}/o"], "is a folder (expected a TOML file)"),
        (["replay", CSV, "--profile", "{folder}", "--out", "{tmp}/o"], "is a folder (expected a TOML file)"),
        (["sim", "--connect", "udpout:127.0.0.1:99999"], "argument --connect: bad MAVLink URL"),
        (
            ["sim", "--connect", "udpout:127.0.0.1:5760", "--speed", "0"],
            "argument --speed: expected a number > 0",
        ),
        (["display", "--port", "99999"], "argument --port: expected a port number 1..65535, got 99999"),
        (["agent", "--connect", "{tmp}/missing.tlog"], "missing.tlog: file not found"),
        (["agent", "--connect", "{tmp}/empty.tlog"], "empty.tlog: empty file: no MAVLink messages"),
        (["replay", CSV, "--jobs", "0"], "argument --jobs: expected a whole number >= 1, got 0"),
        (["replay", CSV, "--jobs", "-3"], "argument --jobs: expected a whole number >= 1, got -3"),
        (["agent", "--sim", "--duration", "-5"], "argument --duration: expected a number > 0, got -5"),
        (["predict", "--voltage", "-5"], "argument --voltage: expected a number >= 0, got -5"),
        (["predict", "--voltage", "nan"], "argument --voltage: expected a finite number"),
        (["simulate", "flight/healthy_calm", "--out", "{tmp}/x.csv", "--duration", "0"], "--duration"),
        (["sim", "--connect", "udpout:127.0.0.1:5760", "--fault", "X@a:b"], "bad fault 'X@a:b'"),
    ],
)
def test_bad_input_gets_one_clear_line_and_a_failing_exit(capsys, tmp_path, argv, says) -> None:
    folder = tmp_path / "a_folder"
    folder.mkdir()
    (tmp_path / "empty.tlog").write_bytes(b"")
    argv = [a.format(folder=folder, tmp=tmp_path) for a in argv]
    code, err = _run(capsys, argv)
    assert code == 2
    assert says in err
    assert "Traceback" not in err
    last = [line for line in err.splitlines() if line.strip()][-1]
    assert "error:" in last and says.split(":")[0] in last


def test_replay_and_the_agent_start_without_scipy_optimize() -> None:
    """Only the fits need scipy.optimize, whose import takes about a third of the package's (issue 18):
    the command line, replay and the agent do not import it until a fit runs."""
    code = (
        "import sys, mav_motor_health.cli, mav_motor_health.replay, mav_motor_health.agent\n"
        "assert 'scipy.optimize' not in sys.modules, 'imported at start'\n"
        "from mav_motor_health.model.lsq import fit_linear\n"
        "fit_linear([[1.0], [2.0]], [2.0, 4.0], ['k'])\n"
        "assert 'scipy.optimize' in sys.modules, 'a fit imports it'\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
