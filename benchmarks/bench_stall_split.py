"""The F2.1/F4.2 stall split on randomised worlds: each stall's current in units of the motor's typical one.

    PYTHONPATH=src python benchmarks/bench_stall_split.py --first 0 --count 20 --jobs 2   # development
    PYTHONPATH=src python benchmarks/bench_stall_split.py --splits 1.58 1.27              # held out

A phase open (F2.1) and a lost back-EMF signal (F4.2) both stall the motor; the tree tells them apart by
the stalled motor's current against ``stall_split_typical`` times its typical flight current (rules/tree.py).
Per world: the vehicle identified from its healthy 150-s flight (``fit``), then its 60-s F2.1 and F4.2
flights at every turbulence level (the flights of ``bench_flight_worlds.py --duration-s 60
--healthy-flights 2``, the same seeds), each replayed once per split asked. Printed per flight: the world's
true hover current (the simulator's design point), the typical current identification measured on the faulty
motor, the stall's judged current (the median on the samples named F2.1 or F4.2 after onset, with the
first split), their ratios, and the accuracy after onset at each split; then, over every flight, the
range of each stall's current in units of identification's typical current and of the hover current, and
per split and fault the median and lowest accuracy. Worlds whose ESCs report no usable current have no
typical current and judge no stall by its current: listed, not counted.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import sys
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.config import load_profile  # noqa: E402
from mav_motor_health.diagnosis.noise import band_noise_of  # noqa: E402
from mav_motor_health.diagnosis.pipeline import diagnose  # noqa: E402
from mav_motor_health.diagnosis.states import MotorState  # noqa: E402
from mav_motor_health.errors import MotorHealthError  # noqa: E402
from mav_motor_health.evaluation.score import score  # noqa: E402
from mav_motor_health.evaluation.worlds import fly_flight, identify_world, world_flights  # noqa: E402
from mav_motor_health.sim.worlds import draw_world  # noqa: E402
from mav_motor_health.sim.writers import truth_path, write_record  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402

STALLS = ("F2.1", "F4.2")
NAMED = (int(MotorState.F2_1), int(MotorState.F4_2))


def stall_world(world: int, splits: tuple[float, ...], profile_name: str) -> list[dict[str, Any]]:
    """One world's stall flights, each replayed at every split (module doc); one dict per flight."""
    with tempfile.TemporaryDirectory(prefix=f"mmh-stall{world}-") as tmp:
        folder = Path(tmp)
        try:
            _, _, vehicle = identify_world(world, folder)
        except MotorHealthError as exc:
            return [{"world": world, "refused": str(exc)}]
        base = load_profile(profile_name)
        profiles = {s: dataclasses.replace(base, stall_split_typical=s) for s in splits}
        hover_a = draw_world(world).hover_current_a
        rows = []
        for flight in world_flights(world, duration_s=60.0, healthy_flights=2, faults=STALLS):
            if flight.fault is None or flight.motor is None or flight.onset_s is None:
                continue
            log = folder / f"{flight.name}.tlog"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                write_record(fly_flight(flight), log)
                table = vehicle.calibrate(sources.read(log))
            truth = {
                "faults": [{"fault": flight.fault, "motor": flight.motor, "onset_s": flight.onset_s}],
                "duration_s": flight.duration_s,
            }
            typical = float(vehicle.noise.get(flight.motor, {}).get("current_typical_a", math.nan))
            row: dict[str, Any] = {
                "world": world,
                "level": flight.turbulence,
                "fault": flight.fault,
                "hover_a": hover_a,
                "typical_a": typical,
                "stall_a": math.nan,
                "accuracy": {},
            }
            for i, (split, profile) in enumerate(profiles.items()):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    columns = diagnose(
                        table, vehicle.models(range(1, 7)), profile, band_noise_of(vehicle.noise)
                    ).columns
                accuracy = score(columns, truth).fault_accuracy_pct  # None: nothing judged after onset
                row["accuracy"][split] = math.nan if accuracy is None else accuracy
                if i == 0:
                    after = (columns["motor"] == flight.motor) & (columns["time_s"] > flight.onset_s + 0.5)
                    named = np.isin(columns["state"][after], NAMED)
                    if named.any():
                        row["stall_a"] = float(np.nanmedian(columns["current_judged_a"][after][named]))
            for path in (log, truth_path(log)):
                path.unlink(missing_ok=True)
            rows.append(row)
        return rows


def _range(values: list[float]) -> str:
    return f"{min(values):.2f}-{max(values):.2f}" if values else "-"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000, help="first world seed (default 1000: held out)")
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--profile", default="flight_vehicle")
    parser.add_argument(
        "--splits", type=float, nargs="+", default=[1.58, 1.27], help="stall_split_typical values (1.58 1.27)"
    )
    args = parser.parse_args(argv)
    started = time.monotonic()
    splits = tuple(args.splits)
    worlds = list(range(args.first, args.first + args.count))
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        per_world = list(pool.map(stall_world, worlds, [splits] * len(worlds), [args.profile] * len(worlds)))
    rows = [r for rows in per_world for r in rows]
    print(f"worlds {worlds[0]}-{worlds[-1]}, profile {args.profile}: F2.1 and F4.2 flights of 60 s")
    print(
        f"{'world':>5s} {'air':8s} {'fault':5s} {'hover A':>8s} {'typical A':>9s} {'stall A':>8s} "
        f"{'/typical':>8s} {'/hover':>7s}  " + "  ".join(f"acc % at {s:g}" for s in splits)
    )
    for r in rows:
        if "refused" in r:
            print(f"{r['world']:5d} refused by identification: {r['refused'][:100]}")
            continue
        acc_text = "  ".join(f"{r['accuracy'][s]:12.1f}" for s in splits)
        print(
            f"{r['world']:5d} {r['level']:8s} {r['fault']:5s} {r['hover_a']:8.2f} {r['typical_a']:9.2f} "
            f"{r['stall_a']:8.2f} {r['stall_a'] / r['typical_a']:8.2f} {r['stall_a'] / r['hover_a']:7.2f}  {acc_text}"
        )
    counted = [r for r in rows if "refused" not in r and math.isfinite(r["typical_a"])]
    print()
    print("stall current in units of identification's typical current / of the hover current (range):")
    for fault in STALLS:
        mine = [r for r in counted if r["fault"] == fault and math.isfinite(r["stall_a"])]
        print(
            f"  {fault}: {_range([r['stall_a'] / r['typical_a'] for r in mine])} / "
            f"{_range([r['stall_a'] / r['hover_a'] for r in mine])} ({len(mine)} flights)"
        )
    print(
        "  identification's typical current / hover current: "
        + _range([r["typical_a"] / r["hover_a"] for r in counted])
    )
    print("accuracy after onset per split, median / lowest flight [%] (flights with a typical current):")
    for split in splits:
        parts: list[str] = []
        for fault in STALLS:
            # a flight that judged nothing after onset named nothing: 0
            acc = [
                a if a is not None and math.isfinite(a) else 0.0
                for a in (r["accuracy"][split] for r in counted if r["fault"] == fault)
            ]
            below = sum(a < 90.0 for a in acc)
            parts.append(
                f"{fault} {statistics.median(acc):5.1f} / {min(acc):5.1f} ({below} of {len(acc)} below 90 %)"
            )
        print(f"  {split:g}: " + "; ".join(parts))
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
