"""Whole replay of a long six-motor log against pymavlink only extracting the same records, in one run.

    PYTHONPATH=src python benchmarks/bench_replay_speed.py [--minutes 60] [--simulate-minutes 10]
                                                           [--esc-hz 25] [--repeat 3] [--profile]
                                                           [--vehicle bundled|identified] [--keep DIR]

The log is written here with the project's simulator and writers (``sim.engine.run_scenario``,
``sim.writers.write_record``): a healthy hexacopter in moderate air repeating hover, climb, translate and
descend, each ESC reporting at 25–50 Hz (drawn per ESC), ``ESC_TELEMETRY_*`` streamed at ``--esc-hz``
(default 25 Hz: every motor sampled at ≥ 20 Hz in the .tlog), vehicle records (SERVO_OUTPUT_RAW / RCOU,
battery, attitude, position) at 10 Hz, battery messages at 1 Hz in the .tlog. Simulating a whole hour
takes about a minute and a half of CPU here, so by default ``--simulate-minutes`` (10) are simulated
and the written block is repeated with shifted timestamps up to ``--minutes`` (60), in each writer's own
format: .tlog frames keep their bytes with the 8-byte time stamp moved, DataFlash records their bytes with
``TimeUS`` moved; the repeats leave out the header (PARAM_VALUE; FMT, PARM, MSG). The diagnosis sees the
same ten minutes six times; the readers and the core cost the same per record either way
(``--simulate-minutes 60`` simulates the whole hour).

Timed, in the same run, on the same files (process CPU time, single-threaded; wall time printed too):

1. ``.tlog``: pymavlink's ``mavutil.mavlink_connection(path)`` + ``recv_match`` loop extracting
   ESC_TELEMETRY_1_TO_4/5_TO_8, SERVO_OUTPUT_RAW, SYS_STATUS and BATTERY_STATUS, against the project's
   reader alone (``telemetry.sources.read``), reader + diagnosis (``diagnosis.pipeline.diagnose``, the
   ``flight`` profile, the default motor) and the whole replay (``replay.replay_log``: read, diagnose and
   write diagnosis.csv, events.jsonl and report.html), as ``replay`` runs it;
2. ``.bin``: pymavlink's ``DFReader.DFReader_binary`` + ``recv_match`` extracting ESC, RCOU and BAT,
   against the same three.

``--repeat N`` times each of the four N times in a row and keeps each one's least CPU time: on a shared
machine the least is the run other work disturbed least (pymavlink's runs as much as ours; each replay
writes a new folder). The ratios (pymavlink's time / ours) are the result; issue 18's goal is ≥ 10× for
the whole replay, on both formats.

``--vehicle identified`` replays with the vehicle file a user who ran ``fit`` has: the simulated motor with
each motor's noise measured as ``fit`` measures it (``identification.with_band_noise``) on another flight
of the same vehicle (150 s, the same manoeuvres, another seed), so that the diagnosis runs the
``flight_vehicle`` profile (bands in the vehicle's noise, the sequential test, the vehicle stage, the slow
look and the siblings' prediction), as ``replay --params vehicle.toml`` picks it; ``bundled`` (the
default) the bundled motor and the ``flight`` profile. ``--profile`` adds two cProfiles on the .tlog: ``diagnose`` on its table (where the core's
time goes) and the whole ``replay_log`` (reading, the core and writing the files, by cumulative time).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import math
import pstats
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mav_motor_health.config import DEFAULT_MOTOR, dump_vehicle_params, load_profile, load_vehicle_params
from mav_motor_health.diagnosis.noise import band_noise_of
from mav_motor_health.diagnosis.pipeline import diagnose
from mav_motor_health.identification import with_band_noise
from mav_motor_health.model.vehicle import VehicleParams
from mav_motor_health.replay import replay_log
from mav_motor_health.sim.engine import run_scenario
from mav_motor_health.sim.scenario import scenario_from_dict
from mav_motor_health.sim.writers import write_record
from mav_motor_health.sim.writers.dataflash import FORMATS
from mav_motor_health.telemetry import sources

TLOG_TYPES = [
    "ESC_TELEMETRY_1_TO_4",
    "ESC_TELEMETRY_5_TO_8",
    "SERVO_OUTPUT_RAW",
    "SYS_STATUS",
    "BATTERY_STATUS",
]
BIN_TYPES = ["ESC", "RCOU", "BAT"]
LOG_HZ = 10.0
#: one round of manoeuvres (26 s), repeated over the flight
MANOEUVRES = [
    {"kind": "hover", "duration_s": 10.0},
    {"kind": "climb", "duration_s": 4.0, "speed_m_s": 1.0},
    {"kind": "translate", "duration_s": 8.0, "speed_m_s": 2.0, "heading_deg": 45.0},
    {"kind": "descend", "duration_s": 4.0, "speed_m_s": 1.0},
]
PARAM_VALUE_ID = 22
#: the vehicle and profile replayed (``--vehicle``): None, the bundled motor and ``flight``
VEHICLE: VehicleParams | None = None
PROFILE = "flight"


# -- the log --------------------------------------------------------------------------------------------
def simulate(directory: Path, seconds: float, esc_hz: float, seed: int = 18) -> tuple[Path, Path, int]:
    """A healthy six-motor flight of ``seconds`` written as .tlog and .bin; returns both and the samples."""
    rounds = math.ceil(seconds / sum(s["duration_s"] for s in MANOEUVRES))
    scenario = scenario_from_dict(
        {
            "scenario": {
                "name": "replay speed",
                "mode": "flight",
                "duration_s": seconds,
                "dt_s": 0.02,
                "seed": seed,
            },
            "flight": {
                "turbulence": "moderate",
                "battery_capacity_mah": 100_000.0,  # an hour's flight on one battery, repeatable blocks
                "segment": MANOEUVRES * rounds,
            },
            "sensors": {"rate_hz": [25.0, 50.0], "dropout": 0.01},
            "output": {"esc_stream_hz": esc_hz, "log_hz": LOG_HZ},
        }
    )
    record = run_scenario(scenario)
    tlog, _ = write_record(record, directory / "block.tlog", force=True)
    dataflash, _ = write_record(record, directory / "block.bin", force=True)
    return tlog, dataflash, len(record.esc)


def identified_vehicle(directory: Path, esc_hz: float) -> VehicleParams:
    """The bundled motor with each motor's noise measured as ``fit`` measures it, on a 150-s flight of
    the same vehicle (seed 19): the vehicle file of ``--vehicle identified``."""
    folder = directory / "identification"
    folder.mkdir(exist_ok=True)
    tlog, _, _ = simulate(folder, 150.0, esc_hz, seed=19)
    return with_band_noise(load_vehicle_params(DEFAULT_MOTOR), [sources.read(tlog)])


def _vehicle_and_profile() -> tuple[VehicleParams, Any]:
    vehicle = VEHICLE if VEHICLE is not None else load_vehicle_params(DEFAULT_MOTOR)
    return vehicle, load_profile(PROFILE)


def _shift_u64(data: np.ndarray, at: np.ndarray, dtype: str, shift: int) -> None:
    """Add ``shift`` to the unaligned 8-byte integers of ``dtype`` at byte offsets ``at`` (in place)."""
    index = at[:, None] + np.arange(8)
    values = np.ascontiguousarray(data[index]).view(dtype)[:, 0]
    data[index] = (values + shift).astype(dtype).view(np.uint8).reshape(-1, 8)


def repeat_tlog(block: Path, out: Path, repeats: int, period_s: float) -> None:
    """The .tlog block ``repeats`` times, each ``period_s`` later (PARAM_VALUE only in the first)."""
    data = np.frombuffer(block.read_bytes(), dtype=np.uint8)
    starts, keep = [], []
    pos = 0
    while pos + 18 <= data.size:  # [8-byte time stamp][MAVLink 2 frame]
        size = 10 + int(data[pos + 9]) + 2 + (13 if data[pos + 10] & 1 else 0)
        msgid = int(data[pos + 15]) | int(data[pos + 16]) << 8 | int(data[pos + 17]) << 16
        starts.append(pos)
        keep.append(msgid != PARAM_VALUE_ID)
        pos += 8 + size
    ends = np.append(np.asarray(starts[1:]), pos)
    body_starts = np.asarray(starts)[np.asarray(keep)]
    body_ends = ends[np.asarray(keep)]
    body_mask = np.zeros(data.size, dtype=bool)
    for s, e in zip(body_starts.tolist(), body_ends.tolist()):
        body_mask[s:e] = True
    body = data[body_mask]
    body_at = np.concatenate([[0], np.cumsum(body_ends - body_starts)[:-1]])
    with out.open("wb") as handle:
        handle.write(data[:pos].tobytes())
        for r in range(1, repeats):
            copy = body.copy()
            _shift_u64(copy, body_at, ">u8", round(r * period_s * 1e6))
            handle.write(copy.tobytes())


def repeat_dataflash(block: Path, out: Path, repeats: int, period_s: float) -> None:
    """The DataFlash block ``repeats`` times, each ``period_s`` later (FMT, PARM and MSG only in the first)."""
    data = np.frombuffer(block.read_bytes(), dtype=np.uint8)
    length = {type_id: 3 + _struct_size(fmt) for type_id, fmt, _ in FORMATS.values()}
    header = {FORMATS[name][0] for name in ("FMT", "PARM", "MSG")}
    pos, body_starts, body_lengths = 0, [], []
    while pos + 3 <= data.size:
        kind = int(data[pos + 2])
        if kind not in header:
            body_starts.append(pos)
            body_lengths.append(length[kind])
        pos += length[kind]
    starts, lengths = np.asarray(body_starts), np.asarray(body_lengths)
    index = np.repeat(starts - np.cumsum(np.append(0, lengths[:-1])), lengths) + np.arange(lengths.sum())
    body = data[index]
    body_at = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    with out.open("wb") as handle:
        handle.write(data.tobytes())
        for r in range(1, repeats):
            copy = body.copy()
            _shift_u64(copy, body_at + 3, "<u8", round(r * period_s * 1e6))  # TimeUS follows the 3-byte head
            handle.write(copy.tobytes())


def _struct_size(fmt: str) -> int:
    sizes = {"B": 1, "b": 1, "H": 2, "h": 2, "c": 2, "C": 2, "I": 4, "i": 4, "e": 4, "E": 4, "L": 4, "f": 4}
    sizes.update({"Q": 8, "q": 8, "d": 8, "M": 1, "n": 4, "N": 16, "Z": 64})
    return sum(sizes[c] for c in fmt)


# -- the contestants -------------------------------------------------------------------------------------
def pymavlink_tlog(path: Path) -> int:
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(path))
    found = []
    while (msg := conn.recv_match(type=TLOG_TYPES)) is not None:
        found.append(msg)
    return len(found)


def pymavlink_bin(path: Path) -> int:
    from pymavlink import DFReader

    reader = DFReader.DFReader_binary(str(path))
    found = []
    while (msg := reader.recv_match(type=BIN_TYPES)) is not None:
        found.append(msg)
    return len(found)


def _timed(fn: Callable[[], Any]) -> tuple[float, float, Any]:
    """(CPU s, wall s, result) of one call."""
    cpu, wall = time.process_time(), time.perf_counter()
    result = fn()
    return time.process_time() - cpu, time.perf_counter() - wall, result


def _least(fn: Callable[[], Any], runs: int) -> tuple[float, float, Any]:
    """(CPU s, wall s, result) of the call with the least CPU time among ``runs`` calls."""
    best: tuple[float, float, Any] | None = None
    for _ in range(runs):
        timed = _timed(fn)
        if best is None or timed[0] < best[0]:
            best = timed
        del timed
    assert best is not None
    return best


def compare(
    log: Path, out_dir: Path, baseline: Callable[[Path], int], label: str, runs: int = 1
) -> dict[str, float]:
    vehicle, profile = _vehicle_and_profile()
    params = vehicle.models(range(1, 7))
    sources.read(log)  # warm-up: imports, page cache
    folders = (out_dir / f"run{k}" for k in range(runs))  # each replay writes a new folder, as replay does
    base_cpu, base_wall, records = _least(lambda: baseline(log), runs)
    read_cpu, read_wall, table = _least(lambda: sources.read(log), runs)
    noise = band_noise_of(vehicle.noise) if profile.noise_bands > 0 else None  # as replay gives it
    diag_cpu, diag_wall, result = _least(
        lambda: diagnose(vehicle.calibrate(table), params, profile, noise), runs
    )
    whole_cpu, whole_wall, replay = _least(
        lambda: replay_log(log, next(folders), vehicle, profile, force=True), runs
    )
    assert replay.rows == len(result) == len(table)
    print(
        f"\n{log.name}: {log.stat().st_size / 1e6:.1f} MB, {replay.duration_s / 60:.1f} min, {len(table)} motor samples"
    )
    print(f"   {'':52s} {'CPU s':>8s} {'wall s':>8s} {'pymavlink / this (CPU)':>24s}")
    print(f"   {label + f' ({records} records)':52s} {base_cpu:8.2f} {base_wall:8.2f} {'1.0x':>24s}")
    rows = [
        ("project reader alone (telemetry.sources.read)", read_cpu, read_wall),
        (f"reader + diagnose ({profile.name} profile)", read_cpu + diag_cpu, read_wall + diag_wall),
        ("whole replay (replay_log: read, diagnose, 3 files)", whole_cpu, whole_wall),
    ]
    for name, cpu, wall in rows:
        print(f"   {name:52s} {cpu:8.2f} {wall:8.2f} {base_cpu / cpu:23.1f}x")
    print(
        f"   whole replay: {base_cpu / whole_cpu:.1f}x faster than {label.split(':')[0]} (CPU; wall {base_wall / whole_wall:.1f}x), goal >= 10x"
    )
    return {"table": table, "params": params, "profile": profile, "vehicle": vehicle}  # type: ignore[dict-item]


def profile_diagnosis(table: Any, vehicle: Any, params: Any, profile: Any, lines: int = 25) -> None:
    calibrated = vehicle.calibrate(table)
    noise = band_noise_of(vehicle.noise) if profile.noise_bands > 0 else None
    profiler = cProfile.Profile()
    profiler.enable()
    diagnose(calibrated, params, profile, noise)
    profiler.disable()
    text = io.StringIO()
    stats = pstats.Stats(profiler, stream=text)
    stats.sort_stats("tottime").print_stats(lines)
    print("\ncProfile of diagnose() on the .tlog's table (sorted by own time):")
    print("\n".join(line for line in text.getvalue().splitlines() if line.strip())[:6000])


def profile_replay(log: Path, out_dir: Path, lines: int = 30) -> None:
    """cProfile of the whole replay of ``log`` (sorted by cumulative time): reading, the core, the files."""
    vehicle, profile = _vehicle_and_profile()
    profiler = cProfile.Profile()
    profiler.enable()
    replay_log(log, out_dir, vehicle, profile, force=True)
    profiler.disable()
    text = io.StringIO()
    pstats.Stats(profiler, stream=text).sort_stats("cumulative").print_stats(lines)
    print(f"\ncProfile of the whole replay_log() on {log.name} (sorted by cumulative time):")
    print("\n".join(line for line in text.getvalue().splitlines() if line.strip())[:8000])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--minutes", type=float, default=60.0, help="length of the replayed log")
    ap.add_argument("--simulate-minutes", type=float, default=10.0, help="length of the simulated block")
    ap.add_argument("--esc-hz", type=float, default=25.0, help="ESC_TELEMETRY stream rate in the .tlog")
    ap.add_argument(
        "--repeat", type=int, default=1, help="time each contestant this often, keep its least CPU time"
    )
    ap.add_argument(
        "--profile",
        action="store_true",
        help="also cProfile diagnose() and the whole replay_log() on the .tlog",
    )
    ap.add_argument(
        "--vehicle",
        choices=("bundled", "identified"),
        default="bundled",
        help="the bundled motor (flight profile), or its vehicle file with the noise fit measures"
        " (flight_vehicle, as replay --params picks it for a file fit wrote)",
    )
    ap.add_argument(
        "--keep",
        type=Path,
        metavar="DIR",
        help="write the logs (flight.tlog, flight.bin) and, with --vehicle identified, vehicle.toml into DIR"
        " and leave them there (to time the replay command on them: docs/replay.md)",
    )
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    global VEHICLE, PROFILE
    block_s = 60.0 * min(args.simulate_minutes, args.minutes)
    repeats = max(1, round(args.minutes * 60.0 / block_s))
    period_s = block_s + 1.0 / args.esc_hz  # each repeat starts one ESC period after the block's end
    print(
        f"python {sys.version.split()[0]}; a {repeats * period_s / 60:.1f}-minute six-motor flight: {block_s / 60:g} min simulated, written {repeats}x"
        + (f"; each time the least of {args.repeat} runs" if args.repeat > 1 else "")
    )
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.keep is not None:
            folder = args.keep
            folder.mkdir(parents=True, exist_ok=True)
        cpu, _, (tlog_block, bin_block, samples) = _timed(lambda: simulate(folder, block_s, args.esc_hz))
        print(f"   simulated and written in {cpu:.1f} s CPU ({samples} ESC samples in the block)")
        if args.vehicle == "identified":
            cpu, _, VEHICLE = _timed(lambda: identified_vehicle(folder, args.esc_hz))
            PROFILE = "flight_vehicle"
            if args.keep is not None:
                (folder / "vehicle.toml").write_text(dump_vehicle_params(VEHICLE))
            print(f"   vehicle: the noise measured as fit does, on another 150-s flight, in {cpu:.1f} s CPU")
        tlog, dataflash = folder / "flight.tlog", folder / "flight.bin"
        repeat_tlog(tlog_block, tlog, repeats, period_s)
        repeat_dataflash(bin_block, dataflash, repeats, period_s)
        got = compare(
            tlog,
            folder / "out_tlog",
            pymavlink_tlog,
            "pymavlink mavutil recv_match: ESC, servo, battery",
            args.repeat,
        )
        compare(
            dataflash,
            folder / "out_bin",
            pymavlink_bin,
            "pymavlink DFReader recv_match: ESC, RCOU, BAT",
            args.repeat,
        )
        if args.profile:
            profile_diagnosis(got["table"], got["vehicle"], got["params"], got["profile"])
            profile_replay(tlog, folder / "out_profile")
    return 0


if __name__ == "__main__":
    sys.exit(main())
