"""CSV telemetry: the project's plain-text table.

Columns: ``time_s``, ``motor`` (1-based), ``rpm`` (mechanical) or ``omega_rad_s``, ``current_a``, and
either ``voltage_v`` (voltage applied to the motor) or ``bus_voltage_v`` + ``throttle`` (0..1). Any other
numeric column is carried along as context. Cells that are empty or not numbers become NaN, with one
warning naming the file, the column and the first rows concerned; the rest of the file is used.
"""

from __future__ import annotations

import csv as _csv
import math
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from ..errors import DataError
from .table import TelemetryTable

__all__ = ["read_csv", "write_csv"]

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


def read_csv(path: str | Path) -> TelemetryTable:
    """Read a telemetry CSV into a :class:`TelemetryTable`."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = list(_csv.reader(handle))
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    except UnicodeDecodeError as exc:
        raise DataError(f"not a text CSV file (byte {exc.start} is not UTF-8)", path=path) from exc
    if not rows:
        raise DataError(
            "empty file; expected a header line such as 'time_s,motor,rpm,current_a,voltage_v'", path=path
        )
    header = [h.strip() for h in rows[0]]
    body = [r for r in rows[1:] if any(cell.strip() for cell in r)]
    duplicates = {h for h in header if header.count(h) > 1}
    if duplicates:
        raise DataError(
            f"column(s) {', '.join(sorted(duplicates))} appear more than once", path=path, where="line 1"
        )
    speed = "omega_rad_s" if "omega_rad_s" in header else "rpm"
    needed = ["time_s", "motor", speed, "current_a"]
    missing = [c for c in needed if c not in header]
    has_voltage = "voltage_v" in header or ("bus_voltage_v" in header and "throttle" in header)
    if missing or not has_voltage:
        what = missing + ([] if has_voltage else ["voltage_v (or bus_voltage_v and throttle)"])
        raise DataError(
            f"missing column(s): {', '.join(what)}; the header has {', '.join(header)}",
            path=path,
            where="line 1",
        )
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        if not name:
            continue
        values = np.full(len(body), np.nan)
        bad: list[int] = []
        for r, row in enumerate(body):
            cell = row[j].strip() if j < len(row) else ""
            if not cell:
                continue
            try:
                values[r] = float(cell)
            except ValueError:
                bad.append(r)
        if len(bad) == len(body) and body and name not in needed:
            continue  # a text column (a note, a label): not telemetry
        if bad:
            lines = ", ".join(str(_line_of(rows, body, r)) for r in bad[:5])
            warnings.warn(
                f"{path}: column '{name}': {len(bad)} cell(s) are not numbers (line {lines}"
                f"{', ...' if len(bad) > 5 else ''}); read as missing",
                stacklevel=2,
            )
        columns[name] = values
    motor = columns.pop("motor")
    good_motor = np.isfinite(motor) & (motor >= 1) & (motor == np.round(motor))
    if not good_motor.all():
        first = int(np.flatnonzero(~good_motor)[0])
        warnings.warn(
            f"{path}: {int((~good_motor).sum())} row(s) have no valid motor number (first at line "
            f"{_line_of(rows, body, first)}; expected an integer >= 1); those rows are skipped",
            stacklevel=2,
        )
    if speed == "rpm":
        columns["omega_rad_s"] = columns.pop("rpm") * RPM_TO_RAD_S
    columns["motor"] = motor
    table = TelemetryTable({k: v[good_motor] for k, v in columns.items()}, source=str(path))
    return table.sorted_by_motor_time()


def _line_of(rows: list[list[str]], body: list[list[str]], index: int) -> int:
    """1-based line number of a body row (blank lines were dropped from ``body``)."""
    target = body[index]
    seen = -1
    for line, row in enumerate(rows[1:], start=2):
        if any(cell.strip() for cell in row):
            seen += 1
            if seen == index and row is target:
                return line
    return index + 2


def write_csv(table: TelemetryTable, path: str | Path, columns: Iterable[str] | None = None) -> Path:
    """Write a table as CSV (``motor`` and state codes as integers, floats with full precision)."""
    path = Path(path)
    names = list(columns) if columns is not None else table.names
    arrays = [table[n].astype(np.int64) if table[n].dtype == bool else table[n] for n in names]
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = _csv.writer(handle)
        writer.writerow(names)
        for row in zip(*(a.tolist() for a in arrays)):
            writer.writerow(
                [
                    "" if isinstance(x, float) and math.isnan(x) else (repr(x) if isinstance(x, float) else x)
                    for x in row
                ]
            )
    return path
