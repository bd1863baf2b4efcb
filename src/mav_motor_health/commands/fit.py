"""``mav-motor-health fit DATA``: estimate the motor model (two-step Levenberg–Marquardt)."""

from __future__ import annotations

import argparse
import json
from functools import partial
from pathlib import Path

from ..config import dump_motor_params
from ..errors import DataError, FitError
from ..model.estimation import DEFAULT_BIN_WIDTH_V, FitResult, estimate, estimate_with_esc
from ..telemetry.table import TelemetryTable
from ._common import read_telemetry, write_new_file


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="estimate the motor model from steady-state telemetry",
        description="Two-step Levenberg-Marquardt estimate of R, k_e (eq. 9) and C_p, B, T_f, "
        "k (eq. 10) from measured voltage, current and speed.",
    )
    p.add_argument(
        "data",
        nargs="+",
        help="a test stand's steady steps (CSV, bench file), or one or more healthy flight logs of one vehicle "
        "(.tlog, .bin, .log, .ulg, or a flight CSV): those are identified as a vehicle (motor, ESC map, "
        "current reading, inertia) from every sample",
    )
    p.add_argument(
        "--mode",
        choices=("auto", "flight", "bench"),
        default="auto",
        help="flight: identify a vehicle from flight logs; bench: the two-step fit of steady points; auto "
        "(default): flight for log formats and for a CSV with command, bus voltage and several motors",
    )
    p.add_argument(
        "--prior",
        metavar="FILE",
        help="flight mode: a motor params TOML (a bench fit, a bundled motor) for what the flight cannot "
        "determine (default: a weak prior from the flight itself)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--out", metavar="FILE", help="write the fitted motor as a params TOML")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--motor", type=int, action="append", help="use only this motor (repeatable)")
    p.add_argument(
        "--esc-map",
        action="store_true",
        help="bench mode: fit the ESC's idle offset and current side too, for files that give the ESC command "
        "and the battery voltage (not the motor's voltage); see docs/model.md for what test-stand data allow",
    )
    p.add_argument("--k", type=float, help="fix the propeller exponent instead of choosing it")
    p.add_argument("--fit-k", action="store_true", help="fit k as a real number")
    p.add_argument(
        "--bin-width",
        type=float,
        default=DEFAULT_BIN_WIDTH_V,
        metavar="V",
        help=f"operating-point bin width of input voltage (default {DEFAULT_BIN_WIDTH_V} V)",
    )
    p.add_argument(
        "--with",
        dest="with_effects",
        metavar="EFFECT[,EFFECT...]",
        help="add these effects one by one and show the error after each (see `explain`)",
    )
    p.add_argument(
        "--effects-file",
        action="append",
        default=[],
        metavar="FILE",
        help="a Python file declaring user effects for --with (repeatable). The file is RUN as Python with "
        "your rights: name only files you trust",
    )
    p.add_argument("--plot", metavar="FILE", help="with --with: plot the error after each step (PNG)")
    p.set_defaults(run=run)


def fit_table(
    table: TelemetryTable,
    *,
    motors: list[int] | None = None,
    k: float | None = None,
    fit_k: bool = False,
    bin_width_v: float = DEFAULT_BIN_WIDTH_V,
    name: str = "fitted motor",
    esc_map: bool = False,
) -> FitResult:
    """Fit the model to a telemetry table (optionally only some motors).

    With ``esc_map``, a table with the ESC's command and bus voltage but no motor voltage (a test stand's
    file) is fitted through the ESC map (:func:`estimate_with_esc`: idle offset, current side); otherwise,
    and for a table with the motor voltage, by :func:`estimate` (the command taken as the duty). The map is
    opt-in: a test stand's few steps rarely determine the idle offset (docs/model.md, "The ESC map in the
    bench fit"), and on the CTU tables it made the fit worse."""
    import numpy as np

    if motors:
        table = table.select(np.isin(table["motor"], motors))
    direct = table.get("voltage_v")
    through_esc = (
        esc_map
        and (direct is None or not np.isfinite(direct).any())
        and "throttle" in table
        and "bus_voltage_v" in table
        and bool(np.isfinite(table["throttle"] * table["bus_voltage_v"]).any())
    )
    if through_esc:
        fit = partial(estimate_with_esc, table["throttle"], table["bus_voltage_v"])
    else:
        fit = partial(estimate, table.voltage_v())
    arrays = (table["current_a"], table["omega_rad_s"])
    try:
        return fit(*arrays, k=k, fit_k=fit_k, bin_width_v=bin_width_v, name=name)
    except FitError:
        # Bench files hold one sample per throttle step: each sample is its own operating point.
        return fit(*arrays, k=k, fit_k=fit_k, bin_width_v=bin_width_v, name=name, min_samples=1)


def run(args: argparse.Namespace) -> int:
    logs = list(args.data)
    if args.mode == "flight" or (args.mode == "auto" and _looks_like_flight(logs[0])):
        return run_flight(args, logs)
    if len(logs) > 1:
        raise DataError(
            f"the bench fit takes one file, got {len(logs)}; give one file, or --mode flight for flight logs"
        )
    args.data = logs[0]
    for target in (args.out, args.plot):
        if target and Path(target).exists() and not args.force:  # fail before the work, not after
            raise DataError("exists already; not overwritten (use --force to replace it)", path=target)
    table = read_telemetry(args.data)
    result = fit_table(
        table,
        motors=args.motor,
        k=args.k,
        fit_k=args.fit_k,
        bin_width_v=args.bin_width,
        name=f"fitted from {args.data}",
        esc_map=args.esc_map,
    )
    params = result.params
    steps = None
    if args.with_effects:
        from ..model.effects.user import available_effects
        from ..workbench.data import WorkbenchData
        from ..workbench.steps import fit_with_effects

        if args.motor:
            import numpy as np

            table = table.select(np.isin(table["motor"], args.motor))
        names = [n.strip() for n in args.with_effects.split(",") if n.strip()]
        steps = fit_with_effects(
            WorkbenchData.from_table(table), names, registry=available_effects(args.effects_file), base=result
        )
        if steps.final is not None:
            params = steps.final.params
    if args.json:
        out = result.to_dict()
        if steps is not None:
            out["with_effects"] = steps.to_dict()
        print(json.dumps(out, indent=2, allow_nan=True))
    else:
        print(result.report())
        if steps is not None:
            print()
            print(steps.report())
    if steps is not None and args.plot:
        from ..workbench.plots import plot_steps

        path = plot_steps(steps, args.plot, force=args.force)
        if not args.json:
            print(f"wrote {path}")
    if args.out:
        source = {
            "fitted_from": str(args.data),
            "operating_points": str(len(result.points)),
            "accuracy_current_pct": f"{result.mechanical.accuracy_pct:.3f}",
        }
        if result.esc is not None:  # the test stand's ESC, as provenance: not a map for flight logs
            source["bench_esc_idle_offset"] = f"{result.esc.esc.idle_offset:.5f}"
            source["bench_current_side"] = result.esc.current_side
        if steps is not None and steps.final is not None:
            source["effects"] = ", ".join(steps.final.effects)
            source["rmse_omega_rad_s"] = f"{steps.final.rmse_omega_rad_s:.4g}"
            source["rmse_current_a"] = f"{steps.final.rmse_current_a:.4g}"
        path = write_new_file(args.out, dump_motor_params(params, source), force=args.force)
        if not args.json:
            print(f"wrote {path}")
    return 0


def _looks_like_flight(path: str) -> bool:
    from ..identification import FLIGHT_LOG_SUFFIXES, is_flight_table

    suffix = Path(path).suffix.lower()
    return suffix in FLIGHT_LOG_SUFFIXES or is_flight_table(read_telemetry(path), suffix)


def run_flight(args: argparse.Namespace, logs: list[str]) -> int:
    """Identify the vehicle from its flight logs; print the report; write the vehicle file with --out."""
    from ..config import dump_vehicle_params
    from ..identification import identify_logs

    if args.with_effects or args.motor or args.fit_k:
        raise DataError("--with, --motor and --fit-k belong to the bench fit (--mode bench)")
    result = identify_logs(logs, prior=args.prior, k=args.k)
    if args.json:
        f = result.found
        print(
            json.dumps(
                {
                    "params": result.vehicle.motor.to_dict(),
                    "esc": {"idle_offset": f.esc.idle_offset},
                    "current": {
                        "side": f.current.side,
                        "gain": f.current.gain,
                        "gain_from": f.current.gain_from,
                    },
                    "stderr": dict(f.stderr),
                    "determined_by": dict(f.determined_by),
                    "k_bic": {str(k): v for k, v in f.k_bic.items()},
                    "deviations": {str(m): dict(d) for m, d in f.deviations.items()},
                    "noise": {str(m): dict(d) for m, d in f.noise.items()},
                    "findings": list(f.findings),
                    "logs": list(result.logs),
                },
                indent=2,
                allow_nan=True,
            )
        )
    else:
        print(result.report())
    if args.out:
        path = write_new_file(args.out, dump_vehicle_params(result.vehicle), force=args.force)
        if not args.json:
            print(f"wrote {path}: replay LOG --params {path}  (or the agent's [model] params)")
    return 0
