"""Randomised worlds (sim/worlds.py): a seed picks a consistent vehicle that flies, its logs carry the
autopilot's command (not the ESC's duty), its ESCs report current their own way, its faults act."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavutil

from mav_motor_health.cli import main
from mav_motor_health.errors import ConfigError
from mav_motor_health.model.equations import steady_state
from mav_motor_health.model.esc import EscMap
from mav_motor_health.model.vehicle import CURRENT_SIDES
from mav_motor_health.sim import worlds
from mav_motor_health.sim.engine import SimRecord, Simulation, run_scenario
from mav_motor_health.sim.faults import FaultScale, FaultSpec, effects_at
from mav_motor_health.sim.scenario import (
    Scenario,
    Segment,
    load_scenario,
    scenario_from_dict,
    world_scenario,
)
from mav_motor_health.sim.sensors import CurrentSensing, EscSensors, SensorSpec
from mav_motor_health.sim.vehicle import GRAVITY_M_S2
from mav_motor_health.sim.worlds import draw_world, plan_altitude_m
from mav_motor_health.sim.writers import write_record
from mav_motor_health.telemetry import sources

#: every kind of manoeuvre in 20 s (the worlds' own plan is 150 s)
SHORT_PLAN = (
    Segment("hover", 3.0),
    Segment("climb", 4.0, 1.5),
    Segment("translate", 4.0, 3.0, 60.0),
    Segment("yaw", 3.0, 0.0, 90.0),
    Segment("descend", 3.0, 1.0),
    Segment("translate", 3.0, 2.0, -120.0),
)


def short_flight(seed: int, duration_s: float = 20.0, faults: tuple[FaultSpec, ...] = ()) -> Scenario:
    sc = world_scenario(seed, duration_s=duration_s)
    return dataclasses.replace(sc, flight=dataclasses.replace(sc.flight, segments=SHORT_PLAN), faults=faults)


def test_a_seed_picks_one_world():
    assert draw_world(5) == draw_world(5)
    assert draw_world(5) != draw_world(6)
    with pytest.raises(ValueError):
        draw_world(-1)


def test_twenty_worlds_span_the_stated_ranges_consistently():
    ws = [draw_world(seed) for seed in range(20)]

    def spread(values: list[float]) -> float:
        return max(values) / min(values)

    mass = [w.mass_kg for w in ws]
    assert min(mass) < 1.5 and max(mass) > 12.0
    assert spread([w.kv_rpm_per_v for w in ws]) > 4.0
    assert spread([w.motor.R_ohm for w in ws]) > 8.0
    assert spread([w.motor.J_kg_m2 or math.nan for w in ws]) > 30.0
    # small vehicles on 4S (a few on 6S), the heavy ones on 10S or more
    small = [w.cells for w in ws if w.mass_kg < 2.0]
    assert set(small) <= {4, 6} and small.count(4) > small.count(6)
    assert min(w.cells for w in ws if w.mass_kg > 10.0) >= 10
    offsets = [w.esc.idle_offset for w in ws]
    assert all(0.0 <= c <= 0.06 for c in offsets) and min(offsets) < 0.01 and max(offsets) > 0.05
    rates = [w.rate_hz for w in ws]
    assert all(10.0 <= r <= 200.0 for r in rates) and rates.count(10.0) >= 3 and max(rates) > 100.0
    assert {w.current.side for w in ws} == set(CURRENT_SIDES)
    assert {w.current.averaging for w in ws} == {"interval", "filter"}
    assert sum(w.current.side == "unusable" for w in ws) < 6  # a minority
    assert all(0.75 <= w.current.gain <= 1.1 and abs(w.current.offset_a) <= 0.3 for w in ws)
    assert all(0.97 <= w.battery.monitor_gain <= 1.03 for w in ws)
    for w in ws:
        m = w.motor
        # the design point is the model's steady state, and it holds the vehicle up
        state = steady_state(m, [w.hover_duty * w.hover_bus_voltage_v])
        assert state.omega_rad_s[0] == pytest.approx(w.hover_omega_rad_s, rel=1e-6)
        assert state.current_a[0] == pytest.approx(w.hover_current_a, rel=1e-6)
        thrust = w.airframe.thrust_coeff * w.hover_omega_rad_s**2
        assert 6 * thrust == pytest.approx(w.mass_kg * GRAVITY_M_S2, rel=1e-9)
        assert 0.35 <= w.hover_command <= 0.65 and w.thrust_to_weight >= worlds.MIN_THRUST_TO_WEIGHT
        assert w.airframe.arm_m > w.prop_diameter_m  # neighbouring propellers clear each other
        # noise scaled to the motor, not the paper's absolute amperes and rad/s
        assert 0.005 < w.speed_noise_rad_s / w.hover_omega_rad_s < 0.035
        assert 0.01 < w.current_noise_a[0] / w.hover_current_a < 0.07
        assert sum(s.duration_s for s in w.plan) == pytest.approx(150.0)
        assert {s.kind for s in w.plan} == {"hover", "climb", "descend", "translate", "yaw"}
        assert min(plan_altitude_m(w.plan, 0.0, np.linspace(0, 150, 301))) >= -1e-9
        assert json.loads(json.dumps(w.truth()))["esc"]["idle_offset"] == w.esc.idle_offset


def test_infeasible_draws_are_redrawn_deterministically(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(worlds, "MIN_THRUST_TO_WEIGHT", 2.6)
    ws = [draw_world(seed) for seed in range(10)]
    assert all(w.thrust_to_weight >= 2.6 for w in ws)
    assert any(w.attempts > 1 for w in ws)
    assert ws == [draw_world(seed) for seed in range(10)]


def _longest_run(flags: np.ndarray) -> int:
    longest = run = 0
    for flag in flags:
        run = run + 1 if flag else 0
        longest = max(longest, run)
    return longest


# 1.2 to 15 kg, calm to gusty, ESC reports 10 to 82 Hz, every current convention, thrust/weight down to 1.94
@pytest.mark.parametrize("seed", [0, 1, 7, 9, 10, 12, 14, 17, 18])
def test_every_world_flies_its_manoeuvres(seed: int):
    sim = Simulation(short_flight(seed))
    world = sim.world
    assert world is not None and sim.dt <= 0.5 / world.rate_hz
    times, alts, yaws, commands, tilts = [], [], [], [], []
    reports = 0
    while sim.time_s < 20.0 - 1e-9:
        reports += len(sim.step())
        assert sim.body is not None
        times.append(sim.time_s)
        alts.append(sim.body.alt_m)
        yaws.append(sim.body.att[2])
        tilts.append(max(abs(sim.body.att[0]), abs(sim.body.att[1])))
        commands.append(sim.command.copy())
    t = np.array(times)
    cmd = np.array(commands)
    plan = plan_altitude_m(SHORT_PLAN, 10.0, t)
    assert np.max(np.abs(np.array(alts) - plan)[t > 1.0]) < 2.0, world.report()
    assert math.degrees(abs(np.mean(yaws[-50:]) - math.radians(90.0))) < 10.0
    assert math.degrees(max(tilts)) < 50.0
    saturated = cmd >= 0.999
    assert saturated.mean() < (0.05 if world.turbulence == "gusty" else 0.01)  # gusty air is rough
    assert max(_longest_run(saturated[:, j]) for j in range(6)) * sim.dt < 0.3
    # hovering at about the command the world was designed for (the controller does not know the
    # ESC's idle offset: its loops find the command that gives the duty)
    hover = cmd[(t > 1.5) & (t < 3.0)].mean()
    assert hover == pytest.approx(world.hover_command, abs=0.06)
    assert np.allclose(sim.duty, world.esc.duty(sim.command))
    # every ESC reports at the world's rate (less the dropouts)
    assert reports == pytest.approx(6 * 20.0 * world.rate_hz, rel=0.12)


@pytest.fixture(scope="module")
def offset_world(tmp_path_factory: pytest.TempPathFactory) -> tuple[SimRecord, dict[str, Path]]:
    # world 8: an ESC idle offset of 0.048, ESC reports at 10 Hz, input-side current
    record = run_scenario(short_flight(8, duration_s=8.0))
    folder = tmp_path_factory.mktemp("world")
    files = {ext: write_record(record, folder / f"w8{ext}")[0] for ext in (".csv", ".tlog", ".bin")}
    return record, files


def test_logs_carry_the_command_not_the_duty(offset_world: tuple[SimRecord, dict[str, Path]]):
    record, files = offset_world
    truth = json.loads(Path(str(files[".csv"]) + ".truth.json").read_text())
    esc = EscMap(truth["world"]["esc"]["idle_offset"])
    assert esc.idle_offset > 0.03
    samples = sorted(record.esc, key=lambda s: (s.motor, s.time_s))
    command = np.array([s.command for s in samples])
    duty = np.array([s.duty for s in samples])
    np.testing.assert_allclose(esc.duty(command), duty, atol=1e-12)  # the truth recovers the duty
    assert np.all((command - duty)[command < 0.75] > 0.01)  # c − d = c₀·(1 − c)/(1 − c₀)

    csv = sources.read(files[".csv"])
    np.testing.assert_array_equal(csv["throttle"], command)
    np.testing.assert_allclose(csv["voltage_v"], csv["throttle"] * csv["bus_voltage_v"])
    # as a reader computes it from a real log: the reading over the command
    np.testing.assert_allclose(csv["current_a"], csv["esc_current_a"] / csv["throttle"], rtol=0.02, atol=0.02)

    log = mavutil.mavlink_connection(str(files[".tlog"]), dialect="ardupilotmega")
    pwm = []
    while (msg := log.recv_match(type="SERVO_OUTPUT_RAW")) is not None:
        pwm.append([getattr(msg, f"servo{n}_raw") for n in range(1, 7)])
    expected = [[round(1000 + 1000 * c) for c in v.command] for v in record.vehicle]
    assert pwm == expected
    assert pwm != [[round(1000 + 1000 * d) for d in v.duty] for v in record.vehicle]

    logged = np.round([c for v in record.vehicle for c in v.command], 3)  # SERVO_OUTPUT_RAW, RCOU
    for ext in (".tlog", ".bin"):
        table = sources.read(files[ext])
        moving = np.isfinite(table["throttle"])
        assert np.all(np.isin(np.round(table["throttle"][moving], 3), logged))
        np.testing.assert_allclose(
            table["voltage_v"][moving], (table["throttle"] * table["bus_voltage_v"])[moving], rtol=1e-9
        )
        assert np.median(table["throttle"][moving]) > np.median(duty) + 0.01


def test_the_truth_sidecar_describes_the_world(offset_world: tuple[SimRecord, dict[str, Path]]):
    record, files = offset_world
    assert record.world is not None
    truth = json.loads(Path(str(files[".bin"]) + ".truth.json").read_text())
    assert truth["world"] == json.loads(json.dumps(record.world.truth()))
    assert truth["world"]["motor"]["J_kg_m2"] == record.world.motor.J_kg_m2
    assert truth["turbulence"] == record.world.turbulence
    params = record.world.vehicle_params()
    assert params.esc == record.world.esc and params.current is not None
    assert params.current.side == record.world.current.side


@pytest.mark.parametrize(
    ("sensing", "expected_a"),
    [
        # input side, 0.5 × 10 A, through the filter: 0.9 × 5 + 0.2
        (CurrentSensing("input", "filter", 0.02, 0.9, 0.2), 4.7),
        # motor side, averaged over the interval (the current alternates 8 and 12 A): 1.05 × 10 − 0.1
        (CurrentSensing("motor", "interval", 0.02, 1.05, -0.1), 10.4),
        (CurrentSensing("unusable", "filter", 0.02, 1.0, 0.0, constant_a=0.0), 0.0),
    ],
)
def test_current_sensing_conventions(sensing: CurrentSensing, expected_a: float):
    spec = SensorSpec(
        rate_hz=(50.0, 50.0), current_noise_low_a=0.0, current_noise_high_a=0.0, current_sensing=sensing
    )
    sensors = EscSensors(spec, 2, np.random.default_rng(1))
    duty, command = np.full(2, 0.5), np.full(2, 0.53)
    readings = []
    for k in range(1, 1001):
        amps = np.full(2, 8.0 if k % 2 else 12.0)
        samples = sensors.sample(k * 0.001, 0.001, np.full(2, 500.0), amps, duty, 16.0, amps, amps, command)
        readings += [s for s in samples if s.time_s > 0.2]
    assert len(readings) > 50
    reading_a = np.array([s.esc_current_ca for s in readings]) / 100.0
    # an interval of an odd number of steps has one 8 or 12 A step more (±0.2 A over ~20 steps); a 20-ms
    # filter still wobbles with a zigzag of 1-ms steps (±0.05 A)
    np.testing.assert_allclose(reading_a, expected_a, atol=0.12 if sensing.averaging == "interval" else 0.06)
    motor_ca = np.array([s.motor_current_ca for s in readings])
    np.testing.assert_allclose(motor_ca, np.rint(reading_a * 100 / 0.53), atol=1)  # reading / command
    assert all(s.command == 0.53 and s.duty == 0.5 for s in readings)


def test_fault_constants_scale_with_the_motor():
    faults = [FaultSpec("F1.1", 1, 0.0), FaultSpec("F2.1", 2, 0.0), FaultSpec("F4.2", 3, 0.0, 0.5)]
    paper = effects_at(faults, 1.0, 6)
    same = effects_at(faults, 1.0, 6, FaultScale())
    for name in ("rub_torque_nm", "rub_viscous_nm_s", "stall_current_a"):
        np.testing.assert_array_equal(getattr(paper, name), getattr(same, name))
    big = effects_at(faults, 1.0, 6, FaultScale(torque=40.0, speed=0.4, current=3.0))
    assert big.rub_torque_nm[0] == pytest.approx(40.0 * paper.rub_torque_nm[0])
    assert big.rub_viscous_nm_s[0] == pytest.approx(100.0 * paper.rub_viscous_nm_s[0])
    assert big.stall_current_a[1] == pytest.approx(3.0 * 3.0)
    assert big.stall_current_a[2] == pytest.approx(3.0 * 7.7 * 0.5)
    explicit = FaultSpec("F2.1", 2, 0.0, stall_current_a=2.0)
    assert FaultScale(current=3.0).resolve(explicit) == explicit


def test_trimmed_blades_speed_the_faulty_motor_up():
    # world 4: 1.8 kg, calm; F3.1 (blades trimmed to 30 %) on motor 2 at 8 s
    record = run_scenario(
        dataclasses.replace(
            short_flight(4, duration_s=14.0, faults=(FaultSpec("F3.1", 2, 8.0),)),
            flight=dataclasses.replace(world_scenario(4).flight, segments=(Segment("hover", 14.0),)),
        )
    )
    world = record.world
    assert world is not None

    def level(motor: int, start_s: float, end_s: float) -> tuple[float, float, float]:
        s = [x for x in record.esc if x.motor == motor and start_s < x.time_s < end_s]
        return (
            float(np.mean([x.rpm for x in s])) * 2 * math.pi / 60,
            float(np.mean([x.duty for x in s])),
            float(np.mean([x.voltage_cv for x in s])) / 100,
        )

    w_before, _, _ = level(2, 4.0, 8.0)
    w_after, duty_after, bus_after = level(2, 10.0, 14.0)
    w_opposite_before, _, _ = level(1, 4.0, 8.0)
    w_opposite_after, _, _ = level(1, 10.0, 14.0)
    assert w_after > 1.4 * w_before  # it lost its load and most of its thrust: it speeds up
    healthy = float(steady_state(world.motor, [duty_after * bus_after]).omega_rad_s[0])
    assert w_after > 1.2 * healthy  # faster than a healthy motor at its duty: the F3.1 signature
    assert w_opposite_after < 0.7 * w_opposite_before  # the opposite motor throttled back to balance it
    assert abs(record.vehicle[-1].alt_m - 10.0) < 2.0


def test_scenarios_name_a_world():
    sc = scenario_from_dict({"scenario": {"mode": "flight", "world": 3}})
    assert sc.world == 3 and sc.truth()["world"] == 3
    assert "world" not in scenario_from_dict({"scenario": {"mode": "flight"}}).truth()
    with pytest.raises(ConfigError, match=r"scenario\.world"):
        scenario_from_dict({"scenario": {"mode": "testbed", "world": 3}})
    with pytest.raises(ConfigError, match=r"scenario\.world"):
        scenario_from_dict({"scenario": {"mode": "flight", "world": -2}})
    assert load_scenario("world") == world_scenario() and load_scenario("flight/world").world is None
    applied = draw_world(3).apply(short_flight(3))
    assert applied.flight.segments == SHORT_PLAN  # its own plan is kept
    assert draw_world(3).apply(applied) == applied
    assert draw_world(3).apply(world_scenario(3)).flight.segments == draw_world(3).plan


def test_simulate_command_flies_a_world(tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    out = tmp_path / "w12.csv"
    rc = main(
        ["simulate", "world", "--world", "12", "--duration", "3", "--fault", "F1.1@1:4", "--out", str(out)]
    )
    assert rc == 0
    printed = capsys.readouterr().out
    assert "world 12:" in printed and "idle offset" in printed
    truth = json.loads(Path(str(out) + ".truth.json").read_text())
    assert truth["world"]["seed"] == 12 and truth["faults"][0]["motor"] == 4
    assert main(["simulate", "world", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--world SEED" in capsys.readouterr().err
