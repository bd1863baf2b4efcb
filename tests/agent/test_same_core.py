"""The agent runs the replay's core: a log diagnosed in batch and streamed through the agent agree exactly."""

from __future__ import annotations

import asyncio
from pathlib import Path

import numpy as np
import pytest
from flightlog import BATTERY_MISSCALED_FROM_S, make_fields, table_from_fields, write_tlog

from mav_motor_health.agent import Agent, load_agent_config
from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.diagnosis.plausibility import SensorIssue
from mav_motor_health.diagnosis.states import MotorState


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory, paper_motor):
    fields = make_fields(paper_motor)
    path = write_tlog(fields, tmp_path_factory.mktemp("flight") / "flight.tlog")
    return fields, path


def stream_through_agent(path: Path, profile: str) -> tuple[list[dict], Agent]:
    rows: list[dict] = []
    config = load_agent_config(None, connect=str(path), profile=profile)

    async def main() -> Agent:
        async with Agent(config, on_row=rows.append) as agent:
            await asyncio.wait_for(agent.wait(), timeout=60)
        return agent

    return rows, asyncio.run(main())


@pytest.mark.parametrize("profile", ["flight", "testbed"])
def test_streamed_log_announces_what_batch_diagnosis_announces(flight, paper_motor, profile):
    fields, path = flight
    from mav_motor_health.config import load_profile

    batch = diagnose(table_from_fields(fields), paper_motor, load_profile(profile))
    rows, agent = stream_through_agent(path, profile)

    assert len(rows) == len(batch)
    assert agent.link.bad_bytes == 0
    for motor in range(1, 7):
        live = [r for r in rows if r["motor"] == motor]
        sel = batch["motor"] == motor
        np.testing.assert_array_equal([r["time_s"] for r in live], batch["time_s"][sel])
        np.testing.assert_array_equal(
            [r["state"] for r in live], batch["state"][sel], err_msg=f"motor {motor}"
        )
        np.testing.assert_array_equal(
            [r["announced"] for r in live], batch["announced"][sel], err_msg=f"motor {motor}"
        )
        np.testing.assert_array_equal([r["steady"] for r in live], batch["steady"][sel])
        np.testing.assert_array_equal(
            [r["sensor_flags"] for r in live], batch["sensor_flags"][sel], err_msg=f"motor {motor}"
        )
        np.testing.assert_allclose(
            [r["omega_model_rad_s"] for r in live], batch["omega_model_rad_s"][sel], rtol=1e-12
        )

    # the published changes are the batch's announced transitions (plus NO_DATA before data / after the end)
    expected = []
    for motor in range(1, 7):
        sel = batch["motor"] == motor
        announced = batch["announced"][sel]
        times = batch["time_s"][sel]
        expected.append((motor, float(times[0]), MotorState(int(announced[0]))))
        for k in np.flatnonzero(np.diff(announced)) + 1:
            expected.append((motor, float(times[k]), MotorState(int(announced[k]))))
    published = [(c.motor, c.time_s, c.state) for c in agent.changes if c.state != MotorState.NO_DATA]
    assert sorted(published) == sorted(expected)
    # the flight holds faults the agent must have announced: the test is not vacuous
    states = {s for _, _, s in published}
    assert {MotorState.F3_1, MotorState.F2_1, MotorState.F1_1} <= states
    # and a battery monitor that disagrees with the ESC currents' sum (from BATTERY_MISSCALED_FROM_S),
    # which both find only after it (the sums agree before)
    summed = (batch["sensor_flags"] & SensorIssue.CURRENT_SUM) != 0
    assert summed.any() and batch["time_s"][summed].min() > BATTERY_MISSCALED_FROM_S


def test_without_a_row_callback_the_agent_publishes_the_same(flight):
    """Without ``on_row`` (the product) the monitor makes no row per sample, only each motor's last one and
    each change's evidence (issue 18): the same changes, evidence and last rows as with every row made."""
    _, path = flight
    rows, with_rows = stream_through_agent(path, "flight")
    config = load_agent_config(None, connect=str(path), profile="flight")

    async def main() -> Agent:
        async with Agent(config) as agent:
            await asyncio.wait_for(agent.wait(), timeout=60)
        return agent

    bare = asyncio.run(main())
    assert rows and len(with_rows.changes) > 6
    assert repr(bare.changes) == repr(with_rows.changes)  # NaN evidence: compared as text
    assert repr({n: s.row for n, s in bare.monitor.status.items()}) == repr(
        {n: s.row for n, s in with_rows.monitor.status.items()}
    )


def test_the_replay_reader_and_the_agent_see_the_same_samples(flight):
    """The project's .tlog reader (replay) and the agent's live path extract the same samples from a log:
    times, motors (SERVOn_FUNCTION mapping), speeds, ESC and motor currents, commands and bus voltages."""
    from mav_motor_health.telemetry import sources

    _, path = flight
    table = sources.read(path)
    rows, _ = stream_through_agent(path, "flight")
    assert len(rows) == len(table)
    for motor in range(1, 7):
        live = [r for r in rows if r["motor"] == motor]
        ref = table.for_motor(motor)
        for name in ("time_s", "omega_rad_s", "esc_current_a", "throttle", "bus_voltage_v"):
            np.testing.assert_array_equal([r[name] for r in live], ref[name], err_msg=f"motor {motor} {name}")
        np.testing.assert_allclose([r["voltage_v"] for r in live], ref.voltage_v(), rtol=1e-12)
        # the motor current too: both derive it with mavlink_esc.motor_inputs (ESC current / throttle)
        np.testing.assert_allclose(
            [r["current_a"] for r in live], ref["current_a"], rtol=1e-12, equal_nan=True
        )


@pytest.mark.parametrize("profile", ["flight", "flight_vehicle"])
def test_a_vehicle_file_is_applied_live_as_replay_applies_it(flight, paper_motor, tmp_path, profile):
    """The ESC map and the current sensor's gain of a vehicle file, each motor's own model, and
    (flight_vehicle) each motor's noise its bands are measured in: the agent calibrates each
    batch with the same function replay calibrates the whole table with, and announces what replay
    announces."""
    from mav_motor_health.config import dump_vehicle_params, load_profile, load_vehicle_params
    from mav_motor_health.diagnosis.noise import BandNoise, EquationNoise, band_noise_of
    from mav_motor_health.model.identify import CurrentReading, EscMap
    from mav_motor_health.model.vehicle import VehicleParams

    fields, path = flight
    vehicle_file = tmp_path / "vehicle.toml"
    # each motor's noise, the torque balance's too: judged in it on motors 1-3, read through the duty
    # (not judged: rules/equations.py) on 4-6; against the siblings' (diagnosis/siblings.py) on 2-5,
    # where the vehicle stage runs across the motors in the order their samples arrive
    noise = {
        m: BandNoise(
            6.0 + m,
            0.25,
            20.0,
            0.4,
            900,
            3.8,
            300.0,
            900.0,
            torque=EquationNoise(0.002, 0.004, 0.0, 0.0005, through_duty=m > 3),
            torque_vs_siblings=EquationNoise(0.0004, 0.001, 0.0, 0.0001) if 2 <= m <= 5 else None,
        ).as_mapping()
        for m in range(1, 7)
    }
    if (
        profile == "flight"
    ):  # bands in amperes: refused for a file with the vehicle's noise (a hand-written map)
        noise = {}
    current = CurrentReading(side="input", gain=0.9, gain_from="battery", offset_a=0.5)
    vehicle_file.write_text(
        dump_vehicle_params(
            VehicleParams(
                motor=paper_motor,
                # each motor its own R and k_e, as fit writes them: diagnosed live in one core call
                per_motor={
                    m: paper_motor.replace(
                        R_ohm=paper_motor.R_ohm * (1 + 0.01 * (m - 3.5)),
                        k_e=paper_motor.k_e * (1 + 0.001 * (m - 3.5)),
                    )
                    for m in range(1, 7)
                },
                esc=EscMap(0.04),
                current=current,
                noise=noise,
            )
        ),
        encoding="utf-8",
    )
    vehicle = load_vehicle_params(vehicle_file)
    table = vehicle.calibrate(table_from_fields(fields))
    assert table.meta["esc_sum_checked"] is True
    batch = diagnose(table, vehicle.models(range(1, 7)), load_profile(profile), band_noise_of(vehicle.noise))
    plain = diagnose(table_from_fields(fields), paper_motor, load_profile("flight"))
    assert not np.array_equal(batch["state"], plain["state"])  # the map changes what is judged
    if profile == "flight_vehicle":
        np.testing.assert_allclose(batch["speed_band_rad_s"][batch["motor"] == 3][:1], [4.5 * 9.0], rtol=0.01)
        assert np.isfinite(batch["torque_siblings_nm"]).mean() > 0.5  # the vehicle stage ran

    rows: list[dict] = []
    config = load_agent_config(None, connect=str(path), profile=profile, params=str(vehicle_file))
    assert config.esc == EscMap(0.04)

    async def main() -> None:
        async with Agent(config, on_row=rows.append) as agent:
            assert agent.monitor.diagnoser.together(list(range(1, 7)))  # six models, one core call
            await asyncio.wait_for(agent.wait(), timeout=60)

    asyncio.run(main())
    assert len(set(map(id, vehicle.models(range(1, 7)).values()))) == 6  # type: ignore[union-attr]
    assert len(rows) == len(batch)
    for motor in range(1, 7):
        live = [r for r in rows if r["motor"] == motor]
        sel = batch["motor"] == motor
        np.testing.assert_array_equal(
            [r["state"] for r in live], batch["state"][sel], err_msg=f"motor {motor}"
        )
        np.testing.assert_array_equal(
            [r["announced"] for r in live], batch["announced"][sel], err_msg=f"motor {motor}"
        )
        np.testing.assert_array_equal([r["sensor_flags"] for r in live], batch["sensor_flags"][sel])
        if profile == "flight_vehicle":  # the siblings' torque, sample by sample
            np.testing.assert_allclose(
                [r["torque_siblings_nm"] for r in live],
                batch["torque_siblings_nm"][sel],
                rtol=1e-9,
                atol=1e-12,
                equal_nan=True,
                err_msg=f"motor {motor}",
            )


def test_a_simulated_tlog_streamed_through_the_agent_gives_replays_samples(paper_motor):
    """The simulator's .tlog stamps many ESC and servo messages with one time, in either order; replay
    pairs them whatever the order, and the agent reading the .tlog in batches must too (its batches end
    between time stamps, never inside one): the same samples, the same diagnosis.

    The log pairs its samples loosely (ESC messages at 10 Hz, each carrying a packet up to 100 ms older
    than its stamp), so the balance rule's pairing guard (diagnosis/pairing.py) sets samples aside. Both
    weigh each sample's own pairing, worked out causally by the same code (telemetry/assemble.py:
    ``pairing_s``, issue 18): the agent announces what ``replay`` announces, guard included."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.plausibility import SensorIssue
    from mav_motor_health.telemetry import sources

    path = Path(__file__).resolve().parents[2] / "sitl_logs" / "flight_F4.1_moderate.tlog"
    table = sources.read(path)
    assert table.meta["pairing_s"] > 0.05  # a loosely paired log: the case the guard is for
    batch = diagnose(table, paper_motor, load_profile("flight"))  # as replay runs it
    guarded = (batch["sensor_flags"] & SensorIssue.CURRENT_UNPAIRED) != 0
    assert guarded.any() and (batch["pairing_error_rad_s"] > 0).any()  # not vacuous: the guard acts
    rows, agent = stream_through_agent(path, "flight")
    assert len(rows) == len(batch)
    for motor in range(1, 7):
        live = [r for r in rows if r["motor"] == motor]
        sel = batch["motor"] == motor
        for name in ("time_s", "voltage_v", "current_a", "state", "announced", "steady", "sensor_flags"):
            np.testing.assert_array_equal(
                [r[name] for r in live], batch[name][sel], err_msg=f"motor {motor}: {name}"
            )
        # the low-passes in batches or whole differ in the last bits only
        for name in ("omega_model_rad_s", "pairing_error_rad_s", "input_activity_v"):
            np.testing.assert_allclose(
                [r[name] for r in live],
                batch[name][sel],
                rtol=1e-9,
                atol=1e-12,
                err_msg=f"motor {motor}: {name}",
            )
    # the announcements: the agent's published changes are replay's announced transitions
    expected = []
    for motor in range(1, 7):
        sel = batch["motor"] == motor
        announced, times = batch["announced"][sel], batch["time_s"][sel]
        expected.append((motor, float(times[0]), MotorState(int(announced[0]))))
        for k in np.flatnonzero(np.diff(announced)) + 1:
            expected.append((motor, float(times[k]), MotorState(int(announced[k]))))
    published = [(c.motor, c.time_s, c.state) for c in agent.changes if c.state != MotorState.NO_DATA]
    assert sorted(published) == sorted(expected)
    assert (batch["announced"] == MotorState.F4_1).any()  # not vacuous: the fault is announced


def test_commands_between_two_esc_reports_count_alike_live_and_in_replay(paper_motor, tmp_path):
    """A world whose ESCs report at 10 Hz and whose commands are logged at 50 Hz (world 2): the commands
    between two reports go beyond the two held ones (``input_excursion_v``, telemetry/assemble.py), and
    with ``steady.excursion_weight`` and ``excursion_pairing_weight`` (options, off in the shipped
    profiles) the balance rule's input activity and the pairing guard take them in. The agent, reading the .tlog in batches, carries the commands from one batch
    to the next sample: the same activity, the same diagnosis as replay."""
    import dataclasses

    from mav_motor_health.config import dump_profile, load_profile
    from mav_motor_health.evaluation.worlds import fly_world
    from mav_motor_health.sim.worlds import draw_world
    from mav_motor_health.sim.writers import write_record
    from mav_motor_health.telemetry import sources

    world = draw_world(2)
    assert (world.esc_stream_hz, world.log_hz) == (10.0, 50.0)
    path, _ = write_record(fly_world(2, duration_s=20.0, turbulence="moderate"), tmp_path / "world2.tlog")
    table = sources.read(path)
    fresh = np.isfinite(table["omega_rad_s"])  # replay keeps an ESC's repeated reports as rows without data
    assert (table["input_excursion_v"][fresh] > 0.05).mean() > 0.2  # not vacuous: commands moved
    shipped = load_profile("flight")
    assert shipped.steady.excursion_weight == 0.0
    assert shipped.steady.excursion_pairing_weight == 0.0
    both = {"excursion_weight": 1.0, "excursion_pairing_weight": 1.0}  # the activity and the pairing guard
    profile = dataclasses.replace(shipped, steady=dataclasses.replace(shipped.steady, **both))
    profile_file = tmp_path / "with_excursions.toml"
    profile_file.write_text(dump_profile(profile), encoding="utf-8")
    assert load_profile(profile_file).steady == profile.steady
    batch = diagnose(table, paper_motor, profile)
    rows, _ = stream_through_agent(path, str(profile_file))
    assert len(rows) == fresh.sum()
    for motor in range(1, 7):
        live = [r for r in rows if r["motor"] == motor]
        sel = (batch["motor"] == motor) & fresh
        for name in ("time_s", "state", "announced", "steady", "sensor_flags"):
            np.testing.assert_array_equal(
                [r[name] for r in live], batch[name][sel], err_msg=f"{motor} {name}"
            )
        for name in ("input_activity_v", "omega_model_rad_s", "pairing_error_rad_s"):
            np.testing.assert_allclose(
                [r[name] for r in live], batch[name][sel], rtol=1e-9, atol=1e-12, err_msg=f"{motor} {name}"
            )
    # the shipped profile leaves the excursions out: its activity is the same as with none; with the
    # option it is higher where the commands moved between reports
    off = diagnose(table, paper_motor, shipped)
    none = diagnose(table.with_columns(input_excursion_v=np.zeros(len(table))), paper_motor, profile)
    judged = np.isfinite(batch["input_activity_v"])
    np.testing.assert_array_equal(off["input_activity_v"], none["input_activity_v"])
    assert (batch["input_activity_v"][judged] >= none["input_activity_v"][judged] - 1e-12).all()
    ratio = batch["input_activity_v"][judged] / np.fmax(none["input_activity_v"][judged], 1e-9)
    assert np.median(ratio) > 1.05
    np.testing.assert_array_equal(off["pairing_error_rad_s"], none["pairing_error_rad_s"])
    assert (batch["pairing_error_rad_s"][judged] >= none["pairing_error_rad_s"][judged] - 1e-12).all()
    assert (
        np.median(batch["pairing_error_rad_s"][judged] / np.fmax(none["pairing_error_rad_s"][judged], 1e-9))
        > 1.05
    )
