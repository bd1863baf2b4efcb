"""The agent's CPU cost per motor sample and its latency at 6 motors × 50 Hz and × 200 Hz, against
baselines in the same run.

    PYTHONPATH=src python benchmarks/bench_agent.py [--seconds 60] [--live-seconds 10] [--rates 50 200]
        [--vehicle bundled|per-motor|identified]

1. **CPU per sample** (replay of a synthetic six-motor flight at each rate, written as a .tlog, through
   the agent's real feeding path: reader thread, MAVLink parsing, SampleAssembler, HealthMonitor → the
   diagnosis core, all motors of a batch in one core call), for several ``batch_s``. Baseline: the cost
   of only parsing the same MAVLink bytes with pymavlink. Process CPU time (all threads), so the reader
   thread is included.
2. **Live**: the agent on a UDP socket with a vehicle in a separate process streaming 6 motors at each
   rate, with the default ``batch_s`` (0.1 s) and with ``batch_s`` = 0.02 s; the agent process's CPU
   share of one core over the run, and latency from a sample's arrival (reader thread) to its diagnosis,
   and from fault onset in the vehicle to the STATUSTEXT back at the vehicle.
``--vehicle per-motor`` gives the agent a vehicle file with a model per motor, as ``fit`` writes one (the
bundled motor with R up to 2.5 % and k_e up to 0.25 % apart between the motors: small enough that the test
vehicle, which flies the bundled motor, stays healthy; the core's work does not depend on the values),
instead of the bundled motor itself. ``--vehicle identified`` adds to that file each motor's noise, measured
as ``fit`` measures it (``identification.with_band_noise``) on another synthetic flight of the same
vehicle (seed 4): the agent then picks the ``flight_vehicle`` profile, as it does for every user whose
vehicle file ``fit`` wrote (bands in the vehicle's noise, the sequential test, the vehicle stage), where
the other two run the ``flight`` profile.

3. **Raspberry Pi 4 estimate**: the same run times the benchmarks-game n-body program in pure Python; a
   Raspberry Pi 4 at 1.5 GHz takes 158.3 s for 5,000,000 steps (chaitanyamehta.github.io, "Performance
   Analysis of Languages on Raspberry Pi", performance governor). The ratio of that to this machine's
   time scales our CPU share to a Pi 4 core. Interpreter-bound code scales like n-body; it is an estimate.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import io
import math
import multiprocessing as mp
import statistics
import struct
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "agent"))  # the test vehicle (peer.py)

from mav_motor_health.agent import Agent, load_agent_config  # noqa: E402
from mav_motor_health.config import dump_vehicle_params, load_motor_params, load_vehicle_params  # noqa: E402
from mav_motor_health.identification import with_band_noise  # noqa: E402
from mav_motor_health.model.equations import steady_state  # noqa: E402
from mav_motor_health.model.vehicle import VehicleParams  # noqa: E402
from mav_motor_health.publish import dialect  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402

PI4_NBODY_S = 158.263  # 5,000,000 steps, Raspberry Pi 4 @ 1.5 GHz, performance governor (see docstring)
PI4_NBODY_STEPS = 5_000_000
MOTORS = 6
#: batch_s values timed in the replay part, per rate (one sample per core call is too slow to time at 200 Hz)
BATCHES = {50.0: (0.0, 0.02, 0.05, 0.1, 0.2), 200.0: (0.02, 0.1)}
LIVE_BATCHES = (0.1, 0.02)
#: the vehicle file the agent is given (--vehicle per-motor or identified), None: the bundled motor
VEHICLE: str | None = None
#: the profile the agent is given; None: the one it picks for the vehicle (flight_vehicle where the
#: vehicle file carries its noise)
PROFILE: str | None = "flight"


def write_per_motor_vehicle(path: Path) -> str:
    """A vehicle file with each motor's own model: the bundled motor's R and k_e a little apart."""
    motor = load_motor_params("paper_x2212")
    per_motor = {
        m: motor.replace(R_ohm=motor.R_ohm * (1 + 0.01 * (m - 3.5)), k_e=motor.k_e * (1 + 0.001 * (m - 3.5)))
        for m in range(1, MOTORS + 1)
    }
    path.write_text(dump_vehicle_params(VehicleParams(motor=motor, per_motor=per_motor)), encoding="utf-8")
    return str(path)


def write_identified_vehicle(path: Path, seconds: float) -> str:
    """:func:`write_per_motor_vehicle` with each motor's noise measured as ``fit`` measures it, on a
    synthetic flight of the same vehicle (another seed than the one replayed)."""
    write_per_motor_vehicle(path)
    vehicle = load_vehicle_params(path)
    flight = path.with_name("identification.tlog")
    write_flight(flight, seconds, 50.0, seed=4)
    vehicle = with_band_noise(vehicle, [sources.read(flight)])
    path.write_text(dump_vehicle_params(vehicle), encoding="utf-8")
    return str(path)


# -- 1. a synthetic flight as a .tlog ----------------------------------------------------------------
def write_flight(path: Path, seconds: float, rate_hz: float = 50.0, seed: int = 3) -> int:
    params = load_motor_params("paper_x2212")
    rng = np.random.default_rng(seed)
    mav = mavlink2.MAVLink(None, 1, 1)
    ticks = int(seconds * rate_hz)
    t = np.arange(ticks) / rate_hz
    throttle = 0.55 + 0.1 * (np.sin(2 * np.pi * t / 20) > 0) + 0.003 * np.sin(2 * np.pi * 0.7 * t)
    pwm = np.round(1000 + 1000 * throttle).astype(int)
    u = (pwm - 1000) / 1000
    model = steady_state(params, u * 12.0)
    out = bytearray()
    stamp0 = 1_700_000_000_000_000

    def put(stamp: int, msg) -> None:
        out.extend(struct.pack(">Q", stamp))
        out.extend(msg.pack(mav))

    put(stamp0 - 1000, mav.heartbeat_encode(13, 3, 0, 0, 4))
    for k in range(ticks):
        stamp = stamp0 + int(k * 1e6 / rate_hz)
        put(stamp, mav.servo_output_raw_encode(k, 0, *([int(pwm[k])] * MOTORS + [0] * 2)))
        rpm = np.round((model.omega_rad_s[k] + rng.uniform(-6, 6, 8)) * 60 / (2 * math.pi)).astype(int)
        ca = np.round((model.current_a[k] + rng.uniform(-0.08, 0.08, 8)) * u[k] * 100).astype(int)
        rpm[MOTORS:], ca[MOTORS:] = 0, 0
        count = [(k + 1) & 0xFFFF] * MOTORS + [0, 0]
        for group, encode in ((0, mav.esc_telemetry_1_to_4_encode), (4, mav.esc_telemetry_5_to_8_encode)):
            sl = slice(group, group + 4)
            put(stamp, encode([30] * 4, [1200] * 4, ca[sl].tolist(), [0] * 4, rpm[sl].tolist(), count[sl]))
    path.write_bytes(bytes(out))
    return ticks * MOTORS


def parse_only(path: Path) -> tuple[float, int]:
    """Baseline: split the .tlog into frames and parse them with pymavlink, nothing else."""
    data = path.read_bytes()
    parser = mavlink2.MAVLink(None, 0, 0)
    parser.robust_parsing = True
    start = time.process_time()
    pos, n = 0, 0
    while pos + 9 <= len(data):
        size = 10 + data[pos + 9] + 2 + (13 if data[pos + 10] & 1 else 0)
        n += len(parser.parse_buffer(data[pos + 8 : pos + 8 + size]) or [])
        pos += 8 + size
    return time.process_time() - start, n


def agent_replay(path: Path, batch_s: float) -> tuple[float, int]:
    config = load_agent_config(None, connect=str(path), params=VEHICLE, profile=PROFILE)
    config = config.with_overrides(batch_s=batch_s)
    dialect.load()

    async def main() -> int:
        async with Agent(config) as agent:
            await agent.wait()
            return agent.monitor.samples

    start = time.process_time()
    samples = asyncio.run(main())
    return time.process_time() - start, samples


# -- 2. live ----------------------------------------------------------------------------------------
def _vehicle(port_queue: mp.Queue, commands: mp.Queue) -> None:
    from vehicle_peer import VehiclePeer

    with VehiclePeer(load_motor_params("paper_x2212"), seed=5) as peer:
        port_queue.put(peer.port)
        while True:
            cmd = commands.get()
            if cmd is None:
                break
            motor, fault = cmd
            onset = peer.inject(motor, fault)
            port_queue.put(onset)
            deadline = time.monotonic() + 5
            wanted = f"Motor {motor}: " if fault != "NORMAL" else None
            seen = None
            while time.monotonic() < deadline and seen is None and wanted:
                for t, m in peer.messages("STATUSTEXT"):
                    if t >= onset and m.text.startswith(wanted) and fault in m.text:
                        seen = t
                        break
                time.sleep(0.005)
            port_queue.put(seen)


def live(seconds: float, rate_hz: float, batch_s: float) -> dict[str, float]:
    ctx = mp.get_context("spawn")
    ports, commands = ctx.Queue(), ctx.Queue()
    proc = ctx.Process(target=_vehicle, args=(ports, commands), daemon=True)
    proc.start()
    port = ports.get(timeout=30)
    latencies: list[float] = []
    detect: list[float] = []

    async def main() -> tuple[float, float]:
        config = load_agent_config(None, connect=f"udpout:127.0.0.1:{port}", params=VEHICLE, profile=PROFILE)
        # the test vehicle's ESCs report at the stream rate: ask for rate_hz to diagnose 6 × rate_hz samples
        # (the agent's default asks for 200 Hz, which with ESCs reporting at 10–50 Hz adds only parsing)
        config = config.with_overrides(esc_rate_hz=rate_hz, batch_s=batch_s)

        def on_row(row: dict) -> None:
            latencies.append(time.monotonic() - row["time_s"])

        async with Agent(config, on_row=on_row) as agent:
            while agent.monitor.samples < 2 * MOTORS * rate_hz:  # warm-up: streams requested, parameters read
                await asyncio.sleep(0.1)
            latencies.clear()
            cpu0, wall0 = time.process_time(), time.monotonic()
            samples0 = agent.monitor.samples
            loop = asyncio.get_running_loop()
            for k in range(4):
                await asyncio.sleep(seconds / 8)
                motor = 1 + k % MOTORS
                for fault in ("F3.1", "NORMAL"):
                    commands.put((motor, fault))
                    onset = await loop.run_in_executor(None, ports.get)
                    seen = await loop.run_in_executor(None, ports.get)
                    if fault != "NORMAL" and seen is not None:
                        detect.append(seen - onset)
                    await asyncio.sleep(seconds / 16)
            cpu, wall = time.process_time() - cpu0, time.monotonic() - wall0
            rate = (agent.monitor.samples - samples0) / wall
            return cpu / wall, rate

    share, rate = asyncio.run(main())
    commands.put(None)
    proc.join(10)
    lat = sorted(latencies)
    return {
        "cpu_share": share,
        "samples_per_s": rate,
        "lat_p50_ms": 1000 * lat[len(lat) // 2],
        "lat_p95_ms": 1000 * lat[int(len(lat) * 0.95)],
        "lat_max_ms": 1000 * lat[-1],
        "detect_median_ms": 1000 * statistics.median(detect) if detect else math.nan,
        "detect_max_ms": 1000 * max(detect) if detect else math.nan,
        "detections": len(detect),
    }


# -- 3. calibration ----------------------------------------------------------------------------------
def nbody(steps: int) -> float:
    """The benchmarks-game n-body simulation (five bodies, advance with dt = 0.01), pure Python."""
    pi, days = math.pi, 365.24
    solar = 4 * pi * pi
    bodies = [
        [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], solar],
        [
            [4.84143144246472090e00, -1.16032004402742839e00, -1.03622044471123109e-01],
            [1.66007664274403694e-03 * days, 7.69901118419740425e-03 * days, -6.90460016972063023e-05 * days],
            9.54791938424326609e-04 * solar,
        ],
        [
            [8.34336671824457987e00, 4.12479856412430479e00, -4.03523417114321381e-01],
            [-2.76742510726862411e-03 * days, 4.99852801234917238e-03 * days, 2.30417297573763929e-05 * days],
            2.85885980666130812e-04 * solar,
        ],
        [
            [1.28943695621391310e01, -1.51111514016986312e01, -2.23307578892655734e-01],
            [2.96460137564761618e-03 * days, 2.37847173959480950e-03 * days, -2.96589568540237556e-05 * days],
            4.36624404335156298e-05 * solar,
        ],
        [
            [1.53796971148509165e01, -2.59193146099879641e01, 1.79258772950371181e-01],
            [2.68067772490389322e-03 * days, 1.62824170038242295e-03 * days, -9.51592254519715870e-05 * days],
            5.15138902046611451e-05 * solar,
        ],
    ]
    pairs = [(bodies[i], bodies[j]) for i in range(5) for j in range(i + 1, 5)]
    start = time.process_time()
    dt = 0.01
    for _ in range(steps):
        for ([x1, y1, z1], v1, m1), ([x2, y2, z2], v2, m2) in pairs:
            dx, dy, dz = x1 - x2, y1 - y2, z1 - z2
            mag = dt * ((dx * dx + dy * dy + dz * dz) ** (-1.5))
            b1m, b2m = m1 * mag, m2 * mag
            v1[0] -= dx * b2m
            v1[1] -= dy * b2m
            v1[2] -= dz * b2m
            v2[0] += dx * b1m
            v2[1] += dy * b1m
            v2[2] += dz * b1m
        for r, [vx, vy, vz], _m in bodies:
            r[0] += dt * vx
            r[1] += dt * vy
            r[2] += dt * vz
    return time.process_time() - start


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="length of the replayed flights")
    ap.add_argument("--live-seconds", type=float, default=10.0, help="length of each live run")
    ap.add_argument("--rates", type=float, nargs="+", default=[50.0, 200.0], help="ESC rates [Hz]")
    ap.add_argument("--nbody-steps", type=int, default=300_000)
    ap.add_argument(
        "--vehicle",
        choices=("bundled", "per-motor", "identified"),
        default="bundled",
        help="the bundled motor, a vehicle file with a model per motor (as fit writes), or one that also"
        " carries each motor's noise (as fit writes it: the agent then runs flight_vehicle)",
    )
    args = ap.parse_args(argv)
    global VEHICLE, PROFILE
    keep = tempfile.TemporaryDirectory()
    if args.vehicle == "per-motor":
        VEHICLE = write_per_motor_vehicle(Path(keep.name) / "vehicle.toml")
    elif args.vehicle == "identified":
        VEHICLE, PROFILE = write_identified_vehicle(Path(keep.name) / "vehicle.toml", 60.0), None

    picked = load_agent_config(None, connect="udpin:127.0.0.1:14550", params=VEHICLE, profile=PROFILE).profile
    print(
        f"python {sys.version.split()[0]} on {sys.platform}; flights of {args.seconds:.0f} s, {MOTORS} motors;"
        f" vehicle: {args.vehicle}; profile: {picked.name}"
    )
    replay: dict[tuple[float, float], float] = {}
    parse: dict[float, float] = {}
    print("\n1. CPU per motor sample, replay through the agent's feeding path")
    with tempfile.TemporaryDirectory() as tmp:
        for rate in args.rates:
            path = Path(tmp) / f"flight_{rate:.0f}.tlog"
            n_samples = write_flight(path, args.seconds, rate)
            parse_s, n_msgs = parse_only(path)
            parse[rate] = per_parse = parse_s / n_samples
            print(f"   {MOTORS} x {rate:.0f} Hz ({n_samples} samples, {n_msgs} MAVLink messages)")
            print(f"     baseline, parsing the MAVLink bytes only: {1e6 * per_parse:8.1f} us/sample")
            for batch_s in BATCHES.get(rate, (0.02, 0.1)):
                with contextlib.redirect_stdout(io.StringIO()):  # the agent's state changes at the end
                    cpu_s, samples = agent_replay(path, batch_s)
                assert samples == n_samples, (samples, n_samples)
                replay[rate, batch_s] = cpu_s / samples
                print(
                    f"     agent, batch_s = {batch_s:4.2f} s:                {1e6 * cpu_s / samples:8.1f} us/sample"
                    f"  ({cpu_s / samples / per_parse:5.1f}x parsing; {100 * cpu_s / samples * MOTORS * rate:5.1f} % of"
                    f" a core at {MOTORS}x{rate:.0f} Hz)"
                )

    print(
        f"\n2. live over UDP, {MOTORS} motors, default config with esc_rate_hz = the rate, {args.live_seconds:.0f} s each"
    )
    figures: dict[tuple[float, float], dict[str, float]] = {}
    for rate in args.rates:
        for batch_s in LIVE_BATCHES:
            with contextlib.redirect_stdout(io.StringIO()):
                got = figures[rate, batch_s] = live(args.live_seconds, rate, batch_s)
            print(
                f"   {MOTORS} x {rate:.0f} Hz, batch_s = {batch_s:4.2f} s: {got['samples_per_s']:5.0f} samples/s diagnosed;"
                f" agent process {100 * got['cpu_share']:5.1f} % of one core (this machine); arrival -> diagnosed"
                f" p50 {got['lat_p50_ms']:.0f} ms, p95 {got['lat_p95_ms']:.0f} ms, max {got['lat_max_ms']:.0f} ms;"
                f" fault -> STATUSTEXT median {got['detect_median_ms']:.0f} ms, max {got['detect_max_ms']:.0f} ms"
                f" ({got['detections']} faults)"
            )

    nbody_s = nbody(args.nbody_steps)
    factor = (PI4_NBODY_S / PI4_NBODY_STEPS) / (nbody_s / args.nbody_steps)
    print("\n3. Raspberry Pi 4 estimate")
    print(
        f"   n-body here: {nbody_s:.2f} s for {args.nbody_steps} steps; Pi 4 (published): {PI4_NBODY_S} s for"
        f" {PI4_NBODY_STEPS} -> a Pi 4 core is ~{factor:.1f}x slower for pure Python"
    )
    for rate in args.rates:
        live_part = "; ".join(
            f"batch_s {batch_s:.2f}: ~{100 * figures[rate, batch_s]['cpu_share'] * factor:.0f} %"
            for batch_s in LIVE_BATCHES
        )
        replay_part = ", ".join(
            f"batch_s {batch_s:.2f}: ~{100 * replay[rate, batch_s] * MOTORS * rate * factor:.0f} %"
            for batch_s in BATCHES.get(rate, (0.02, 0.1))
        )
        print(f"   {MOTORS} x {rate:.0f} Hz, the whole agent live on a Pi 4 core: {live_part}")
        print(f"   {MOTORS} x {rate:.0f} Hz, the feeding path alone (replay) on a Pi 4 core: {replay_part}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
