"""The vehicle check: a model most motors depart from the same way is the model's fault, not theirs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mav_motor_health.diagnosis import MotorState
from mav_motor_health.diagnosis.vehicle_check import (
    VehicleCheck,
    VehicleCheckRule,
    VehicleFit,
    apply_vehicle_fit,
)
from mav_motor_health.errors import ConfigError


def _flight(
    ratios: dict[int, float], seconds: float = 6.0, rate_hz: float = 25.0, seed: int = 3
) -> tuple[np.ndarray, ...]:
    """Rows in time order: each motor turns at ``ratio`` × the model's speed, with noise and gusts."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate_hz)
    motors = sorted(ratios)
    time_s = np.repeat(t, len(motors))
    motor = np.tile(motors, t.size)
    model = 600.0 + 150.0 * np.sin(2 * np.pi * 0.7 * time_s) + rng.normal(0, 20, time_s.size)
    ratio = np.array([ratios[m] for m in motor])
    omega = model * ratio + rng.normal(0, 15, time_s.size)
    return time_s, motor, omega, model


def _check(motors=(1, 2, 3, 4, 5, 6), **rule) -> VehicleCheck:
    return VehicleCheck(VehicleCheckRule(**rule), list(motors), stop_speed_rad_s=100.0)


def test_a_model_most_motors_depart_from_the_same_way_does_not_fit() -> None:
    rows = _flight({1: 0.74, 2: 0.75, 3: 0.76, 4: 0.75, 5: 0.74, 6: 0.75})
    codes = _check().update(*rows)
    assert codes[0] == VehicleFit.CHECKING
    assert codes[-1] == VehicleFit.SPEED_OFF
    first_off = np.flatnonzero(codes == VehicleFit.SPEED_OFF)[0]
    assert rows[0][first_off] >= 2.0  # not before min_span_s of evidence
    assert np.all(codes[first_off:] == VehicleFit.SPEED_OFF)


@pytest.mark.parametrize("faulty", [1, 2])
def test_one_or_two_faulty_motors_are_not_a_wrong_model(faulty: int) -> None:
    ratios = {m: 1.0 for m in range(1, 7)}
    for m in range(1, faulty + 1):
        ratios[m] = 0.4  # stopped or slowed far beyond the band
    codes = _check().update(*_flight(ratios))
    assert set(np.unique(codes[codes != VehicleFit.CHECKING])) == {VehicleFit.FITS}


def test_three_slowed_motors_of_six_are_no_majority_four_are() -> None:
    ratios = {m: 1.0 for m in range(1, 7)}
    ratios.update({1: 0.6, 2: 0.6, 3: 0.6})
    assert _check().update(*_flight(ratios))[-1] == VehicleFit.FITS
    ratios[4] = 0.6
    assert _check().update(*_flight(ratios))[-1] == VehicleFit.SPEED_OFF


def test_a_departure_within_the_motor_types_spread_fits() -> None:
    spread = _flight({1: 1.04, 2: 0.97, 3: 1.06, 4: 0.95, 5: 1.02, 6: 0.98})
    assert _check().update(*spread)[-1] == VehicleFit.FITS
    assert _check(speed_departure=0.03).update(*spread)[-1] == VehicleFit.FITS  # no common direction
    common = _flight({1: 1.04, 2: 1.05, 3: 1.06, 4: 1.05, 5: 1.04, 6: 1.05})
    assert _check().update(*common)[-1] == VehicleFit.FITS
    assert _check(speed_departure=0.03).update(*common)[-1] == VehicleFit.SPEED_OFF


def test_the_same_codes_row_by_row_and_in_any_chunking() -> None:
    rows = _flight({1: 0.88, 2: 0.9, 3: 0.91, 4: 0.86, 5: 1.0, 6: 0.89}, seconds=8.0)
    whole = _check().update(*rows)
    assert {VehicleFit.CHECKING, VehicleFit.SPEED_OFF} <= set(np.unique(whole).tolist())
    rng = np.random.default_rng(7)
    for _ in range(3):
        check = _check()
        cuts = np.sort(rng.choice(np.arange(1, rows[0].size), size=40, replace=False))
        parts = [check.update(*(c[a:b] for c in rows)) for a, b in zip([0, *cuts], [*cuts, rows[0].size])]
        assert np.array_equal(np.concatenate(parts), whole)
        assert check.departures() == pytest.approx(_check_after(rows).departures(), rel=0, abs=0)


def _check_after(rows) -> VehicleCheck:
    check = _check()
    check.update(*rows)
    return check


def test_a_single_motor_on_a_stand_is_never_held_back() -> None:
    rows = _flight({1: 0.5})
    assert not np.any(_check(motors=(1,)).update(*rows))


def test_rows_below_the_stop_speed_or_without_a_model_are_not_evidence() -> None:
    time_s, motor, omega, model = _flight({m: 0.5 for m in range(1, 7)})
    model = np.where(time_s < 4.0, 50.0, model)  # idle: below the stop speed
    model[::7] = np.nan
    codes = _check().update(time_s, motor, omega, model)
    assert np.all(codes[time_s < 6.0 - 0.05] == VehicleFit.CHECKING)  # 2 s of turning from 4 s on: not yet


def test_announced_states_under_the_verdict() -> None:
    announced = np.array(
        [MotorState.F3_1, MotorState.NORMAL, MotorState.F3_1, MotorState.NO_DATA], dtype=np.int8
    )
    verdict = np.array(
        [VehicleFit.CHECKING, VehicleFit.SPEED_OFF, VehicleFit.FITS, VehicleFit.CHECKING], dtype=np.int8
    )
    out = apply_vehicle_fit(announced, verdict)
    assert out.tolist() == [MotorState.NORMAL, MotorState.UNCALIBRATED, MotorState.F3_1, MotorState.NO_DATA]
    assert not MotorState.UNCALIBRATED.is_fault


def test_the_message_says_how_far_off_and_what_to_do() -> None:
    check = _check()
    check.update(*_flight({m: 0.25 for m in range(1, 7)}))
    text = check.describe(VehicleFit.SPEED_OFF, "params/motors/paper_x2212.toml")
    assert "75 % slower" in text and "fit LOG --out vehicle.toml" in text and "UNCALIBRATED" in text


@pytest.mark.parametrize(
    ("key", "value"),
    [("speed_departure", 0.0), ("speed_departure", 1.5), ("min_samples", 0), ("min_motors", 1)],
)
def test_bad_settings_name_the_key(key: str, value: float) -> None:
    with pytest.raises(ConfigError, match=f"vehicle_check.{key}"):
        VehicleCheckRule(**{key: value})


@pytest.mark.parametrize(
    ("log", "slower"),
    [("px4/esc_status_log.ulg", "75 % slower"), ("ardupilot_sitl/hexa_motor1_half.tlog", "17 % slower")],
)
def test_a_real_log_replayed_with_the_bundled_motor_names_no_fault_and_says_why(
    real_logs, tmp_path, log: str, slower: str
) -> None:
    from mav_motor_health.config import load_motor_params, load_profile
    from mav_motor_health.replay import replay_log

    with pytest.warns(UserWarning, match="does not describe this vehicle"):
        result = replay_log(real_logs / log, tmp_path / "out", load_motor_params(), load_profile("flight"))
    assert not any(v.is_fault for v in result.verdicts)
    assert {v.state for v in result.verdicts} == {"UNCALIBRATED"}
    assert result.summary_row()["verdict"] == "UNCALIBRATED"
    (line,) = [w for w in result.warnings if "does not describe" in w]
    assert slower in line and "--params" in line
    assert "does not describe this vehicle" in (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    lines = (tmp_path / "out" / "events.jsonl").read_text(encoding="utf-8").splitlines()
    assert {json.loads(line)["state"] for line in lines} == {"UNCALIBRATED"}


def test_the_agent_and_replay_hold_faults_back_alike_while_the_check_gathers_evidence() -> None:
    from mav_motor_health.diagnosis.pipeline import StreamingDiagnoser

    rows = _flight({m: 0.5 for m in range(1, 7)})
    announced = np.full(rows[0].size, MotorState.F1_1, dtype=np.int8)
    whole = StreamingDiagnoser.vehicle_check_for(_flight_profile(), range(1, 7)).update(*rows)
    live = StreamingDiagnoser(_paper(), _flight_profile(), range(1, 7))
    verdicts, states = zip(
        *(
            live.judge_vehicle(*(c[k : k + 1] for c in rows), announced[k : k + 1])
            for k in range(rows[0].size)
        )
    )
    assert np.array_equal(np.concatenate(verdicts), whole)
    states_arr = np.concatenate(states)
    assert set(states_arr[whole == VehicleFit.CHECKING].tolist()) == {MotorState.NORMAL}
    assert set(states_arr[whole == VehicleFit.SPEED_OFF].tolist()) == {MotorState.UNCALIBRATED}


def _paper():
    from mav_motor_health.config import load_motor_params

    return load_motor_params()


def _flight_profile():
    from mav_motor_health.config import load_profile

    return load_profile("flight")
