"""``mav-motor-health diagnose DATA``: the state of every motor sample."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ..diagnosis.pipeline import DIAGNOSIS_COLUMNS, diagnose
from ..diagnosis.states import MotorState, state_names
from ..telemetry.table import TelemetryTable
from ._common import add_model_arguments, models_from_args, read_telemetry


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "diagnose",
        help="diagnose every sample of a telemetry file",
        description="Prints one CSV row per motor sample: raw tree state, announced state "
        "(after persistence), steady flag, measured and modelled speed and current.",
    )
    p.add_argument("data", help="telemetry file")
    add_model_arguments(p)
    p.add_argument("--summary", action="store_true", help="print only a per-motor summary")
    p.set_defaults(run=run)


def format_rows(result: TelemetryTable) -> list[str]:
    labels = {n: state_names(result[n]) for n in ("state", "announced")}
    lines = [",".join(DIAGNOSIS_COLUMNS)]
    cols = [labels[n] if n in labels else result[n] for n in DIAGNOSIS_COLUMNS]
    for row in zip(*cols):
        lines.append(
            ",".join(
                str(x)
                if isinstance(x, (str, np.str_))
                else (str(int(x)) if isinstance(x, (np.integer, np.bool_)) else f"{x:.6g}")
                for x in row
            )
        )
    return lines


def summarise(result: TelemetryTable) -> list[str]:
    lines = []
    for motor in result.motors():
        sel = result["motor"] == motor
        announced = result["announced"][sel]
        steady = result["steady"][sel]
        counts = np.bincount(result["state"][sel][steady].astype(np.int64), minlength=len(MotorState))
        share = ", ".join(
            f"{MotorState(c).label} {100 * n / max(steady.sum(), 1):.1f} %" for c, n in enumerate(counts) if n
        )
        lines.append(
            f"motor {motor}: final {MotorState(int(announced[-1])).label:8s} "
            f"steady samples {int(steady.sum())}/{int(sel.sum())}: {share or 'none'}"
        )
    return lines


def run(args: argparse.Namespace) -> int:
    params, profile = models_from_args(args)
    result = diagnose(read_telemetry(args.data), params, profile)
    lines = summarise(result) if args.summary else format_rows(result)
    sys.stdout.write("\n".join(lines) + "\n")
    return 0
