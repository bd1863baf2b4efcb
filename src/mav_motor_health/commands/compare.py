"""``mav-motor-health compare DATA``: the model against the measurements, and where it fails."""

from __future__ import annotations

import argparse
import json

from ..workbench.compare import compare
from ._workbench import add_data_arguments, effects_from_args, params_from_args, workbench_data


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "compare",
        help="compare the motor model with measurements: errors, noise floor, where it fails",
        description="Error statistics of speed and current (forward prediction from voltage, and eqs. 9 "
        "and 10 on their own), the noise floor estimated from the data, and the voltage bins, time spans "
        "and conditions where the error exceeds it.",
    )
    add_data_arguments(p)
    p.add_argument(
        "--params", metavar="FILE", help="motor TOML or bundled name (default: fit the base model to DATA)"
    )
    p.add_argument("--plot-dir", metavar="DIR", help="write PNG plots into this folder")
    p.add_argument("--force", action="store_true", help="write into a non-empty --plot-dir")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    data = workbench_data(args)
    result = compare(data, params_from_args(args), registry=effects_from_args(args))
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=True))
    else:
        print(result.report())
    if args.plot_dir:
        from ..workbench.plots import plot_comparison

        paths = plot_comparison(result, args.plot_dir, force=args.force)
        if not args.json:
            print("\nplots: " + ", ".join(str(p) for p in paths))
    return 0
