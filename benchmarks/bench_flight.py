"""Diagnosis in flight on simulated hexacopter flights the profile was not tuned on, and the PX4-style
current-vs-throttle baseline on the same flights.

Run: ``.venv/bin/python benchmarks/bench_flight.py [--hours H] [--jobs N] [--seed-offset N]`` (``./dev bench`` runs all
benchmarks). Prints three tables:

1. per turbulence level and fault: accuracy after onset (share of quasi-steady samples of the faulty motor
   diagnosed as the true fault), time from onset to the announcement, healthy samples NORMAL, false fault
   events — beside the paper's flight figures;
2. false fault events in healthy flights of ``--hours`` per turbulence level (default 0.25 h; the issue
   asks for 1 h: ``--hours 1``);
3. the smallest severity of F1.1, F3.1 and F4.1 that each method detects with >= 95 % accuracy and no false
   event, on the same calm flights, and what each method calls the fault.

The flight profile used is ``params/profiles/flight.toml`` (``mav-motor-health tune --campaign``: seeds
from 1000); this benchmark flies seeds from 2000 and 3000 (``--seed-offset N`` moves table 1's fault
flights to seeds from 2000 + N: another draw of the same plan).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter

import numpy as np

from mav_motor_health.commands.tune import campaign_cases
from mav_motor_health.config import load_motor_params, load_profile
from mav_motor_health.diagnosis import MotorState, diagnose
from mav_motor_health.diagnosis.tuning import LabelledFlight
from mav_motor_health.evaluation.campaign import (
    FAULTS,
    TURBULENCE_LEVELS,
    FlightCase,
    benchmark_fault_cases,
    run_flights,
)
from mav_motor_health.evaluation.px4_baseline import Px4Baseline, fit_baseline, motor_series, table_flags
from mav_motor_health.evaluation.score import PAPER, score

SEVERITIES = (0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)


def ours(flight: LabelledFlight, params, profile):
    result = diagnose(flight.table, params, profile)
    return result, score({k: result[k] for k in result.names}, flight.truth)


def baseline_flags(
    detector: Px4Baseline, flight: LabelledFlight
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = flight.table
    return table_flags(detector, t), t["motor"], t["time_s"]


def baseline_score(detector: Px4Baseline, flight: LabelledFlight) -> tuple[float | None, int, str]:
    """Accuracy after onset + hold (flagged samples of the faulty motor), false events, what it says."""
    flags, motors, times = baseline_flags(detector, flight)
    faults = flight.truth.get("faults") or []
    faulty = np.zeros(len(flags), dtype=bool)
    acc, said = None, "-"
    if faults:
        f = faults[0]
        faulty = (motors == int(f["motor"])) & (times >= float(f["onset_s"]))
        judged = faulty & (times >= float(f["onset_s"]) + detector.hold_s + 3 * detector.tau_s)
        acc = 100.0 * float(np.mean(flags[judged] != 0)) if judged.any() else None
        kinds = Counter(int(x) for x in flags[judged] if x != 0)
        said = {-1: "under-current", 1: "over-current"}.get(kinds.most_common(1)[0][0], "-") if kinds else "-"
    false = 0
    for motor in np.unique(motors):
        sel = (motors == motor) & ~faulty
        on = flags[sel] != 0
        false += int(on[0]) + int(np.sum(on[1:] & ~on[:-1]))
    return acc, false, said


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--hours", type=float, default=0.25, help="healthy flight per turbulence level [h]")
    parser.add_argument("--jobs", type=int, default=None)
    parser.add_argument("--profile", default="flight", help="profile TOML or name (default: flight)")
    parser.add_argument(
        "--seed-offset",
        type=int,
        default=0,
        help="fly table 1's fault flights with seeds this much higher (another draw; default 0: seeds from 2000)",
    )
    args = parser.parse_args()
    started = time.perf_counter()
    params = load_motor_params()
    profile = load_profile(args.profile)

    # 1. faults at three turbulence levels (test seeds)
    flights = run_flights(benchmark_fault_cases(args.seed_offset), args.jobs)
    seeds = "test seeds" + (f" + {args.seed_offset}" if args.seed_offset else "")
    print(f"1. Faults in flight ({seeds}; profile {args.profile})")
    print(f"{'turbulence':10s} {'fault':5s} {'accuracy':>9s} {'detect s':>9s} {'NORMAL':>8s} {'false':>5s}")
    detections = []
    for turbulence in TURBULENCE_LEVELS:
        for fault in FAULTS:
            rows = [
                ours(f, params, profile)[1]
                for f in flights
                if f.truth["turbulence"] == turbulence and f.truth["faults"][0]["fault"] == fault
            ]
            acc = [r.fault_accuracy_pct for r in rows if r.fault_accuracy_pct is not None]
            det = [r.detection_s for r in rows if r.detection_s is not None]
            detections += det
            normal = [r.normal_accuracy_pct for r in rows if r.normal_accuracy_pct is not None]
            print(
                f"{turbulence:10s} {fault:5s} {np.mean(acc) if acc else float('nan'):8.2f}% "
                f"{np.median(det) if len(det) == len(rows) else float('nan'):9.2f} "
                f"{np.mean(normal):7.2f}% {sum(r.false_events for r in rows):5d}"
            )
    print(
        f"median time to detection over all faults detected: {np.median(detections):.2f} s "
        f"({len(detections)}/{len(flights)} flights)"
    )
    print(
        f"paper, flight: F4.1 accuracy {PAPER['flight_F4.1_accuracy_pct']}, F4.2 error "
        f"{PAPER['flight_F4.2_error_pct']} %, normal {PAPER['flight_normal_accuracy_pct']} %"
    )

    # 2. long healthy flights
    long_cases = [FlightCase(t, 3000 + k, args.hours * 3600.0) for k, t in enumerate(TURBULENCE_LEVELS)]
    print(f"\n2. Healthy flights of {args.hours:g} h per turbulence level")
    for flight in run_flights(long_cases, args.jobs):
        _, s = ours(flight, params, profile)
        print(
            f"{flight.truth['turbulence']:10s} NORMAL {s.normal_accuracy_pct:6.2f}% of quasi-steady samples, "
            f"{s.false_events} false fault events ({s.false_events_per_hour:.2f} per hour)"
        )

    # 3. smallest detectable severity, ours vs the PX4-style baseline, calm flights
    train = [f for f in run_flights([c for c in campaign_cases() if c.fault is None], args.jobs)]
    detector = fit_baseline(motor_series([f.table for f in train]))
    sweep = [
        FlightCase(
            "calm", 4000 + 10 * j + k, 40.0, fault=fault, motor=1 + (j + k) % 6, onset_s=15.0, severity=sev
        )
        for j, fault in enumerate(("F1.1", "F3.1", "F4.1"))
        for k, sev in enumerate(SEVERITIES)
    ]
    swept = run_flights(sweep, args.jobs)
    print(
        f"\n3. Smallest severity detected (>= 95 % accuracy, no false event), calm; baseline: expected current "
        f"{detector.c2t_a:.2f}*u + {detector.idle_a:.2f} A, band -{detector.low_band_a:.2f}/+{detector.high_band_a:.2f} A"
    )
    print(f"{'fault':5s} {'ours':>6s} {'baseline':>9s}   ours says / baseline says at the paper's severity")
    for fault in ("F1.1", "F3.1", "F4.1"):
        best_ours = best_base = None
        said_ours = said_base = "-"
        for sev, flight in [(c.severity, f) for c, f in zip(sweep, swept) if c.fault == fault]:
            result, s = ours(flight, params, profile)
            acc_b, false_b, said_b = baseline_score(detector, flight)
            if (
                best_ours is None
                and s.fault_accuracy_pct is not None
                and s.fault_accuracy_pct >= 95
                and not s.false_events
            ):
                best_ours = sev
            if best_base is None and acc_b is not None and acc_b >= 95 and not false_b:
                best_base = sev
            if sev == 1.0:
                motor = flight.truth["faults"][0]["motor"]
                late = (result["motor"] == motor) & (result["time_s"] > 20.0)
                said_ours = MotorState(int(np.bincount(result["announced"][late]).argmax())).label
                said_base = said_b
        print(
            f"{fault:5s} {best_ours if best_ours is not None else '>1':>6} "
            f"{best_base if best_base is not None else '>1':>9}   {said_ours} / {said_base}"
        )
    print(f"\n(benchmark took {time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
