"""``mav-motor-health replay LOG... [--profile P] [--params FILE] [--out DIR] [--force] [--jobs N]
[--calibrate START:END]``."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from ..config import (
    DEFAULT_MOTOR,
    FALLBACK_PROFILE,
    VEHICLE_PROFILE,
    check_profile_for_vehicle,
    default_profile,
    load_profile,
    load_vehicle_params,
)
from ..replay import ReplayResult, collect_logs, print_verdicts, replay_log, replay_many
from ._common import positive_int


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="replay flight logs (.tlog .bin .ulg .csv) through the diagnosis",
        description="Reads ArduPilot .tlog/.bin, PX4 .ulg or the project's CSV and writes diagnosis.csv, "
        "events.jsonl and report.html. One log: straight into DIR. Several logs or a folder: one "
        "folder per log in DIR, replayed in parallel, plus fleet_summary.csv/.json.",
    )
    p.add_argument("logs", nargs="+", metavar="LOG", help="log files or folders (searched recursively)")
    p.add_argument(
        "--params",
        default=None,
        metavar="FILE",
        help="the vehicle: a params TOML written by `fit LOG --out` (motor, ESC map, current reading, "
        f"per-motor models), a motor TOML, or a name in params/motors (default {DEFAULT_MOTOR})",
    )
    p.add_argument(
        "--profile",
        default=None,
        metavar="P",
        help="threshold profile: flight_vehicle, flight, testbed or a TOML file (default: "
        f"{VEHICLE_PROFILE} for a vehicle file written by fit, which carries the vehicle's noise; else "
        f"{FALLBACK_PROFILE})",
    )
    p.add_argument("--out", default="replay", metavar="DIR", help="output folder (default ./replay)")
    p.add_argument("--force", action="store_true", help="replace the files of an existing output folder")
    p.add_argument(
        "--jobs", type=positive_int, default=None, metavar="N", help="worker processes (default: CPU count)"
    )
    p.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="map the logs over a dask.distributed cluster (scheduler address, e.g. tcp://host:8786) instead "
        "of local processes; the logs and --out must be at the same paths on every worker. Needs the "
        "'fleet' extra",
    )
    p.add_argument(
        "--calibrate",
        type=_window,
        default=None,
        metavar="START:END",
        help="fit the motor model on this healthy stretch of each log first (seconds on the log's time "
        "axis, e.g. a hover before anything happened)",
    )
    p.set_defaults(run=run)


def _window(text: str) -> tuple[float, float]:
    try:
        start, end = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected START:END in seconds, got {text!r}") from None
    if not end > start:
        raise argparse.ArgumentTypeError(f"END must be after START, got {text!r}")
    return start, end


def run(args: argparse.Namespace) -> int:
    vehicle = load_vehicle_params(args.params or DEFAULT_MOTOR)
    profile = load_profile(args.profile or default_profile(vehicle))
    check_profile_for_vehicle(profile, vehicle)
    if args.params and profile.steady.kind == "balance":
        for missing in vehicle.missing_for_flight():  # said once for the run, not once per log
            warnings.warn(
                f"{args.params}: no {missing}; identify the vehicle with `fit LOG --out vehicle.toml`",
                stacklevel=1,
            )
    params = vehicle
    logs = collect_logs(args.logs)
    if len(logs) == 1 and not any(Path(a).is_dir() for a in args.logs) and not args.dask:
        result = replay_log(
            logs[0],
            args.out,
            params,
            profile,
            force=args.force,
            progress=sys.stderr,
            calibrate_s=args.calibrate,
        )
        print_verdicts(result)
        return 0

    def show(result: ReplayResult) -> None:
        for note in result.warnings:
            warnings.warn(note, stacklevel=1)
        if result.error:
            sys.stderr.write(f"\nmav-motor-health replay: error: {result.error}\n")

    fleet = replay_many(
        logs,
        args.out,
        params,
        profile,
        force=args.force,
        jobs=args.jobs,
        progress=sys.stderr,
        on_result=show,
        calibrate_s=args.calibrate,
        dask_scheduler=args.dask,
    )
    for result in fleet.results:
        if not result.error:
            print_verdicts(result)
    print(
        f"fleet summary: {args.out}/fleet_summary.csv ({len(fleet.results)} logs, {len(fleet.failed)} failed)"
    )
    return 1 if fleet.failed else 0
