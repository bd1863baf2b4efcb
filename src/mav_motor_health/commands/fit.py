"""``mav-motor-health fit DATA``: estimate the motor model (two-step Levenberg–Marquardt)."""

from __future__ import annotations

import argparse
import json

from ..config import dump_motor_params
from ..model.estimation import DEFAULT_BIN_WIDTH_V, FitResult, estimate
from ..telemetry.table import TelemetryTable
from ._common import read_telemetry, write_new_file


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="estimate the motor model from steady-state telemetry",
        description="Two-step Levenberg-Marquardt estimate of R, k_e (eq. 9) and C_p, B, T_f, "
        "k (eq. 10) from measured voltage, current and speed.",
    )
    p.add_argument("data", help="telemetry file (CSV; flight logs where supported)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--out", metavar="FILE", help="write the fitted motor as a params TOML")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--motor", type=int, action="append", help="use only this motor (repeatable)")
    p.add_argument("--k", type=float, help="fix the propeller exponent instead of choosing it")
    p.add_argument("--fit-k", action="store_true", help="fit k as a real number")
    p.add_argument(
        "--bin-width",
        type=float,
        default=DEFAULT_BIN_WIDTH_V,
        metavar="V",
        help=f"operating-point bin width of input voltage (default {DEFAULT_BIN_WIDTH_V} V)",
    )
    p.set_defaults(run=run)


def fit_table(
    table: TelemetryTable,
    *,
    motors: list[int] | None = None,
    k: float | None = None,
    fit_k: bool = False,
    bin_width_v: float = DEFAULT_BIN_WIDTH_V,
    name: str = "fitted motor",
) -> FitResult:
    """Fit the model to a telemetry table (optionally only some motors)."""
    if motors:
        import numpy as np

        table = table.select(np.isin(table["motor"], motors))
    return estimate(
        table.voltage_v(),
        table["current_a"],
        table["omega_rad_s"],
        k=k,
        fit_k=fit_k,
        bin_width_v=bin_width_v,
        name=name,
    )


def run(args: argparse.Namespace) -> int:
    table = read_telemetry(args.data)
    result = fit_table(
        table,
        motors=args.motor,
        k=args.k,
        fit_k=args.fit_k,
        bin_width_v=args.bin_width,
        name=f"fitted from {args.data}",
    )
    if args.json:
        print(json.dumps(result.to_dict(), indent=2, allow_nan=True))
    else:
        print(result.report())
    if args.out:
        source = {
            "fitted_from": str(args.data),
            "operating_points": str(len(result.points)),
            "accuracy_current_pct": f"{result.mechanical.accuracy_pct:.3f}",
        }
        path = write_new_file(args.out, dump_motor_params(result.params, source), force=args.force)
        if not args.json:
            print(f"wrote {path}")
    return 0
