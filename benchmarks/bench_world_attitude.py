"""Do the randomised worlds' simulated vehicles fly their plans upright? (docs/simulator.md, "The mixer gives the yaw twice")

    PYTHONPATH=src python benchmarks/bench_world_attitude.py --first 1000 --count 40 --jobs 2
    PYTHONPATH=src python benchmarks/bench_world_attitude.py --first 0 --count 40 --jobs 2

For each world: its 150-s identification flight (its own air and seed, what ``fit`` identifies the
vehicle from) and a 60-s healthy test flight at each turbulence level (``evaluation.worlds.world_flights``
with one healthy flight per level, flown by ``fly_flight`` as the world benchmarks fly theirs), without
the ESC reports.
Printed per flight: the largest roll or pitch [rad] and the first time after take-off the vehicle lay on
the ground (none: it never did). A flight that tips beyond 1.2 rad or touches the ground is marked
``FELL``: the diagnosis and the identification of that world would be scored on a vehicle lying on the
ground with motors at full command, not on a flight. Ends with the count of fallen flights and the
largest tilt of the others.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.evaluation.worlds import fly_flight, fly_world, world_flights  # noqa: E402

LEVELS = ("calm", "moderate", "gusty")
#: tilt beyond which a flight counts as fallen [rad] (the lean limit is 30°, 0.52 rad, and a
#: translation's braking overshoots it a little)
FELL_TILT_RAD = 1.2


def fly(args: tuple[int, str]) -> tuple[int, str, float, float | None]:
    """One flight of a world: ``"identification"`` or a turbulence level; its largest tilt and when it
    first lay on the ground (None: never)."""
    world, kind = args
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if kind == "identification":
            record = fly_world(world, duration_s=150.0, collect_esc=False)
        else:
            flight = world_flights(world, duration_s=60.0, healthy_flights=1, levels=(kind,), faults=())[0]
            record = fly_flight(flight, collect_esc=False)
    tilt = max(max(abs(v.roll_rad), abs(v.pitch_rad)) for v in record.vehicle)
    ground = [v.time_s for v in record.vehicle if v.time_s > 5.0 and v.alt_m <= 0.05]
    return world, kind, tilt, (ground[0] if ground else None)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--first", type=int, default=1000)
    ap.add_argument("--count", type=int, default=40)
    ap.add_argument("--jobs", type=int, default=1)
    args = ap.parse_args(argv)
    start = time.perf_counter()
    flights = [
        (w, k) for w in range(args.first, args.first + args.count) for k in ("identification", *LEVELS)
    ]
    fallen, upright = 0, 0.0
    with ProcessPoolExecutor(max(1, args.jobs)) as pool:
        for world, kind, tilt, ground in pool.map(fly, flights):
            fell = ground is not None or tilt > FELL_TILT_RAD
            fallen += fell
            if not fell:
                upright = max(upright, tilt)
            on_ground = "-" if ground is None else f"{ground:.1f} s"
            print(
                f"world {world:5d} {kind:14s} largest tilt {tilt:6.2f} rad  on the ground {on_ground:8s}"
                f"{'  FELL' if fell else ''}",
                flush=True,
            )
    print(
        f"\n{fallen} of {len(flights)} flights fell; the others tipped at most {upright:.2f} rad"
        f" ({time.perf_counter() - start:.0f} s)"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
