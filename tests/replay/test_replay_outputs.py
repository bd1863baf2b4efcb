"""Replay end to end on the real logs: the three output files, --force, fleet mode, missing telemetry."""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis.pipeline import DIAGNOSIS_COLUMNS
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.replay import Progress, replay_log
from mav_motor_health.telemetry.tlog import read_messages


@pytest.fixture(scope="module")
def tlog_replay(sitl_tlog: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("replay") / "one"
    assert main(["replay", str(sitl_tlog), "--out", str(out)]) == 0
    return out


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_diagnosis_csv_has_one_row_per_motor_sample_with_state_labels(
    tlog_replay: Path, sitl_tlog: Path
) -> None:
    rows = _csv(tlog_replay / "diagnosis.csv")
    header = (tlog_replay / "diagnosis.csv").read_text().splitlines()[0].split(",")
    assert header[: len(DIAGNOSIS_COLUMNS)] == list(DIAGNOSIS_COLUMNS)
    esc = read_messages(sitl_tlog, ["ESC_TELEMETRY_1_TO_4"], warn=False)
    assert len(rows) == 6 * len(esc["ESC_TELEMETRY_1_TO_4"])
    labels = {s.label for s in MotorState}
    assert {r["state"] for r in rows} <= labels and {r["announced"] for r in rows} <= labels
    assert {r["steady"] for r in rows} <= {"0", "1"}
    assert sorted({int(r["motor"]) for r in rows}) == [1, 2, 3, 4, 5, 6]
    for motor in ("1", "4"):
        times = [float(r["time_s"]) for r in rows if r["motor"] == motor]
        assert times == sorted(times)
    hover = [r for r in rows if 60 < float(r["time_s"]) < 100 and r["omega_rad_s"]]
    assert all(float(r["omega_model_rad_s"]) > 0 for r in hover)  # the model ran on every hover sample


def test_events_are_exactly_the_changes_of_announced_state(tlog_replay: Path) -> None:
    rows = _csv(tlog_replay / "diagnosis.csv")
    expected = []
    previous: dict[str, str] = {}
    for r in rows:
        before = previous.get(r["motor"], "NORMAL")
        if r["announced"] != before:
            expected.append((round(float(r["time_s"]), 6), int(r["motor"]), r["announced"], before))
        previous[r["motor"]] = r["announced"]
    events = [json.loads(line) for line in (tlog_replay / "events.jsonl").read_text().splitlines()]
    got = [(round(e["time_s"], 6), e["motor"], e["state"], e["previous"]) for e in events]
    assert sorted(got) == sorted(expected)
    assert len(events) > 0
    for e in events:
        assert set(e["evidence"]) >= {"omega_rad_s", "omega_model_rad_s", "current_a", "current_model_a"}


def test_report_is_self_contained_and_names_every_motor(tlog_replay: Path) -> None:
    page = (tlog_replay / "report.html").read_text()
    # scripts only inline (the top view's time slider, docs/display.md), never loaded from anywhere
    assert not re.search(r"<script[^>]*\bsrc\s*=", page, re.IGNORECASE)
    assert not re.search(r"(src|href)\s*=\s*['\"]?(https?:)?//", page)  # nothing fetched
    assert page.count("<svg") >= 1 + 2 * 6  # timeline + speed and current per motor
    for motor in range(1, 7):
        assert f"Motor {motor} " in page
    assert "Verdict per motor" in page and "Fault timeline" in page


def test_existing_output_is_not_overwritten_without_force(
    sitl_tlog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    keep = out / "notes.txt"
    keep.write_text("mine")
    assert main(["replay", str(sitl_tlog), "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert main(["replay", str(sitl_tlog), "--out", str(out), "--force"]) == 0
    assert keep.read_text() == "mine"
    assert (out / "report.html").exists()


def test_log_without_esc_telemetry_is_an_error_naming_what_it_holds(
    px4_no_esc_ulg: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "none"
    assert main(["replay", str(px4_no_esc_ulg), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "no ESC telemetry" in err and "actuator_outputs" in err and "esc_status" in err
    assert not out.exists()


def test_fleet_mode_replays_a_folder_in_workers_with_a_summary(
    sitl_tlog: Path, px4_esc_ulg: Path, px4_no_esc_ulg: Path, tmp_path: Path
) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    for src in (sitl_tlog, px4_esc_ulg, px4_no_esc_ulg):
        (logs / src.name).symlink_to(src)
    out = tmp_path / "fleet"
    assert main(["replay", str(logs), "--out", str(out), "--jobs", "2"]) == 1  # one log has no ESC data
    summary = _csv(out / "fleet_summary.csv")
    assert [Path(r["log"]).name for r in summary] == sorted(p.name for p in logs.iterdir())
    by_name = {Path(r["log"]).name: r for r in summary}
    assert by_name["quadrotor_local.ulg"]["verdict"] == "ERROR"
    assert "no ESC telemetry" in by_name["quadrotor_local.ulg"]["error"]
    assert by_name["esc_status_log.ulg"]["motors"] == "4"
    for name in ("hexa_motor1_half_tlog", "esc_status_log_ulg"):
        assert sorted(p.name for p in (out / name).iterdir()) == [
            "diagnosis.csv",
            "events.jsonl",
            "report.html",
        ]
    detail = json.loads((out / "fleet_summary.json").read_text())
    assert len(detail) == 3 and all("verdicts" in d for d in detail)
    assert main(["replay", str(logs), "--out", str(out)]) == 2  # exists: not overwritten


def _without_frames(sitl_tlog: Path, name: str, after_s: float) -> bytes:
    """The tlog with every ``name`` frame recorded after ``after_s`` cut out."""
    data = sitl_tlog.read_bytes()
    msgs = read_messages(sitl_tlog, [name], warn=False)
    t = (msgs.time_us[name].astype(np.int64) - msgs.first_time_us) / 1e6
    cut = set(msgs.offsets[name][t > after_s].tolist())
    out = bytearray()
    pos = 0
    for offset in sorted(cut):
        length = 8 + 10 + data[offset + 9] + 2 if data[offset + 8] == 0xFD else 8 + 6 + data[offset + 9] + 2
        out += data[pos:offset]
        pos = offset + length
    out += data[pos:]
    return bytes(out)


@pytest.mark.parametrize(("after_s", "reason"), [(-1.0, "no ESC telemetry"), (60.0, "telemetry stops at")])
def test_missing_or_stopped_motor_telemetry_is_no_data_while_the_others_are_diagnosed(
    sitl_tlog: Path, tmp_path: Path, after_s: float, reason: str
) -> None:
    log = tmp_path / "partial.tlog"
    log.write_bytes(_without_frames(sitl_tlog, "ESC_TELEMETRY_5_TO_8", after_s))
    result = replay_log(log, tmp_path / "out", load_motor_params("paper_x2212"), load_profile("flight"))
    verdicts = {v.motor: v for v in result.verdicts}
    assert sorted(verdicts) == [1, 2, 3, 4, 5, 6]  # FRAME_CLASS 2: six motors expected
    for motor in (5, 6):
        assert verdicts[motor].state == "NO_DATA"
        assert reason in verdicts[motor].reason
    for motor in (1, 2, 3, 4):
        assert verdicts[motor].state != "NO_DATA"
        assert verdicts[motor].samples > 1000
    assert "NO_DATA" in (tmp_path / "out" / "report.html").read_text()


def test_progress_line_goes_to_the_stream() -> None:
    stream = io.StringIO()
    bar = Progress("flight.bin", stream, delay_s=0.0)
    bar.update(2, 4, "diagnosing")
    bar.close()
    assert "flight.bin [############------------] 2/4 diagnosing" in stream.getvalue()
    assert stream.getvalue().endswith("\n")


def test_calibrated_replay_finds_motor_1_on_the_sitl_flight_and_nothing_else(
    sitl_bin: Path, tmp_path: Path
) -> None:
    """MANIFEST: motor 1's thrust halved 110-130 s; calibrated on the hover before, replay names motor 1 only."""
    out = tmp_path / "cal"
    assert main(["replay", str(sitl_bin), "--out", str(out), "--calibrate", "38:108"]) == 0
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    faulty = {e["motor"] for e in events if MotorState.from_label(e["state"]).is_fault}
    assert faulty == {1}
    onset = min(e["time_s"] for e in events if e["motor"] == 1)
    assert 112 < onset < 118  # this log's clock: the command crosses 0.7 at 114.0 s
    page = (out / "report.html").read_text()
    assert "calibrated on 38–108 s" in page


def test_calibration_window_must_be_start_colon_end(sitl_bin: Path, tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as info:
        main(["replay", str(sitl_bin), "--out", str(tmp_path / "x"), "--calibrate", "108:38"])
    assert info.value.code == 2
    assert not (tmp_path / "x").exists()
