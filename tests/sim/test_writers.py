"""File round trips: what the simulator writes, pymavlink and the project's CSV reader read back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from pymavlink import DFReader, mavutil

from mav_motor_health.errors import DataError
from mav_motor_health.sim.engine import run_scenario
from mav_motor_health.sim.scenario import scenario_from_dict
from mav_motor_health.sim.writers import truth_path, write_record
from mav_motor_health.telemetry.csv import read_csv
from mav_motor_health.telemetry.mavlink_esc import RPM_TO_RAD_S, motor_for_output, pwm_range


@pytest.fixture(scope="module")
def record():
    scenario = scenario_from_dict(
        {
            "scenario": {"name": "round trip", "mode": "flight", "duration_s": 6.0, "seed": 11, "dt_s": 0.01},
            "flight": {"turbulence": "moderate"},
            "fault": [{"kind": "F4.1", "motor": 5, "onset_s": 3.0, "severity": 0.8}],
            "sensors": {"rate_hz": [20.0, 40.0], "dropout": 0.02},
        }
    )
    return run_scenario(scenario)


def test_tlog_reads_back_with_pymavlink(record, tmp_path: Path):
    path, truth = write_record(record, tmp_path / "flight.tlog")
    log = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    params: dict[str, float] = {}
    esc: dict[int, list[int]] = {m: [] for m in range(1, 7)}
    counts: dict[str, int] = {}
    heartbeat = None
    while (msg := log.recv_match()) is not None:
        kind = msg.get_type()
        counts[kind] = counts.get(kind, 0) + 1
        if kind == "PARAM_VALUE":
            params[msg.param_id] = msg.param_value
        elif kind == "HEARTBEAT" and heartbeat is None:
            heartbeat = msg
        elif kind in ("ESC_TELEMETRY_1_TO_4", "ESC_TELEMETRY_5_TO_8"):
            first = 0 if kind.endswith("1_TO_4") else 4
            for k in range(4):
                output = first + k + 1
                motor = motor_for_output(output, params)
                if motor is not None and msg.count[k]:
                    esc[motor].append(msg.rpm[k])
    assert heartbeat.type == mavutil.mavlink.MAV_TYPE_HEXAROTOR
    assert heartbeat.autopilot == mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert params["FRAME_CLASS"] == 2 and params["FRAME_TYPE"] == 1
    assert pwm_range(params) == (1000.0, 2000.0)
    assert [params[f"SERVO{n}_FUNCTION"] for n in range(1, 7)] == [33, 34, 35, 36, 37, 38]
    for name in ("SERVO_OUTPUT_RAW", "SYS_STATUS", "BATTERY_STATUS", "VFR_HUD", "GLOBAL_POSITION_INT"):
        assert counts[name] > 0
    # the values written: each ESC's last rpm in the file is the last sample the simulation produced
    for m in range(1, 7):
        last = [s for s in record.esc if s.motor == m][-1]
        assert esc[m][-1] == last.rpm
    assert json.loads(truth.read_text())["faults"][0]["motor"] == 5


def test_dataflash_reads_back_with_dfreader(record, tmp_path: Path):
    path, _ = write_record(record, tmp_path / "flight.bin")
    log = DFReader.DFReader_binary(str(path))
    esc, rcou, bat, parm = [], [], [], {}
    while (msg := log.recv_msg()) is not None:
        kind = msg.get_type()
        if kind == "ESC":
            esc.append((msg.TimeUS, msg.Instance, msg.RPM, msg.Curr, msg.Volt, msg.Temp))
        elif kind == "RCOU":
            rcou.append(msg.C1)
        elif kind == "BAT":
            bat.append(msg.Volt)
        elif kind == "PARM":
            parm[msg.Name] = msg.Value
    assert len(esc) == len(record.esc)
    for (us, inst, rpm, curr, volt, temp), s in zip(esc, record.esc):
        assert us == round(s.time_s * 1e6) and inst == s.motor - 1 and rpm == s.rpm
        assert curr == pytest.approx(s.esc_current_ca / 100, abs=1e-4)
        assert volt == pytest.approx(s.voltage_cv / 100, abs=1e-4)
        assert temp == pytest.approx(s.temp_c)
    assert rcou == [v.pwm_us[0] for v in record.vehicle]
    assert bat[0] == pytest.approx(record.vehicle[0].bus_voltage_v, abs=1e-4)
    assert parm["SERVO3_FUNCTION"] == 35 and parm["MOT_PWM_MAX"] == 2000


def test_dataflash_formats_match_a_real_ardupilot_log(real_logs, record, tmp_path: Path):
    path, _ = write_record(record, tmp_path / "flight.bin")
    ours = DFReader.DFReader_binary(str(path))
    real = DFReader.DFReader_binary(str(real_logs / "ardupilot_sitl" / "hexa_motor1_half.bin"))
    for name in ("ESC", "RCOU", "BAT", "PARM", "MSG"):
        mine = next(f for f in ours.formats.values() if f.name == name)
        theirs = next(f for f in real.formats.values() if f.name == name)
        assert (mine.type, mine.format, mine.columns, mine.len) == (
            theirs.type,
            theirs.format,
            theirs.columns,
            theirs.len,
        )


def test_csv_reads_back_in_the_project_format(record, tmp_path: Path):
    path, _ = write_record(record, tmp_path / "flight.csv")
    table = read_csv(path)
    assert len(table) == len(record.esc)
    mine = sorted((s.motor, s.time_s, s.rpm * RPM_TO_RAD_S, s.motor_current_ca / 100) for s in record.esc)
    order = np.lexsort((table["time_s"], table["motor"]))
    np.testing.assert_allclose(table["time_s"][order], [m[1] for m in mine])
    np.testing.assert_allclose(table["omega_rad_s"][order], [m[2] for m in mine])
    np.testing.assert_allclose(table["current_a"][order], [m[3] for m in mine])
    np.testing.assert_allclose(table.voltage_v(), table["throttle"] * table["bus_voltage_v"])
    assert set(table.motors()) == {1, 2, 3, 4, 5, 6}


def test_writers_never_overwrite(record, tmp_path: Path):
    path, _ = write_record(record, tmp_path / "a.csv")
    with pytest.raises(DataError, match="not overwritten"):
        write_record(record, path)
    truth_path(tmp_path / "b.csv").write_text("{}")
    with pytest.raises(DataError, match=r"b\.csv\.truth\.json"):
        write_record(record, tmp_path / "b.csv")
    write_record(record, path, force=True)
    with pytest.raises(DataError, match="expected one of"):
        write_record(record, tmp_path / "a.ulg")
