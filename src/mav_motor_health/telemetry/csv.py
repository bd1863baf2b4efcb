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


#: motor numbers a vehicle can have (ArduPilot and PX4 drive at most 32 outputs)
MAX_MOTOR = 32


def _text_lines(raw: bytes) -> tuple[list[tuple[int, list[str]]], list[tuple[int, int]]]:
    """(line number, cells) of every line that is UTF-8 text, and (line, byte offset) of those that are
    not: one bad byte loses its line, not the file."""
    offset = 3 if raw.startswith(b"\xef\xbb\xbf") else 0  # byte offsets count in the file
    raw = raw[offset:]
    good: list[tuple[int, list[str]]] = []
    bad: list[tuple[int, int]] = []
    for number, chunk in enumerate(raw.split(b"\n"), start=1):
        start = offset
        offset += len(chunk) + 1
        text = chunk[:-1] if chunk.endswith(b"\r") else chunk
        # each line on its own: a damaged quote or line end must not pull the next lines into this one
        junk = min((k for k in (text.find(b"\x00"), text.find(b"\r")) if k >= 0), default=-1)
        if junk >= 0:
            bad.append((number, start + junk))
            continue
        try:
            cells = next(_csv.reader([text.decode("utf-8")]), [])
        except UnicodeDecodeError as exc:
            bad.append((number, start + exc.start))
            continue
        except _csv.Error:
            bad.append((number, start))
            continue
        good.append((number, cells))
    return good, bad


def read_csv(path: str | Path) -> TelemetryTable:
    """Read a telemetry CSV into a :class:`TelemetryTable`.

    Damage costs the rows it touches, with one warning each kind naming the first line: a line that is
    not UTF-8 text (with its byte offset), a row with more or fewer cells than the header, a time that is
    not a finite number, a motor number that is not an integer 1..32, a negative speed.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise DataError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    lines, not_text = _text_lines(raw)
    rows = [(n, r) for n, r in lines if any(cell.strip() for cell in r)]
    if not_text:
        first_line, first_byte = not_text[0]
        if not rows:
            raise DataError(f"not a text CSV file (byte {first_byte} is not UTF-8 text)", path=path)
        _warn(
            path,
            f"{len(not_text)} line(s) are not UTF-8 text (first: line {first_line}, byte {first_byte}); "
            "skipped",
        )
    if not rows:
        raise DataError(
            "empty file; expected a header line such as 'time_s,motor,rpm,current_a,voltage_v'", path=path
        )
    header_line, header_cells = rows[0]
    header = [h.strip() for h in header_cells]
    where = f"line {header_line}"
    duplicates = {h for h in header if header.count(h) > 1}
    if duplicates:
        raise DataError(
            f"column(s) {', '.join(sorted(duplicates))} appear more than once", path=path, where=where
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
            where=where,
        )
    body, line_no, ragged = [], [], []
    for number, row in rows[1:]:
        if len(row) != len(header) and not (
            len(row) > len(header) and not any(c.strip() for c in row[len(header) :])
        ):
            ragged.append(number)
            continue
        body.append(row)
        line_no.append(number)
    if ragged:
        _warn(
            path,
            f"{len(ragged)} row(s) have another number of cells than the header's {len(header)} (first: "
            f"line {ragged[0]}); skipped",
        )
    lines_arr = np.asarray(line_no, dtype=np.int64)
    columns: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        if not name:
            continue
        values = np.full(len(body), np.nan)
        bad: list[int] = []
        for r, row in enumerate(body):
            cell = row[j].strip()
            if not cell:
                continue
            try:
                values[r] = float(cell)
            except ValueError:
                bad.append(r)
        if len(bad) == len(body) and body and name not in needed:
            continue  # a text column (a note, a label): not telemetry
        if bad:
            shown = ", ".join(str(int(lines_arr[r])) for r in bad[:5])
            _warn(
                path,
                f"column '{name}': {len(bad)} cell(s) are not numbers (line {shown}"
                f"{', ...' if len(bad) > 5 else ''}); read as missing",
            )
        columns[name] = values
    motor = columns.pop("motor")
    keep = np.ones(len(body), dtype=bool)
    checks = (
        (
            np.isfinite(motor) & (motor >= 1) & (motor <= MAX_MOTOR) & (motor == np.round(motor)),
            f"have no valid motor number (expected an integer 1..{MAX_MOTOR})",
        ),
        (np.isfinite(columns["time_s"]), "have no finite time_s"),
        (~(columns[speed] < 0), f"have a negative {speed} (a speed is >= 0)"),
    )
    for ok, reason in checks:
        wrong = keep & ~ok
        if wrong.any():
            first = int(lines_arr[np.flatnonzero(wrong)[0]])
            _warn(path, f"{int(wrong.sum())} row(s) {reason} (first: line {first}); those rows are skipped")
            keep &= ok
    if speed == "rpm":
        columns["omega_rad_s"] = columns.pop("rpm") * RPM_TO_RAD_S
    columns["motor"] = motor
    table = TelemetryTable({k: v[keep] for k, v in columns.items()}, source=str(path))
    return table.sorted_by_motor_time()


def _warn(path: Path, text: str) -> None:
    warnings.warn(f"{path}: {text}", stacklevel=3)


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
