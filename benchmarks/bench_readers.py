"""Log readers against pymavlink's own readers, in the same run, on the same files; plus end-to-end replay.

    PYTHONPATH=src python benchmarks/bench_readers.py [--logs ../shared/real_logs] [--hour]

1. ``.bin``: the ESC, RCOU (motor command) and BAT records, with pymavlink's ``DFReader`` (its
   ``recv_match`` loop) and with :func:`mav_motor_health.telemetry.dataflash.read_records`;
2. ``.tlog``: the ESC_TELEMETRY_*, SERVO_OUTPUT_RAW, BATTERY_STATUS and SYS_STATUS messages, with the
   ``mavutil`` message loop and with :func:`mav_motor_health.telemetry.tlog.read_messages`.

Every value both readers return is compared (they must be identical), then the ratio of the times is
printed (goal: ≥ 20× on .bin, ≥ 10× on .tlog). Ours is timed as the best of 5 runs, pymavlink as the best
of 2 (both warmed up: dialect modules imported, file in the page cache). Last, the real SITL ``.bin`` is
replayed end to end (read, diagnose, write the three files), and with ``--hour`` a synthetic one-hour
hexacopter DataFlash log (100 Hz ESC records per motor, written here with numpy) is replayed as well.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
import warnings
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from mav_motor_health.config import load_motor_params, load_profile  # noqa: E402
from mav_motor_health.replay import replay_log  # noqa: E402
from mav_motor_health.telemetry.dataflash import read_records  # noqa: E402
from mav_motor_health.telemetry.tlog import read_messages  # noqa: E402

BIN_TYPES = ["ESC", "RCOU", "BAT"]
TLOG_TYPES = [
    "ESC_TELEMETRY_1_TO_4",
    "ESC_TELEMETRY_5_TO_8",
    "SERVO_OUTPUT_RAW",
    "BATTERY_STATUS",
    "SYS_STATUS",
]


def _best(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    best, result = math.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - start)
    return best, result


def pymavlink_bin(path: Path) -> dict[str, list[dict[str, Any]]]:
    from pymavlink import DFReader

    reader = DFReader.DFReader_binary(str(path))
    found: dict[str, list[dict[str, Any]]] = defaultdict(list)
    while (msg := reader.recv_match(type=BIN_TYPES)) is not None:
        found[msg.get_type()].append(msg.to_dict())
    return found


def pymavlink_tlog(path: Path) -> dict[str, list[Any]]:
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(path), dialect="ardupilotmega")
    found: dict[str, list[Any]] = defaultdict(list)
    while (msg := conn.recv_match(type=TLOG_TYPES)) is not None:
        found[msg.get_type()].append(msg)
    return found


def check_bin(ours: Any, theirs: dict[str, list[dict[str, Any]]]) -> int:
    values = 0
    for name in BIN_TYPES:
        records = theirs[name]
        assert len(ours[name]["TimeUS"]) == len(records), name
        for column, arr in ours[name].items():
            want = np.array([r[column] for r in records], dtype=float)
            np.testing.assert_array_equal(arr.astype(float), want, err_msg=f"{name}.{column}")
            values += len(want)
    return values


def check_tlog(ours: Any, theirs: dict[str, list[Any]]) -> int:
    values = 0
    for name in TLOG_TYPES:
        msgs = theirs[name]
        arr = ours[name]
        assert len(arr) == len(msgs), name
        for field in arr.dtype.names:
            got = arr[field].tolist()
            want = [getattr(m, field) for m in msgs]
            assert got == want, f"{name}.{field}"
            values += len(want) * (len(want[0]) if want and isinstance(want[0], list) else 1)
    return values


def write_hour_log(path: Path, hours: float = 1.0, rate_hz: float = 100.0) -> None:
    """A DataFlash log of a hexacopter hovering for an hour: FMT, PARM, ESC (100 Hz × 6), RCOU, BAT."""
    rng = np.random.default_rng(1)

    def fmt(type_id: int, name: str, form: str, columns: str, length: int) -> bytes:
        return (
            bytes([0xA3, 0x95, 128, type_id, length])
            + name.encode().ljust(4, b"\0")
            + form.encode().ljust(16, b"\0")
            + columns.encode().ljust(64, b"\0")
        )

    esc_dt = np.dtype([("h1", "u1"), ("h2", "u1"), ("t", "u1"), ("TimeUS", "<u8"), ("Instance", "u1"),
                       ("RPM", "<f4"), ("RawRPM", "<f4"), ("Volt", "<f4"), ("Curr", "<f4"), ("Temp", "<i2"),
                       ("CTot", "<f4"), ("MotTemp", "<i2"), ("Err", "<f4")])  # fmt: skip
    rcou_dt = np.dtype(
        [("h1", "u1"), ("h2", "u1"), ("t", "u1"), ("TimeUS", "<u8")]
        + [(f"C{i}", "<u2") for i in range(1, 15)]
    )
    bat_dt = np.dtype([("h1", "u1"), ("h2", "u1"), ("t", "u1"), ("TimeUS", "<u8"), ("Inst", "u1"), ("Volt", "<f4"),
                       ("Curr", "<f4")])  # fmt: skip
    parm_dt = np.dtype([("h1", "u1"), ("h2", "u1"), ("t", "u1"), ("TimeUS", "<u8"), ("Name", "S16"), ("Value", "<f4"),
                        ("Default", "<f4")])  # fmt: skip
    header = b"".join(
        [
            fmt(128, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns", 89),
            fmt(32, "PARM", "QNff", "TimeUS,Name,Value,Default", parm_dt.itemsize),
            fmt(
                86,
                "ESC",
                "QBffffcfcf",
                "TimeUS,Instance,RPM,RawRPM,Volt,Curr,Temp,CTot,MotTemp,Err",
                esc_dt.itemsize,
            ),
            fmt(
                62,
                "RCOU",
                "Q" + "H" * 14,
                "TimeUS," + ",".join(f"C{i}" for i in range(1, 15)),
                rcou_dt.itemsize,
            ),
            fmt(88, "BAT", "QBff", "TimeUS,Inst,Volt,Curr", bat_dt.itemsize),
        ]
    )
    params = [("FRAME_CLASS", 2.0), ("MOT_PWM_MIN", 1000.0), ("MOT_PWM_MAX", 2000.0)]
    params += [(f"SERVO{i}_FUNCTION", 32.0 + i) for i in range(1, 7)]
    parm = np.zeros(len(params), parm_dt)
    parm["h1"], parm["h2"], parm["t"], parm["TimeUS"] = 0xA3, 0x95, 32, 1000
    parm["Name"] = [p[0].encode() for p in params]
    parm["Value"] = [p[1] for p in params]
    steps = int(hours * 3600 * rate_hz)
    t_us = (2_000_000 + np.arange(steps) * (1e6 / rate_hz)).astype(np.uint64)
    pwm = 1500 + 60 * np.sin(np.arange(steps) / (rate_hz * 20)) + rng.normal(0, 5, steps)
    esc = np.zeros((steps, 6), esc_dt)
    esc["h1"], esc["h2"], esc["t"] = 0xA3, 0x95, 86
    esc["TimeUS"] = t_us[:, None]
    esc["Instance"] = np.arange(6)[None, :]
    esc["RPM"] = (pwm - 1000)[:, None] * 16 + rng.normal(0, 20, (steps, 6))
    esc["Volt"], esc["Temp"], esc["MotTemp"] = 15.5, 3500, 4000
    esc["Curr"] = (((pwm - 1000) / 1000) ** 2 * 10)[:, None] + rng.normal(0, 0.1, (steps, 6))
    every = int(rate_hz / 10)
    rcou = np.zeros(steps // every, rcou_dt)
    rcou["h1"], rcou["h2"], rcou["t"] = 0xA3, 0x95, 62
    rcou["TimeUS"] = t_us[::every][: len(rcou)] - 500
    for i in range(1, 7):
        rcou[f"C{i}"] = pwm[::every][: len(rcou)].astype(np.uint16)
    bat = np.zeros(len(rcou), bat_dt)
    bat["h1"], bat["h2"], bat["t"] = 0xA3, 0x95, 88
    bat["TimeUS"], bat["Volt"], bat["Curr"] = rcou["TimeUS"], 15.6, 40.0
    with path.open("wb") as handle:
        handle.write(header)
        handle.write(parm.tobytes())
        for block in range(0, len(rcou), 6000):  # interleave in 10-minute blocks, as a logger would in time
            start, stop = block * every, min((block + 6000) * every, steps)
            handle.write(rcou[block : block + 6000].tobytes())
            handle.write(bat[block : block + 6000].tobytes())
            handle.write(esc[start:stop].tobytes())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--logs", default=str(REPO.parent / "shared" / "real_logs"), help="the real_logs folder"
    )
    parser.add_argument("--hour", action="store_true", help="also replay a synthetic one-hour log")
    args = parser.parse_args(argv)
    logs = Path(args.logs)
    if not logs.is_dir():
        for parent in REPO.parents:
            if (parent / "shared" / "real_logs").is_dir():
                logs = parent / "shared" / "real_logs"
                break
    bin_path = logs / "ardupilot_sitl" / "hexa_motor1_half.bin"
    tlog_path = logs / "ardupilot_sitl" / "hexa_motor1_half.tlog"
    warnings.simplefilter("ignore")

    read_messages(tlog_path, TLOG_TYPES)  # warm-up: pymavlink dialect tables, page cache
    read_records(bin_path, BIN_TYPES)
    t_ref_bin, ref_bin = _best(lambda: pymavlink_bin(bin_path), 2)
    t_ours_bin, ours_bin = _best(lambda: read_records(bin_path, BIN_TYPES), 5)
    n_bin = check_bin(ours_bin, ref_bin)
    t_ref_tlog, ref_tlog = _best(lambda: pymavlink_tlog(tlog_path), 2)
    t_ours_tlog, ours_tlog = _best(lambda: read_messages(tlog_path, TLOG_TYPES), 5)
    n_tlog = check_tlog(ours_tlog, ref_tlog)

    print(f"{'file':32s} {'records':>9s} {'values':>10s} {'pymavlink':>10s} {'ours':>8s} {'ratio':>7s}  goal")
    records_bin = sum(len(v) for v in ref_bin.values())
    records_tlog = sum(len(v) for v in ref_tlog.values())
    print(
        f"{bin_path.name:32s} {records_bin:9d} {n_bin:10d} {t_ref_bin:9.3f}s {t_ours_bin:7.3f}s "
        f"{t_ref_bin / t_ours_bin:6.1f}x  >=20x  (DFReader: ESC, RCOU, BAT)"
    )
    print(
        f"{tlog_path.name:32s} {records_tlog:9d} {n_tlog:10d} {t_ref_tlog:9.3f}s {t_ours_tlog:7.3f}s "
        f"{t_ref_tlog / t_ours_tlog:6.1f}x  >=10x  (mavutil: ESC_TELEMETRY, SERVO_OUTPUT_RAW, battery)"
    )
    print("values identical: yes (every field of every record compared)")

    params, profile = load_motor_params("paper_x2212"), load_profile("flight")
    with tempfile.TemporaryDirectory() as tmp:
        start, cpu = time.perf_counter(), time.process_time()
        result = replay_log(bin_path, Path(tmp) / "bin", params, profile)
        elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
        print(
            f"end-to-end replay of {bin_path.name}: {result.duration_s:.0f} s of flight, {result.rows} motor "
            f"samples in {elapsed:.2f} s wall, {cpu:.2f} s CPU"
        )
        if args.hour:
            hour = Path(tmp) / "hour.bin"
            write_hour_log(hour)
            start, cpu = time.perf_counter(), time.process_time()
            result = replay_log(hour, Path(tmp) / "hour", params, profile)
            elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu
            size_mb = hour.stat().st_size / 1e6
            print(
                f"end-to-end replay of a synthetic one-hour hexacopter .bin ({size_mb:.0f} MB, {result.rows} "
                f"motor samples at 100 Hz): {elapsed:.2f} s wall, {cpu:.2f} s CPU"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
