"""Diagnosis on randomised worlds nothing was tuned on (issue 17, leave-worlds-out): each world identified
from one healthy flight as ``fit LOG --out vehicle.toml`` does, its fault and healthy flights replayed as
``replay LOG --params vehicle.toml --profile flight`` does and scored.

    PYTHONPATH=src python benchmarks/bench_flight_worlds.py --jobs 2              # the issue's measurement
    PYTHONPATH=src python benchmarks/bench_flight_worlds.py --count 10 --duration-s 60 --healthy-flights 2
    PYTHONPATH=src python benchmarks/bench_flight_worlds.py --vehicle truth       # the world's true vehicle

The default worlds are 1000-1019, held out: nothing (profile, identification) was developed or tuned on
them; worlds 0-19 are the development worlds (``--first 0`` to look at those). Per world
(:func:`mav_motor_health.evaluation.worlds.evaluate_world`): one healthy 150-s identification flight of the
world's own manoeuvre plan and turbulence, written as a log of ``--format`` (.tlog: ESC_TELEMETRY at the
world's rate, at most 50 Hz, commands at 10-50 Hz) and identified (no prior); then at each turbulence
level (calm, moderate, gusty) one ``--duration-s`` flight per fault (F1.1, F2.1, F3.1, F4.1, F4.2 at the
paper's strength scaled to the world's motor, on a drawn motor at a drawn onset at 40-70 % of the flight)
and ``--healthy-flights`` healthy ones, other noise seeds than the identification flight's, written in the
same format, replayed with the identified vehicle file and the profile, and scored
(``evaluation/score.py``).

Printed: per world its identification (k_e error, idle-offset error, current side true/found) and per
level the accuracy after onset of each fault (the faulty motor's judged samples after onset diagnosed as
the true fault; "-" no judged sample, counted as 0 %), the detection delay (onset to the first announcement
of the true fault; "never"), the healthy motors' judged samples NORMAL, the share of healthy samples judged
and the false events of the healthy flights; then over the worlds the median world and the worst decile
(10th percentile of accuracies and shares, 90th of delays; with fewer than 10 worlds the worst decile lies
between the two worst), beside the accuracy the share of the faulty motor's judged samples that are the
fault or the speed-only state covering it (SLOW for F1.1/F4.1, STALLED for F2.1/F4.2, FAST for F3.1:
noticed but not named where the current is not trusted), false events per flight hour over all healthy flight hours, and how many worlds
identification refused (counted apart, not scored). The issue's goals are printed beside them.

The defaults (20 worlds, 150-s flights, 8 healthy flights per level: 20 healthy flight hours) take hours
of CPU; ``--count``, ``--duration-s`` and ``--healthy-flights`` make a smaller run.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.evaluation.campaign import FAULTS, TURBULENCE_LEVELS  # noqa: E402
from mav_motor_health.evaluation.worlds import (  # noqa: E402
    FORMATS,
    VEHICLE_SOURCES,
    WorldEvaluation,
    WorldsSummary,
    evaluate_world,
    summarise,
)

#: the issue's goals: accuracy after onset per level, median world and worst decile [%]
GOAL_ACCURACY_MEDIAN = {"calm": 99.0, "moderate": 98.0, "gusty": 95.0}
GOAL_ACCURACY_WORST = {"calm": 97.0, "moderate": 95.0, "gusty": 90.0}
GOAL_DETECTION_S = 0.3  # median
GOAL_NORMAL_PCT = 99.5
GOAL_FALSE_PER_100_H = 1.0
GOAL_JUDGED_PCT = 80.0  # calm and moderate
GOAL_HEALTHY_HOURS = 20.0


def one_world(
    seed: int,
    duration_s: float,
    healthy_flights: int,
    profile: str,
    fmt: str,
    identification_s: float,
    vehicle_from: str,
    healthy_only: bool = False,
) -> WorldEvaluation:
    started = time.monotonic()
    try:
        return evaluate_world(
            seed,
            duration_s=duration_s,
            healthy_flights=healthy_flights,
            profile=profile,
            fmt=fmt,
            identification_s=identification_s,
            vehicle_from=vehicle_from,
            **({"faults": ()} if healthy_only else {}),
        )
    except Exception as exc:  # a benchmark reports every world, a failure too
        return WorldEvaluation(
            seed, "", error=f"{type(exc).__name__}: {exc}", seconds=time.monotonic() - started
        )


def _pct(x: float | None, width: int = 6) -> str:
    if x is None:
        return f"{'-':>{width}}"
    return f"{x:>{width}.1f}" if math.isfinite(x) else f"{'nan':>{width}}"


def _secs(x: float | None, width: int = 6) -> str:
    if x is None or math.isnan(x):
        return f"{'-':>{width}}"
    return f"{'never':>{width}}" if math.isinf(x) else f"{x:>{width}.2f}"


def print_world(e: WorldEvaluation) -> None:
    if e.error:
        print(f"world {e.world}: FAILED ({e.error})")
        return
    if e.refused:
        print(f"world {e.world} ({e.description}): REFUSED by identification: {e.refused}")
        return
    ident = e.identified
    if "k_e_error" in ident:
        how = (
            f"identified: k_e {100 * ident['k_e_error']:+.1f} %, idle offset "
            f"{ident['idle_offset_error']:+.3f}, current side (true/found) {ident['current_side']}"
        )
    else:
        how = "the world's true vehicle"
    print(
        f"world {e.world} ({e.description}); {how}; {e.fault_flight_false_events()} false events on the "
        f"fault flights' healthy motors{_states(e.fault_flight_false_events_by_state())}; {e.seconds:.0f} s"
    )
    for level in TURBULENCE_LEVELS:
        acc = " ".join(_pct(e.accuracy(level, f), 5) for f in FAULTS)
        det = " ".join(_secs(e.detection(level, f), 5) for f in FAULTS)
        print(
            f"  {level:8s} acc % {acc} | det s {det} | NORMAL {_pct(e.normal_share(level))} % "
            f"judged {_pct(e.judged_share(level))} % | false {e.false_events(level)} "
            f"in {60 * e.healthy_hours(level):.0f} min{_states(e.false_events_by_state(level))}"
        )
        noticed = [e.noticed(level, f) for f in FAULTS]
        if noticed != [e.accuracy(level, f) for f in FAULTS]:  # a speed-only state named some of them
            print(f"  {'':8s} or its speed-only state % {' '.join(_pct(n, 5) for n in noticed)}")


def _states(counts: dict[str, int]) -> str:
    return " (" + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + ")" if counts else ""


def print_summary(s: WorldsSummary, faults: bool = True) -> None:
    print(
        f"\nOver {s.evaluated} worlds evaluated ({len(s.refused)} refused by identification"
        + (f": {', '.join(map(str, s.refused))}" if s.refused else "")
        + (f"; {len(s.failed)} failed: {', '.join(map(str, s.failed))}" if s.failed else "")
        + f"; {s.worlds} drawn)"
    )
    if not s.evaluated:
        return
    if faults:
        print_faults(s)
    print_healthy(s)


def print_faults(s: WorldsSummary) -> None:
    print(
        "\n                 accuracy after onset [%]          detection [s]     fault or its speed-only"
        "\n                 median / worst decile (goal)      median / 90th     state [%]: median / worst"
    )
    for level in TURBULENCE_LEVELS:
        for fault in FAULTS:
            med, worst = s.accuracy[level, fault]
            dmed, dworst = s.detection[level, fault]
            nmed, nworst = s.noticed[level, fault]
            unjudged = s.unjudged[level, fault]
            print(
                f"  {level:8s} {fault:5s} {_pct(med)} / {_pct(worst)}  "
                f"(>= {GOAL_ACCURACY_MEDIAN[level]:g} / {GOAL_ACCURACY_WORST[level]:g})"
                f"  {_secs(dmed)} / {_secs(dworst)}    {_pct(nmed)} / {_pct(nworst)}"
                + (f"   [{unjudged} world(s) judged nothing after onset]" if unjudged else "")
            )
    dmed, dworst = s.detection_all
    print(
        f"  detection over every fault flight: median {_secs(dmed).strip()} s, 90th percentile "
        f"{_secs(dworst).strip()} s (goal: median <= {GOAL_DETECTION_S} s)"
    )


def print_healthy(s: WorldsSummary) -> None:
    print("\nhealthy motors' judged samples NORMAL / healthy samples judged [%]: median world / worst decile")
    for level in TURBULENCE_LEVELS:
        nmed, nworst = s.normal[level]
        jmed, jworst = s.judged[level]
        goal = f"(>= {GOAL_JUDGED_PCT:g})" if level in ("calm", "moderate") else ""
        print(
            f"  {level:8s} NORMAL {_pct(nmed)} / {_pct(nworst)} (>= {GOAL_NORMAL_PCT:g})   "
            f"judged {_pct(jmed)} / {_pct(jworst)} {goal}"
        )
    hours = sum(s.healthy_hours.values())
    print("\nfalse fault events in the healthy flights")
    for level in TURBULENCE_LEVELS:
        h = s.healthy_hours[level]
        rate = s.false_events[level] / h if h > 0 else math.nan
        print(f"  {level:8s} {s.false_events[level]:4d} in {h:6.2f} h ({rate:.1f} per flight hour)")
    print(
        f"  all      {sum(s.false_events.values()):4d} in {hours:6.2f} h: "
        f"{100 * s.false_events_per_hour:.1f} per 100 flight hours (goal <= {GOAL_FALSE_PER_100_H:g}, "
        f"over >= {GOAL_HEALTHY_HOURS:g} healthy hours)"
    )
    if s.false_events_by_state:
        print("  by state announced: " + ", ".join(f"{k} {v}" for k, v in s.false_events_by_state.items()))
    print(
        f"  (and {s.fault_flight_false_events} on healthy motors of the fault flights, or before onset"
        f"{_states(dict(s.fault_flight_false_events_by_state))})"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000, help="first world seed (default 1000: held out)")
    parser.add_argument("--count", type=int, default=20, help="how many worlds (default 20)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes, one world each (default 1)")
    parser.add_argument("--duration-s", type=float, default=150.0, help="test flight length [s] (150)")
    parser.add_argument(
        "--healthy-flights", type=int, default=8, help="healthy flights per turbulence level per world (8)"
    )
    parser.add_argument("--profile", default="flight", help="profile name or TOML (default flight)")
    parser.add_argument("--format", choices=FORMATS, default="tlog", help="log format (default tlog)")
    parser.add_argument(
        "--identification-s", type=float, default=150.0, help="identification flight length [s] (150)"
    )
    parser.add_argument(
        "--vehicle",
        choices=VEHICLE_SOURCES,
        default="fit",
        help="fit: identified from the healthy flight (default); truth: the world's true vehicle",
    )
    parser.add_argument(
        "--healthy-only", action="store_true", help="no fault flights: false events and judged share only"
    )
    args = parser.parse_args(argv)
    if args.count < 1 or args.jobs < 1 or args.duration_s <= 0 or args.healthy_flights < 0:
        parser.error("--count and --jobs must be >= 1, --duration-s > 0, --healthy-flights >= 0")
    started = time.monotonic()
    seeds = list(range(args.first, args.first + args.count))
    rest = (
        args.duration_s,
        args.healthy_flights,
        args.profile,
        args.format,
        args.identification_s,
        args.vehicle,
        args.healthy_only,
    )
    results: list[WorldEvaluation] = []
    if args.jobs == 1:
        for seed in seeds:
            results.append(one_world(seed, *rest))
            print(f"world {seed} done ({len(results)}/{len(seeds)})", file=sys.stderr, flush=True)
    else:
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            futures = [pool.submit(one_world, seed, *rest) for seed in seeds]
            for future in as_completed(futures):
                results.append(future.result())
                print(
                    f"world {results[-1].world} done ({len(results)}/{len(seeds)})",
                    file=sys.stderr,
                    flush=True,
                )
    results.sort(key=lambda e: e.world)
    vehicle = "identified by fit from" if args.vehicle == "fit" else "the true vehicle; no"
    print(
        f"worlds {seeds[0]}-{seeds[-1]}: {vehicle} one {args.identification_s:g}-s healthy flight; per "
        f"turbulence level {0 if args.healthy_only else 5} fault flights and {args.healthy_flights} healthy of {args.duration_s:g} s, "
        f"as .{args.format}, profile {args.profile}\n"
        f"columns: accuracy after onset and detection per fault ({', '.join(FAULTS)})\n"
    )
    for e in results:
        print_world(e)
    print_summary(summarise(results), faults=not args.healthy_only)
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
