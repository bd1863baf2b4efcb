"""Identification of a vehicle from its own flight log (model/identify.py)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mav_motor_health.config import load_motor_params
from mav_motor_health.errors import FitError
from mav_motor_health.evaluation.worlds import write_identification_log
from mav_motor_health.model.estimation import choose_exponent
from mav_motor_health.model.identify import (
    K_BIC_MARGIN,
    SIDE_ELASTICITY,
    SIDE_MARGIN_SE,
    EscMap,
    battery_current_pairs,
    electrical_balance_at,
    identify,
)
from mav_motor_health.sim.worlds import draw_world
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.table import TelemetryTable

SITL_LOGS = Path(__file__).resolve().parents[1] / "sitl_logs"


@pytest.fixture(scope="module")
def paper_flight() -> TelemetryTable:
    return sources.read(SITL_LOGS / "flight_healthy_calm.csv")


def test_a_simulated_hexacopter_is_identified_from_one_minute_of_flight(paper_flight) -> None:
    truth = load_motor_params()  # the simulator flies the paper's motor with J = 2e-5
    result = identify(paper_flight, truth.replace(C_p=1e-9, B=0.0, T_f=0.0, J_kg_m2=None))
    p = result.params
    assert abs(p.k_e / truth.k_e - 1) < 0.07
    assert abs(p.J_kg_m2 / truth.J_kg_m2 - 1) < 0.3
    assert p.k == 3 and all(v >= 0 for v in (p.R_ohm, p.C_p, p.B, p.T_f, p.J_kg_m2))
    assert result.current.side == "input"  # the simulated ESCs report duty × motor current
    assert set(result.per_motor) == set(range(1, 7))
    assert all(abs(d["k_e"]) < 0.02 for d in result.deviations.values())  # six motors of one type
    assert not [f for f in result.findings if "departs" in f]  # no motor unlike its siblings
    # a hover spans too narrow a speed range to tell k: the report says k = 3 came from the rule
    assert any("too narrow a range" in f for f in result.findings)
    text = result.report()
    assert "k = 3: " in text and "<- chosen" in text and "determined by" in text


def test_a_motor_unlike_its_siblings_is_a_finding_not_averaged_in(paper_flight) -> None:
    cols = dict(paper_flight.columns)
    four = cols["motor"] == 4
    cols["omega_rad_s"] = np.where(four, cols["omega_rad_s"] / 1.3, cols["omega_rad_s"])  # k_e 30 % larger
    result = identify(TelemetryTable(cols, source="altered"), load_motor_params())
    assert result.deviations[4]["k_e"] > 0.2
    assert any("motor 4" in f and "k_e" in f for f in result.findings)
    others = [result.per_motor[m].k_e for m in (1, 2, 3, 5, 6)]
    assert abs(result.params.k_e / np.median(others) - 1) < 0.01  # the type is the siblings'


def test_a_log_without_command_or_bus_voltage_is_refused_with_the_reason(paper_flight) -> None:
    cols = {k: v for k, v in paper_flight.columns.items() if k != "throttle"}
    with pytest.raises(FitError, match="throttle"):
        identify(TelemetryTable(cols), load_motor_params())


def test_a_current_that_does_not_follow_the_load_is_found_unusable(paper_flight) -> None:
    cols = dict(paper_flight.columns)
    cols["esc_current_a"] = np.full(len(paper_flight), 0.8)  # stock SITL: a constant
    truth = load_motor_params()
    result = identify(TelemetryTable(cols), truth)
    assert result.current.side == "unusable"
    assert result.determined_by["R_ohm"] == "prior"
    assert any("no usable current" in f for f in result.findings)
    # k_e from the motor voltage over the speed, the winding's typical share (10 %) taken off: the
    # paper's motor takes 9.6 % at its hover
    assert result.determined_by["k_e"] == "data and prior"
    assert result.params.k_e == pytest.approx(truth.k_e, rel=0.02)
    # the idle offset search ended on its bound, which says nothing of the offset: 0 (the truth here)
    assert result.esc.idle_offset == 0.0 and result.determined_by["idle_offset"] == "prior"


def test_the_real_px4_log_current_scale_is_read_off_the_battery_monitor(real_logs) -> None:
    # MANIFEST: the four ESC currents sum to about half the battery monitor's current
    table = sources.read(real_logs / "px4" / "esc_status_log.ulg")
    result = identify(table, load_motor_params())
    assert result.current.gain_from == "battery"
    assert 0.35 < result.current.gain < 0.75
    assert result.current.offset_a == 0.0  # the charges' ratio: the regression read 23.6 A of "rest"
    kv = 60.0 / (2 * math.pi * result.params.k_e)
    assert 120 < kv < 400  # a large 6S quad turning ~230 rad/s at ~12 V: a low-KV motor
    assert all(math.isfinite(v) for v in result.k_bic.values())
    best = min(result.k_bic, key=result.k_bic.get)
    assert result.params.k == (best if result.k_bic[3.0] - result.k_bic[best] >= K_BIC_MARGIN else 3.0)


def test_the_electrical_balance_at_the_true_esc_map_recovers_the_motor_where_commands_pair(
    paper_flight,
) -> None:
    # the simulated ESCs report duty x motor current with the command as the duty (idle offset 0), and
    # the CSV pairs every ESC sample with its own command: the balance itself is sound
    truth = load_motor_params()
    fits = electrical_balance_at(paper_flight, 0.0, "input")
    assert set(fits) == set(range(1, 7))
    for k_e, r_ohm in fits.values():
        assert abs(k_e / truth.k_e - 1) < 0.015
        assert abs(r_ohm / truth.R_ohm - 1) < 0.10


def test_where_the_current_does_not_part_r_from_k_e_the_winding_s_typical_share_gives_k_e(
    tmp_path: Path,
) -> None:
    # development world 1 (seeded; 1.4 kg, input-side readings at 16 Hz, logged commands that jitter by
    # 0.15 of their range from one to the next): the speed taken out, the current barely follows the motor
    # voltage, and least squares put R on its bound and k_e about 15 % high. With the back-EMF taking
    # 1 - 0.10 of the motor voltage at the flight's loads, k_e is the voltage over the speed: no current
    # reading in it, the pairing's zero-mean error averaged out over the flight
    world = draw_world(1)
    table = sources.read(write_identification_log(1, tmp_path / "world1.tlog"))
    result = identify(table, load_motor_params())
    free = electrical_balance_at(table, result.esc.idle_offset, result.current.side)
    assert np.median([k_e for k_e, _ in free.values()]) / world.motor.k_e - 1 > 0.10
    assert result.params.k_e == pytest.approx(world.motor.k_e, rel=0.05)
    assert (
        result.determined_by["R_ohm"].startswith("prior") and result.determined_by["k_e"] == "data and prior"
    )
    said = [f for f in result.findings if "did not part R from k_e" in f]
    assert len(said) == 1 and "partial correlation of only" in said[0] and "10 %" in said[0]
    # R is then the winding's share at the flight's loads (the reading's gain from the battery applied)
    assert 0 < result.params.R_ohm < 2 * world.motor.R_ohm
    # a prior the user gives (`fit --prior`, a bench fit of the motor) keeps its own R instead of the share
    from mav_motor_health.identification import identify_logs

    prior_file = Path(__file__).resolve().parents[1] / "params" / "motors" / "paper_x2212.toml"
    given = identify_logs([tmp_path / "world1.tlog"], prior=prior_file).found
    assert any("R is the prior's" in f for f in given.findings)
    assert given.params.R_ohm == load_motor_params().R_ohm


def test_the_winding_s_typical_share_is_what_real_motors_take_at_their_hover(real_logs) -> None:
    """The share ``COPPER_SHARE`` stands for (docs/model.md): R·i over the motor voltage at hover, on the
    two real motors whose R is known. The paper's motor at its 3.8 A hover (Table I's R and k_e, its
    load's speed); the DTU stand's MultiStar 3508-700KV (R 0.083 ohm, hexacopter_config.txt) with its
    14x5.5 propeller at the row nearest the DTU hexacopter's hover thrust (1.414 kg over six motors), the
    stand's current being the battery's (motor current = battery current / duty)."""
    from scipy.optimize import brentq

    from mav_motor_health.model.identify import COPPER_SHARE

    paper = load_motor_params()
    hover_a = 3.8
    omega = brentq(lambda w: paper.C_p * w**3 + paper.B * w + paper.T_f - paper.k_e * hover_a, 1.0, 5000.0)
    paper_share = paper.R_ohm * hover_a / (paper.R_ohm * hover_a + paper.k_e * omega)
    assert paper_share == pytest.approx(0.096, abs=0.0015)
    rows = np.loadtxt(real_logs / "bench" / "dtu" / "3508-700_14x5.5.txt", comments="%")
    hover_g = 1000 * (0.914 + 0.5) / 6  # droneMass + batteryMass over motorCount, hexacopter_config.txt
    row = rows[np.argmin(np.abs(rows[:, 5] - hover_g))]
    duty, bus_v, battery_a = row[0] / 1024, row[3], row[4]
    dtu_share = 0.083 * (battery_a / duty) / (duty * bus_v)
    assert dtu_share == pytest.approx(0.12, abs=0.005)
    assert all(abs(share - COPPER_SHARE) < 0.05 for share in (paper_share, dtu_share))


def test_the_current_side_is_read_from_the_readings_dependence_on_the_bus_voltage(tmp_path: Path) -> None:
    # development world 22 (seeded): its ESCs report their input current, and the electrical balances'
    # residuals preferred the motor side (0.332 V against 0.338 V: the commands' pairing biases both by
    # more than R*i's share of the duty parts them), so the old choice by the smaller residual read the
    # input side as the motor side. At a given speed the motor current is set by the load and the duty
    # driving it goes as 1/V_bus: an input-side reading has elasticity -1 with the bus voltage, a
    # motor-side one 0, and the pack's discharge over the flight measures which.
    assert draw_world(22).current.side == "input"
    log = write_identification_log(22, tmp_path / "world22.tlog")
    result = identify(sources.read(log), load_motor_params())
    assert result.current.residual_v["motor"] < result.current.residual_v["input"]  # the old choice: motor
    test = result.current.side_test
    assert test is not None and test.side == "input" and test.margin_se >= SIDE_MARGIN_SE
    assert abs(test.elasticity - SIDE_ELASTICITY["input"]) < 3 * test.stderr
    assert result.current.side == "input"
    assert "side test: elasticity" in result.report()


def test_a_motor_side_reading_is_told_and_a_flight_that_cannot_tell_says_so(paper_flight) -> None:
    cols = dict(paper_flight.columns)
    duty = cols["throttle"]  # the simulated hexacopter's ESCs: the command is the duty
    phase = np.where(duty > 0.05, cols["esc_current_a"] / np.maximum(duty, 0.05), np.nan)
    motor_side = identify(TelemetryTable({**cols, "esc_current_a": phase}), load_motor_params())
    assert motor_side.current.side == "motor" and motor_side.current.side_test.side == "motor"
    # at a constant bus voltage nothing parts the two sides: the test says so, and the side is the
    # smaller residual's ("motor" here), stated as a guess
    flat = np.full(len(paper_flight), float(np.nanmedian(cols["bus_voltage_v"])))
    result = identify(TelemetryTable({**cols, "bus_voltage_v": flat}), load_motor_params())
    test = result.current.side_test  # None: the voltage never moved, nothing to fit
    assert test is None or test.side == "undetermined"
    smaller = min(result.current.residual_v, key=result.current.residual_v.__getitem__)
    assert result.current.side == smaller
    assert any("does not tell which side" in f for f in result.findings)
    assert result.determined_by["R_ohm"].endswith(f"as for the {smaller} side (a guess)")


def test_the_inertia_comes_from_the_reported_current_and_the_voltage_balance_together(tmp_path: Path) -> None:
    # development world 3 (seeded; 4.4 kg, input side, ESCs at 141 Hz): from the voltage balance alone,
    # (d*V - k_e*w)/R with R near its bound and the speed's noise in the derivative, J came out 90 % low;
    # the reported current's torque, weighed against the voltage balance's by their scatter, through a
    # second-order state-variable filter, gives it within the 30 %
    world = draw_world(3)
    log = write_identification_log(3, tmp_path / "world3.tlog")
    result = identify(sources.read(log), load_motor_params())
    assert result.current.side == world.current.side == "input"
    assert world.motor.J_kg_m2 is not None and result.params.J_kg_m2 is not None
    assert result.params.J_kg_m2 == pytest.approx(world.motor.J_kg_m2, rel=0.3)
    assert result.determined_by["J_kg_m2"] == "data"
    assert result.params.C_p > 0


@pytest.mark.parametrize("world_seed", [8, 10])
def test_where_the_voltage_cannot_tell_the_side_the_battery_s_charge_does(
    world_seed: int, tmp_path: Path
) -> None:
    # development worlds 8 (input side, 10 Hz) and 10 (motor side): a 150-s flight moves the bus voltage
    # too little for the side test, and the balances' smaller residual picks the wrong side on both. The
    # ESCs' summed charge against the battery monitor's does not: read on the wrong side, the sum comes
    # out ~duty (input read as motor) or ~1/duty (motor read as input) of the battery's, a gain far from 1
    world = draw_world(world_seed)
    log = write_identification_log(world_seed, tmp_path / f"world{world_seed}.tlog")
    result = identify(sources.read(log), load_motor_params())
    current = result.current
    assert current.side_test is not None and current.side_test.side == "undetermined"
    assert min(current.residual_v, key=current.residual_v.__getitem__) != world.current.side  # the old guess
    assert current.side == world.current.side
    said = [f for f in result.findings if "does not tell which side" in f]
    assert len(said) == 1 and "summed charge" in said[0] and "a guess" in said[0]
    true_gain = world.current.gain / world.battery.monitor_gain
    assert current.gain == pytest.approx(true_gain, rel=0.25)


def test_a_battery_monitor_that_lags_gives_the_current_scale_from_the_charges(tmp_path: Path) -> None:
    # development world 13 (seeded): its battery monitor is a filtered current in the .tlog at 1 Hz, and
    # regressed bin by bin on it the ESCs' sum has a slope of about 0.47 for a true gain of 1.02, with the
    # rest of the vehicle drawing -17 A: impossible, so the ratio of the charges both counted is taken
    world = draw_world(13)
    log = write_identification_log(13, tmp_path / "world13.tlog")
    table = sources.read(log)
    pairs = battery_current_pairs(table, world.current.side, EscMap(world.esc.idle_offset))
    assert pairs is not None
    slope, intercept = np.polyfit(pairs[1], pairs[0], 1)
    assert 0 < slope < 0.6 and -intercept / slope < 0  # attenuated, and a negative draw for the rest
    result = identify(table, load_motor_params())
    true_gain = world.current.gain / world.battery.monitor_gain
    assert result.current.side == world.current.side == "input"
    assert result.current.gain_from == "battery"
    assert result.current.gain == pytest.approx(true_gain, rel=0.1)
    assert result.current.offset_a == 0.0


def test_an_input_current_that_is_mostly_duty_ripple_is_said_so_and_does_not_choose_k(tmp_path: Path) -> None:
    # development world 17 flies its identification flight in gusty air with ESCs that read their input
    # current: the logged commands jitter by about half the duty between reports, and the reading holds
    # the ripple's copper loss, (σ_d/d̄)² over the winding's share: about twice the load's current
    # (bench_identify_worlds.py: the identified current at hover +324 % against the true motor's). Its
    # readings' dependence on the speed is then the ripple's, and the BIC picks k = 2 from it.
    # Development world 7 flies in calm air: 2.5 % jitter, a share of about 1 %
    gusty = identify(sources.read(write_identification_log(17, tmp_path / "w17.tlog")), load_motor_params())
    calm = identify(sources.read(write_identification_log(7, tmp_path / "w7.tlog")), load_motor_params())
    assert gusty.current.side == calm.current.side == "input"
    assert gusty.duty_jitter > 0.3 and gusty.ripple_share > 1.0
    assert calm.duty_jitter < 0.05 and calm.ripple_share < 0.05
    said = [f for f in gusty.findings if "mostly the duty ripple" in f]
    assert len(said) == 1 and "k = 3" in said[0] and "identify from a calmer flight" in said[0]
    assert gusty.params.k == 3.0 and choose_exponent(gusty.k_bic) != 3.0  # the rule, not the BIC
    assert not any("duty ripple" in f for f in calm.findings)
    assert "duty ripple: the commands jitter by" in gusty.report()
