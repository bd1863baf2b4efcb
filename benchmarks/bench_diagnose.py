"""Diagnose 10^6 motor samples with the vectorised pipeline; compare with the per-sample path.

Run: ``./dev run`` environment or ``.venv/bin/python benchmarks/bench_diagnose.py [--samples N]``.
Prints the throughput of ``diagnose()`` on whole arrays and, as the baseline measured in the same run,
the throughput of the same pipeline fed one sample at a time (``StreamingDiagnoser``, the live agent's
path), and their ratio. Timing goals are ratios, never absolute seconds.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis import MotorState, StreamingDiagnoser, diagnose
from mav_motor_health.model import steady_state
from mav_motor_health.telemetry import TelemetryTable


def make_table(n: int, seed: int = 1) -> TelemetryTable:
    rng = np.random.default_rng(seed)
    motors = 6
    per = n // motors
    t = np.arange(per) / 50.0
    # a slowly varying input with occasional steps, per motor
    v = (
        7.5
        + 1.5 * np.sin(2 * np.pi * t[None, :] / 30.0 + np.arange(motors)[:, None])
        + np.round(rng.normal(0, 0.3, (motors, per)).cumsum(axis=1) / 50.0, 1)
    )
    v = np.clip(v, 4.0, 11.0)
    s = steady_state(load_motor_params(), v)
    return TelemetryTable.from_columns(
        time_s=np.tile(t, motors),
        motor=np.repeat(np.arange(1, motors + 1), per),
        voltage_v=v.ravel(),
        omega_rad_s=(s.omega_rad_s + rng.uniform(-10, 10, v.shape)).ravel(),
        current_a=(s.current_a + rng.uniform(-0.5, 0.5, v.shape)).ravel(),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--samples", type=int, default=1_000_000)
    parser.add_argument("--streaming-samples", type=int, default=6_000)
    args = parser.parse_args()
    params, profile = load_motor_params(), load_profile("testbed")
    table = make_table(args.samples)
    start = time.perf_counter()
    result = diagnose(table, params, profile)
    batch_s = time.perf_counter() - start
    normal = float(np.mean(result["state"][result["steady"]] == MotorState.NORMAL))

    sub = table.select(np.arange(len(table)) % (len(table) // args.streaming_samples) == 0)
    stream = StreamingDiagnoser(params, profile)
    volts = sub.voltage_v()
    start = time.perf_counter()
    for j in range(len(sub)):
        stream.update(
            int(sub["motor"][j]),
            float(sub["time_s"][j]),
            float(volts[j]),
            float(sub["omega_rad_s"][j]),
            float(sub["current_a"][j]),
        )
    stream_s = time.perf_counter() - start

    batch_rate = len(table) / batch_s
    stream_rate = len(sub) / stream_s
    print(
        f"diagnose() on {len(table):,} samples: {batch_s:.2f} s, {batch_rate:,.0f} samples/s "
        f"({100 * normal:.2f} % of steady samples NORMAL)"
    )
    print(f"baseline, one sample at a time ({len(sub):,} samples): {stream_rate:,.0f} samples/s")
    print(f"ratio vectorised / per-sample: {batch_rate / stream_rate:.0f}x")


if __name__ == "__main__":
    main()
