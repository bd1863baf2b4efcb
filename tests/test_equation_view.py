"""Each fault judged in the balance it moves (issue 17; diagnosis/rules/equations.py): identification
measures each balance's own noise, the profile's ``equation_bands`` reads F1.1 and F3.1 in the torque
and F4.1 in the voltage, and the sequential test reads the same."""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.config import dump_vehicle_params, load_motor_params, load_profile, load_vehicle_params
from mav_motor_health.diagnosis.detection import DIRECTIONS, equation_evidence
from mav_motor_health.diagnosis.noise import BandNoise, EquationNoise, band_noise_of, measure_band_noise
from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.diagnosis.rules.base import Frame
from mav_motor_health.diagnosis.rules.equations import Equations
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.evaluation.campaign import FlightCase, run_flights
from mav_motor_health.model.vehicle import VehicleParams
from mav_motor_health.telemetry.table import TelemetryTable

FAULTS = ("F1.1", "F3.1", "F4.1")


def _torque_profile():
    """The shipped vehicle profile without the speed against its siblings' prediction: this file's noise is
    measured by measure_band_noise alone, without the siblings' covariances that prediction needs (a test
    of its own: tests/test_sibling_prediction.py)."""
    return dataclasses.replace(load_profile("flight_vehicle"), speed_against_siblings=0.0)


@pytest.fixture(scope="module")
def motor():
    return load_motor_params("paper_x2212")


@pytest.fixture(scope="module")
def flights():
    """A healthy moderate flight to measure the noise on, another to judge, and the three faults whose
    signature is a deviation (motor 2 at 12 s), in moderate air: where the current deviation's band holds
    the paired command's noise as well as the sensor's."""
    cases = [
        FlightCase("moderate", 5200, 40.0),
        FlightCase("moderate", 5201, 30.0),
        *(
            FlightCase("moderate", 5202 + k, 30.0, fault=f, motor=2, onset_s=12.0)
            for k, f in enumerate(FAULTS)
        ),
    ]
    return dict(zip(("identification", "healthy", *FAULTS), run_flights(cases, jobs=2)))


@pytest.fixture(scope="module")
def noise(motor, flights) -> dict[int, BandNoise]:
    """Each motor's noise measured on the identification flight, as ``fit`` measures it: the profile's own
    rule run with no band at all."""
    profile = _torque_profile()
    unbounded = {m: BandNoise.unbounded() for m in range(1, 7)}
    diagnosed = diagnose(flights["identification"].table, motor, profile, unbounded)
    settle_s = float(getattr(profile.steady, "settle_s", 0.0))
    return measure_band_noise(diagnosed, profile.min_command, settle_s)


def _synthetic(rng: np.random.Generator, n: int) -> TelemetryTable:
    """A diagnosed healthy flight whose balances are Gaussian around offsets: the torque with σ =
    √(0.002² + (0.004·a)²) N·m around +0.001, the voltage with σ = √(0.05² + (0.2·a)²) V around −0.03."""
    a = rng.uniform(0.0, 1.0, n)
    w, i = np.full(n, 600.0), np.full(n, 5.0)
    return TelemetryTable(
        {
            "time_s": np.arange(n) * 0.02,
            "motor": np.ones(n, dtype=np.int64),
            "omega_rad_s": w,
            "current_a": i,
            "voltage_v": np.full(n, 8.0),
            "steady": np.ones(n, dtype=bool),
            "throttle": np.full(n, 0.5),
            "omega_judged_rad_s": w + rng.normal(0.0, 5.0, n),
            "omega_model_rad_s": w,
            "current_judged_a": i + rng.normal(0.0, 0.3, n),
            "current_model_a": i,
            "input_activity_v": a,
            "sensor_flags": np.zeros(n, dtype=np.int16),
            "torque_residual_nm": 0.001 + rng.normal(0.0, np.hypot(0.002, 0.004 * a)),
            "voltage_residual_v": -0.03 + rng.normal(0.0, np.hypot(0.05, 0.2 * a)),
        }
    )


def test_identification_measures_each_balances_noise_and_the_vehicle_file_carries_it(tmp_path: Path) -> None:
    noise = measure_band_noise(_synthetic(np.random.default_rng(29), 8000), min_command=0.2)[1]
    assert noise.has_torque_noise and noise.torque is not None and noise.voltage is not None
    assert noise.torque.offset == pytest.approx(0.001, abs=2e-4)
    assert noise.voltage.offset == pytest.approx(-0.03, abs=5e-3)
    # σ₀ carries the offset in quadrature, as the deviations' does (noise.py)
    assert noise.torque.sigma == pytest.approx(math.hypot(0.002, 0.001), rel=0.25)
    assert noise.torque.per_activity == pytest.approx(0.004, rel=0.15)
    assert noise.voltage.sigma == pytest.approx(math.hypot(0.05, 0.03), rel=0.25)
    assert noise.voltage.per_activity == pytest.approx(0.2, rel=0.15)
    assert noise.voltage.sigmas(np.array([1.0]))[0] == pytest.approx(math.hypot(0.05, 0.2), rel=0.15)
    assert not noise.torque.through_duty
    # an input current: the torque read through the duty, marked so (not judged)
    ripple = measure_band_noise(_synthetic(np.random.default_rng(29), 8000), 0.2, input_current=True)[1]
    assert ripple.torque is not None and ripple.torque.through_duty
    assert ripple.voltage is not None and not ripple.voltage.through_duty
    # written to a vehicle file and read back exactly, the offsets' signs and the mark too
    for measured in (noise, ripple):
        vehicle = VehicleParams(load_motor_params("paper_x2212"), noise={1: measured.as_mapping()})
        path = tmp_path / "vehicle.toml"
        path.write_text(dump_vehicle_params(vehicle), encoding="utf-8")
        again = band_noise_of(load_vehicle_params(path).noise)[1]
        assert again.torque == measured.torque and again.voltage == measured.voltage
    # a flight without the balances (another rule) measures the deviations' noise alone
    plain = _synthetic(np.random.default_rng(29), 8000)
    plain = TelemetryTable({k: plain[k] for k in plain.names if not k.endswith("_residual_nm")})
    assert not measure_band_noise(plain, min_command=0.2)[1].has_torque_noise


def test_friction_and_a_lighter_propeller_are_named_in_the_torque_balance(motor, flights, noise) -> None:
    profile = _torque_profile()
    assert profile.equation_bands > 0
    deviations_only = dataclasses.replace(profile, equation_bands=0.0)
    healthy = diagnose(flights["healthy"].table, motor, profile, noise)
    assert np.all(healthy["announced"] == MotorState.NORMAL)
    for name in FAULTS:
        r = diagnose(flights[name].table, motor, profile, noise)
        before = diagnose(flights[name].table, motor, deviations_only, noise)
        sel = (r["motor"] == 2) & (r["time_s"] > 16.0) & r["steady"]
        fault = MotorState.from_label(name)
        assert np.mean(r["state"][sel] == fault) > 0.9, name
        assert fault in set(r["announced"][r["motor"] == 2].tolist()), name
        # the deviations alone name it no more often
        assert np.mean(r["state"][sel] == fault) >= np.mean(before["state"][sel] == fault), name
        n = noise[2]
        assert n.torque is not None and n.voltage is not None
        z_torque = (r["torque_residual_nm"] - n.torque.offset) / n.torque.sigmas(r["input_activity_v"])
        z_voltage = (r["voltage_residual_v"] - n.voltage.offset) / n.voltage.sigmas(r["input_activity_v"])
        if name == "F4.1":
            # an open transistor is voltage lost; the torque balance stays within its band, and the
            # deviations name it as before (this rule leaves F4.1 to them)
            assert np.median(z_voltage[sel]) > profile.equation_bands
            assert np.median(np.abs(z_torque[sel])) < 1.5
            np.testing.assert_array_equal(
                r["announced"][r["motor"] != 2], before["announced"][r["motor"] != 2]
            )
            continue
        # friction is torque the model lacks, a lighter propeller torque it has too much of: beyond the
        # band, in the fault's direction, with the voltage balance within a σ or so
        assert np.median(z_torque[sel]) * (-1 if name == "F3.1" else 1) > profile.equation_bands, name
        assert np.median(np.abs(z_voltage[sel])) < 1.5, name


def test_a_vehicle_file_without_the_torques_noise_is_judged_as_before_and_says_so(motor, flights, noise):
    profile = _torque_profile()
    older = {
        m: dataclasses.replace(n, torque=None, voltage=None, torque_vs_siblings=None)
        for m, n in noise.items()
    }
    table = flights["F1.1"].table
    with pytest.warns(UserWarning, match="torque_residual_nm"):
        r = diagnose(table, motor, profile, older)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        before = diagnose(table, motor, dataclasses.replace(profile, equation_bands=0.0), older)
    np.testing.assert_array_equal(r["state"], before["state"])
    np.testing.assert_array_equal(r["announced"], before["announced"])
    # a vehicle whose ESCs report no usable current has no torque to judge: nothing to say
    speed_only = {m: dataclasses.replace(n, current_a=math.nan) for m, n in older.items()}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        diagnose(table, motor, profile, speed_only)


def test_a_torque_read_through_the_duty_is_not_judged_the_deviations_judge(motor, flights, noise) -> None:
    profile = _torque_profile()
    table = flights["F1.1"].table
    before = diagnose(table, motor, dataclasses.replace(profile, equation_bands=0.0), noise)
    # a file without the torque against its siblings (before .siblings), its torque through the duty
    through = {
        m: dataclasses.replace(
            n, torque=dataclasses.replace(n.torque, through_duty=True), torque_vs_siblings=None
        )
        for m, n in noise.items()
        if n.torque is not None
    }
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # measured, and marked: nothing to warn about
        r = diagnose(table, motor, profile, through)
    np.testing.assert_array_equal(r["state"], before["state"])
    np.testing.assert_array_equal(r["announced"], before["announced"])
    # a motor's own current: the torque judges, and names the friction at least as much
    judged = diagnose(table, motor, profile, noise)
    sel = (r["motor"] == 2) & (r["time_s"] > 16.0) & r["steady"]
    assert np.mean(judged["state"][sel] == MotorState.F1_1) >= np.mean(r["state"][sel] == MotorState.F1_1)
    assert not np.array_equal(judged["state"], r["state"])


def test_tiny_torque_noise_makes_healthy_motors_faulty_the_bands_bite(motor, flights, noise) -> None:
    profile = _torque_profile()
    table = flights["healthy"].table
    tight = {
        m: dataclasses.replace(
            n,
            torque_vs_siblings=EquationNoise(
                0.05 * n.torque_vs_siblings.sigma, 0.0, 0.0, n.torque_vs_siblings.offset
            ),
        )
        for m, n in noise.items()
        if n.torque_vs_siblings is not None
    }
    r = diagnose(table, motor, profile, tight)
    judged = r["steady"]
    torque_states = np.isin(r["state"][judged], [MotorState.F1_1, MotorState.F3_1])
    assert np.mean(torque_states) > 0.3
    assert np.any(np.isin(r["announced"], [MotorState.F1_1, MotorState.F3_1]))


def test_the_sequential_test_reads_friction_and_a_lighter_propeller_in_the_torque_where_it_is_judged() -> (
    None
):
    z_torque = np.array([3.0, -4.0, np.nan, 7.0])
    trusted = np.array([True, True, True, False])
    before = np.arange(len(DIRECTIONS) * 4, dtype=float).reshape(len(DIRECTIONS), 4)
    out = equation_evidence(z_torque, trusted, before)
    row = {d: out[DIRECTIONS.index(d)] for d in DIRECTIONS}
    old = {d: before[DIRECTIONS.index(d)] for d in DIRECTIONS}
    # judged in the torque: its departure, along each fault's sign
    np.testing.assert_array_equal(row[MotorState.F1_1][:2], [3.0, 0.0])
    np.testing.assert_array_equal(row[MotorState.F3_1][:2], [0.0, 4.0])
    # not judged there (NaN: outside the activity its offset holds in; no trusted current): as given
    for d in (MotorState.F1_1, MotorState.F3_1):
        np.testing.assert_array_equal(row[d][2:], old[d][2:])
    # the other directions as given everywhere, and the evidence given is not changed
    for d in (MotorState.F4_1, MotorState.UNKNOWN, MotorState.SLOW, MotorState.FAST):
        np.testing.assert_array_equal(row[d], old[d])
    assert before[DIRECTIONS.index(MotorState.F1_1), 0] == DIRECTIONS.index(MotorState.F1_1) * 4


def test_a_torque_shortfall_on_a_current_read_above_its_band_is_no_lighter_propeller() -> None:
    # Held-out world 1005, a healthy motor in calm air: a command step up between two commands logged at
    # 10 Hz drove it 67 rad/s above the logged command's model on 12.1 A against 4.1 A modelled (band
    # 2.4 A); the balance, its current low-passed, read the acceleration as load gone, and three such
    # samples announced F3.1 (uncapped). A lighter propeller draws less current, never more.
    z_torque = np.array([-5.0, -5.0, -5.0, -5.0])
    z_current_read = np.array([14.9, 4.5, 4.6, np.nan])  # in sigma; the band is 4.5 sigma
    trusted = np.ones(4, dtype=bool)
    before = np.ones((len(DIRECTIONS), 4))
    out = equation_evidence(z_torque, trusted, before, z_current_read, 4.5)
    np.testing.assert_array_equal(out[DIRECTIONS.index(MotorState.F3_1)], [0.0, 5.0, 0.0, 5.0])
    # friction is read as before, and without the reading nothing changes
    np.testing.assert_array_equal(out[DIRECTIONS.index(MotorState.F1_1)], [0.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(
        equation_evidence(z_torque, trusted, before)[DIRECTIONS.index(MotorState.F3_1)], [5.0] * 4
    )


def test_a_current_every_motor_gains_alike_is_judged_against_the_siblings_not_named_friction(
    motor, flights, noise
) -> None:
    """An input current's ripple adds about the same current to every motor (diagnosis/siblings.py): a
    torque judged on its own names every motor F1.1, judged against its siblings none."""
    profile = _torque_profile()
    table = flights["healthy"].table
    n = noise[1]
    assert n.torque is not None and n.torque_vs_siblings is not None  # identification measured both
    # a current every motor gains after 10 s: 8 σ of the torque balance's own noise, in amperes
    extra_a = 8.0 * n.torque.sigma / motor.k_t
    columns = {name: np.array(table[name], copy=True) for name in table.names}
    later = columns["time_s"] > 10.0
    for name in ("current_a", "esc_current_a"):
        if name in columns:
            columns[name][later] += extra_a
    if "battery_current_a" in columns:  # the battery monitor sees the six motors' (the sum check agrees)
        columns["battery_current_a"][later] += 6 * extra_a
    shifted = TelemetryTable(columns, source=table.source, meta=table.meta)
    on_its_own = {m: dataclasses.replace(v, torque_vs_siblings=None) for m, v in noise.items()}
    alone = diagnose(shifted, motor, profile, on_its_own)
    siblings = diagnose(shifted, motor, profile, noise)
    sel = (alone["time_s"] > 12.0) & alone["steady"]
    # (about half: the speed, which the added current does not move, reads above its model on the rest,
    # where friction is no reading: detection.torque_agrees_with_speed)
    assert np.mean(alone["state"][sel] == MotorState.F1_1) > 0.4
    assert MotorState.F1_1 in set(alone["announced"].tolist())
    judged = np.isfinite(siblings["torque_siblings_nm"][sel])
    assert judged.mean() > 0.8  # not by setting the samples aside
    assert np.mean(siblings["state"][sel] == MotorState.F1_1) < 0.01
    assert MotorState.F1_1 not in set(siblings["announced"].tolist())


def test_siblings_beyond_their_identified_speeds_count_only_at_the_motors_own_speed(
    motor, flights, noise
) -> None:
    """The pipeline gives the vehicle stage each sample's model speed and whether it lies in the motor's
    identified range (diagnosis/siblings.py): with every motor's range set below the flight, a reference
    stays only where three siblings turn within ``range_margin`` of the motor's speed, so some samples of
    the moderate flight lose theirs; with the ranges measured, none does."""
    profile = _torque_profile()
    table = flights["healthy"].table
    slow = {"omega_low_rad_s": 50.0, "omega_high_rad_s": 50.0}
    beyond = {m: dataclasses.replace(v, **slow) for m, v in noise.items()}
    measured, carried = diagnose(table, motor, profile, noise), diagnose(table, motor, profile, beyond)
    had = np.isfinite(measured["torque_siblings_nm"])
    kept = np.isfinite(carried["torque_siblings_nm"])
    assert had.mean() > 0.9 and not (kept & ~had).any()
    assert 0.005 < (had & ~kept).sum() / had.sum() < 0.5  # some lost: siblings more than 10 % apart


def _judged_after_f41(motor, noise: BandNoise, depth: float, torque_nm: float, voltage_v: float = 0.0):
    """Two samples of one motor that the tree read F4.1 ``depth`` bands deep, with the torque band 0.01
    N·m, the torque and voltage residuals given, after the torque balance's rule."""
    profile = _torque_profile()
    ones = np.ones((1, 2))
    frame = Frame(motor, profile, np.array([[0.0, 0.02]]), 8 * ones, 800 * ones, 4 * ones, [2], noise=[noise])
    frame.sensor_flags = np.zeros((1, 2), dtype=np.int16)
    frame.state = np.full((1, 2), MotorState.F4_1, dtype=np.int8)
    frame.depth = depth * ones
    frame.torque_band_nm = 0.01 * ones
    frame.torque_residual_nm = torque_nm * ones
    frame.voltage_residual_v = voltage_v * ones
    Equations(profile).judge(frame, [Equations(profile).new_carry()])
    return frame


def test_a_torque_above_its_band_names_friction_even_where_the_tree_reads_an_open_transistor_deeper(
    motor,
) -> None:
    # the tree read F4.1, three bands deep (friction's lower speed against a narrowed speed band); the
    # torque departs two bands: above, that is friction (an open transistor takes voltage, not torque);
    # below, it may be the open transistor's lower current, and the deeper F4.1 stands
    n, band = _torque_profile().equation_bands, 0.01
    noise = BandNoise(5.0, 0.3, torque=EquationNoise(band / n))
    for sign, expected in ((1.0, MotorState.F1_1), (-1.0, MotorState.F4_1)):
        frame = _judged_after_f41(motor, noise, 3.0, sign * 2 * band)
        assert np.all(frame.state == expected), sign
        np.testing.assert_allclose(frame.z_torque, sign * 2 * n)
        np.testing.assert_allclose(frame.depth, 2.0 if expected == MotorState.F1_1 else 3.0)


def test_a_slower_motor_is_friction_where_its_torque_departs_more_than_its_voltage_balance(motor) -> None:
    # the tree read F4.1 (slower, the current not above its band); the torque within its band but 3 σ
    # up: friction where the voltage balance departs less (torque added), an open transistor where it
    # departs more (voltage lost); a vehicle file without the voltage balance's noise: the tree's F4.1
    n, band, sigma_v = _torque_profile().equation_bands, 0.01, 0.05
    cases = (
        (EquationNoise(sigma_v, offset=0.1), 0.1 + 1.0 * sigma_v, MotorState.F1_1),
        (EquationNoise(sigma_v, offset=0.1), 0.1 + 5.0 * sigma_v, MotorState.F4_1),
        (None, 0.0, MotorState.F4_1),
    )
    for voltage, residual_v, expected in cases:
        noise = BandNoise(5.0, 0.3, torque=EquationNoise(band / n), voltage=voltage)
        frame = _judged_after_f41(motor, noise, 1.5, 3.0 * (band / n), residual_v)
        assert np.all(frame.state == expected), (voltage, residual_v)
        np.testing.assert_allclose(frame.depth, 1.5)  # the tree's depth, whichever the name
