"""ArduPilot DataFlash logs (``.bin``), parsed from their own FMT records with numpy.

A record is ``0xA3 0x95 <type>`` followed by the payload laid out as the ``FMT`` record for ``<type>``
says (FMT records may appear anywhere: ArduPilot writes them as message types first occur). Reading:

1. one numpy pass finds every ``A3 95`` pair; the ``FMT`` records (type 128) among them give each type's
   length, field names and format characters;
2. each candidate's length gives the next record; :func:`~._logscan.follow_chain` keeps the chain and
   resynchronises after damage (DataFlash has no checksum: a record counts as valid when it starts with
   the header, has a known type and is followed by another valid record);
3. the records of the types used are gathered into one byte array per type and viewed through a numpy
   structured dtype; scaled formats are scaled as pymavlink's DFReader does (``c C e E`` ×0.01, ``L`` ×1e-7).

Records used: ``ESC`` (RPM is mechanical: ArduPilot divides the ESC's eRPM by the pole pairs before
logging), ``RCOU`` (µs), ``BAT``, ``BARO``, ``CTUN``, ``POS``, ``PARM``, ``MSG``. ESC instance ``i`` is
servo output ``i+1``, so its motor follows from ``SERVO{i+1}_FUNCTION`` (see :mod:`.mavlink_esc`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import LogFormatError
from . import mavlink_esc
from ._logscan import Damage, follow_chain, gather_rows
from .assemble import EscSamples, Series, motor_table, no_esc_error
from .table import TelemetryTable

__all__ = ["DataflashLog", "read_dataflash", "read_dataflash_text", "read_records", "read_text_records"]

HEAD = (0xA3, 0x95)
FMT_TYPE = 128
FMT_LENGTH = 89
USED_RECORDS = ("ESC", "RCOU", "BAT", "BARO", "CTUN", "POS", "PARM", "MSG")

#: DataFlash format character → (numpy dtype, scale applied on reading), as pymavlink's DFReader.
FORMAT_CHARS: dict[str, tuple[str, float | None]] = {
    "a": ("(32,)<i2", None),
    "b": ("i1", None),
    "B": ("u1", None),
    "g": ("<f2", None),
    "h": ("<i2", None),
    "H": ("<u2", None),
    "i": ("<i4", None),
    "I": ("<u4", None),
    "f": ("<f4", None),
    "d": ("<f8", None),
    "n": ("S4", None),
    "N": ("S16", None),
    "Z": ("S64", None),
    "c": ("<i2", 0.01),
    "C": ("<u2", 0.01),
    "e": ("<i4", 0.01),
    "E": ("<u4", 0.01),
    "L": ("<i4", 1.0e-7),
    "M": ("i1", None),
    "q": ("<i8", None),
    "Q": ("<u8", None),
}


@dataclass(frozen=True)
class RecordFormat:
    """One FMT record: the layout of a message type."""

    type: int
    name: str
    length: int  # including the 3 header bytes
    format: str
    columns: tuple[str, ...]

    def dtype(self) -> np.dtype | None:
        """The payload's numpy dtype, or None when the FMT is inconsistent (a damaged FMT record)."""
        if len(self.format) != len(self.columns) or any(c not in FORMAT_CHARS for c in self.format):
            return None
        names = [c or f"field{i}" for i, c in enumerate(self.columns)]
        if len(set(names)) != len(names):
            return None
        dtype = np.dtype([(n, FORMAT_CHARS[c][0]) for n, c in zip(names, self.format)])
        return dtype if dtype.itemsize == self.length - 3 else None


@dataclass
class DataflashLog:
    """Decoded records of a DataFlash log: per type name, a dict of column arrays (scaled as DFReader),
    and the byte offset of every record."""

    records: dict[str, dict[str, NDArray[Any]]] = field(default_factory=dict)
    formats: dict[str, RecordFormat] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    offsets: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    damage: Damage = field(default_factory=Damage)

    def __contains__(self, name: object) -> bool:
        return name in self.records and len(next(iter(self.records[str(name)].values()), ())) > 0

    def __getitem__(self, name: str) -> dict[str, NDArray[Any]]:
        return self.records[name]


#: format characters of integer fields (a damaged text cell there cannot stand as NaN)
_INTEGER_CHARS = "bBhHiIqQMLc"


def _text(raw: object) -> str:
    if isinstance(raw, str):
        return raw
    if isinstance(raw, bytes):
        return raw.split(b"\0", 1)[0].decode("ascii", "replace")
    return ""  # a string field whose format character was damaged into a number's


def _time_us(rec: dict[str, NDArray[Any]]) -> NDArray[np.int64] | None:
    """A record type's timestamps [µs]: ``TimeUS``, or ``TimeMS`` in old logs; None if it has neither."""
    if "TimeUS" in rec:
        return np.asarray(rec["TimeUS"]).astype(np.int64)
    if "TimeMS" in rec:
        return (np.asarray(rec["TimeMS"], dtype=float) * 1000).astype(np.int64)
    return None


def _scan_formats(data: NDArray[np.uint8], heads: NDArray[np.int64]) -> dict[int, RecordFormat]:
    """Every FMT record in the file (the first consistent one wins per type)."""
    fmt_at = heads[(data[heads + 2] == FMT_TYPE) & (heads + FMT_LENGTH <= len(data))]
    formats: dict[int, RecordFormat] = {
        FMT_TYPE: RecordFormat(
            FMT_TYPE, "FMT", FMT_LENGTH, "BBnNZ", ("Type", "Length", "Name", "Format", "Columns")
        )
    }
    if len(fmt_at) == 0:
        return formats
    rows = gather_rows(data, fmt_at + 3, FMT_LENGTH - 3)
    recs = rows.view(
        np.dtype([("Type", "u1"), ("Length", "u1"), ("Name", "S4"), ("Format", "S16"), ("Columns", "S64")])
    ).ravel()
    seen: set[tuple[int, int, bytes, bytes, bytes]] = set()
    for r in recs.tolist():
        if r in seen:
            continue
        seen.add(r)
        ftype, length, name, fmt, cols = r
        try:
            candidate = RecordFormat(
                int(ftype),
                name.split(b"\0", 1)[0].decode("ascii"),
                int(length),
                fmt.split(b"\0", 1)[0].decode("ascii"),
                tuple(cols.split(b"\0", 1)[0].decode("ascii").split(",")),
            )
        except UnicodeDecodeError:
            continue  # a damaged FMT record (or A3 95 80 inside a payload)
        if ftype == FMT_TYPE or candidate.dtype() is None or not candidate.name.isidentifier():
            continue
        formats.setdefault(int(ftype), candidate)
    return formats


def read_records(path: str | Path, names: Iterable[str] = USED_RECORDS, *, warn: bool = True) -> DataflashLog:
    """Decode the named record types of a DataFlash log, in file order."""
    path = Path(path)
    try:
        mapped = np.memmap(path, dtype=np.uint8, mode="r") if path.stat().st_size else np.zeros(0, np.uint8)
    except (OSError, ValueError) as exc:
        raise LogFormatError(f"cannot read: {exc}", path=path) from exc
    data: NDArray[np.uint8] = mapped.view(np.ndarray)
    size = len(data)
    out = DataflashLog()
    if size < 3:
        raise LogFormatError("empty or too short for a DataFlash log", path=path, offset=0)
    heads = np.flatnonzero(data[:-2] == HEAD[0]).astype(np.int64)
    heads = heads[data[heads + 1] == HEAD[1]]
    formats = _scan_formats(data, heads)
    lengths = np.zeros(256, dtype=np.int64)
    for ftype, fmt in formats.items():
        lengths[ftype] = fmt.length
    types = data[heads + 2]
    rec_len = lengths[types]
    heads, types, rec_len = heads[rec_len > 0], types[rec_len > 0], rec_len[rec_len > 0]
    if len(heads) == 0:
        raise LogFormatError(
            "no DataFlash record found (no A3 95 header with a known FMT)", path=path, offset=0
        )
    next_start = heads + rec_len
    # A resynchronisation point: a header whose next two successors are headers too (or the file's end),
    # found for every candidate at once.
    k = np.minimum(np.searchsorted(heads, next_start), len(heads) - 1)
    succ = np.where(heads[k] == next_start, k, -1)
    at_end = next_start >= size - 2
    fits_end = next_start <= size
    s1 = np.maximum(succ, 0)
    second = np.where(at_end[s1], fits_end[s1], succ[s1] >= 0)
    accepted = np.where(at_end, fits_end, (succ >= 0) & second).tolist()

    def accept(k: int) -> bool:
        return accepted[k]

    first = 0
    while first < len(heads) and heads[first] != 0 and not accept(first):
        first += 1
    chain = follow_chain(heads, next_start, size, accept, out.damage, first=first, tail_slack=2)
    chain_types = types[chain]
    by_name = {fmt.name: fmt for fmt in formats.values()}
    out.formats = by_name
    type_counts = np.bincount(chain_types, minlength=256)
    for ftype in np.flatnonzero(type_counts).tolist():
        if ftype in formats:
            out.counts[formats[ftype].name] = int(type_counts[ftype])
    for name in names:
        found = by_name.get(name)
        if found is None:
            continue
        fmt = found
        dtype = fmt.dtype()
        assert dtype is not None
        at = heads[chain[chain_types == fmt.type]]
        recs = gather_rows(data, at + 3, fmt.length - 3).view(dtype).ravel()
        columns: dict[str, NDArray[Any]] = {}
        for col, char in zip(dtype.names or (), fmt.format):
            scale = FORMAT_CHARS[char][1]
            values = recs[col]
            # Divide by 1/scale as DFReader does (more accurate than multiplying by 0.01 or 1e-7).
            columns[col] = values / (1.0 / scale) if scale is not None else values.copy()
        out.records[name] = columns
        out.offsets[name] = at
    if warn:
        out.damage.warn(path, "records")
    del data, mapped
    return out


def _first_instance(rec: dict[str, NDArray[Any]], key: str) -> NDArray[np.bool_]:
    if key not in rec:
        return np.ones(len(rec["TimeUS"]), dtype=bool)
    inst = rec[key]
    return inst == (inst.min() if len(inst) else 0)


def read_dataflash(path: str | Path) -> TelemetryTable:
    """Read a ``.bin`` DataFlash log into the telemetry table (one row per ESC record)."""
    path = Path(path)
    return _dataflash_table(path, read_records(path), "ArduPilot DataFlash (.bin)")


#: The fields this reader uses of each record type. A FMT record damaged into other field names loses its
#: type (a warning says which); ESC records without them cannot be read at all (a clear error).
REQUIRED_FIELDS = {
    "ESC": ("Instance", "RPM", "Curr", "Volt", "Temp"),
    "PARM": ("Name", "Value"),
    "BAT": ("Volt", "Curr"),
    "MSG": ("Message",),
    "POS": ("RelHomeAlt",),
}


def _drop_damaged_types(path: Path, log: DataflashLog) -> None:
    """Record types whose format lacks the fields the reader uses (a damaged FMT record)."""
    for name, needed in REQUIRED_FIELDS.items():
        if name not in log.records:
            continue
        missing = [f for f in needed if f not in log.records[name]]
        if _time_us(log.records[name]) is None and log.records[name]:
            missing.append("TimeUS")
        if not missing:
            continue
        if name == "ESC":
            raise LogFormatError(
                f"the format (FMT record) of the ESC records is damaged: it lacks the field(s) "
                f"{', '.join(missing)}; expected {', '.join(needed)}",
                path=path,
            )
        del log.records[name]
        warnings.warn(
            f"{path}: the format (FMT record) of the {name} records is damaged: it lacks the field(s) "
            f"{', '.join(missing)}; those records are skipped",
            stacklevel=3,
        )


def _dataflash_table(path: Path, log: DataflashLog, kind: str) -> TelemetryTable:
    """The telemetry table from decoded DataFlash records (binary or text)."""
    _drop_damaged_types(path, log)
    if "ESC" not in log or _time_us(log["ESC"]) is None:
        raise no_esc_error(path, kind, log.counts, "ESC records: set LOG_BITMASK to log ESC telemetry")
    times = [_time_us(log[n]) for n in ("ESC", "RCOU", "BAT", "PARM") if n in log]
    origin_us = int(min(int(stamps.min()) for stamps in times if stamps is not None and len(stamps)))

    def seconds(rec: dict[str, NDArray[Any]]) -> NDArray[np.float64]:
        t = _time_us(rec)
        assert t is not None
        return (t - origin_us) / 1e6

    params: dict[str, float] = {}
    if "PARM" in log:
        for name, value in zip(log["PARM"]["Name"].tolist(), log["PARM"]["Value"].tolist()):
            try:
                number = float(value)
            except (TypeError, ValueError):
                continue  # a value damaged into text: that parameter is not known
            if math.isfinite(number) and _text(name):
                params[_text(name)] = number
    esc = log["ESC"]
    temp = esc["Temp"].astype(float)
    samples = EscSamples(
        seconds(esc),
        esc["Instance"].astype(np.int64),
        esc["RPM"].astype(float) * mavlink_esc.RPM_TO_RAD_S,
        esc["Curr"].astype(float),
        esc["Volt"].astype(float),
        temp,
        esc["MotTemp"].astype(float) if "MotTemp" in esc else None,
    )
    slots = sorted(set(samples.slot.tolist()))
    motor_of_slot = {s: mavlink_esc.motor_for_output(s + 1, params) for s in slots}
    commands: dict[int, Series] = {}
    if "RCOU" in log and _time_us(log["RCOU"]) is not None:
        rec = log["RCOU"]
        t = seconds(rec)
        low, high = mavlink_esc.pwm_range(params)
        for output in range(1, 17):
            motor = mavlink_esc.motor_for_output(output, params)
            if motor is None or motor in commands or f"C{output}" not in rec:
                continue
            commands[motor] = (t, mavlink_esc.throttle_from_pwm(rec[f"C{output}"].astype(float), low, high))
    context: dict[str, Series] = {}
    battery: Series | None = None
    if "BAT" in log and _time_us(log["BAT"]) is not None:
        rec = log["BAT"]
        sel = _first_instance(rec, "Inst" if "Inst" in rec else "Instance")
        t = seconds(rec)[sel]
        battery = (t, rec["Volt"][sel].astype(float))
        context["battery_voltage_v"] = battery
        context["battery_current_a"] = (t, rec["Curr"][sel].astype(float))
    if "CTUN" in log and _time_us(log["CTUN"]) is not None and "Alt" in log["CTUN"]:
        rec = log["CTUN"]
        context["alt_m"] = (seconds(rec), rec["Alt"].astype(float))
        if "CRt" in rec:
            context["climb_m_s"] = (seconds(rec), rec["CRt"].astype(float) / 100.0)  # cm/s in CTUN
    elif "POS" in log and _time_us(log["POS"]) is not None:
        rec = log["POS"]
        context["alt_m"] = (seconds(rec), rec["RelHomeAlt"].astype(float))
    if "BARO" in log and _time_us(log["BARO"]) is not None and "Temp" in log["BARO"]:
        rec = log["BARO"]
        sel = _first_instance(rec, "I")
        context["air_temp_c"] = (seconds(rec)[sel], rec["Temp"][sel].astype(float))
        if "climb_m_s" not in context and "CRt" in rec:
            context["climb_m_s"] = (seconds(rec)[sel], rec["CRt"][sel].astype(float))
    vehicle_info: dict[str, Any] = {}
    if "MSG" in log:
        texts = [_text(m) for m in log["MSG"]["Message"].tolist()]
        firmware = next((m for m in texts if m.startswith(("Ardu", "Copter", "APM", "PX4"))), None)
        if firmware:
            vehicle_info["firmware"] = firmware
        vehicle_info["messages"] = texts[:50]
    for key in ("FRAME_CLASS", "FRAME_TYPE"):
        if key in params:
            vehicle_info[key.lower()] = int(params[key])
    ends = [_time_us(log[n]) for n in log.records]
    end_us = max(int(stamps.max()) for stamps in ends if stamps is not None and len(stamps))
    meta = {
        "format": "dataflash" if kind.endswith("(.bin)") else "dataflash-text",
        "params": params,
        "vehicle": vehicle_info,
        "motors": mavlink_esc.expected_motors(params) or sorted({m for m in motor_of_slot.values() if m}),
        "record_counts": dict(log.counts),
        "time_origin_boot_s": origin_us / 1e6,
        "duration_s": (end_us - origin_us) / 1e6,
        "damage": log.damage.to_dict(),
        "pwm_range_us": list(mavlink_esc.pwm_range(params)),
    }
    return motor_table(path, samples, motor_of_slot, commands, context, meta, battery)


def read_text_records(
    path: str | Path, names: Iterable[str] = USED_RECORDS, *, warn: bool = True
) -> DataflashLog:
    """Decode a DataFlash *text* log (``.log``: ``NAME, value, value...`` lines after ``FMT`` lines).

    Values in text logs are already scaled. Lines that are not records (a banner) are skipped; a record
    with the wrong number of fields or a non-numeric value is skipped as damage (one warning naming the
    first line).
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="ascii", errors="replace").splitlines()
    except OSError as exc:
        raise LogFormatError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    out = DataflashLog()
    wanted = set(names)
    rows: dict[str, list[list[str]]] = {}
    bad_lines: list[int] = []
    for number, line in enumerate(lines, start=1):
        parts = [p.strip() for p in line.split(",")]
        if len(parts) < 2:
            continue
        name = parts[0]
        if name == "FMT" and len(parts) >= 5:
            try:
                ftype, length = int(parts[1]), int(parts[2])
            except ValueError:
                bad_lines.append(number)
                continue
            column_names = tuple(c for c in parts[5:] if c)
            out.formats[parts[3]] = RecordFormat(ftype, parts[3], length, parts[4], column_names)
            continue
        fmt = out.formats.get(name)
        if fmt is None:
            continue  # a banner line ("ArduCopter V3.1", "Free RAM: ...")
        out.counts[name] = out.counts.get(name, 0) + 1
        if name not in wanted:
            continue
        values = parts[1:]
        if len(values) != len(fmt.columns):
            bad_lines.append(number)
            out.counts[name] -= 1
            continue
        rows.setdefault(name, []).append(values)
    for name, records in rows.items():
        fmt = out.formats[name]
        columns: dict[str, NDArray[Any]] = {}
        unreadable = np.zeros(len(records), dtype=bool)
        for k, (column, char) in enumerate(zip(fmt.columns, fmt.format)):
            cells = [r[k] for r in records]
            if char in "nNZ":
                columns[column] = np.array(cells, dtype=object)
                continue
            numbers = np.full(len(cells), np.nan)
            for i, cell in enumerate(cells):
                try:
                    numbers[i] = float(cell)
                except ValueError:
                    unreadable[i] = True
            if char in _INTEGER_CHARS:  # an instance, a time stamp, a PWM: a damaged one is no number at all
                unreadable |= ~np.isfinite(numbers)
            columns[column] = numbers
        # a record with a value that is not a number is damage: it goes whole, not as a NaN in one field
        if unreadable.any():
            bad_lines.extend([-1] * int(unreadable.sum()))
            out.counts[name] -= int(unreadable.sum())
            columns = {column: values[~unreadable] for column, values in columns.items()}
        out.records[name] = columns
    if bad_lines:
        first = min(n for n in bad_lines if n > 0) if any(n > 0 for n in bad_lines) else 0
        out.damage.bad_records = len(bad_lines)
        if warn:
            warnings.warn(
                f"{path}: damaged text log at line {first} ({len(bad_lines)} record(s) or value(s) "
                "unreadable, skipped); the rest was read",
                stacklevel=2,
            )
    if not out.formats:
        raise LogFormatError("no FMT line found: not an ArduPilot DataFlash text log", path=path, offset=0)
    return out


def read_dataflash_text(path: str | Path) -> TelemetryTable:
    """Read a DataFlash text log (``.log``) into the telemetry table, as :func:`read_dataflash` does."""
    path = Path(path)
    return _dataflash_table(path, read_text_records(path), "ArduPilot DataFlash text (.log)")
