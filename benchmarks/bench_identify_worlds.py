"""Identification on vehicles nothing was tuned on: `fit` on one healthy 150-s flight of each randomised
world, against the world's truth (issue 16).

    PYTHONPATH=src python benchmarks/bench_identify_worlds.py                  # worlds 1000-1019, .tlog
    PYTHONPATH=src python benchmarks/bench_identify_worlds.py --first 0 --count 20 --format bin

Each world (``sim.worlds.draw_world``: motor KV, R, propeller, inertia, ESC idle offset, current sensing,
telemetry rate, turbulence all drawn) flies its own 150-s manoeuvre plan (take-off, climbs, descents,
translations, yaw turns); the flight is written as a log in the chosen format by the simulator's writer
(the .tlog carries ESC_TELEMETRY at the world's rate, at most 50 Hz, commands at 10-50 Hz, as a ground
station records them), read back by the project's reader and identified as ``fit LOG`` does
(:func:`mav_motor_health.identification.identify_logs`, no prior given). Printed per world: the truth and
the error of k_e, R, J and the idle offset c0, the current side found ("undetermined" where the reading
follows the load but the flight does not tell its side: the params file says "unusable"), which values
the flight determined; then the median and the worst world, how many worlds meet the issue's bounds
(k_e within 3 %, R within 15 %, J within 30 %, c0 within 0.01), and the current side true × found. R is
judged only where the ESCs report a usable current, and against R/gain where no battery monitor could
give the sensor's gain.

A second table says what the log does to the electrical balance itself: k_e and R from the balance at
the world's *true* idle offset and current side (:func:`~mav_motor_health.model.identify.
electrical_balance_at`: no search, no prior), next to what drives its error: the logged command's
jitter (the spread of successive logged commands, /√2, of the command range), the pairing of ESC samples
with commands (``pairing_s``) and the share of current readings at exactly 0 (an ESC reports no negative
current). Beside it, the same balance on the simulator's own record of the flight, where each ESC report
carries the duty of its own instant (``k_e paired``, ``R paired``): the same reports, readings and bins,
no pairing. What the log's pairing adds is the difference; what is left is the readings' own doing (their
noise, averaging and the missing negative current). Last (``k_e share``), k_e from the motor voltage over
the speed less the winding's typical share at the true idle offset (``back_emf_share_at``): what
identification takes where the current does not part R from k_e, without the idle offset's error.

The default worlds 1000-1019 are not the worlds 0-19 used while developing the identification: report
figures from these.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.identification import identify_logs  # noqa: E402
from mav_motor_health.model.equations import current_from_speed  # noqa: E402
from mav_motor_health.model.identify import (  # noqa: E402
    RIPPLE_SHARE_MAX,
    back_emf_share_at,
    command_jitter,
    electrical_balance_at,
)
from mav_motor_health.sim.engine import SimRecord, run_scenario  # noqa: E402
from mav_motor_health.sim.scenario import world_scenario  # noqa: E402
from mav_motor_health.sim.worlds import World, draw_world  # noqa: E402
from mav_motor_health.sim.writers import write_record  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402
from mav_motor_health.telemetry.table import TelemetryTable  # noqa: E402

BOUNDS = {"k_e": 0.03, "R_ohm": 0.15, "J_kg_m2": 0.30, "idle_offset": 0.01}


@dataclass(frozen=True)
class WorldResult:
    seed: int
    kv: float
    mass_kg: float
    rate_hz: float
    side_true: str
    side_found: str
    errors: dict[str, float]  # relative for k_e, R, J; absolute for the idle offset
    determined: dict[str, str]
    seconds: float
    failure: str = ""
    #: the balance at the true idle offset and side (relative errors of k_e and R), and the log's
    #: command jitter, pairing [s] and share of zero current readings
    at_truth: dict[str, float] = field(default_factory=dict)
    #: the duty ripple identification estimated (jitter, ripple share), the exponent it chose, and the
    #: identified model's current at the world's hover speed against the true motor's (relative excess)
    ripple: dict[str, float] = field(default_factory=dict)


def one_world(seed: int, fmt: str, duration_s: float) -> WorldResult:
    world = draw_world(seed)
    truth = world.motor
    started = time.monotonic()

    at_truth: dict[str, float] = {}
    ripple: dict[str, float] = {}

    def result(
        side_found: str, errors: dict[str, float], determined: dict[str, str], failure: str = ""
    ) -> WorldResult:
        return WorldResult(
            seed,
            world.kv_rpm_per_v,
            world.mass_kg,
            world.rate_hz,
            world.current.side,
            side_found,
            errors,
            determined,
            time.monotonic() - started,
            failure,
            at_truth,
            ripple,
        )

    with tempfile.TemporaryDirectory(prefix="mmh-world-") as tmp:
        path = Path(tmp) / f"world{seed}.{fmt}"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            record = run_scenario(world_scenario(seed, duration_s=duration_s))  # as `simulate world` flies it
            write_record(record, path)
            at_truth.update(balance_at_truth(path, world, record))
            try:
                found = identify_logs([path]).found
            except Exception as exc:  # a benchmark reports every world, a failure too
                return result("-", {}, {}, f"{type(exc).__name__}: {exc}")
    p = found.params
    hover = world.hover_omega_rad_s
    ripple.update(
        jitter=getattr(found, "duty_jitter", math.nan),
        share=getattr(found, "ripple_share", math.nan),
        k=p.k,
        excess=current_from_speed(p, hover) / current_from_speed(truth, hover) - 1.0,
    )
    errors = {
        "k_e": p.k_e / truth.k_e - 1.0,
        "J_kg_m2": (p.J_kg_m2 or math.nan) / (truth.J_kg_m2 or math.nan) - 1.0,
        "idle_offset": found.esc.idle_offset - world.esc.idle_offset,
    }
    if world.current.side != "unusable":
        # without a battery monitor's comparison the sensor's gain is assumed 1: R is R/gain then
        gain = world.current.gain if found.current.gain_from == "assumed" else 1.0
        errors["R_ohm"] = p.R_ohm / (truth.R_ohm / gain) - 1.0
    side = found.current.side
    if side == "unusable" and found.current.side_test is not None:
        side = "undetermined"  # a reading that follows the load, on a side the flight does not tell
    return result(side, errors, dict(found.determined_by))


def balance_at_truth(path: Path, world: World, record: SimRecord) -> dict[str, float]:
    """The electrical balance at the world's true idle offset and side, from the log and from the
    simulator's record with each report's own duty, and the log's command jitter, pairing and share of
    zero current readings (module doc)."""
    table = sources.read(path)
    jitter = []
    for motor in table.motors():
        sel = table["motor"] == motor
        c = table["throttle"][sel]
        spread = command_jitter(c[np.isfinite(c)])
        if math.isfinite(spread):
            jitter.append(spread)
    reading = table["esc_current_a"]
    out = {
        "jitter": statistics.median(jitter) if jitter else math.nan,
        "pairing_s": float(table.meta.get("pairing_s") or math.nan),
        "zero": float(np.mean(reading[np.isfinite(reading)] == 0.0)),
    }
    # k_e from the motor voltage over the speed less the winding's typical share, at the true offset: what
    # identification takes where the current does not part R from k_e, with no idle offset error in it
    shares = back_emf_share_at(table, world.esc.idle_offset)
    if shares:
        out["k_e_share"] = statistics.median(shares.values()) / world.motor.k_e - 1.0
    if world.current.side == "unusable":
        return out
    columns = record.esc_columns()
    columns["throttle"] = np.array([s.duty for s in record.esc], dtype=float)  # each report's own duty
    # the log's bins (they span at least four of its pairing intervals)
    paired = TelemetryTable(columns, source="the record", meta={"pairing_s": table.meta.get("pairing_s")})
    for suffix, fits in (
        ("", electrical_balance_at(table, world.esc.idle_offset, world.current.side)),
        ("_paired", electrical_balance_at(paired, 0.0, world.current.side)),  # the duty itself: no map
    ):
        if fits:
            truth = world.motor
            out["k_e" + suffix] = statistics.median(v[0] for v in fits.values()) / truth.k_e - 1.0
            r_ohm = statistics.median(v[1] for v in fits.values()) * world.current.gain
            out["R_ohm" + suffix] = r_ohm / truth.R_ohm - 1.0
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000, help="first world seed (default 1000)")
    parser.add_argument("--count", type=int, default=20, help="how many worlds (default 20)")
    parser.add_argument("--format", choices=("tlog", "bin", "csv"), default="tlog")
    parser.add_argument("--duration", type=float, default=150.0, help="flight length [s] (default 150)")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args(argv)
    seeds = list(range(args.first, args.first + args.count))
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(one_world, seeds, [args.format] * len(seeds), [args.duration] * len(seeds)))
    print(
        f"identification from one {args.duration:g}-s healthy flight per world, as .{args.format} "
        f"(worlds {seeds[0]}-{seeds[-1]})\n"
    )
    head = f"{'world':>6}{'KV':>7}{'kg':>6}{'Hz':>5}  {'current (true/found)':<20}"
    head += "".join(f"{name:>13}" for name in BOUNDS) + "   determined by prior"
    print(head)
    for r in results:
        if r.failure:
            print(f"{r.seed:>6}{r.kv:>7.0f}{r.mass_kg:>6.1f}{r.rate_hz:>5.0f}  FAILED: {r.failure}")
            continue
        cells = ""
        for name in BOUNDS:
            v = r.errors.get(name)
            if v is None:
                cells += f"{'-':>13}"
            elif name == "idle_offset":
                cells += f"{v:>+13.4f}"
            else:
                cells += f"{100 * v:>+12.1f}%"
        prior = ", ".join(k for k, v in r.determined.items() if v == "prior") or "-"
        print(
            f"{r.seed:>6}{r.kv:>7.0f}{r.mass_kg:>6.1f}{r.rate_hz:>5.0f}  "
            f"{r.side_true + '/' + r.side_found:<20}{cells}   {prior}"
        )
    print()
    ok = [r for r in results if not r.failure]
    print(f"{'':<36}{'median |err|':>14}{'worst |err|':>13}{'within':>10}  bound")
    for name, bound in BOUNDS.items():
        values = [abs(r.errors[name]) for r in ok if name in r.errors and math.isfinite(r.errors[name])]
        if not values:
            continue
        within = sum(v <= bound for v in values)
        scale, unit = (1.0, "") if name == "idle_offset" else (100.0, " %")
        print(
            f"{name:<36}{scale * statistics.median(values):>13.3g}{unit[:2]:<1}{scale * max(values):>12.3g}"
            f"{within:>7}/{len(values):<3}  {scale * bound:g}{unit}"
        )
    print(f"\n{len(results) - len(ok)} of {len(results)} worlds failed to identify")
    found_sides = ("input", "motor", "undetermined", "unusable")
    print(f"\ncurrent side, true (rows) x found (columns), identified worlds\n{'':>10}", end="")
    print("".join(f"{name:>14}" for name in found_sides))
    for true_side in ("input", "motor", "unusable"):
        counts = [sum(r.side_true == true_side and r.side_found == f for r in ok) for f in found_sides]
        print(f"{true_side:>10}" + "".join(f"{n:>14}" for n in counts))
    print(
        "\nthe electrical balance at the true idle offset and current side (no search, no prior), and what"
        "\nthe log does to it: command jitter (of the command range), pairing, current readings at 0\n"
    )
    print(
        f"{'world':>6}{'side':>9}{'k_e':>9}{'R_ohm':>9}{'k_e paired':>12}{'R paired':>10}"
        f"{'jitter':>9}{'pairing':>10}{'zero':>8}{'k_e share':>11}"
    )
    for r in results:
        a = r.at_truth
        if not a:
            continue
        cells = "".join(
            f"{100 * a[k]:>+8.1f}%" if k in a and math.isfinite(a[k]) else f"{'-':>9}"
            for k in ("k_e", "R_ohm")
        )
        cells += "".join(
            f"{100 * a[k]:>+{w - 1}.1f}%" if k in a and math.isfinite(a[k]) else f"{'-':>{w}}"
            for k, w in (("k_e_paired", 12), ("R_ohm_paired", 10))
        )
        print(
            f"{r.seed:>6}{r.side_true:>9}{cells}{a['jitter']:>9.3f}{1000 * a['pairing_s']:>8.0f}ms"
            f"{100 * a['zero']:>7.1f}%"
            + (
                f"{100 * a['k_e_share']:>+10.1f}%"
                if math.isfinite(a.get("k_e_share", math.nan))
                else f"{'-':>11}"
            )
        )
    for key, what in (
        ("k_e", "from the log"),
        ("k_e_paired", "each report with its own duty"),
        ("k_e_share", "the motor voltage over the speed less the winding's typical share (every world)"),
    ):
        kes = [abs(r.at_truth[key]) for r in results if math.isfinite(r.at_truth.get(key, math.nan))]
        if kes:
            print(
                f"k_e at the true ESC map, {what}: median |err| {100 * statistics.median(kes):.3g} %, worst "
                f"{100 * max(kes):.3g} %, within 3 %: {sum(v <= BOUNDS['k_e'] for v in kes)}/{len(kes)}"
            )
    print(
        "\nthe duty ripple identification estimated from the logged commands (jitter of the duty between"
        "\nreports, relative; the share an input current reads above the load's from the ripple's copper"
        "\nloss), the exponent chosen, and the identified model's current at the world's hover speed"
        "\nagainst the true motor's: what a calmer flight's diagnosis would read the model against\n"
    )
    print(f"{'world':>6}{'side (true/found)':>22}{'jitter':>9}{'ripple':>9}{'k':>6}{'current at hover':>19}")
    for r in ok:
        q = r.ripple
        flagged = (
            " (k = 3: mostly ripple)" if r.side_found == "input" and q["share"] >= RIPPLE_SHARE_MAX else ""
        )
        print(
            f"{r.seed:>6}{r.side_true + '/' + r.side_found:>22}{100 * q['jitter']:>8.1f}%{100 * q['share']:>8.0f}%"
            f"{q['k']:>6g}{100 * q['excess']:>+18.1f}%{flagged}"
        )
    rows = [r for r in ok if r.side_found == "input"]
    for name, chosen in (
        ("below", [r for r in rows if r.ripple["share"] < RIPPLE_SHARE_MAX]),
        ("at or above", [r for r in rows if r.ripple["share"] >= RIPPLE_SHARE_MAX]),
    ):
        if chosen:
            excess = [abs(r.ripple["excess"]) for r in chosen]
            print(
                f"input-side worlds with the ripple share {name} {100 * RIPPLE_SHARE_MAX:.0f} %: {len(chosen)}, "
                f"current at hover off by median {100 * statistics.median(excess):.0f} %, worst "
                f"{100 * max(excess):.0f} %"
            )
    print(f"time per world: median {statistics.median(r.seconds for r in results):.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
