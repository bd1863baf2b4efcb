"""``mav-motor-health explain DATA``: which physical effect is missing from the model."""

from __future__ import annotations

import argparse
import json

from ..workbench.explain import explain
from ._workbench import add_data_arguments, effects_from_args, params_from_args, workbench_data


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "explain",
        help="rank the variables and library effects that explain the model's residual",
        description="Ranks the measured variables the residual depends on beyond voltage (distance "
        "correlation with a permutation threshold), then tries each effect of the library (and user "
        "effects), refits, and ranks them by held-out error; says so when nothing explains the residual.",
    )
    add_data_arguments(p)
    p.add_argument(
        "--params", metavar="FILE", help="motor TOML or bundled name (default: fit the base model to DATA)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the permutation test (default 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object: effects, variables, verdict")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    data = workbench_data(args)
    result = explain(data, params_from_args(args), effects=effects_from_args(args), seed=args.seed)
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=True))
    else:
        print(result.report())
    return 0
