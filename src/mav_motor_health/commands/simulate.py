"""``mav-motor-health simulate SCENARIO --out FILE``: a simulated flight or testbed run as a log file."""

from __future__ import annotations

import argparse
import dataclasses
import time

from ..sim.engine import run_scenario
from ..sim.scenario import load_scenario
from ..sim.writers import write_record
from ._common import positive_float


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a scenario (TOML) and write .tlog, .bin or .csv with a ground-truth .truth.json",
        description="SCENARIO is a TOML file or a name under params/scenarios (e.g. testbed/F1.1_4.2V, "
        "flight/F4.1_moderate). The output format follows the extension of --out.",
    )
    p.add_argument("scenario", help="scenario TOML file or bundled name")
    p.add_argument("--out", required=True, metavar="FILE", help="output .tlog, .bin or .csv")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument(
        "--duration", type=positive_float, default=None, metavar="S", help="override the duration [s]"
    )
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.scenario)
    changes = {}
    if args.seed is not None:
        changes["seed"] = args.seed
    if args.duration is not None:
        changes["duration_s"] = args.duration
    if changes:
        scenario = dataclasses.replace(scenario, **changes)
    start = time.monotonic()
    record = run_scenario(scenario)
    out, truth = write_record(record, args.out, force=args.force)
    print(
        f"{scenario.name}: {scenario.duration_s:.0f} s simulated in {time.monotonic() - start:.1f} s; "
        f"wrote {out} and {truth}"
    )
    return 0
