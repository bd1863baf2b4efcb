"""The current scale from the battery monitor (identification step 2), against each world's truth: the
regression of the ESCs' summed current on the battery's, and the ratio of the charges both counted.

    PYTHONPATH=src python benchmarks/bench_battery_gain.py [--first 0] [--count 20]

Per world one healthy 150-s identification flight of its own plan and air, written as a .tlog (the
benchmark's and ``fit``'s log); the pairs of 1-s bins are those identification uses
(:func:`mav_motor_health.model.identify.battery_current_pairs`), at the world's *true* current side and
idle offset, so that only the estimator differs. Printed: the true gain (the ESC sensor's over the
battery monitor's), the regression's slope and offset (the rest of the vehicle's draw it implies), the
ratio, and what identification keeps (the ratio). Then the ratio with the reading taken as each side's
(an input-side reading as is, a motor-side one x duty), as identification's guess weighs them where the
side test cannot tell (the side whose ratio is nearer 1). Worlds 0-19 are the development worlds;
1000-1019 are held out.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.evaluation.worlds import write_identification_log  # noqa: E402
from mav_motor_health.model.identify import (  # noqa: E402
    EscMap,
    battery_current_pairs,
    gain_from_pairs,
)
from mav_motor_health.sim.worlds import draw_world  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402


def one_world(world: int, folder: Path) -> dict | None:
    truth = draw_world(world)
    if truth.current.side == "unusable":
        return None
    log = write_identification_log(world, folder / f"world{world}.tlog")
    table = sources.read(log)
    pairs = battery_current_pairs(table, truth.current.side, EscMap(truth.esc.idle_offset))
    if pairs is None:
        return None
    e, b = pairs
    slope, intercept = np.polyfit(b, e, 1)
    offset = -intercept / slope if slope > 0 else -np.inf
    ratio = float(np.sum(e) / np.sum(b))
    as_side = {}
    for side in ("input", "motor"):
        read = battery_current_pairs(table, side, EscMap(truth.esc.idle_offset))
        as_side[side] = math.nan if read is None else float(np.sum(read[0]) / np.sum(read[1]))
    return {
        "world": world,
        "side": truth.current.side,
        "true": truth.current.gain / truth.battery.monitor_gain,
        "other_a": truth.avionics_current_a,
        "slope": float(slope),
        "offset": float(offset),
        "ratio": ratio,
        "kept": gain_from_pairs(e, b)[0],  # what identification keeps
        "as_input": as_side["input"],
        "as_motor": as_side["motor"],
    }


def nearer(row: dict) -> str:
    """The side whose charge ratio lies nearer 1 (identification's guess where the side test cannot tell)."""
    return min(("input", "motor"), key=lambda side: abs(math.log(row[f"as_{side}"])))


def _span(values: list[float]) -> str:
    return f"{min(values):.2f}-{max(values):.2f}" if values else "-"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=0, help="first world seed (default 0: development)")
    parser.add_argument("--count", type=int, default=20, help="how many worlds (default 20)")
    args = parser.parse_args(argv)
    rows = []
    print(
        "world side  true gain  other draw | regression: slope  offset A | ratio | kept, error | "
        "ratio read as input / as motor -> nearer 1"
    )
    with tempfile.TemporaryDirectory(prefix="mmh-gain-") as tmp:
        for world in range(args.first, args.first + args.count):
            row = one_world(world, Path(tmp))
            if row is None:
                print(f"{world:5d} (no usable current or no battery monitor)")
                continue
            rows.append(row)
            print(
                f"{world:5d} {row['side']:5s} {row['true']:9.3f} {row['other_a']:8.2f} A | "
                f"{row['slope']:17.3f} {row['offset']:8.1f} | {row['ratio']:.3f} | "
                f"{row['kept']:.3f}, {100 * (row['kept'] / row['true'] - 1):+.1f} % | "
                f"{row['as_input']:.3f} / {row['as_motor']:.3f} -> {nearer(row)}",
                flush=True,
            )
    if not rows:
        return 1
    for side in ("input", "motor"):
        mine = [r for r in rows if r["side"] == side]
        print(
            f"{side}-side worlds: {sum(nearer(r) == side for r in mine)} of {len(mine)} nearer 1 on their "
            f"own side; read as input {_span([r['as_input'] for r in mine])}, "
            f"as motor {_span([r['as_motor'] for r in mine])}"
        )
    errors = [abs(r["kept"] / r["true"] - 1) for r in rows]
    slope_errors = [abs(r["slope"] / r["true"] - 1) for r in rows]
    print(
        f"\n{len(rows)} worlds: regression offset negative in {sum(r['offset'] < 0 for r in rows)}; "
        f"|slope error| median {100 * statistics.median(slope_errors):.0f} %; "
        f"kept gain |error| median {100 * statistics.median(errors):.1f} %, worst {100 * max(errors):.1f} %, "
        f"within 10 % in {sum(e <= 0.10 for e in errors)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
