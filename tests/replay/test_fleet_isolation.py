"""A fleet replay isolates each log: a bug met in one log is an ERROR row, and the other logs finish."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.replay import replay_many
from mav_motor_health.telemetry import sources

SITL_LOGS = Path(__file__).resolve().parents[2] / "sitl_logs"


def _reader_with_a_bug(path: Path):
    raise ZeroDivisionError("a bug in a reader")


@pytest.fixture
def fleet_logs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    # a format whose reader has a bug, registered where every reader is (inherited by forked workers)
    monkeypatch.setitem(sources.READERS, ".buggy", _reader_with_a_bug)
    logs = tmp_path / "logs"
    logs.mkdir()
    a = shutil.copy(SITL_LOGS / "flight_F4.1_calm.csv", logs / "a.csv")
    broken = logs / "broken.buggy"
    broken.write_bytes(b"anything")
    b = shutil.copy(SITL_LOGS / "flight_F4.1_moderate.tlog", logs / "b.tlog")
    return [Path(a), broken, Path(b)]


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_crash_in_one_log_is_an_error_row_and_the_others_finish(tmp_path, fleet_logs, jobs: int) -> None:
    out = tmp_path / f"out{jobs}"
    fleet = replay_many(fleet_logs, out, load_motor_params(), load_profile("flight"), jobs=jobs)
    by_log = {Path(r.log).name: r for r in fleet.results}
    assert by_log["broken.buggy"].error is not None
    assert "internal error (ZeroDivisionError: a bug in a reader)" in by_log["broken.buggy"].error
    assert by_log["a.csv"].error is None and by_log["b.tlog"].error is None
    assert (out / "a_csv" / "diagnosis.csv").exists() and (out / "b_tlog" / "report.html").exists()
    with (out / "fleet_summary.csv").open(encoding="utf-8") as handle:
        rows = {Path(r["log"]).name: r for r in csv.DictReader(handle)}
    assert rows["broken.buggy"]["verdict"] == "ERROR"
    assert "ZeroDivisionError" in rows["broken.buggy"]["error"]
    assert {rows["a.csv"]["verdict"], rows["b.tlog"]["verdict"]} <= {"FAULT", "NORMAL"}
    detail = {Path(d["log"]).name: d for d in json.loads((out / "fleet_summary.json").read_text())}
    assert "Traceback" in detail["broken.buggy"]["warning_messages"][0]  # the whole story, for a bug report


def test_the_command_says_which_log_failed_exits_1_and_reruns_with_force(
    tmp_path, fleet_logs, capsys
) -> None:
    out = tmp_path / "out"
    args = ["replay", *map(str, fleet_logs), "--out", str(out), "--jobs", "2"]
    assert main(args) == 1
    assert (out / "fleet_summary.csv").exists()
    assert main(args) == 2  # the outputs are not overwritten without --force ...
    assert "use --force" in capsys.readouterr().err
    assert main([*args, "--force"]) == 1  # ... and are with it
