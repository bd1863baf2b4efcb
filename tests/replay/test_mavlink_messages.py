"""One reading of MAVLink messages (telemetry/mavlink_messages.py) for the .tlog reader and the live agent.

The same messages go two ways: written as a .tlog and read by replay's reader (the whole log in one
call, then ``assemble.motor_table``), and decoded by pymavlink and fed to the agent's
``SampleAssembler`` in small batches of varying size (the live link's path). The tables must agree
column by column on every fresh sample, through a parameter change, a silent ESC, empty ESC slots, an ESC
without voltage sensing, servo outputs 9-16 (MAVLink 2 extensions and MAVLink 1's port 1), PX4's
ESC_STATUS and the battery messages and their "not measured" values. Both pair the samples with commands
and battery by one rule (``assemble.HeldValues``: the last value at or before the sample's time, none
older than 1 s for commands, 5 s for the battery; a "not measured" is the latest word), replay on the
whole log, the agent batch by batch; tests/replay/test_pairing.py splits the batches everywhere.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink.dialects.v10 import ardupilotmega as mav1
from pymavlink.dialects.v20 import ardupilotmega as mav2

from mav_motor_health.agent.samples import SampleAssembler
from mav_motor_health.publish import dialect
from mav_motor_health.telemetry.mavlink_esc import RPM_TO_RAD_S
from mav_motor_health.telemetry.mavlink_messages import MessageReader, columns_from_messages
from mav_motor_health.telemetry.tlog import read_tlog

T0_US = 1_700_000_000_000_000
TICK_US = 20_000  # 50 Hz
LIVE_COLUMNS = (
    "time_s",
    "omega_rad_s",
    "current_a",
    "voltage_v",
    "bus_voltage_v",
    "throttle",
    "esc_current_a",
    "esc_temp_c",
    "battery_voltage_v",
    "battery_current_a",
    "pairing_s",  # each sample's pairing with its command (telemetry/assemble.py)
    "input_excursion_v",  # how far the command went between two samples (telemetry/assemble.py)
)

V2 = mav2.MAVLink(None, srcSystem=1, srcComponent=1)
V1 = mav1.MAVLink(None, srcSystem=1, srcComponent=1)
Frames = list[tuple[int, bytes]]  # (record time [µs], MAVLink frame)


def param(name: str, value: float) -> bytes:
    return V2.param_value_encode(name.encode(), value, 9, 100, 0).pack(V2)


def esc_message(first: int, rpm: list[int], cv: list[int], ca: list[int], temp: list[int], count: list[int]):
    encode = {
        0: V2.esc_telemetry_1_to_4_encode,
        4: V2.esc_telemetry_5_to_8_encode,
        8: V2.esc_telemetry_9_to_12_encode,
    }[first]
    return encode(temp, cv, ca, [0] * 4, rpm, count).pack(V2)


def ardupilot_hexa() -> Frames:
    """A hexacopter at 50 Hz for 6 s: motors 1-6 on outputs/ESC slots 0-5 (slots 6 and 7 never report),
    ESC 4 without voltage sensing (the battery's stands in), ESC 3 silent from 2 s to 3.2 s (ArduPilot
    repeats its last packet, count frozen), motors 1 and 2 swapped by SERVOn_FUNCTION at 3 s, the PWM
    range narrowed at 4 s, the battery monitor not measuring its current at first."""
    frames: Frames = [(T0_US, V2.heartbeat_encode(2, 3, 128 | 1, 0, 4).pack(V2))]
    for output in range(1, 7):
        frames.append((T0_US + output, param(f"SERVO{output}_FUNCTION", 32 + output)))
    frames += [(T0_US + 10, param("MOT_PWM_MIN", 1000)), (T0_US + 11, param("MOT_PWM_MAX", 2000))]
    rpm = np.zeros(8, dtype=int)
    cv, ca, temp, count = [0] * 8, [0] * 8, [0] * 8, [0] * 8
    for k in range(300):
        stamp = T0_US + 1_000_000 + k * TICK_US
        if k == 150:  # motors 1 and 2 change outputs
            frames += [(stamp, param("SERVO1_FUNCTION", 34)), (stamp, param("SERVO2_FUNCTION", 33))]
        if k == 200:
            frames.append((stamp, param("MOT_PWM_MAX", 1900)))
        pwm = [1300 + 40 * m + int(80 * math.sin(0.05 * k + m)) for m in range(6)]
        frames.append((stamp, V2.servo_output_raw_encode(k, 0, *pwm, 0, 0).pack(V2)))
        if k % 5 == 0:
            current = -1 if k < 20 else 1500 + k  # -1: not measured (yet)
            frames.append(
                (stamp, V2.sys_status_encode(0, 0, 0, 0, 15800 - k, current, -1, 0, 0, 0, 0, 0, 0).pack(V2))
            )
        for e in range(6):
            if e == 2 and 100 <= k < 160:
                continue  # ESC 3 silent: its last packet repeated
            rpm[e] = 3000 + 100 * e + 7 * k
            cv[e] = 0 if e == 3 else 1580 - k // 10
            ca[e] = 300 + 10 * e + (k % 13)
            temp[e] = 30 + e
            count[e] = (k + 1) & 0xFFFF
        for first in (0, 4):
            sl = slice(first, first + 4)
            frames.append((stamp, esc_message(first, rpm[sl].tolist(), cv[sl], ca[sl], temp[sl], count[sl])))
    return frames


def extension_outputs_quad() -> Frames:
    """A quadcopter on servo outputs 9-12 (MAVLink 2's extension fields; ESC_TELEMETRY_9_TO_12), its
    battery in BATTERY_STATUS by cell (UINT16_MAX: no such cell), a second battery and a SYS_STATUS that
    disagree (battery 0 is the one), ESCs without voltage sensing."""
    frames: Frames = [(T0_US, V2.heartbeat_encode(2, 3, 128 | 1, 0, 4).pack(V2))]
    for output in range(1, 13):
        frames.append(
            (T0_US + output, param(f"SERVO{output}_FUNCTION", 32 + output - 8 if output > 8 else 0))
        )
    for k in range(120):
        stamp = T0_US + 500_000 + k * TICK_US
        if k % 10 == 0:
            cells = [3950 - k, 3940 - k, 3960 - k, 3945 - k] + [0xFFFF] * 6
            frames.append(
                (stamp, V2.battery_status_encode(0, 0, 1, 2500, cells, 2000 + k, 100, -1, 80).pack(V2))
            )
            frames.append(
                (
                    stamp,
                    V2.battery_status_encode(1, 0, 1, 2500, [11000] + [0xFFFF] * 9, 100, 1, -1, 80).pack(V2),
                )
            )
            frames.append(
                (stamp, V2.sys_status_encode(0, 0, 0, 0, 12000, 500, -1, 0, 0, 0, 0, 0, 0).pack(V2))
            )
        pwm = [1500] * 8 + [1400 + 10 * m + (k % 17) for m in range(4)] + [0] * 4
        frames.append((stamp, V2.servo_output_raw_encode(k, 0, *pwm).pack(V2)))
        frames.append(
            (
                stamp,
                esc_message(
                    8,
                    [4000 + 50 * e + k for e in range(4)],
                    [0] * 4,
                    [400 + e + k % 7 for e in range(4)],
                    [40] * 4,
                    [k + 1] * 4,
                ),
            )
        )
    return frames


def mavlink1_port1_quad() -> Frames:
    """Outputs 9-12 drive the motors; a MAVLink 1 autopilot sends them as port 1's servo1..4."""
    frames: Frames = [(T0_US, V1.heartbeat_encode(2, 3, 128 | 1, 0, 4).pack(V1))]
    for output in range(1, 13):
        frames.append(
            (T0_US + output, param(f"SERVO{output}_FUNCTION", 32 + output - 8 if output > 8 else 0))
        )
    for k in range(60):
        stamp = T0_US + 200_000 + k * TICK_US
        frames.append((stamp, V1.sys_status_encode(0, 0, 0, 0, 16000, 900, -1, 0, 0, 0, 0, 0, 0).pack(V1)))
        frames.append((stamp, V1.servo_output_raw_encode(k, 0, *([1100] * 8)).pack(V1)))
        upper = [1450 + 20 * m + k for m in range(4)] + [0] * 4
        frames.append((stamp, V1.servo_output_raw_encode(k, 1, *upper).pack(V1)))
        frames.append(
            (
                stamp,
                esc_message(
                    8, [5000 + e + k for e in range(4)], [1600] * 4, [500] * 4, [35] * 4, [k + 1] * 4
                ),
            )
        )
    return frames


def px4_hexa() -> Frames:
    """PX4: ESC_STATUS (rpm [1/min], voltage [V], current [A] as floats, four ESCs a message from index)."""
    gen = dialect.load()
    px4 = gen.MAVLink(None, srcSystem=1, srcComponent=1)
    frames: Frames = [(T0_US, V2.heartbeat_encode(13, 12, 128, 0, 4).pack(V2))]
    for k in range(80):
        stamp = T0_US + 100_000 + k * TICK_US
        frames.append(
            (stamp, V2.servo_output_raw_encode(k, 0, *[1500 + 3 * m + k for m in range(8)]).pack(V2))
        )
        if k % 4 == 0:
            cells = [16100 - k] + [0xFFFF] * 9
            frames.append((stamp, V2.battery_status_encode(0, 0, 1, 2500, cells, 1200, 100, -1, 80).pack(V2)))
        for index in (0, 4):
            rpm = [6000 + 10 * (index + i) + k if index + i < 6 else 0 for i in range(4)]
            volts = [15.9 if index + i < 6 else 0.0 for i in range(4)]
            amps = [3.25 + 0.125 * (index + i) if index + i < 6 else 0.0 for i in range(4)]
            msg = gen.MAVLink_esc_status_message(index, stamp - T0_US, rpm, volts, amps)
            frames.append((stamp, msg.pack(px4)))
    return frames


SCENARIOS: dict[str, Callable[[], Frames]] = {
    "ardupilot_param_change_silent_esc": ardupilot_hexa,
    "outputs_9_to_12_battery_status": extension_outputs_quad,
    "mavlink1_port_1": mavlink1_port1_quad,
    "px4_esc_status": px4_hexa,
}


def write_tlog(frames: Frames, path: Path) -> Path:
    path.write_bytes(b"".join(struct.pack(">Q", stamp) + frame for stamp, frame in frames))
    return path


def decoded(frames: Frames) -> list[tuple[float, Any]]:
    """The frames as the live link receives them: pymavlink's MAVLink 2 parser, times from the first."""
    dialect.register(mav2)  # PX4's ESC_STATUS
    parser = mav2.MAVLink(None, 0, 0)
    first = frames[0][0]
    out = []
    for stamp, frame in frames:
        (msg,) = parser.parse_buffer(frame)
        out.append(((stamp - first) / 1e6, msg))
    return out


def live_columns(frames: Frames, seed: int) -> dict[str, np.ndarray]:
    """The agent's path: batches of 1 to 40 messages, as the link delivers them."""
    assembler = SampleAssembler(motors=8)
    rng = np.random.default_rng(seed)
    parts = []
    received = decoded(frames)
    k = 0
    while k < len(received):
        n = int(rng.integers(1, 41))
        for t, msg in received[k : k + n]:
            assembler.add(msg, t)
        parts.append(assembler.take())
        k += n
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_the_tlog_reader_and_the_live_path_give_the_same_table(scenario: str, tmp_path: Path) -> None:
    frames = SCENARIOS[scenario]()
    table = read_tlog(write_tlog(frames, tmp_path / "flight.tlog"))
    for seed in (1, 2):
        live = live_columns(frames, seed)
        assert sorted(set(live["motor"].tolist())) == table.motors()
        assert np.all(np.diff(live["time_s"]) >= 0)
        for motor in table.motors():
            ref = table.for_motor(motor)
            fresh = np.isfinite(ref["omega_rad_s"])  # replay keeps stale rows, without speed and current
            mine = live["motor"] == motor
            for name in LIVE_COLUMNS:
                np.testing.assert_array_equal(
                    live[name][mine], ref[name][fresh], err_msg=f"motor {motor} {name}"
                )


def test_a_parameter_change_and_a_silent_esc_read_alike_both_ways(tmp_path: Path) -> None:
    frames = ardupilot_hexa()
    table = read_tlog(write_tlog(frames, tmp_path / "flight.tlog"))
    live = live_columns(frames, seed=3)
    t_change = 1.0 + 150 * TICK_US / 1e6
    for rows in (table.for_motor(1).columns, {k: v[live["motor"] == 1] for k, v in live.items()}):
        after = rows["time_s"] >= t_change
        # before 3 s motor 1 is ESC slot 0 (3000 rpm + ...); after, slot 1 (3100 rpm + ...)
        k = np.round((rows["time_s"] - 1.0) * 1e6 / TICK_US).astype(int)
        slot = np.where(after, 1, 0)
        np.testing.assert_allclose(rows["omega_rad_s"], (3000 + 100 * slot + 7 * k) * RPM_TO_RAD_S)
    # ESC 3's repeats: stale rows in the table, no samples live
    silent = (table.for_motor(3)["time_s"] >= 1.0 + 100 * TICK_US / 1e6) & (
        table.for_motor(3)["time_s"] < 1.0 + 160 * TICK_US / 1e6
    )
    assert silent.sum() == 60 and np.isnan(table.for_motor(3)["omega_rad_s"][silent]).all()
    m3 = live["time_s"][live["motor"] == 3]
    assert not ((m3 >= 1.0 + 100 * TICK_US / 1e6) & (m3 < 1.0 + 160 * TICK_US / 1e6)).any()
    # its command swung on during the silence: the first sample after it carries how far beyond the two
    # held commands (times the bus voltage), every sample of a command message's own tick none
    for rows in (table.for_motor(3).columns, {k: v[live["motor"] == 3] for k, v in live.items()}):
        fresh = np.isfinite(rows["omega_rad_s"])
        k = np.round((rows["time_s"][fresh] - 1.0) * 1e6 / TICK_US).astype(int)
        excursion = rows["input_excursion_v"][fresh]
        pwm = 1300 + 40 * 2 + (80 * np.sin(0.05 * np.arange(300) + 2)).astype(int)
        swing = (pwm[100:161].max() - max(pwm[99], pwm[160])) / 1000  # throttle: (pwm - 1000) / 1000
        bus = rows["bus_voltage_v"][fresh][k == 160]
        np.testing.assert_allclose(excursion[k == 160], swing * bus)
        assert swing > 0.02 and (excursion[(k != 160) & (k > 0)] == 0).all()
    # the narrower PWM range from 4 s on: throttle = (pwm - 1000) / 900
    m6 = table.for_motor(6)
    late = m6["time_s"] >= 1.0 + 200 * TICK_US / 1e6
    k = np.round((m6["time_s"][late] - 1.0) * 1e6 / TICK_US).astype(int)
    pwm = 1300 + 40 * 5 + (80 * np.sin(0.05 * k + 5)).astype(int)
    np.testing.assert_allclose(m6["throttle"][late], (pwm - 1000) / 900)
    # ESC 4 measures no voltage: the battery's (SYS_STATUS) stands in
    assert (table.for_motor(4)["bus_voltage_v"][5:] < 15.8).all()
    assert np.isnan(live["battery_current_a"][live["time_s"] < 1.0 + 20 * TICK_US / 1e6]).all()  # -1


def test_the_reader_gives_the_same_reading_whole_or_in_batches() -> None:
    """The module alone: one call with every message, or a call per few messages, gives the same rows,
    commands and battery readings (its carried state: counts, parameters, what the stream has shown)."""
    received = decoded(ardupilot_hexa())
    whole = MessageReader().read(columns_from_messages(received))
    reader = MessageReader()
    parts = [reader.read(columns_from_messages(received[k : k + 7], k)) for k in range(0, len(received), 7)]
    batched_order = np.lexsort(
        (np.concatenate([p.time_s for p in parts]), np.concatenate([p.motor for p in parts]))
    )
    whole_order = np.lexsort((whole.time_s, whole.motor))  # rows per motor, in time
    for name in ("time_s", "motor", "omega_rad_s", "esc_current_a", "bus_voltage_v", "esc_temp_c", "fresh"):
        batched = np.concatenate([getattr(p, name) for p in parts])
        np.testing.assert_array_equal(batched[batched_order], getattr(whole, name)[whole_order], err_msg=name)
    commands = whole.commands()
    for motor, (t, throttle) in commands.items():
        batched = [p.commands()[motor] for p in parts if motor in p.commands()]
        np.testing.assert_array_equal(np.concatenate([b[0] for b in batched]), t)
        np.testing.assert_array_equal(np.concatenate([b[1] for b in batched]), throttle)
    np.testing.assert_array_equal(
        np.concatenate([p.battery_current_a for p in parts]), whole.battery_current_a
    )
    assert reader.repeats == 60  # ESC 3's silence
    assert reader.params["SERVO1_FUNCTION"] == 34 and reader.params["MOT_PWM_MAX"] == 1900


def test_battery_sentinels_are_no_reading(tmp_path: Path) -> None:
    """UINT16_MAX (and 0) volts and a negative current (-1: not measured) are NaN in the reading; the
    table and the agent hold the latest message's values (NaN included)."""
    sys_status = [
        V2.sys_status_encode(0, 0, 0, 0, 15000, 800, -1, 0, 0, 0, 0, 0, 0),
        V2.sys_status_encode(0, 0, 0, 0, 0xFFFF, -1, -1, 0, 0, 0, 0, 0, 0),
        V2.sys_status_encode(0, 0, 0, 0, 0, 700, -1, 0, 0, 0, 0, 0, 0),
    ]
    received = [
        (0.1 * k, mav2.MAVLink(None, 0, 0).parse_buffer(m.pack(V2))[0]) for k, m in enumerate(sys_status)
    ]
    reading = MessageReader().read(columns_from_messages(received))
    np.testing.assert_array_equal(reading.battery_voltage_v, [15.0, np.nan, np.nan])
    np.testing.assert_array_equal(reading.battery_current_a, [8.0, np.nan, 7.0])
    cells = [[0xFFFF] * 10, [4000, 4100, 0xFFFF] + [0xFFFF] * 7]
    battery = [V2.battery_status_encode(0, 0, 1, 2500, c, -1, 1, -1, 80) for c in cells]
    received = [
        (0.1 * k, mav2.MAVLink(None, 0, 0).parse_buffer(m.pack(V2))[0]) for k, m in enumerate(battery)
    ]
    reading = MessageReader().read(columns_from_messages(received))
    np.testing.assert_array_equal(reading.battery_voltage_v, [np.nan, 8.1])
    assert np.isnan(reading.battery_current_a).all()
    # the agent: a "not measured" after a reading is no value (NaN until the next reading), as in replay
    assembler = SampleAssembler(motors=4)
    for k, m in enumerate(sys_status[:2]):
        assembler.add(mav2.MAVLink(None, 0, 0).parse_buffer(m.pack(V2))[0], 0.1 * k)
    esc = esc_message(0, [5000] * 4, [0] * 4, [100] * 4, [30] * 4, [1] * 4)
    (sample, *_) = assembler.feed(mav2.MAVLink(None, 0, 0).parse_buffer(esc)[0], 0.25)
    assert math.isnan(sample.bus_voltage_v) and math.isnan(sample.battery_current_a)
    # replay: the table holds the latest message, "not measured" included
    frames = [(T0_US + 100_000 * k, m.pack(V2)) for k, m in enumerate(sys_status[:2])]
    frames.append((T0_US + 250_000, esc))
    table = read_tlog(write_tlog(frames, tmp_path / "sentinel.tlog"))
    assert np.isnan(table["bus_voltage_v"]).all() and np.isnan(table["battery_current_a"]).all()


def test_outputs_9_to_16_battery_cells_and_px4_scaling(tmp_path: Path) -> None:
    """What the scenarios read (the live path reads the same, test above): commands from outputs 9-12 as
    MAVLink 2 extensions and as MAVLink 1's port 1, the battery as the sum of battery 0's cells, PX4's
    ESC_STATUS in SI units already."""
    table = read_tlog(write_tlog(extension_outputs_quad(), tmp_path / "ext.tlog"))
    assert table.motors() == [1, 2, 3, 4]
    for motor in (1, 4):
        rows = table.for_motor(motor)
        k = np.round((rows["time_s"] - 0.5) * 1e6 / TICK_US).astype(int)
        np.testing.assert_allclose(rows["throttle"], (400 + 10 * (motor - 1) + k % 17) / 1000)
        np.testing.assert_allclose(rows["omega_rad_s"], (4000 + 50 * (motor - 1) + k) * RPM_TO_RAD_S)
        cells = 4 * 3948.75 - 4 * (k - k % 10)  # battery 0's four cells at the last BATTERY_STATUS
        np.testing.assert_allclose(rows["bus_voltage_v"], cells / 1000)
        np.testing.assert_allclose(rows["battery_current_a"], (2000 + k - k % 10) / 100)
    table = read_tlog(write_tlog(mavlink1_port1_quad(), tmp_path / "port1.tlog"))
    assert table.motors() == [1, 2, 3, 4]
    rows = table.for_motor(3)
    k = np.round((rows["time_s"] - 0.2) * 1e6 / TICK_US).astype(int)
    np.testing.assert_allclose(rows["throttle"], (450 + 40 + k) / 1000)
    table = read_tlog(write_tlog(px4_hexa(), tmp_path / "px4.tlog"))
    assert table.motors() == [1, 2, 3, 4, 5, 6, 7, 8]  # index 4's message carries ESCs 7 and 8 too
    rows = table.for_motor(5)
    k = np.round((rows["time_s"] - 0.1) * 1e6 / TICK_US).astype(int)
    np.testing.assert_allclose(rows["omega_rad_s"], (6040 + k) * RPM_TO_RAD_S)
    np.testing.assert_allclose(rows["esc_current_a"], 3.75)
    np.testing.assert_allclose(rows["bus_voltage_v"], 15.9, rtol=1e-7)  # float32 on the wire
    assert np.isnan(rows["esc_temp_c"]).all()


# -- pairing: one rule, whole log or batches ------------------------------------------------------------
SLOW_TICK_US = 50_000  # 20 Hz: a small stream, cut at every message below


def stale_command_and_battery_hexa() -> Frames:
    """A hexacopter at 20 Hz for 12.5 s whose streams stop: SERVO_OUTPUT_RAW silent for 1.5 s from 4 s (the
    last 0.5 s of ESC samples have a command older than 1 s), SYS_STATUS silent for 6.5 s from 6 s (ESC 4
    measures no voltage: its bus voltage comes from the battery, stale after 5 s), the battery's current
    "not measured" for a second after readings and its voltage "no reading" for a moment. A command comes
    at the ESC message's own stamp before it on even ticks, 7 ms before it on odd ones."""
    frames: Frames = [(T0_US, V2.heartbeat_encode(2, 3, 128 | 1, 0, 4).pack(V2))]
    for output in range(1, 7):
        frames.append((T0_US + output, param(f"SERVO{output}_FUNCTION", 32 + output)))
    for k in range(250):
        stamp = T0_US + 1_000_000 + k * SLOW_TICK_US
        if not 60 <= k < 90:
            pwm = [1300 + 40 * m + (7 * k) % 90 for m in range(6)]
            frames.append((stamp - (k % 2) * 7000, V2.servo_output_raw_encode(k, 0, *pwm, 0, 0).pack(V2)))
        if k % 2 == 0 and not 100 <= k < 230:
            volts_mv = 0 if 40 <= k < 46 else 15800 - 3 * k  # 0: no reading
            current = -1 if 20 <= k < 40 else 1500 + k  # -1: not measured
            frames.append(
                (stamp, V2.sys_status_encode(0, 0, 0, 0, volts_mv, current, -1, 0, 0, 0, 0, 0, 0).pack(V2))
            )
        rpm = [3000 + 100 * e + 7 * k for e in range(6)] + [0, 0]
        cv = [0 if e == 3 else 1580 - k // 10 for e in range(6)] + [0, 0]
        ca = [300 + 10 * e + k % 13 for e in range(6)] + [0, 0]
        count = [k + 1] * 6 + [0, 0]
        for first in (0, 4):
            sl = slice(first, first + 4)
            frames.append((stamp, esc_message(first, rpm[sl], cv[sl], ca[sl], [30] * 4, count[sl])))
    return frames


def batched_columns(received: list[tuple[float, Any]], cuts: list[int]) -> dict[str, np.ndarray]:
    """The agent's path on decoded messages, a batch between consecutive ``cuts`` (message indices)."""
    assembler = SampleAssembler(motors=6)
    parts = []
    for start, end in zip([0, *cuts], [*cuts, len(received)]):
        for t, msg in received[start:end]:
            assembler.add(msg, t)
        parts.append(assembler.take())
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


def assert_same_columns(got: dict[str, np.ndarray], want: dict[str, np.ndarray], what: str) -> None:
    assert got.keys() == want.keys()
    for name in want:
        np.testing.assert_array_equal(got[name], want[name], err_msg=f"{what}: {name}")


def test_stale_commands_and_battery_pair_alike_in_replay_and_live_cut_anywhere(tmp_path: Path) -> None:
    """Replay's table and the agent's samples of the same messages are equal column by column, the agent's
    messages read in one batch, one by one, or in two batches cut at every place in the stream — between a
    command and the ESC message that uses it, inside the command and battery gaps. A command older than
    1 s is no command (throttle, motor voltage and current NaN), a battery message older than 5 s no
    battery value, a "not measured" the latest word."""
    frames = stale_command_and_battery_hexa()
    table = read_tlog(write_tlog(frames, tmp_path / "stale.tlog"))
    received = decoded(frames)
    whole = batched_columns(received, [])
    for motor in table.motors():
        ref, mine = table.for_motor(motor), whole["motor"] == motor
        for name in LIVE_COLUMNS:
            np.testing.assert_array_equal(whole[name][mine], ref[name], err_msg=f"motor {motor} {name}")
    # what the scenario is for: samples with a stale command, with a stale battery, with "not measured"
    tick = np.round((whole["time_s"] - 1.0) * 1e6 / SLOW_TICK_US).astype(int)
    stale_command = (tick >= 79) & (tick < 90)  # the last command at tick 59 - 7 ms: 1.007 s before tick 79
    assert stale_command.sum() == 6 * 11 and np.isnan(whole["throttle"][stale_command]).all()
    assert np.isnan(whole["voltage_v"][stale_command]).all()
    assert np.isnan(whole["current_a"][stale_command]).all()
    assert np.isfinite(whole["omega_rad_s"][stale_command]).all()
    assert np.isfinite(whole["throttle"][~stale_command]).all()
    stale_battery = (tick >= 199) & (tick < 230)  # the last SYS_STATUS at tick 98: 5.05 s before tick 199
    assert np.isnan(whole["battery_voltage_v"][stale_battery]).all()
    assert np.isnan(whole["bus_voltage_v"][stale_battery & (whole["motor"] == 4)]).all()
    no_voltage = (tick >= 40) & (tick < 46)
    assert np.isfinite(whole["battery_voltage_v"][~stale_battery & ~no_voltage]).all()
    assert np.isnan(whole["battery_current_a"][(tick >= 20) & (tick < 40)]).all()  # not measured
    # each sample's pairing: the interval of its motor's ESC messages (50 ms at 20 Hz) while the
    # commands come with the messages (0 or 7 ms before), the command's age once that is more (the
    # SERVO_OUTPUT_RAW gap), none without a command; a motor's first message has none before it
    pairing = whole["pairing_s"]
    age = (tick - 59) * SLOW_TICK_US / 1e6 + 0.007
    gap = (tick >= 60) & (tick < 79)
    np.testing.assert_allclose(pairing[gap], age[gap], rtol=1e-9)
    assert np.isnan(pairing[stale_command]).all()
    steady = (tick > 0) & ~gap & ~stale_command
    np.testing.assert_allclose(pairing[steady], SLOW_TICK_US / 1e6, rtol=1e-6)
    np.testing.assert_allclose(pairing[tick == 0], 0.0, atol=1e-9)  # command at the stamp, nothing before
    # batches: one message each, and two batches cut at every place
    assert_same_columns(batched_columns(received, list(range(1, len(received)))), whole, "one by one")
    kinds = [msg.get_type() for _, msg in received]
    between = [
        k for k in range(1, len(kinds)) if kinds[k - 1] == "SERVO_OUTPUT_RAW" and kinds[k].startswith("ESC")
    ]
    assert len(between) > 100  # a cut between a command and the ESC message that uses it
    # every one of those, every fourth place, every place around where the command or battery goes stale
    # or comes back
    times = np.array([t for t, _ in received])
    edges = 1.0 + SLOW_TICK_US / 1e6 * np.array([59, 79, 90, 98, 199, 230])
    near = np.flatnonzero((np.abs(times[:, None] - edges) < 0.12).any(axis=1))
    cuts = sorted({*between, *range(1, len(received), 4), *near[near > 0].tolist()})
    for cut in cuts:
        assert_same_columns(batched_columns(received, [cut]), whole, f"cut at message {cut}")


def test_a_command_stamped_with_the_sample_but_after_it(tmp_path: Path) -> None:
    """Where rule and batching meet: a command with the ESC message's own time counts (at or before the
    sample's time) even if it came after the ESC message — in replay, and live when both come in the same
    batch (the agent's link stamps all messages of one read alike and never splits a read). Only a batch
    boundary between them, with equal times, leaves the agent the command before (it had not come)."""
    frames: Frames = [(T0_US, V2.heartbeat_encode(2, 3, 128 | 1, 0, 4).pack(V2))]
    frames.append((T0_US + 10_000, V2.servo_output_raw_encode(0, 0, *([1500] * 8)).pack(V2)))
    stamp = T0_US + 30_000
    frames.append((stamp, esc_message(0, [5000] * 4, [1600] * 4, [400] * 4, [30] * 4, [1] * 4)))
    frames.append((stamp, V2.servo_output_raw_encode(1, 0, *([1600] * 8)).pack(V2)))
    table = read_tlog(write_tlog(frames, tmp_path / "tie.tlog"))
    np.testing.assert_allclose(table["throttle"], 0.6)
    received = decoded(frames)
    np.testing.assert_allclose(batched_columns(received, [])["throttle"], 0.6)
    np.testing.assert_allclose(batched_columns(received, [3])["throttle"], 0.5)
