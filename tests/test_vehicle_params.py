"""The vehicle a params file carries (fit LOG --out): written, read back, and applied by replay and the
agent alike (model/vehicle.py, config.load_vehicle_params, identification.py)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import (
    dump_vehicle_params,
    load_motor_params,
    load_profile,
    load_vehicle_params,
)
from mav_motor_health.diagnosis.noise import band_noise_of
from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.diagnosis.plausibility import SensorIssue
from mav_motor_health.errors import ConfigError
from mav_motor_health.identification import identify_logs, join_flights
from mav_motor_health.model.identify import CurrentReading, EscMap
from mav_motor_health.model.vehicle import VehicleParams, calibrate_columns
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.csv import write_csv
from mav_motor_health.telemetry.table import TelemetryTable

SITL_LOGS = Path(__file__).resolve().parents[1] / "sitl_logs"
CALM = SITL_LOGS / "flight_healthy_calm.csv"


@pytest.fixture(scope="module")
def identified():
    return identify_logs([CALM])


def test_an_identified_vehicle_survives_the_params_file(identified, tmp_path: Path) -> None:
    path = tmp_path / "vehicle.toml"
    path.write_text(dump_vehicle_params(identified.vehicle), encoding="utf-8")
    back = load_vehicle_params(path)
    v = identified.vehicle
    assert back.motor == v.motor and back.motor.J_kg_m2 is not None
    assert back.esc == v.esc
    assert (back.current.side, back.current.gain, back.current.gain_from) == (
        v.current.side,
        v.current.gain,
        v.current.gain_from,
    )
    assert set(back.per_motor) == set(range(1, 7))
    for n in range(1, 7):
        assert (back.per_motor[n].R_ohm, back.per_motor[n].k_e) == (v.per_motor[n].R_ohm, v.per_motor[n].k_e)
        # a vehicle file leaves out what is NaN (an after-step bin not measured): read back as NaN
        assert back.noise[n] == pytest.approx({k: x for k, x in v.noise[n].items() if math.isfinite(x)})
        np.testing.assert_array_equal(
            band_noise_of(back.noise)[n].after_step, band_noise_of(v.noise)[n].after_step
        )
        assert back.noise[n]["voltage_v"] > 0 and back.noise[n]["torque_nm"] > 0
        assert back.noise[n]["speed_rad_s"] > 0 and back.noise[n]["current_a"] > 0  # the band noise
    assert back.source["identified_from"] == str(CALM)
    assert back.missing_for_flight() == []
    # a plain motor file is a vehicle whose ESC map is unknown, and it says which keys it lacks
    plain = load_vehicle_params("paper_x2212")
    assert plain.esc is None and plain.per_motor == {}
    assert [m.split(" ")[0] for m in plain.missing_for_flight()] == ["esc.idle_offset"]
    # and a vehicle file still reads as a motor file for the tools that need only the motor type
    assert load_motor_params(path) == v.motor


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("[esc]\nidle_offset = 0.9\n", "esc.idle_offset"),
        ('[current]\nside = "phase"\n', "current.side"),
        ("[per_motor.40]\nk_e = 0.01\n", "per_motor.40"),
        ("[per_motor.2]\nk_e = -1.0\n", "per_motor.2.k_e"),
        ("[esc]\nidle_offset = 0.02\nspare = 1\n", "esc"),
    ],
)
def test_a_bad_vehicle_section_is_refused_naming_the_key(tmp_path: Path, text: str, key: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text("[motor]\nR_ohm = 0.1\nk_e = 0.01\nC_p = 1e-10\n" + text, encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        load_vehicle_params(path)
    assert key in str(err.value) and str(path) in str(err.value)


def test_calibration_turns_command_and_reading_into_duty_and_true_current() -> None:
    command = np.array([0.03, 0.05, 0.5, 1.0])
    cols = {
        "throttle": command,
        "bus_voltage_v": np.full(4, 20.0),
        "esc_current_a": np.array([0.0, 0.8, 4.0, 16.0]),
    }
    esc = EscMap(idle_offset=0.05)
    duty = (command - 0.05) / 0.95
    out = calibrate_columns(cols, esc, CurrentReading(side="input", gain=0.8))
    assert out["throttle"] == pytest.approx(np.clip(duty, 0, 1))
    assert out["command"] is not None and np.array_equal(out["command"], command)
    assert out["voltage_v"] == pytest.approx(np.clip(duty, 0, 1) * 20.0)
    assert out["esc_current_a"] == pytest.approx(cols["esc_current_a"] / 0.8)
    assert out["current_a"][2:] == pytest.approx(cols["esc_current_a"][2:] / 0.8 / duty[2:])
    assert np.isnan(out["current_a"][:2]).all()  # below the minimum duty the quotient means nothing
    motor_side = calibrate_columns(cols, esc, CurrentReading(side="motor", gain=0.8))
    assert motor_side["current_a"][2:] == pytest.approx(cols["esc_current_a"][2:] / 0.8)
    assert motor_side["esc_current_a"] == pytest.approx(np.clip(duty, 0, 1) * cols["esc_current_a"] / 0.8)
    unusable = calibrate_columns(cols, esc, CurrentReading(side="unusable"))
    assert np.isnan(unusable["esc_current_a"]).all() and np.isnan(unusable["current_a"]).all()
    assert calibrate_columns(cols, None, None) == cols  # no ESC map: nothing changes


def _as_logged_through(table: TelemetryTable, c0: float, gain: float) -> TelemetryTable:
    """What a log of the same flight holds when the ESC has an idle offset and its sensor a gain error:
    the autopilot's command, the voltage a reader derives from it, the sensor's reading."""
    duty = table["throttle"]
    command = c0 + duty * (1.0 - c0)
    reading = gain * table["esc_current_a"]
    return table.with_columns(
        throttle=command,
        voltage_v=command * table["bus_voltage_v"],
        esc_current_a=reading,
        current_a=reading / command,
    )


def test_replay_with_the_vehicle_undoes_its_esc_offset_and_sensor_gain(tmp_path: Path) -> None:
    original = sources.read(CALM)
    profile = load_profile("flight")
    motor = load_motor_params()
    logged = _as_logged_through(original, c0=0.05, gain=0.8)
    vehicle = VehicleParams(
        motor=motor, esc=EscMap(idle_offset=0.05), current=CurrentReading(side="input", gain=0.8)
    )
    truth = diagnose(original, motor, profile)
    calibrated = diagnose(vehicle.calibrate(logged), motor, profile)
    naive = diagnose(logged, motor, profile)
    healthy = truth["announced"] == 0
    assert healthy.mean() > 0.95
    agree = np.mean(calibrated["announced"] == truth["announced"])
    assert agree > 0.999, agree
    assert np.mean(naive["announced"] == truth["announced"]) < 0.9  # what a user without the map got
    # the CLI: the same log through replay with the vehicle file gives no fault
    log = tmp_path / "offset.csv"
    write_csv(logged, log)
    params = tmp_path / "vehicle.toml"
    params.write_text(dump_vehicle_params(vehicle), encoding="utf-8")
    assert (
        main(
            ["replay", str(log), "--params", str(params), "--profile", "flight", "--out", str(tmp_path / "r")]
        )
        == 0
    )
    events = (tmp_path / "r" / "events.jsonl").read_text(encoding="utf-8")
    assert '"F' not in events and "STALL" not in events


def test_replay_warns_once_naming_what_a_motor_file_lacks_for_flight(tmp_path: Path) -> None:
    no_j = tmp_path / "no_j.toml"
    no_j.write_text("[motor]\nR_ohm = 0.165\nk_e = 0.00975\nC_p = 1.692e-10\n", encoding="utf-8")
    logs = [CALM, SITL_LOGS / "flight_F4.1_calm.csv"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(
            [
                "replay",
                *map(str, logs),
                "--params",
                str(no_j),
                "--profile",
                "flight",
                "--out",
                str(tmp_path / "o"),
            ]
        )
    assert code == 0
    said = [str(w.message) for w in caught if str(no_j) in str(w.message)]
    assert len([s for s in said if "motor.J_kg_m2" in s]) == 1, said
    assert len([s for s in said if "esc.idle_offset" in s]) == 1, said


def test_fit_on_flight_logs_writes_a_vehicle_and_refuses_to_overwrite(
    tmp_path: Path, capsys, real_logs
) -> None:
    out = tmp_path / "vehicle.toml"
    assert main(["fit", str(CALM), str(SITL_LOGS / "flight_healthy_long.tlog"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Identification from flight" in text and "2 log(s)" in text and "determined by" in text
    vehicle = load_vehicle_params(out)
    assert vehicle.esc is not None and vehicle.current is not None and vehicle.motor.J_kg_m2
    before = out.read_bytes()
    assert main(["fit", str(CALM), "--out", str(out)]) == 2
    assert out.read_bytes() == before  # nothing the user had is overwritten
    # a test stand's steps still go to the bench fit
    bench = real_logs / "bench" / "dtu" / "3508-700_14x5.5.txt"
    assert main(["fit", str(bench)]) == 0
    assert "Two-step Levenberg-Marquardt" in capsys.readouterr().out


def test_flights_are_joined_with_a_gap_so_no_balance_spans_two() -> None:
    a = sources.read(CALM)
    joined = join_flights([a, a])
    t = joined["time_s"]
    assert len(joined) == 2 * len(a)
    first_end = float(np.max(a["time_s"]))
    assert np.min(t[len(a) :]) >= first_end + 59.9 or np.min(t[t > first_end]) >= first_end + 59.9
    assert math.isfinite(float(np.max(t)))


def test_the_real_px4_quad_identified_from_its_own_log_replays_without_a_fault(
    real_logs, tmp_path: Path, capsys
) -> None:
    log = real_logs / "px4" / "esc_status_log.ulg"
    vehicle_file = tmp_path / "px4.toml"
    assert main(["fit", str(log), "--out", str(vehicle_file)]) == 0
    vehicle = load_vehicle_params(vehicle_file)
    assert vehicle.current is not None and vehicle.current.gain_from == "battery"
    # each motor's noise measured on the flight, so that flight_vehicle's bands come from this vehicle
    assert all(vehicle.noise[m]["speed_rad_s"] > 0 for m in range(1, 5)), vehicle.noise
    # but its ESCs report every 0.3 s, too slowly for the siblings' prediction: said, in the report and
    # the file, and the speed judged motor by motor
    said = [v for k, v in vehicle.source.items() if k.startswith("finding_") and "siblings' prediction" in v]
    assert len(said) == 1 and "every 0.30 s" in said[0], vehicle.source
    assert "siblings' prediction" in capsys.readouterr().out
    assert not any(k.startswith("speed_covariance") for m in vehicle.noise for k in vehicle.noise[m])
    for profile in (None, "flight_vehicle"):  # the default for a vehicle file with its noise, and named
        out = tmp_path / str(profile)
        chosen = [] if profile is None else ["--profile", profile]
        assert main(["replay", str(log), "--params", str(vehicle_file), *chosen, "--out", str(out)]) == 0
        events = (out / "events.jsonl").read_text(encoding="utf-8")
        assert '"F' not in events and "STALL" not in events and "UNCALIBRATED" not in events, events[:500]
    # bands in amperes and rad/s set on the project's simulator are refused for this vehicle's own file
    # (with the ESCs' current read on the input side, as the charges say, they named F1.1/F4.1 here)
    for profile in ("testbed", "flight"):
        out = tmp_path / profile
        assert (
            main(["replay", str(log), "--params", str(vehicle_file), "--profile", profile, "--out", str(out)])
            == 2
        )
        said = capsys.readouterr().err
        assert f"profile {profile!r} has bands in amperes" in said and "'flight_vehicle'" in said
        assert not out.exists()


def test_the_esc_sum_is_checked_against_the_battery_only_where_identification_related_them() -> None:
    """The ESC-sum plausibility check compares the ESCs' summed current with the battery monitor. Where
    identification could not relate the two on this vehicle (the gain assumed), the check has nothing to
    compare and must not set every current aside (it did: most randomised worlds' currents went to the
    speed-only path); where it related them, or without a vehicle file, the check runs as before."""
    table = sources.read(CALM)
    esc = table["esc_current_a"]
    columns = dict(table.columns)
    # the six ESCs' mean total (the motors report at their own instants) and 12 A of avionics, payload
    columns["battery_current_a"] = np.full(len(table), len(table.motors()) * float(np.mean(esc)) + 12.0)
    with_battery = TelemetryTable(columns, source=table.source, meta=table.meta)
    motor = load_motor_params()
    profile = load_profile("flight")
    flagged = SensorIssue.CURRENT_SUM

    def share_flagged(vehicle: VehicleParams | None) -> float:
        data = with_battery if vehicle is None else vehicle.calibrate(with_battery)
        result = diagnose(data, motor, profile)
        return float(np.mean((result["sensor_flags"] & flagged) != 0))

    esc_map = EscMap(idle_offset=0.0)
    # no vehicle file, or a vehicle whose ESCs identification related to the battery: the check runs
    # (the sum 12 A short of the battery: a mismatch)
    assert share_flagged(None) > 0.5
    related = CurrentReading(side="input", gain=1.0, gain_from="battery", offset_a=12.0)
    assert share_flagged(VehicleParams(motor=motor, esc=esc_map, current=related)) > 0.5
    # identification could not relate them: no check, the current stays in use
    assumed = CurrentReading(side="input", gain=1.0, gain_from="assumed")
    assert share_flagged(VehicleParams(motor=motor, esc=esc_map, current=assumed)) == 0.0
