"""Arguments and data loading shared by the workbench subcommands (compare, explain, fit --with)."""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from ..config import load_motor_params
from ..model.effects.base import Effect
from ..model.effects.user import available_effects
from ..model.params import MotorParams
from ..telemetry.table import TelemetryTable
from ..workbench.data import WorkbenchData
from ._common import read_telemetry

__all__ = ["add_data_arguments", "effects_from_args", "params_from_args", "workbench_data"]


def add_data_arguments(p: argparse.ArgumentParser, *, several: bool = True) -> None:
    if several:
        p.add_argument(
            "data",
            nargs="+",
            help="telemetry file(s) the project reads (CSV, bench files, flight logs where supported); "
            "several files are joined one after the other",
        )
    p.add_argument("--motor", type=int, action="append", help="use only this motor (repeatable)")
    p.add_argument(
        "--effects-file",
        action="append",
        default=[],
        metavar="FILE",
        help="a Python file declaring user effects (EFFECTS = [Effect(...)]); repeatable. The file is RUN as "
        "Python with your rights: name only files you trust",
    )


def params_from_args(args: argparse.Namespace) -> MotorParams | None:
    return load_motor_params(args.params) if getattr(args, "params", None) else None


def effects_from_args(args: argparse.Namespace) -> dict[str, Effect]:
    return available_effects(args.effects_file)


def read_joined(paths: Sequence[str]) -> TelemetryTable:
    """Read every file and join them; later files' times are shifted to follow the earlier ones."""
    tables: list[TelemetryTable] = []
    offset = 0.0
    for path in paths:
        table = read_telemetry(path)
        t = np.asarray(table["time_s"], float)
        shift = offset - (np.nanmin(t) if len(t) else 0.0)
        tables.append(table.with_columns(time_s=t + shift, source_file=np.full(len(t), float(len(tables)))))
        if len(t):
            offset = float(np.nanmax(t) + shift) + 1.0
    if len(tables) == 1:
        only = tables[0]
        return TelemetryTable(
            {k: v for k, v in only.columns.items() if k != "source_file"}, only.source, only.meta
        )
    joined = TelemetryTable.concat(tables)
    return TelemetryTable(joined.columns, source=", ".join(paths), meta=joined.meta)


def workbench_data(args: argparse.Namespace) -> WorkbenchData:
    paths = args.data if isinstance(args.data, list) else [args.data]
    table = read_joined(paths)
    if args.motor:
        table = table.select(np.isin(table["motor"], args.motor))
    return WorkbenchData.from_table(table)
