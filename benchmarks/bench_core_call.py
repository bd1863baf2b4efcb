"""The diagnosis core's cost per live-agent call, by profile: what a vehicle identified by ``fit`` costs
the agent against the bundled profile, in the same run.

    PYTHONPATH=src python benchmarks/bench_core_call.py [--seconds 20] [--rate 50] [--batch-s 0.1]
        [--repeat 5] [--only flight|flight_vehicle]

The vehicle is ``bench_agent.py``'s (the bundled motor with each motor's R and k_e a little apart, as
``fit`` writes a vehicle file), its noise measured as ``fit`` measures it on one synthetic flight; another
flight of the same vehicle (``--seconds`` at ``--rate`` Hz, six motors) is read from its .tlog and cut, in
the order its samples arrive, into the agent's calls of ``--batch-s`` seconds, every motor's samples of a
call in one :meth:`StreamingDiagnoser.update_motors`. Timed (process CPU, the least of ``--repeat`` runs
over the whole flight, after a first run that is not timed): the ``flight`` profile without the noise
(the bundled motor's way), and ``flight_vehicle`` with it (the profile the agent picks for a vehicle file
that carries its noise: bands in that noise, the sequential test, the vehicle stage). The ratio of the two
is the figure; both are per call and per motor sample.

``--only PROFILE`` times one profile.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_agent
from mav_motor_health.config import load_profile, load_vehicle_params
from mav_motor_health.diagnosis.noise import band_noise_of
from mav_motor_health.diagnosis.pipeline import MotorBatch, StreamingDiagnoser
from mav_motor_health.telemetry import sources


def calls_of(table, batch_s: float) -> list[dict[int, MotorBatch]]:
    """The agent's calls: every motor's samples of each ``batch_s`` of arrival (time, then motor)."""
    motor = np.asarray(table["motor"]).astype(int)
    time_s = np.asarray(table["time_s"], dtype=float)
    columns = {name: table[name] for name in table.names}
    # the vehicle's six motors (the flight's ESC_TELEMETRY_5_TO_8 carries two empty slots, which the
    # agent's reader drops)
    order = np.lexsort((motor, time_s))
    order = order[motor[order] <= bench_agent.MOTORS]
    arrival = time_s[order]
    cuts = arrival[0] + batch_s * np.arange(1, int((arrival[-1] - arrival[0]) / batch_s) + 1)
    edges = np.unique(np.concatenate([[0], np.searchsorted(arrival, cuts, "left"), [arrival.size]]))
    calls = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        part = order[lo:hi]
        batches = {}
        for m in np.unique(motor[part]).tolist():
            batches[m] = MotorBatch.of_columns(columns, part[motor[part] == m])
        if batches:
            calls.append(batches)
    return calls


def run(profile_name: str, vehicle, calls, motors) -> None:
    profile = load_profile(profile_name)
    noise = band_noise_of(vehicle.noise) if profile.noise_bands > 0 else None
    stream = StreamingDiagnoser(vehicle.models(range(1, max(motors) + 1)), profile, motors, noise)
    for batches in calls:
        stream.update_motors(batches)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--rate", type=float, default=50.0, help="ESC rate [Hz]")
    ap.add_argument("--batch-s", type=float, default=0.1, help="the agent's batch_s")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--only", choices=("flight", "flight_vehicle"))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(bench_agent.write_identified_vehicle(Path(tmp) / "vehicle.toml", 60.0))
        vehicle = load_vehicle_params(path)
        flight = Path(tmp) / "flight.tlog"
        bench_agent.write_flight(flight, args.seconds, args.rate)
        table = vehicle.calibrate(sources.read(flight))
    motors = [m for m in sorted(int(m) for m in table.motors()) if m <= bench_agent.MOTORS]
    calls = calls_of(table, args.batch_s)
    samples = sum(b.time_s.size for batches in calls for b in batches.values())
    profiles = (args.only,) if args.only else ("flight", "flight_vehicle")
    print(
        f"{len(motors)} motors x {args.rate:.0f} Hz, {args.seconds:.0f} s: {len(calls)} calls of batch_s ="
        f" {args.batch_s} s, {samples / len(calls):.1f} motor samples per call"
    )
    per_call = {}
    for name in profiles:
        run(name, vehicle, calls, motors)  # warm-up: the threshold's design, imports, caches
        times = []
        for _ in range(args.repeat):
            start = time.process_time()
            run(name, vehicle, calls, motors)
            times.append(time.process_time() - start)
        if not times:
            continue
        per_call[name] = min(times) / len(calls)
        print(
            f"  {name:15s} {1e3 * per_call[name]:6.2f} ms per call, {1e6 * min(times) / samples:6.1f} us per"
            f" motor sample (least of {len(times)}; runs {', '.join(f'{t:.2f}' for t in times)} s)"
        )
    if len(per_call) == 2:
        print(f"  flight_vehicle / flight: {per_call['flight_vehicle'] / per_call['flight']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
