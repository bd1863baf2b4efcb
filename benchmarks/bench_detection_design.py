"""The sequential test's designed false-alarm rate against what Gaussian noise of the assumed shape gives
(issue 17, item 2; diagnosis/detection.py).

Run: ``PYTHONPATH=src python benchmarks/bench_detection_design.py [--hours H]``

Each row simulates ``--hours`` hours (default 10) of two healthy motors: speed and current deviations in σ,
white Gaussian noise through the balance rule's low-pass (τ = 0.15 s) sampled at 50 Hz, and runs the
CUSUMs with a threshold designed for a false-alarm rate high enough to be measured in that time. It prints
the designed and the measured false alarms per motor-hour and their ratio (< 1: the design is
conservative). Seeded: the same numbers every run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.diagnosis.detection import (  # noqa: E402
    DESIGN_MOTORS,
    SequentialCarry,
    SequentialRule,
    direction_evidence,
    sequential_alarms,
)

DT_S, TAU_S, MOTORS = 0.02, 0.15, 2
CASES = ((1e4, 2.5), (1e5, 2.5), (1e4, 2.0), (1e5, 1.5))  # (false alarms per 100 h, reference k)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=10.0, help="hours of noise per row (default 10)")
    args = parser.parse_args(argv)
    started = time.monotonic()
    n = int(args.hours * 3600 / DT_S)
    a = np.exp(-DT_S / TAU_S)
    rng = np.random.default_rng(17)
    noise = []
    for _ in range(MOTORS):
        z = lfilter([1 - a], [1, -a], rng.standard_normal((2, n)), axis=1)
        noise.append(z / z.std(axis=1, keepdims=True))
    t = np.arange(n) * DT_S
    print(
        f"{args.hours:g} h of {MOTORS} healthy motors per row (low-passed Gaussian deviations, tau {TAU_S} s)"
    )
    print(
        f"{'designed /100 h':>16}{'k [sigma]':>10}{'h':>7}{'designed':>10}{'measured':>10}{'ratio':>8}   per motor-hour"
    )
    for rate, k in CASES:
        rule = SequentialRule(false_alarms_per_100h=rate, reference_sigmas=k)
        alarms = 0
        for z in noise:
            evidence = direction_evidence(z[0], z[1], np.ones(n, dtype=bool), 4.5)
            announced, _, _ = sequential_alarms(
                rule,
                t,
                evidence,
                np.full(n, 2 * TAU_S),
                np.ones(n, dtype=bool),
                SequentialCarry(),
                0.5,
                TAU_S,
            )
            alarms += int(np.sum((announced[1:] != 0) & (announced[:-1] == 0)) + (announced[0] != 0))
        designed = rate / 100.0 / DESIGN_MOTORS
        measured = alarms / (MOTORS * args.hours)
        print(
            f"{rate:>16g}{k:>10.1f}{rule.threshold(TAU_S):>7.2f}{designed:>10.2f}{measured:>10.2f}"
            f"{measured / designed:>8.3f}"
        )
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
