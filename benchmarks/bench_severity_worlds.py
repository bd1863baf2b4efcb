"""The severity floor on randomised worlds, ours against the PX4-style baseline (issue 17's last goal).

    PYTHONPATH=src python benchmarks/bench_severity_worlds.py --jobs 2                   # worlds 1000-1019
    PYTHONPATH=src python benchmarks/bench_severity_worlds.py --first 0 --count 10       # development

Per world (:func:`mav_motor_health.evaluation.severity.severity_world`): the vehicle identified from its
healthy 150-s flight (``fit``) and the PX4-style baseline fitted on the same flight; then calm 30-s flights
with F1.1, F3.1 and F4.1 at severities 0.05-1 (onset at 15 s), and F1.1 and F4.1 also beyond the paper's
strength (1.5, 2, 3, 5), replayed with the vehicle file and the ``flight_vehicle`` profile. A method names
a flight when it names the fault within 3 s with no false event (the baseline: any flag on the faulty
motor); its floor is the smallest severity from which every stronger flight up to 1 is named, else the
weakest rung beyond 1 it names ("none": not even 5; F3.1 has no rung beyond 1, ">1" there). Printed per
world, then the median world's floor per fault and method, and the goal: ours at most a quarter of the
baseline's in the median world (where the baseline names none up to the ladder's top, its floor lies
above the top: ours at most a quarter of the top meets it).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.evaluation.severity import (  # noqa: E402
    BEYOND,
    BEYOND_FAULTS,
    SEVERITY_FAULTS,
    WorldSeverity,
    severity_world,
)


def _floor(value: float, fault: str) -> str:
    if math.isinf(value):
        return "none" if fault in BEYOND_FAULTS else ">1"
    return f"{value:g}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000, help="first world seed (default 1000: held out)")
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--profile", default="flight_vehicle")
    args = parser.parse_args(argv)
    started = time.monotonic()
    worlds = list(range(args.first, args.first + args.count))
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results: list[WorldSeverity] = list(pool.map(_with_profile, worlds, [args.profile] * len(worlds)))
    print("severity floor (named within 3 s, no false event), calm; ours / PX4-style baseline")
    print(f"{'world':6s} {'vehicle':58s} " + "  ".join(f"{f:>12s}" for f in SEVERITY_FAULTS))
    evaluated = [r for r in results if r.refused is None]
    for r in results:
        if r.refused is not None:
            print(f"{r.world:<6d} {r.description:58s} refused by identification: {r.refused[:60]}")
            continue
        cells = "  ".join(
            f"{_floor(r.floor(f, 'ours'), f):>5s} / {_floor(r.floor(f, 'baseline'), f):<4s}"
            for f in SEVERITY_FAULTS
        )
        note = f"   (baseline: {r.baseline})" if r.baseline else ""
        print(f"{r.world:<6d} {r.description:58s} {cells}{note}")
    print(f"\nmedian world over {len(evaluated)} identified (goal: ours <= a quarter of the baseline's)")
    for fault in SEVERITY_FAULTS:
        ours = statistics.median([r.floor(fault, "ours") for r in evaluated]) if evaluated else math.inf
        base = statistics.median([r.floor(fault, "baseline") for r in evaluated]) if evaluated else math.inf
        if math.isinf(base):
            # the baseline names none up to the ladder's top: its floor lies above it, and a quarter of it
            # above a quarter of the top
            top = max(BEYOND) if fault in BEYOND_FAULTS else 1.0
            met = ours <= top / 4
            verdict = (
                f"{'met' if met else 'not shown'}: the baseline names none up to {top:g}, so a quarter of its "
                f"floor lies above {top / 4:g}"
            )
        else:
            verdict = "met" if ours <= base / 4 else "not met"
        print(f"  {fault}  ours {_floor(ours, fault):>5s}   baseline {_floor(base, fault):>5s}   {verdict}")
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


def _with_profile(world: int, profile: str) -> WorldSeverity:
    return severity_world(world, profile=profile)


if __name__ == "__main__":
    raise SystemExit(main())
