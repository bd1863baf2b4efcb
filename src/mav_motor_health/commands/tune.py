"""``mav-motor-health tune``: fit a flight profile on labelled flights and write it as TOML."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..config import dump_profile, load_motor_params, load_profile
from ..diagnosis.tuning import LabelledFlight, TuneResult, tune_profile
from ..errors import DataError
from ..evaluation.score import read_truth
from ._common import positive_int, read_telemetry, write_new_file

#: The standard training campaign: seeds used for tuning only (the benchmark tests on other seeds).
CAMPAIGN_SEED = 1000


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "tune",
        help="fit a flight profile (bands, stall split, persistence) on labelled flights",
        description="LOGS are telemetry files (CSV, .tlog, .bin, .ulg), each with a ground-truth JSON "
        "(the simulator's LOG.truth.json, or --truth in the same order). With --campaign, the project's "
        "standard training flights are simulated instead (3 turbulence levels x healthy + 5 faults).",
    )
    p.add_argument("logs", nargs="*", help="labelled telemetry files")
    p.add_argument("--truth", nargs="*", default=None, help="truth JSON per log (default: LOG.truth.json)")
    p.add_argument("--campaign", action="store_true", help="simulate the standard training campaign")
    p.add_argument("--params", default="paper_x2212", metavar="FILE", help="motor parameters TOML or name")
    p.add_argument(
        "--base",
        default="flight_base",
        metavar="P",
        help="profile whose rules are kept and whose numbers are tuned (default flight_base)",
    )
    p.add_argument("--name", default="flight", help="name of the tuned profile")
    p.add_argument("--out", metavar="FILE", help="write the tuned profile TOML here")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--jobs", type=positive_int, default=None, help="worker processes for --campaign")
    p.set_defaults(run=run)


#: length of the campaign's healthy flight per turbulence level [s]: long enough to meet the rare gust
#: that a few minutes of flight bring, which is what the hold times are tuned against
HEALTHY_S = 1800.0


def campaign_cases(seed: int = CAMPAIGN_SEED) -> list:
    """The standard training flights: per turbulence level one healthy flight (``HEALTHY_S``) and each
    fault (50 s, onset at 25 s)."""
    from ..evaluation.campaign import FAULTS, TURBULENCE_LEVELS, FlightCase

    cases = []
    for k, turbulence in enumerate(TURBULENCE_LEVELS):
        cases.append(FlightCase(turbulence, seed + k, HEALTHY_S))
        for j, fault in enumerate(FAULTS):
            cases.append(
                FlightCase(
                    turbulence,
                    seed + 100 + 10 * k + j,
                    50.0,
                    fault=fault,
                    motor=1 + (j + k) % 6,
                    onset_s=25.0,
                )
            )
    return cases


def labelled_logs(logs: list[str], truths: list[str] | None) -> list[LabelledFlight]:
    if truths is not None and truths and len(truths) != len(logs):
        raise DataError(f"{len(logs)} logs but {len(truths)} truth files: give one --truth per log")
    flights = []
    for k, log in enumerate(logs):
        truth_path = Path(truths[k]) if truths else Path(f"{log}.truth.json")
        if not truth_path.exists():
            raise DataError(
                "no ground truth for this log (expected LOG.truth.json or --truth)", path=truth_path
            )
        flights.append(LabelledFlight(read_telemetry(log), read_truth(truth_path), Path(log).name))
    return flights


def run(args: argparse.Namespace) -> int:
    if args.campaign:
        from ..evaluation.campaign import run_flights

        flights = run_flights(campaign_cases(), args.jobs)
        source = f"simulated training campaign (mav-motor-health tune --campaign), seeds from {CAMPAIGN_SEED}"
    elif args.logs:
        flights = labelled_logs(args.logs, args.truth)
        source = ", ".join(f.name for f in flights)
    else:
        raise DataError("nothing to tune on: give labelled LOGS or --campaign")
    result: TuneResult = tune_profile(
        flights, load_motor_params(args.params), load_profile(args.base), name=args.name
    )
    report = {k: v for k, v in result.report.items() if k != "flights"}
    text = dump_profile(
        result.profile,
        {
            "tuned_on": source,
            "flights": str(len(flights)),
            "healthy_steady_samples": str(result.report["healthy_steady_samples"]),
            "command": "mav-motor-health tune "
            + ("--campaign" if args.campaign else " ".join(args.logs))
            + f" --params {args.params} --base {args.base} --name {args.name}",
        },
    )
    if args.out:
        write_new_file(args.out, text, force=args.force)
        print(f"wrote {args.out}")
    else:
        print(text)
    print(json.dumps(report, indent=2, default=str))
    return 0
