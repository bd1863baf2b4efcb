"""Bands in units of the vehicle's own noise (issue 17, item 1; diagnosis/noise.py): measured from a
healthy flight, carried by the vehicle file, required by a profile with ``noise_bands``."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.cli import main
from mav_motor_health.config import dump_vehicle_params, load_motor_params, load_profile, load_vehicle_params
from mav_motor_health.diagnosis.noise import (
    BandNoise,
    EquationNoise,
    NoiseRows,
    band_noise_of,
    measure_band_noise,
)
from mav_motor_health.diagnosis.pipeline import StreamingDiagnoser, diagnose
from mav_motor_health.diagnosis.plausibility import SensorIssue
from mav_motor_health.diagnosis.states import MotorState
from mav_motor_health.errors import ConfigError
from mav_motor_health.model.vehicle import VehicleParams
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.table import TelemetryTable

# the noise these tests build by hand has no torque balance's (they test the deviations' bands): the
# profile says once that it judges without it (rules/bands.py), which here is the point
pytestmark = pytest.mark.filterwarnings("ignore:profile 'flight_vehicle' judges friction:UserWarning")

SITL_LOGS = Path(__file__).resolve().parents[1] / "sitl_logs"
FLIGHT = SITL_LOGS / "flight_F4.2_moderate.csv"  # motor 1 stalls at 30 s


def diagnosed_table(rng: np.random.Generator, counts: dict[int, int]) -> TelemetryTable:
    """What the flight rule's output looks like on a healthy flight whose deviations are Gaussian with
    σ_ω = √(5² + (20·a)²) rad/s and σ_i = √(0.3² + (1.0·a)²) A at input activity a."""
    cols: dict[str, list] = {k: [] for k in ("time_s", "motor", "a", "dw", "di")}
    for motor, n in counts.items():
        a = rng.uniform(0.0, 1.0, n)
        cols["time_s"].append(np.arange(n) * 0.02)
        cols["motor"].append(np.full(n, motor))
        cols["a"].append(a)
        cols["dw"].append(rng.normal(0.0, np.hypot(5.0, 20.0 * a)))
        cols["di"].append(rng.normal(0.0, np.hypot(0.3, 1.0 * a)))
    c = {k: np.concatenate(v) for k, v in cols.items()}
    n = c["time_s"].size
    model_w, model_i = np.full(n, 600.0), np.full(n, 5.0)
    return TelemetryTable(
        {
            "time_s": c["time_s"],
            "motor": c["motor"],
            "omega_rad_s": model_w + c["dw"],
            "current_a": model_i + c["di"],
            "voltage_v": np.full(n, 8.0),
            "steady": np.ones(n, dtype=bool),
            "throttle": np.full(n, 0.5),
            "omega_judged_rad_s": model_w + c["dw"],
            "omega_model_rad_s": model_w,
            "current_judged_a": model_i + c["di"],
            "current_model_a": model_i,
            "input_activity_v": c["a"],
            "sensor_flags": np.zeros(n, dtype=np.int16),
        }
    )


def test_the_measured_noise_recovers_a_known_spread_and_its_growth_with_activity() -> None:
    table = diagnosed_table(np.random.default_rng(17), {1: 6000, 2: 6000, 3: 60})
    noise = measure_band_noise(table, min_command=0.2)
    for motor in (1, 2):
        n = noise[motor]
        assert n.band_samples == 6000
        assert n.speed_rad_s == pytest.approx(5.0, rel=0.25)
        assert n.speed_rad_s_per_v == pytest.approx(20.0, rel=0.15)
        assert n.current_a == pytest.approx(0.3, rel=0.25)
        assert n.current_a_per_v == pytest.approx(1.0, rel=0.15)
        # and the band it gives at high activity is the spread there, not the quiet one
        speed, current = n.sigmas(np.array([0.0, 1.0]))
        assert speed[1] == pytest.approx(np.hypot(5.0, 20.0), rel=0.1)
        assert current[1] == pytest.approx(np.hypot(0.3, 1.0), rel=0.1)
    # a motor with too few judged samples of its own takes the vehicle's (all motors pooled)
    assert noise[3].band_samples == 12060
    # a flight with nearly nothing judged gives no noise at all rather than a guess
    assert measure_band_noise(diagnosed_table(np.random.default_rng(1), {1: 50, 2: 50})) == {}


def test_the_slow_looks_own_noise_is_measured_where_the_rule_had_one() -> None:
    """noise.py, "The slow look's own noise": the slow averages' spread around their own median, on the
    samples the slow look could judge (``slow_ready``), for speed, current and the torque against its
    siblings; none without the columns."""
    rng = np.random.default_rng(23)
    table = diagnosed_table(rng, {1: 6000, 2: 6000})
    n = len(table)
    dw = np.asarray(table["omega_judged_rad_s"]) - np.asarray(table["omega_model_rad_s"])
    di = np.asarray(table["current_judged_a"]) - np.asarray(table["current_model_a"])
    ready = rng.uniform(size=n) < 0.7
    # the slow averages: half the fast spread, off by an offset of their own; wild where not ready
    slow_w = np.where(ready, 0.5 * dw + 2.0, 1e4)
    slow_i = np.where(ready, 0.5 * di - 0.1, -1e4)
    with_slow = TelemetryTable(
        {
            **{name: table[name] for name in table.names},
            "omega_slow_judged_rad_s": np.asarray(table["omega_model_rad_s"]) + slow_w,
            "current_slow_judged_a": np.asarray(table["current_model_a"]) + slow_i,
            "slow_ready": ready,
            # the torque against its siblings averaged as long: a spread of 1 mN·m, known where ready
            "torque_slow_nm": np.where(ready, rng.normal(0.0, 1e-3, n), np.nan),
        }
    )
    measured = measure_band_noise(with_slow, min_command=0.2)
    for motor in (1, 2):
        speed, current = measured[motor].slow_speed, measured[motor].slow_current
        assert speed is not None and current is not None
        assert speed.offset == pytest.approx(2.0, abs=0.3) and current.offset == pytest.approx(-0.1, abs=0.02)
        assert speed.per_activity == pytest.approx(10.0, rel=0.2)
        assert current.per_activity == pytest.approx(0.5, rel=0.2)
        # σ₀ holds the offset in quadrature, as the fast look's does
        assert speed.sigma == pytest.approx(np.hypot(2.5, 2.0), rel=0.3)
        torque = measured[motor].slow_torque
        assert torque is not None and np.hypot(torque.sigma, torque.per_activity * 0.5) == pytest.approx(
            1e-3, rel=0.2
        )
    assert measure_band_noise(table, min_command=0.2)[1].slow_speed is None


def test_a_vehicle_file_carries_the_band_noise_and_reads_it_back(tmp_path: Path) -> None:
    noise = {
        1: BandNoise(
            4.2,
            0.31,
            12.5,
            0.8,
            900,
            after_step=(2.5, 1.25, 1.0, 1.0),
            slow_speed=EquationNoise(1.9, 5.0, 0.0, -0.4),
            slow_current=EquationNoise(0.12, 0.3, 0.01, 0.05),
            # the speed against the siblings' prediction (diagnosis/prediction.py): a covariance may be
            # negative (opposite motors move opposite ways)
            speed_covariance=((1, 17.6), (2, -6.5)),
            speed_lagged_covariance=((1, 17.6), (2, -5.9)),
            speed_vs_siblings_after_step=(2.1, 1.3, 1.0, 1.0),
            speed_vs_siblings=EquationNoise(2.8, 3.1, 0.0, 0.02),
        ),
        2: BandNoise(3.9, float("nan"), 10.0, 0.0, 850),
    }
    vehicle = VehicleParams(
        motor=load_motor_params("paper_x2212"), noise={m: n.as_mapping() for m, n in noise.items()}
    )
    path = tmp_path / "vehicle.toml"
    path.write_text(dump_vehicle_params(vehicle), encoding="utf-8")
    back = band_noise_of(load_vehicle_params(path).noise)
    assert back[1] == noise[1]
    # a motor without a usable current keeps its speed noise; its current band is infinite (speed only)
    assert back[2].speed_rad_s == 3.9 and np.isnan(back[2].current_a)
    assert np.isinf(back[2].sigmas(np.array([0.5]))[1]).all()
    bad = tmp_path / "bad.toml"
    bad.write_text(path.read_text(encoding="utf-8").replace("speed_rad_s = 4.2", "speed_rad_s = -4.2"))
    with pytest.raises(ConfigError) as err:
        load_vehicle_params(bad)
    assert "noise.1.speed_rad_s" in str(err.value) and str(bad) in str(err.value)


def test_a_noise_profile_without_the_vehicles_noise_is_refused_naming_the_key(paper_motor, tmp_path) -> None:
    profile = load_profile("flight_vehicle")
    table = sources.read(FLIGHT)
    with pytest.raises(ConfigError) as err:
        diagnose(table, paper_motor, profile)
    assert "noise.1.speed_rad_s" in str(err.value) and "fit" in str(err.value)
    noise = {m: BandNoise(8.0, 0.4, 20.0, 0.5) for m in range(1, 6)}  # motor 6 missing
    with pytest.raises(ConfigError, match=r"noise\.6\.speed_rad_s"):
        StreamingDiagnoser(paper_motor, profile, range(1, 7), noise)
    # and the command line says so in one line, exit code 2, nothing written
    out = tmp_path / "out"
    assert main(["replay", str(FLIGHT), "--profile", "flight_vehicle", "--out", str(out)]) == 2
    assert not (out / "diagnosis.csv").exists()


def test_the_bands_are_in_units_of_each_motors_noise(paper_motor) -> None:
    table = sources.read(FLIGHT)
    profile = load_profile("flight_vehicle")
    noise = {m: BandNoise(6.0 + m, 0.3, 20.0, 0.6) for m in range(1, 7)}
    result = diagnose(table, paper_motor, profile, noise)
    # twice the noise in half as many units: the same bands, the same diagnosis
    doubled = {
        m: BandNoise(2 * n.speed_rad_s, 2 * n.current_a, 2 * n.speed_rad_s_per_v, 1.2)
        for m, n in noise.items()
    }
    halved = dataclasses.replace(profile, noise_bands=profile.noise_bands / 2)
    again = diagnose(table, paper_motor, halved, doubled)
    np.testing.assert_array_equal(again["state"], result["state"])
    np.testing.assert_array_equal(again["announced"], result["announced"])
    # each motor's band is its own noise times noise_bands, at its own activity
    for m in (1, 4):
        sel = result["motor"] == m
        want = profile.noise_bands * noise[m].sigmas(result["input_activity_v"][sel])[0]
        np.testing.assert_allclose(result["speed_band_rad_s"][sel], want)
    # the stall of motor 1 is named with these bands too
    assert (result["announced"][result["motor"] == 1] != 0).any()
    # a noise ten times smaller turns healthy motors' ordinary deviations into faults: the bands bite
    tiny = {m: BandNoise(0.1 * n.speed_rad_s, 0.03, 2.0, 0.06) for m, n in noise.items()}
    strict = diagnose(table, paper_motor, profile, tiny)
    healthy = (strict["motor"] != 1) & strict["steady"]
    assert np.mean(strict["state"][healthy] != 0) > np.mean(result["state"][healthy] != 0) + 0.2


def test_a_vehicle_at_three_times_the_voltage_with_a_motor_wound_for_it_is_judged_alike(paper_motor) -> None:
    """The same flight on a bus three times the voltage, its motor wound with three times the turns (k_e
    ×3, R ×9: the same speeds and torques at a third of the current): the rule's volts scale with the bus
    (``steady.bus_ref_v``), the bands with each motor's noise, so every sample is judged and named alike."""
    table = sources.read(FLIGHT)
    scaled_cols = dict(table.columns)
    for name in ("voltage_v", "bus_voltage_v"):
        scaled_cols[name] = 3.0 * np.asarray(table[name], dtype=float)
    for name in ("current_a", "esc_current_a"):
        scaled_cols[name] = np.asarray(table[name], dtype=float) / 3.0
    scaled = TelemetryTable(scaled_cols, source=table.source, meta=table.meta)
    wound = paper_motor.replace(k_e=3.0 * paper_motor.k_e, R_ohm=9.0 * paper_motor.R_ohm)
    profile = load_profile("flight_vehicle")
    noise = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    # σ per volt of activity: the activity is 3 times the volts, the current noise a third of the amperes
    noise_wound = {
        m: BandNoise(8.0, 0.4 / 3, 20.0 / 3, 0.5 / 9, current_typical_a=3.8 / 3) for m in range(1, 7)
    }
    a = diagnose(table, paper_motor, profile, noise)
    b = diagnose(scaled, wound, profile, noise_wound)
    np.testing.assert_array_equal(b["steady"], a["steady"])
    np.testing.assert_array_equal(b["state"], a["state"])
    np.testing.assert_array_equal(b["announced"], a["announced"])
    assert a["steady"].mean() > 0.5 and (a["announced"] != 0).any()
    # the stall is named by the split in the motor's own amperes: the same fault on both
    stalled = a["announced"][a["motor"] == 1]
    assert set(np.unique(stalled)) - {0} == {MotorState.F4_2}
    # without the scaling, the rule's steps and its low-pass's lengthening are volts of a 3S bus
    fixed = dataclasses.replace(profile, steady=dataclasses.replace(profile.steady, bus_ref_v=0.0))
    c = diagnose(scaled, wound, fixed, noise_wound)
    assert not np.array_equal(c["steady"], a["steady"])


def test_beyond_the_speeds_identification_covered_nothing_is_judged_but_a_stall_is_named(paper_motor) -> None:
    table = sources.read(FLIGHT)
    profile = load_profile("flight_vehicle")
    assert profile.range_margin == pytest.approx(0.1)
    wide = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    everywhere = diagnose(table, paper_motor, profile, wide)
    model = everywhere["omega_model_rad_s"][everywhere["steady"]]
    low, high = np.quantile(model, [0.4, 0.6])  # a flight that covered only the middle fifth of them
    narrow = {m: dataclasses.replace(n, omega_low_rad_s=low, omega_high_rad_s=high) for m, n in wide.items()}
    guarded = diagnose(table, paper_motor, profile, narrow)
    w = guarded["omega_model_rad_s"]
    outside = (w < 0.9 * low) | (w > 1.1 * high)
    assert outside[everywhere["steady"]].mean() > 0.1
    stall = np.isin(guarded["state"], (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED))
    assert not guarded["steady"][outside & ~stall].any()  # a stall is judged anywhere: it needs no model
    np.testing.assert_array_equal(guarded["steady"][~outside], everywhere["steady"][~outside])
    # motor 1's stall (at 30 s) is still named: a motor below the stop speed needs no model
    stalled = guarded["announced"][(guarded["motor"] == 1) & (guarded["time_s"] > 31.0)]
    assert (stalled == MotorState.F4_2).mean() > 0.9


def test_a_typical_current_inflated_by_the_identification_flights_air_gives_way_to_this_flights(
    paper_motor,
) -> None:
    """An ESC that reports its input current, identified in gusty air, gives a typical current a few times
    what its motor draws in calm air (the duty ripple's copper loss, rules/tree.py): the F2.1/F4.2 split
    scaled from it lies above an F4.2 stall. The lower of identification's and this flight's own typical
    current sets the split: the F4.2 stall is named F4.2 again, the F2.1 stall stays F2.1, and where the
    vehicle's noise gives no speed range (an older file) nothing of the flight counts, as before."""
    profile = load_profile("flight_vehicle")
    assert profile.stall_split_typical == pytest.approx(1.27)
    for log, fault in ((FLIGHT, MotorState.F4_2), (SITL_LOGS / "flight_F2.1_moderate.csv", MotorState.F2_1)):
        table = sources.read(log)
        named = {}
        for typical in (3.8, 3.0 * 3.8):  # the motor's hover current, and three times it
            noise = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=typical) for m in range(1, 7)}
            without_range = diagnose(table, paper_motor, profile, noise)
            model = without_range["omega_model_rad_s"][without_range["steady"]]
            low, high = np.quantile(model, [0.01, 0.99])
            ranged = {
                m: dataclasses.replace(n, omega_low_rad_s=low, omega_high_rad_s=high)
                for m, n in noise.items()
            }
            with_range = diagnose(table, paper_motor, profile, ranged)
            for name, result in (("no range", without_range), ("range", with_range)):
                after = result["announced"][(result["motor"] == 1) & (result["time_s"] > 31.0)]
                named[typical, name] = MotorState(int(np.bincount(after).argmax()))
                assert (after == named[typical, name]).mean() > 0.9
                assert not (result["announced"][result["motor"] != 1] != 0).any()
        assert named[3.8, "no range"] == named[3.8, "range"] == fault
        assert named[3.0 * 3.8, "range"] == fault  # this flight's lower typical current
        # identification's inflated one alone: an F4.2 read as F2.1 (what the flight's own figure repairs)
        assert named[3.0 * 3.8, "no range"] == (MotorState.F2_1 if fault == MotorState.F4_2 else fault)


def test_the_stall_split_lies_halfway_between_the_two_stalls_in_units_of_the_typical_current(
    paper_motor,
) -> None:
    """The split sits halfway, in ratio, between the paper's two stalls (about 3 A and 7.7 A over its
    motor's 3.8 A at hover: 1.27 x the typical current), not at its 6 A (1.58 x), which lies near the lost
    back-EMF's stall: a typical current read a little high (an input current's ripple, a busier flight's
    manoeuvres: identification's 1.0-1.5 x the hover current on development worlds 0-19,
    benchmarks/bench_stall_split.py) put the split above that stall and named it F2.1. Identification's
    typical current alone (no speed range: this flight's own does not count): at 1.45 x the hover current
    the F4.2 stall is named F4.2 at the shipped split and F2.1 at 1.58 x; the F2.1 stall stays F2.1 at
    either split, and at a typical current read low (0.7 x)."""
    profile = load_profile("flight_vehicle")
    assert profile.stall_split_typical == pytest.approx(math.sqrt(3.0 * 7.7) / 3.8, abs=0.01)
    paper_split = dataclasses.replace(profile, stall_split_typical=1.58)
    for log, fault in ((FLIGHT, MotorState.F4_2), (SITL_LOGS / "flight_F2.1_moderate.csv", MotorState.F2_1)):
        table = sources.read(log)
        for typical, split, named in (
            (1.45 * 3.8, profile, fault),
            (1.45 * 3.8, paper_split, MotorState.F2_1),
            (0.7 * 3.8, profile, fault),
        ):
            noise = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=typical) for m in range(1, 7)}
            result = diagnose(table, paper_motor, split, noise)
            after = result["announced"][(result["motor"] == 1) & (result["time_s"] > 31.0)]
            assert (after == named).mean() > 0.9, (log.name, typical, split.stall_split_typical)
            assert not (result["announced"][result["motor"] != 1] != 0).any()


def test_a_stall_is_named_however_wide_the_vehicles_noise_band(paper_motor) -> None:
    """A motor expected at twice the stop speed is turning, whatever the speed band: a noisy vehicle's
    wide band (here ±900 rad/s, beyond any speed the motor turns at) must not hide a stopped rotor (tree rule 1)."""
    table = sources.read(FLIGHT)
    noisy = {m: BandNoise(200.0, 0.4, 0.0, 0.0, current_typical_a=3.8) for m in range(1, 7)}
    result = diagnose(table, paper_motor, load_profile("flight_vehicle"), noisy)
    stalled = result["announced"][(result["motor"] == 1) & (result["time_s"] > 31.0)]
    assert (stalled == MotorState.F4_2).mean() > 0.9


def test_each_motors_healthy_offset_is_measured_and_counted_in_its_noise() -> None:
    """A model shared by the six motors leaves each its own offset on the healthy flight: measured as the
    median deviation, the spread measured around it, and the offset's size added to the quiet σ (the
    model is off by that much at the flight's operating points, and may be by as much elsewhere)."""
    table = diagnosed_table(np.random.default_rng(23), {1: 6000, 2: 6000})
    cols = {n: np.asarray(table[n]) for n in table.names}
    motor2 = cols["motor"] == 2
    cols["omega_judged_rad_s"] = cols["omega_judged_rad_s"] + np.where(motor2, -12.0, 0.0)
    cols["current_judged_a"] = cols["current_judged_a"] + np.where(motor2, 0.8, 0.0)
    noise = measure_band_noise(TelemetryTable(cols))
    assert noise[1].speed_offset_rad_s == pytest.approx(0.0, abs=0.5)
    assert noise[2].speed_offset_rad_s == pytest.approx(-12.0, abs=0.5)
    assert noise[2].current_offset_a == pytest.approx(0.8, abs=0.03)
    # the spread is the same around either centre; the offset adds to the quiet σ only
    assert noise[1].speed_rad_s == pytest.approx(5.0, rel=0.25)
    assert noise[2].speed_rad_s == pytest.approx(np.hypot(noise[1].speed_rad_s, 12.0), rel=0.1)
    assert noise[2].current_a == pytest.approx(np.hypot(noise[1].current_a, 0.8), rel=0.1)
    assert noise[2].speed_rad_s_per_v == pytest.approx(noise[1].speed_rad_s_per_v, rel=0.2)


def test_the_model_each_motor_is_judged_against_carries_its_healthy_offset(paper_motor, tmp_path) -> None:
    table = sources.read(FLIGHT)
    profile = load_profile("flight_vehicle")
    plain = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    offset = dict(plain)
    offset[3] = dataclasses.replace(plain[3], speed_offset_rad_s=-60.0, current_offset_a=2.5)
    a = diagnose(table, paper_motor, profile, plain)
    b = diagnose(table, paper_motor, profile, offset)
    m3 = a["motor"] == 3
    np.testing.assert_allclose(b["omega_model_rad_s"][m3], a["omega_model_rad_s"][m3] - 60.0)
    np.testing.assert_allclose(b["current_model_a"][m3], a["current_model_a"][m3] + 2.5)
    np.testing.assert_array_equal(b["omega_judged_rad_s"], a["omega_judged_rad_s"])  # the measurement
    np.testing.assert_array_equal(b["state"][~m3], a["state"][~m3])  # other motors untouched
    # judged against a model 60 rad/s slower with 2.5 A more current (beyond the bands), motor 3 reads faster with less
    # current than its model: not the healthy motor it is against its own model
    assert np.mean(b["state"][m3 & b["steady"]] != 0) > np.mean(a["state"][m3 & a["steady"]] != 0) + 0.3
    # the offsets go through the vehicle file, signed; an older file without them reads as none
    vehicle = VehicleParams(motor=paper_motor, noise={m: n.as_mapping() for m, n in offset.items()})
    path = tmp_path / "vehicle.toml"
    path.write_text(dump_vehicle_params(vehicle), encoding="utf-8")
    assert band_noise_of(load_vehicle_params(path).noise)[3] == offset[3]
    older = path.read_text(encoding="utf-8")
    older = "\n".join(line for line in older.splitlines() if "_offset_" not in line) + "\n"
    path.write_text(older, encoding="utf-8")
    assert band_noise_of(load_vehicle_params(path).noise)[3].speed_offset_rad_s == 0.0


def test_in_busier_air_than_the_identification_flight_nothing_is_judged_but_a_stall_is_named(paper_motor):
    # a profile that does not reach beyond the flight's conditions (the shipped one does: next test)
    table = sources.read(FLIGHT)
    profile = dataclasses.replace(load_profile("flight_vehicle"), conditions_reach=1.0)
    known = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    everywhere = diagnose(table, paper_motor, profile, known)
    activity = everywhere["input_activity_v"]
    calm_flight = float(np.quantile(activity[everywhere["steady"]], 0.5))  # a flight in half as busy air
    limited = {m: dataclasses.replace(n, activity_high_v=calm_flight) for m, n in known.items()}
    guarded = diagnose(table, paper_motor, profile, limited)
    busier = activity > (1.0 + profile.range_margin) * calm_flight
    stall = np.isin(guarded["state"], (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED))
    assert busier[everywhere["steady"]].mean() > 0.3
    assert not guarded["steady"][busier & ~stall].any()
    np.testing.assert_array_equal(guarded["steady"][~busier], everywhere["steady"][~busier])
    stalled = guarded["announced"][(guarded["motor"] == 1) & (guarded["time_s"] > 31.0)]
    assert (stalled == MotorState.F4_2).mean() > 0.9
    # measured: the input of the healthy flight's judged samples but the busiest 5 % (too few to measure
    # a tail σ on)
    table = diagnosed_table(np.random.default_rng(5), {1: 4000})
    assert measure_band_noise(table)[1].activity_high_v == pytest.approx(0.95, abs=0.01)


def test_beyond_the_flights_conditions_the_bands_grow_faster_up_to_the_reach_and_nothing_beyond(paper_motor):
    """The shipped profile judges input busier than the identification flight's, up to
    ``conditions_reach`` times its limit, in bands grown by (a / limit) ** ``conditions_growth`` beyond
    the limit (diagnosis/noise.py, "Beyond the measured conditions"); beyond the reach nothing (a stall
    still is named); within the limit everything as before."""
    table = sources.read(FLIGHT)
    shipped = load_profile("flight_vehicle")
    # the growth by the excess alone (the shipped profile bounds it by the siblings': the test below)
    profile = dataclasses.replace(shipped, conditions_siblings=0.0)
    reach, growth = profile.conditions_reach, profile.conditions_growth
    assert reach > 1 and growth > 0 and not profile.grows_as_siblings
    known = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    everywhere = diagnose(table, paper_motor, profile, known)
    activity = everywhere["input_activity_v"]
    calm_flight = float(np.quantile(activity[everywhere["steady"]], 0.2))  # a calmer flight's busiest
    limited = {m: dataclasses.replace(n, activity_high_v=calm_flight) for m, n in known.items()}
    guarded = diagnose(table, paper_motor, profile, limited)
    excess = activity / ((1.0 + profile.range_margin) * calm_flight)
    beyond, reached = excess > reach, (excess > 1.0) & (excess <= reach)
    stall = np.isin(guarded["state"], (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED))
    steady = everywhere["steady"]
    assert reached[steady].mean() > 0.1 and beyond[steady].mean() > 0.1
    assert not guarded["steady"][beyond & ~stall].any()
    np.testing.assert_array_equal(guarded["steady"][~beyond], steady[~beyond])  # judged up to the reach
    speed, current = known[1].sigmas(activity)
    grown = np.maximum(excess, 1.0) ** growth
    m1 = guarded["motor"] == 1
    np.testing.assert_allclose(guarded["speed_band_rad_s"][m1], profile.noise_bands * (speed * grown)[m1])
    np.testing.assert_allclose(guarded["current_band_a"][m1], profile.noise_bands * (current * grown)[m1])
    assert (grown[m1 & reached] > 1.0).all()
    # the healthy motors of this flight stay NORMAL where they are judged in the grown bands
    healthy = (guarded["motor"] != 1) & guarded["steady"] & reached
    assert healthy.sum() > 500 and (guarded["state"][healthy] == MotorState.NORMAL).mean() > 0.995
    stalled = guarded["announced"][(guarded["motor"] == 1) & (guarded["time_s"] > 31.0)]
    assert (stalled == MotorState.F4_2).mean() > 0.9


def _limited(table: TelemetryTable, paper_motor, profile) -> tuple[dict[int, BandNoise], float]:
    """Each motor's noise, as measured on a calmer flight than ``table``'s (its busiest input the 20th
    percentile of this flight's): most of this flight lies beyond the noise's conditions."""
    known = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    everywhere = diagnose(table, paper_motor, profile, known)
    calm = float(np.quantile(everywhere["input_activity_v"][everywhere["steady"]], 0.2))
    return {m: dataclasses.replace(n, activity_high_v=calm) for m, n in known.items()}, calm


def test_beyond_the_conditions_the_bands_grow_as_the_siblings_run_not_as_the_motor_itself(paper_motor):
    """The shipped profile grows the bands beyond the noise's conditions no more than the other motors'
    deviations run, in their σ (``conditions_siblings``, rules/bands.py), and never below σ as measured
    or above the excess's growth: a motor's own departure leaves its band as it was, noisier siblings
    widen it."""
    profile = load_profile("flight_vehicle")
    assert profile.grows_as_siblings
    table = sources.read(FLIGHT)
    noise, calm = _limited(table, paper_motor, profile)
    base = diagnose(table, paper_motor, profile, noise)
    motor, t = base["motor"], base["time_s"]
    excess = np.maximum(base["input_activity_v"] / ((1.0 + profile.range_margin) * calm), 1.0)
    _, sigma_current = noise[1].sigmas(base["input_activity_v"])
    beyond = (excess > 1.0) & (excess <= profile.conditions_reach)
    grown = excess**profile.conditions_growth
    band = base["current_band_a"] / (profile.noise_bands * sigma_current)
    assert (band >= 1.0 - 1e-9).all() and (band <= grown * (1.0 + 1e-9)).all()
    assert (band[beyond] < 0.5 * grown[beyond]).mean() > 0.5  # healthy siblings: far narrower
    # motor 3's current reads 40 % low from 20 s on: its own band is what it was
    cols = {name: np.array(table[name]) for name in table.names}
    low = (cols["motor"] == 3) & (cols["time_s"] > 20.0)
    for name in ("current_a", "esc_current_a"):
        cols[name][low] *= 0.6
    departed = diagnose(TelemetryTable(cols), paper_motor, profile, noise)
    m3 = motor == 3
    assert (departed["state"][m3 & (t > 25.0)] != MotorState.NORMAL).any()  # it does depart
    np.testing.assert_allclose(departed["current_band_a"][m3], base["current_band_a"][m3], rtol=1e-9)
    # the other motors' currents noisier (seeded): motor 2's band wider beyond the conditions
    rng = np.random.default_rng(17)
    cols = {name: np.array(table[name]) for name in table.names}
    others = cols["motor"] != 2
    for name in ("current_a", "esc_current_a"):
        cols[name][others] += rng.normal(0.0, 1.5, int(others.sum()))
    noisy = diagnose(TelemetryTable(cols), paper_motor, profile, noise)
    m2 = (motor == 2) & beyond
    assert m2.sum() > 300
    assert (noisy["current_band_a"][m2] > 1.2 * base["current_band_a"][m2]).mean() > 0.5
    assert (noisy["current_band_a"][m2] <= profile.noise_bands * (sigma_current * grown)[m2] + 1e-9).all()


def test_the_noise_grows_with_the_pairing_error_as_the_healthy_flights_did() -> None:
    """A log that pairs commands loosely moves the deviations by up to the pairing error: identification
    measures how much (σ² gains (p·e)²) and how loose its flight's pairing got."""
    rng = np.random.default_rng(31)
    table = diagnosed_table(rng, {1: 6000})
    cols = {n: np.asarray(table[n]) for n in table.names}
    e = rng.exponential(10.0, cols["time_s"].size)  # pairing error [rad/s], a long tail
    cols["pairing_error_rad_s"] = e
    cols["omega_judged_rad_s"] = cols["omega_judged_rad_s"] + rng.normal(0.0, 0.4 * e)
    noise = measure_band_noise(TelemetryTable(cols))[1]
    assert noise.speed_per_pairing == pytest.approx(0.4, rel=0.3)
    assert noise.current_a_per_pairing == pytest.approx(0.0, abs=0.01)  # the current was not moved
    assert noise.pairing_error_high_rad_s == pytest.approx(np.quantile(e, 0.95), rel=0.05)
    speed, _ = noise.sigmas(np.zeros(2), np.array([0.0, 40.0]))
    assert speed[1] == pytest.approx(np.hypot(speed[0], 0.4 * 40.0), rel=0.3)
    # a log that pairs exactly (no pairing error): nothing measured, no limit
    cols["pairing_error_rad_s"] = np.full(e.size, np.nan)
    exact = measure_band_noise(TelemetryTable(cols))[1]
    assert exact.speed_per_pairing == 0.0 and np.isnan(exact.pairing_error_high_rad_s)


def test_with_the_pairing_measured_the_bands_grow_with_it_and_looser_pairing_is_not_judged(
    paper_motor,
) -> None:
    """Where the vehicle's noise was measured with the log's pairing error, the bands grow with each
    sample's error, and beyond the flight's loosest pairing nothing is judged (a stall still is); the
    fixed shares of the bands (``pairing_current_share``, ``pairing_speed_share``) are for profiles and
    vehicle files without it."""
    table = sources.read(SITL_LOGS / "flight_F4.1_moderate.tlog")  # pairs commands 20-100 ms apart
    # a profile that does not reach beyond the flight's loosest pairing (the shipped one does: below)
    profile = dataclasses.replace(load_profile("flight_vehicle"), conditions_reach=1.0)
    known = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    before = diagnose(table, paper_motor, profile, known)  # a vehicle file that does not say: as before
    error = before["pairing_error_rad_s"]
    assert (~before["steady"] & (error > 0)).mean() > 0.05
    seen = float(np.quantile(error, 0.5))
    measured = {
        m: dataclasses.replace(
            n, speed_per_pairing=0.5, current_a_per_pairing=0.01, pairing_error_high_rad_s=seen
        )
        for m, n in known.items()
    }
    after = diagnose(table, paper_motor, profile, measured)
    np.testing.assert_array_equal(after["pairing_error_rad_s"], error)
    speed, _ = known[1].sigmas(after["input_activity_v"])
    grown, grown_current = measured[1].sigmas(after["input_activity_v"], error)
    m1 = after["motor"] == 1
    np.testing.assert_allclose(after["speed_band_rad_s"][m1], profile.noise_bands * grown[m1])
    np.testing.assert_allclose(after["current_band_a"][m1], profile.noise_bands * grown_current[m1])
    assert (grown > speed)[error > 0].all()
    looser = error > (1.0 + profile.range_margin) * seen
    stall = np.isin(after["state"], (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED))
    assert looser.mean() > 0.2 and not after["steady"][looser & ~stall].any()
    assert (after["steady"] & ~before["steady"] & ~looser).any()  # judged now, in wider bands
    assert not ((after["sensor_flags"] & SensorIssue.CURRENT_UNPAIRED) != 0).any()
    # the shipped profile judges looser pairing too, up to conditions_reach times the limit, in bands
    # grown by the excess (diagnosis/noise.py, "Beyond the measured conditions"): here for a flight
    # that paired so tightly (its loosest 100 rad/s over the reach; this log's 48-140) that the log lies
    # both within the reach and beyond it; the growth by the excess alone (the shipped profile bounds it
    # by the siblings': tested above)
    shipped = dataclasses.replace(load_profile("flight_vehicle"), conditions_siblings=0.0)
    loosest = 100.0 / shipped.conditions_reach
    tight = {m: dataclasses.replace(n, pairing_error_high_rad_s=loosest) for m, n in measured.items()}
    reaching = diagnose(table, paper_motor, shipped, tight)
    excess = error / ((1.0 + shipped.range_margin) * loosest)
    within = (excess > 1.0) & (excess <= shipped.conditions_reach)
    stall = np.isin(reaching["state"], (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED))
    assert (reaching["steady"] & within & ~stall).mean() > 0.1
    further = np.maximum(excess, 1.0) ** shipped.conditions_growth
    np.testing.assert_allclose(reaching["speed_band_rad_s"][m1], shipped.noise_bands * (grown * further)[m1])
    beyond = excess > shipped.conditions_reach
    assert beyond.mean() > 0.01 and not reaching["steady"][beyond & ~stall].any()


def test_a_motor_faster_than_identified_and_drawing_less_than_it_needed_there_is_judged(paper_motor) -> None:
    """Beyond the identified speeds nothing is judged (the model is an extrapolation), except a motor that
    turns faster than the fastest identified speed while drawing less current than the model needs *at*
    that speed: no healthy propeller's load falls as it speeds up (rules/judged.py)."""
    from mav_motor_health.diagnosis.rules.base import Frame
    from mav_motor_health.diagnosis.rules.judged import Judged
    from mav_motor_health.model.equations import current_from_speed

    profile = load_profile("flight_vehicle")
    top = 600.0
    noise = [BandNoise(5.0, 0.3, omega_low_rad_s=400.0, omega_high_rad_s=top, current_offset_a=0.2)] * 5
    floor = float(current_from_speed(paper_motor, (1.0 + profile.range_margin) * top)) + 0.2
    band = 0.5
    beyond = 1.3 * top
    # rows: lost load; healthy at full command (the extrapolated model asks more, the current is above
    # the floor); lost load read within the range; lost load with an untrusted current; another state
    omega = np.array([beyond, beyond, 0.95 * top, beyond, beyond])[:, None]
    current = np.array([0.3 * floor, floor - 0.5 * band, 0.3 * floor, 0.3 * floor, 0.3 * floor])[:, None]
    state = np.array([MotorState.F3_1, MotorState.F3_1, MotorState.F3_1, MotorState.F3_1, MotorState.F1_1])
    flags = np.array([0, 0, 0, int(SensorIssue.CURRENT_RANGE), 0], dtype=np.int16)[:, None]
    rows = omega.shape
    frame = Frame(
        params=paper_motor,
        profile=profile,
        time_s=np.zeros(rows),
        voltage_v=np.full(rows, 10.0),
        omega_rad_s=omega,
        current_a=current,
        counts=[1] * 5,
        noise=noise,
    )
    frame.omega_model_rad_s = np.array([2.0 * top, 2.0 * top, 0.9 * top, 2.0 * top, 2.0 * top])[:, None]
    frame.omega_judged_rad_s, frame.current_judged_a = omega, current
    frame.current_band_below_a = np.full(rows, band)
    frame.sensor_flags = flags
    frame.state = state.astype(np.int8)[:, None]
    frame.steady = np.ones(rows, dtype=bool)
    frame.depth = np.zeros(rows)
    Judged(profile).judge(frame, [None] * 5)
    assert frame.steady[:, 0].tolist() == [True, False, True, False, False]


def test_a_lost_load_is_judged_from_what_the_motor_draws_in_any_air_and_in_the_wait_after_the_step(
    paper_motor,
) -> None:
    """Beyond the identified speeds the lost-load check reads the motor two ways (rules/judged.py). As
    measured: the low-passed speed and current, no model in them, against the load's floor with the
    motor's quiet band (in busy air the deviation's band is as wide as the model's error there, which the
    floor does not need), a motor driven (input not below its low-pass), also while the rule waits after
    the step the autopilot answers the lost thrust with; not one coasting down, nor a stream not yet
    started. As judged: the model plus the deviations against their band, where the rule holds the
    sample, which names a lost load before the motor has run up to its new speed; not where the motor
    draws what a loaded one needs."""
    from mav_motor_health.diagnosis.rules.base import Frame
    from mav_motor_health.diagnosis.rules.judged import Judged
    from mav_motor_health.model.equations import current_from_speed

    profile = load_profile("flight_vehicle")
    top = 600.0
    quiet_a = 0.3
    rows = 6
    noise = [
        BandNoise(5.0, quiet_a, omega_low_rad_s=400.0, omega_high_rad_s=top, current_offset_a=0.2)
    ] * rows
    floor = float(current_from_speed(paper_motor, (1.0 + profile.range_margin) * top)) + 0.2
    quiet_band = profile.noise_bands * quiet_a
    assert 0.3 * floor + quiet_band < floor
    # rows: lost load driven up while waiting; the same coasting down (input below its low-pass); the same
    # driven up before its stream has settled; lost load settled in busy air, where the deviation's band
    # is wider than the floor itself; a healthy motor settled in busy air above the range, whose judged
    # current (model plus deviation) reads low but which draws what its load needs; lost load settled in
    # quiet air, the motor still running up (its mean below the top) while the deviations already imply
    # a speed beyond it
    omega = np.full((rows, 1), 1.3 * top)
    drawn = np.array([0.3, 0.3, 0.3, 0.3, 1.05, 0.8])[:, None] * floor
    mean_omega = omega.copy()
    mean_omega[5] = 0.95 * top
    frame = Frame(
        params=paper_motor,
        profile=profile,
        time_s=np.zeros((rows, 1)),
        voltage_v=np.array([12.0, 6.0, 12.0, 12.0, 12.0, 12.0])[:, None],
        omega_rad_s=omega,
        current_a=drawn,
        counts=[1] * rows,
        noise=noise,
    )
    frame.judged_voltage_v = np.array([9.0, 9.0, 9.0, 12.0, 12.0, 12.0])[:, None]  # the input's low-pass
    frame.since_step_s = np.array([0.1, 0.1, np.nan, 2.0, 2.0, 2.0])[:, None]
    frame.omega_model_rad_s = np.full((rows, 1), 2.0 * top)
    frame.omega_judged_rad_s = omega
    frame.current_judged_a = np.full((rows, 1), 0.3) * floor
    frame.omega_mean_rad_s, frame.current_mean_a = mean_omega, drawn
    frame.current_band_below_a = np.array([0.5, 0.5, 0.5, 40.0, 0.5, 0.5])[:, None]
    frame.sensor_flags = np.zeros((rows, 1), dtype=np.int16)
    frame.state = np.full((rows, 1), MotorState.F3_1, dtype=np.int8)
    frame.steady = np.array([False, False, False, True, True, True])[:, None]
    frame.depth = np.zeros((rows, 1))
    Judged(profile).judge(frame, [None] * rows)
    assert frame.steady[:, 0].tolist() == [True, False, False, True, False, True]
    assert frame.eligible[:, 0].tolist() == [True, False, False, True, False, True]


def test_a_lost_load_is_judged_in_the_torque_against_the_load_at_the_top_where_the_currents_band_hides_it(
    paper_motor,
) -> None:
    """Beyond the identified speeds a lost load is also read in the torque (rules/judged.py, "In the
    torque"): where the current's bands are too wide to show it, a motor turning beyond the top whose
    torque, with the load taken at the top instead of the model's extrapolation, lies below its band
    against its siblings and on its own is judged, its evidence that shortfall; a healthy motor whose
    torque reads low only by the extrapolated load is not, nor one below its siblings only (siblings that
    fly on a failed motor), nor one the rule holds back, nor one turning within the top, nor another
    state."""
    from mav_motor_health.diagnosis.rules.base import Frame
    from mav_motor_health.diagnosis.rules.judged import Judged
    from mav_motor_health.model.equations import current_from_speed

    profile = load_profile("flight_vehicle")
    n = profile.equation_bands
    top = 600.0
    rows = 6
    edge, beyond = (1.0 + profile.range_margin) * top, 1.3 * top
    added_nm = paper_motor.k_t * float(
        current_from_speed(paper_motor, beyond) - current_from_speed(paper_motor, edge)
    )
    sigma = 0.2 * added_nm / n  # the torque's band a fifth of the load the model adds beyond the top
    torque = EquationNoise(sigma)  # its own noise and against its siblings' alike, offsets 0
    # the current's noise so wide that neither current view sees the lost load (45 A quiet band, 40 A band)
    noise = [
        BandNoise(
            5.0, 10.0, omega_low_rad_s=400.0, omega_high_rad_s=top, torque=torque, torque_vs_siblings=torque
        )
    ] * rows
    # rows: lost load; healthy (its torque low only by 40 % of the extrapolated load); lost load the rule
    # holds back (after a step); lost load still turning within the top; lost load read as friction; a
    # healthy motor below its siblings only (its own torque at the extrapolated model)
    z = np.array([-1.5, -0.4, -1.5, -1.5, -1.5, -1.5])[:, None] * added_nm / sigma
    own_nm = np.array([-1.5, -0.4, -1.5, -1.5, -1.5, 0.0])[:, None] * added_nm
    mean_omega = np.array([beyond, beyond, beyond, 0.95 * top, beyond, beyond])[:, None]
    frame = Frame(
        params=paper_motor,
        profile=profile,
        time_s=np.zeros((rows, 1)),
        voltage_v=np.full((rows, 1), 12.0),
        omega_rad_s=mean_omega,
        current_a=np.full((rows, 1), 0.1),
        counts=[1] * rows,
        noise=noise,
    )
    frame.judged_voltage_v = np.full((rows, 1), 12.0)
    frame.since_step_s = np.array([2.0, 2.0, 0.1, 2.0, 2.0, 2.0])[:, None]
    frame.omega_model_rad_s = np.full((rows, 1), 2.0 * top)
    frame.omega_judged_rad_s = mean_omega
    frame.current_judged_a = np.full((rows, 1), 0.1)
    frame.omega_mean_rad_s, frame.current_mean_a = mean_omega, np.full((rows, 1), 0.1)
    frame.current_band_below_a = np.full((rows, 1), 40.0)
    frame.torque_band_nm = np.full((rows, 1), n * sigma)
    frame.torque_residual_nm = own_nm
    frame.z_torque = z.copy()
    frame.sensor_flags = np.zeros((rows, 1), dtype=np.int16)
    frame.state = np.array([MotorState.F3_1] * 4 + [MotorState.F1_1, MotorState.F3_1], dtype=np.int8)[:, None]
    frame.steady = np.array([True, True, False, True, True, True])[:, None]
    frame.depth = np.zeros((rows, 1))
    Judged(profile).judge(frame, [None] * rows)
    assert frame.steady[:, 0].tolist() == [True, False, False, False, False, False]
    # the judged sample's evidence: its shortfall below the load at the top (-0.5 of the added load)
    assert frame.z_torque[0, 0] == pytest.approx(-0.5 * added_nm / sigma)
    np.testing.assert_array_equal(frame.z_torque[1:], z[1:])


def test_after_a_step_the_bands_widen_by_what_identification_measured_in_each_bin_of_the_wait() -> None:
    noise = BandNoise(5.0, 0.3, after_step=(3.0, 1.5, math.nan, 1.0))
    since = np.array([0.0, 0.1, 0.2, 0.35, 0.5, 0.6, 2.0, np.nan])
    factor = noise.after_step_factor(since, 0.6)  # bins of 0.15 s
    np.testing.assert_array_equal(factor, [3.0, 3.0, 1.5, np.nan, 1.0, 1.0, 1.0, 1.0])
    # a vehicle file written before (nothing measured): every waiting sample waits
    assert np.isnan(BandNoise(5.0, 0.3).after_step_factor(since, 0.6)[:6]).sum() == 5
    # the vehicle file carries them
    back = BandNoise.from_mapping(noise.as_mapping())
    assert back is not None and back.after_step[:2] == (3.0, 1.5) and math.isnan(back.after_step[2])


def test_identification_measures_how_much_wider_the_deviations_are_while_the_rule_waits_after_a_step() -> (
    None
):
    rng = np.random.default_rng(11)
    table = diagnosed_table(rng, {1: 6000, 2: 6000})
    cols = {n: np.asarray(table[n]).copy() for n in table.names}
    n = cols["time_s"].size
    # a third of the samples wait after a step (not steady), spread over the 0.6-s wait; in its first
    # quarter their deviations are twice as wide, later as wide as settled
    waiting = rng.random(n) < 1 / 3
    since = np.where(waiting, rng.uniform(0.0, 0.6, n), 5.0)
    first = waiting & (since < 0.15)
    for name, model in (("omega_judged_rad_s", "omega_model_rad_s"), ("current_judged_a", "current_model_a")):
        cols[name] = np.where(first, cols[model] + 2.0 * (cols[name] - cols[model]), cols[name])
    cols["steady"] = ~waiting
    cols["since_step_s"] = since
    noise = measure_band_noise(TelemetryTable(cols), settle_s=0.6)
    ratios = noise[1].after_step
    assert ratios[0] == pytest.approx(2.0, rel=0.2)
    assert all(r == pytest.approx(1.0, abs=0.15) for r in ratios[1:])
    assert noise[2].after_step == ratios  # pooled: the six motors share one type
    # too few waiting samples in a bin: not measured there
    few = measure_band_noise(
        TelemetryTable({**cols, "since_step_s": np.where(waiting, 0.01, 5.0)}), settle_s=0.6
    )
    assert math.isfinite(few[1].after_step[0]) and all(math.isnan(r) for r in few[1].after_step[1:])
    assert measure_band_noise(TelemetryTable(cols))[1].after_step == ()  # no wait given: nothing measured


def test_samples_waiting_after_a_step_are_judged_where_the_vehicle_measured_them_in_wider_bands(paper_motor):
    table = sources.read(FLIGHT)
    profile = load_profile("flight_vehicle")
    plain = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    before = diagnose(table, paper_motor, profile, plain)
    settle = profile.steady.settle_s  # type: ignore[attr-defined]
    since = before["since_step_s"]
    waiting = np.isfinite(since) & (since < settle)
    assert waiting.mean() > 0.02 and not before["steady"][waiting].any()
    measured = {m: dataclasses.replace(n, after_step=(2.0, 1.5, math.nan, 1.0)) for m, n in plain.items()}
    after = diagnose(table, paper_motor, profile, measured)
    factor = measured[1].after_step_factor(since, settle)
    judged_now = waiting & np.isfinite(factor) & (after["throttle"] >= profile.min_command)  # not at idle
    stall = np.isin(after["state"], (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED))
    assert judged_now.sum() > 200 and after["steady"][judged_now & ~stall].all()
    assert not after["steady"][waiting & ~np.isfinite(factor) & ~stall].any()  # the unmeasured bin waits
    np.testing.assert_array_equal(after["steady"][~waiting], before["steady"][~waiting])
    speed, _ = plain[1].sigmas(after["input_activity_v"])
    m1 = (after["motor"] == 1) & judged_now
    np.testing.assert_allclose(after["speed_band_rad_s"][m1], profile.noise_bands * (speed * factor)[m1])


def test_noise_rows_give_each_motor_what_its_own_noise_gives() -> None:
    """A call of six motors reads their noise as rows (noise.py ``NoiseRows``, one pass for every motor):
    σ(a, e), the identified speed range, how far beyond the conditions, the growth there, the judged
    region and the widening after a step come out, row by row, exactly as each motor's own
    ``BandNoise`` gives them, whatever each motor has or lacks (a range, limits, the pairing's growth,
    a usable current, the after-step bins)."""
    rng = np.random.default_rng(41)
    nan = math.nan
    noise = [
        BandNoise(3.0, 0.2, 4.0, 0.5, omega_low_rad_s=300.0, omega_high_rad_s=700.0, activity_high_v=0.3),
        BandNoise(2.0, nan, 1.0, 0.0, pairing_error_high_rad_s=5.0, speed_per_pairing=0.4),  # no current
        BandNoise(
            5.0, 0.4, 0.0, 0.2, activity_high_v=0.1, pairing_error_high_rad_s=0.0, after_step=(3, 2, 1.5, 1)
        ),
        BandNoise(1.0, 0.1, omega_low_rad_s=450.0, omega_high_rad_s=500.0, current_a_per_pairing=0.02),
        BandNoise(4.0, 0.3, 2.0, 1.0, activity_high_v=0.0, after_step=(2.0, nan, 1.2, 1.0)),
        BandNoise(6.0, 0.5, 3.0, 0.3, omega_low_rad_s=200.0, omega_high_rad_s=nan, activity_high_v=0.5),
    ]
    rows = NoiseRows.of(noise)
    shape = (len(noise), 200)
    activity = np.abs(rng.normal(0.0, 0.4, shape))
    activity[rng.random(shape) < 0.05] = nan
    pairing = np.abs(rng.normal(0.0, 6.0, shape))
    omega = rng.uniform(100.0, 800.0, shape)
    since = np.where(rng.random(shape) < 0.3, nan, rng.uniform(0.0, 1.0, shape))
    got = {
        "sigmas": rows.sigmas(activity, pairing),
        "sigmas without pairing": rows.sigmas(activity),
        "range": rows.in_speed_range(omega, 0.1),
        "beyond": rows.beyond_conditions(0.1, activity, pairing),
        "growth": rows.growth(omega, 0.1, activity, pairing, 2.0),
        "known": rows.known(omega, 0.1, activity, pairing, 5.0),
        "after step": rows.after_step_factor(since, 0.6),
    }
    for r, own in enumerate(noise):
        want = {
            "sigmas": own.sigmas(activity[r], pairing[r]),
            "sigmas without pairing": own.sigmas(activity[r]),
            "range": own.in_speed_range(omega[r], 0.1),
            "beyond": own.beyond_conditions(0.1, activity[r], pairing[r]),
            "growth": own.growth(omega[r], 0.1, activity[r], pairing[r], 2.0),
            "known": own.known(omega[r], 0.1, activity[r], pairing[r], 5.0),
            "after step": own.after_step_factor(since[r], 0.6),
        }
        for name, value in want.items():
            for mine, theirs in zip(
                *((got[name], value) if name.startswith("sigmas") else ((got[name],), (value,)))
            ):
                np.testing.assert_array_equal(mine[r], theirs, err_msg=f"{name}, motor {r + 1}")
    # the rows differ, so a row read with another motor's noise would show
    assert not np.array_equal(got["after step"][2], got["after step"][4])
    assert got["range"][0].mean() != got["range"][3].mean()
    assert np.isinf(got["sigmas"][1][1]).all() and np.isfinite(got["sigmas"][1][0]).all()


def test_noise_rows_give_each_motor_the_torque_noise_it_is_judged_with() -> None:
    """The torque band of every motor in one pass (rules/bands.py): each row is what its motor's own
    ``torque_judged`` gives, against the siblings, its own torque, or none (NaN: an input current read
    through the duty, or no torque noise at all), with and without the pairing's growth."""
    rng = np.random.default_rng(43)
    base = BandNoise(3.0, 0.2, 4.0, 0.5)
    noise = [
        dataclasses.replace(base, torque=EquationNoise(0.01, 0.02, 0.001)),
        dataclasses.replace(
            base,
            torque=EquationNoise(0.02, through_duty=True),
            torque_vs_siblings=EquationNoise(0.008, 0.013),
        ),
        dataclasses.replace(base, torque=EquationNoise(0.03, 0.01, through_duty=True)),  # not judged
        base,  # no torque noise
        dataclasses.replace(base, torque_vs_siblings=EquationNoise(0.005, 0.0, 0.002)),
    ]
    rows = NoiseRows.of(noise)
    activity = np.abs(rng.normal(0.0, 0.8, (5, 150)))
    activity[rng.random(activity.shape) < 0.05] = math.nan
    pairing = np.abs(rng.normal(0.0, 6.0, activity.shape))
    for e in (pairing, None):
        got = rows.torque_sigmas(activity, e)
        for r, own in enumerate(noise):
            judged = own.torque_judged
            if judged is None:
                assert np.isnan(got[r]).all()
            else:
                want = judged.sigmas(activity[r], None if e is None else e[r])
                np.testing.assert_array_equal(got[r], want, err_msg=f"motor {r + 1}")
    assert not np.array_equal(got[0], got[1])


def test_noise_rows_are_made_once_for_the_same_noise_and_never_for_other_noise() -> None:
    """The agent asks for its motors' rows in every call: the same motors' noise gives the rows made
    before (read-only, so no rule can change them for the next call); other noise, or the same in
    another order, its own rows."""
    noise = [BandNoise(1.0 + m, 0.5, 0.1 * m, 0.05) for m in range(6)]
    rows = NoiseRows.of(noise)
    assert NoiseRows.of(list(noise)) is rows
    with pytest.raises(ValueError, match="read-only"):
        rows.speed_rad_s[0, 0] = 0.0
    reordered = NoiseRows.of(noise[::-1])
    np.testing.assert_array_equal(reordered.speed_rad_s[:, 0], [6.0, 5.0, 4.0, 3.0, 2.0, 1.0])
    equal_but_new = [BandNoise(1.0 + m, 0.5, 0.1 * m, 0.05) for m in range(6)]
    other = [BandNoise(9.0, 0.5), *noise[1:]]
    assert NoiseRows.of(other).speed_rad_s[0, 0] == 9.0
    np.testing.assert_array_equal(NoiseRows.of(equal_but_new).speed_rad_s, rows.speed_rad_s)


def test_beyond_the_identified_speeds_the_bands_grow_with_the_distance_in_units_of_the_span(paper_motor):
    """Within ``range_margin`` past the speeds identification covered, the model is an extrapolation of a
    curve fitted over that span: with ``range_growth`` g the bands there are (1 + d/span)**g times the
    measured ones (d how far beyond), and within the range exactly as without it."""
    table = sources.read(FLIGHT)
    shipped = load_profile("flight_vehicle")  # ships with g = 1 (docs/flight.md, "... bands grown there")
    assert shipped.range_growth == 1.0
    flat, with_growth = dataclasses.replace(shipped, range_growth=0.0), shipped
    wide = {m: BandNoise(8.0, 0.4, 20.0, 0.5, current_typical_a=3.8) for m in range(1, 7)}
    model = diagnose(table, paper_motor, flat, wide)["omega_model_rad_s"]
    low, high = np.nanquantile(model, [0.3, 0.7])
    narrow = {m: dataclasses.replace(n, omega_low_rad_s=low, omega_high_rad_s=high) for m, n in wide.items()}
    grown, measured = (
        diagnose(table, paper_motor, with_growth, narrow),
        diagnose(table, paper_motor, flat, narrow),
    )
    w, turning = grown["omega_model_rad_s"], grown["omega_judged_rad_s"]
    np.testing.assert_array_equal(w, measured["omega_model_rad_s"])
    # as far as the motor turns beyond the range too (the lesser of its model's and its speed's distance)
    beyond = np.maximum(np.maximum(w - high, low - w), 0.0)
    beyond = np.minimum(beyond, np.maximum(np.maximum(turning - high, low - turning), 0.0))
    margin = flat.range_margin  # beyond it only a lost load is judged, in the bands as measured
    within = (w >= (1.0 - margin) * low) & (w <= (1.0 + margin) * high)
    factor = np.where(within, 1.0 + beyond / (high - low), 1.0)
    judged = measured["steady"] & np.isfinite(measured["speed_band_rad_s"])
    outside, inside = judged & (beyond > 0), judged & (beyond == 0)
    assert outside.sum() > 200 and inside.sum() > 200 and factor[outside].max() > 1.05
    for band in ("speed_band_rad_s", "current_band_a"):
        np.testing.assert_array_equal(grown[band][inside], measured[band][inside])
        np.testing.assert_allclose(
            grown[band][outside], measured[band][outside] * factor[outside], rtol=1e-12
        )
    # the factor itself, on the noise's rows: 1 within the range, on its ends, beyond the margin and
    # where the range is not known
    known = dataclasses.replace(wide[1], omega_low_rad_s=100.0, omega_high_rad_s=200.0)
    speeds = np.array([[100.0, 200.0, 250.0, 75.0, np.nan, 301.0, 49.0]] * 2)
    rows = NoiseRows.of([known, wide[1]])
    np.testing.assert_allclose(rows.beyond_range(speeds, 0.5, 2.0)[0], [1, 1, 2.25, 1.5625, 1, 1, 1])
    np.testing.assert_array_equal(rows.beyond_range(speeds, 0.5, 2.0)[1], np.ones(7))  # range not known
    # a motor commanded beyond the range that turns short of it (it lost drive) does not grow; one that
    # turns beyond as far as commanded does; a speed not known leaves the model's distance
    turning = np.array([[100.0, 200.0, 190.0, 75.0, np.nan, 301.0, 49.0], [np.nan] * 7])
    np.testing.assert_allclose(rows.beyond_range(speeds, 0.5, 2.0, turning)[0], [1, 1, 1, 1.5625, 1, 1, 1])
    short = np.array([[np.nan, np.nan, 225.0, 90.0, np.nan, np.nan, np.nan]] * 2)
    np.testing.assert_allclose(rows.beyond_range(speeds, 0.5, 2.0, short)[0], [1, 1, 1.5625, 1.21, 1, 1, 1])
    unknown = np.full(speeds.shape, np.nan)
    np.testing.assert_array_equal(
        rows.beyond_range(speeds, 0.5, 2.0, unknown), rows.beyond_range(speeds, 0.5, 2.0)
    )
