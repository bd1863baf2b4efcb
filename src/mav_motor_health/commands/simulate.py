"""``mav-motor-health simulate SCENARIO --out FILE``: a simulated flight or testbed run as a log file.

``--world SEED`` flies a randomised world (:mod:`..sim.worlds`): the scenario's plan and faults on that
world's vehicle; the scenario ``world`` is the world's own 150-s manoeuvre plan. The world's report is
printed and its truth written in the ``.truth.json`` sidecar (key ``world``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import Any

from ..agent.demo import parse_fault
from ..errors import ConfigError
from ..sim.engine import run_scenario
from ..sim.faults import FaultSpec
from ..sim.scenario import WORLD_SCENARIO_NAMES, load_scenario, world_scenario
from ..sim.writers import write_record
from ._common import non_negative_int, positive_float


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a scenario (TOML) and write .tlog, .bin or .csv with a ground-truth .truth.json",
        description="SCENARIO is a TOML file or a name under params/scenarios (e.g. testbed/F1.1_4.2V, "
        "flight/F4.1_moderate), or 'world' (a randomised world's own 150-s manoeuvre plan, with --world). "
        "The output format follows the extension of --out.",
    )
    p.add_argument("scenario", help="scenario TOML file, bundled name, or 'world'")
    p.add_argument("--out", required=True, metavar="FILE", help="output .tlog, .bin or .csv")
    p.add_argument(
        "--world",
        type=non_negative_int,
        default=None,
        metavar="SEED",
        help="fly the randomised world of SEED (its vehicle, motors, ESCs, telemetry); prints its report",
    )
    p.add_argument("--seed", type=int, default=None, help="override the scenario's (noise) seed")
    p.add_argument(
        "--duration", type=positive_float, default=None, metavar="S", help="override the duration [s]"
    )
    p.add_argument(
        "--fault",
        action="append",
        default=[],
        metavar="F@T:M",
        help="add a fault, e.g. F3.1@60:2 (F3.1 at 60 s on motor 2); repeatable",
    )
    p.add_argument("--force", action="store_true", help="replace existing output files")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.scenario in WORLD_SCENARIO_NAMES:
        if args.world is None:
            raise ConfigError(
                f"scenario {args.scenario!r} flies a randomised world", key="--world", expected="--world SEED"
            )
        scenario = world_scenario(args.world)
    else:
        scenario = load_scenario(args.scenario)
    changes: dict[str, Any] = {}
    if args.world is not None:
        if scenario.mode != "flight":
            raise ConfigError(
                f"scenario {scenario.name!r} is a testbed run", key="--world", expected="a flight scenario"
            )
        changes["world"] = args.world
    if args.seed is not None:
        changes["seed"] = args.seed
    if args.duration is not None:
        changes["duration_s"] = args.duration
    if args.fault:
        extra = []
        for text in args.fault:
            plan = parse_fault(text)
            if plan.motor > scenario.n_motors:
                raise ConfigError(
                    f"bad fault {text!r}", key="--fault", expected=f"a motor 1-{scenario.n_motors}"
                )
            extra.append(FaultSpec(plan.kind, plan.motor, plan.at_s))
        changes["faults"] = scenario.faults + tuple(extra)
    if changes:
        scenario = dataclasses.replace(scenario, **changes)
    start = time.monotonic()
    record = run_scenario(scenario)
    out, truth = write_record(record, args.out, force=args.force)
    if record.world is not None:
        print(record.world.report())
    print(
        f"{scenario.name}: {scenario.duration_s:.0f} s simulated in {time.monotonic() - start:.1f} s; "
        f"wrote {out} and {truth}"
    )
    return 0
