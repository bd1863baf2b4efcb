"""PX4 ULog files (``.ulg``), decoded with numpy structured dtypes built from the log's own formats.

A ULog file is a 16-byte header and then messages ``[u16 size][u8 type][payload]``: formats (``F``),
info (``I``/``M``), parameters (``P``), subscriptions (``A``: topic + instance → id), data (``D``: id +
the topic's packed struct), log strings, syncs and dropouts. The message chain is walked once in Python
(one ``struct.unpack_from`` per message, no objects); the data messages of each topic used are then
gathered into one byte array and viewed through the topic's dtype (nested structs and arrays included).
A message that cannot be valid (unknown type, a data message whose id or size does not match) is a break:
the reader resynchronises on the next sync marker or plausible data message, and warns once.

Topics used: ``esc_status`` (per ESC rpm, voltage, current, temperature; ``actuator_function`` − 100 is
the motor where the log has it, else ESC ``i`` is motor ``i+1``), ``actuator_motors`` (throttle 0..1) or
else ``actuator_outputs`` / the ESC's raw setpoint, ``battery_status``, ``vehicle_local_position``,
``vehicle_air_data``, ``vehicle_status``. PX4's ``esc_rpm`` is mechanical. ESC temperatures above 150
are taken as kelvin (PX4's UAVCAN driver reports kelvin) and converted to °C.
"""

from __future__ import annotations

import struct
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import LogFormatError
from . import mavlink_esc
from ._logscan import Damage, gather_rows
from .assemble import EscSamples, Series, motor_table, no_esc_error
from .table import TelemetryTable

__all__ = ["ULog", "read_ulog", "read_ulog_topics"]

MAGIC = b"ULog\x01\x12\x35"
SYNC_MAGIC = bytes([0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12])
HEADER_SIZE = 16
USED_TOPICS = (
    "esc_status",
    "actuator_motors",
    "actuator_outputs",
    "battery_status",
    "vehicle_local_position",
    "vehicle_air_data",
    "vehicle_status",
)
KELVIN_THRESHOLD = 150.0
UAVCAN_RAW_MAX = 8191.0
ESC_CONNECTION_CAN = 4

_BASIC = {
    "int8_t": "i1",
    "uint8_t": "u1",
    "int16_t": "<i2",
    "uint16_t": "<u2",
    "int32_t": "<i4",
    "uint32_t": "<u4",
    "int64_t": "<i8",
    "uint64_t": "<u8",
    "float": "<f4",
    "double": "<f8",
    "bool": "u1",
    "char": "S1",
}
_KNOWN_TYPES = set(b"BFIMPQADLCSOR")


@dataclass
class ULog:
    """Decoded ULog: per topic name and instance (multi id), a structured array of its data messages and
    the byte offset of each message."""

    topics: dict[tuple[str, int], NDArray[Any]] = field(default_factory=dict)
    offsets: dict[tuple[str, int], NDArray[np.int64]] = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    start_timestamp_us: int = 0
    counts: dict[str, int] = field(default_factory=dict)
    damage: Damage = field(default_factory=Damage)

    def get(self, name: str, instance: int = 0) -> NDArray[Any] | None:
        arr = self.topics.get((name, instance))
        return arr if arr is not None and len(arr) else None

    def instances(self, name: str) -> list[int]:
        return sorted(i for n, i in self.topics if n == name and len(self.topics[(n, i)]))


def _parse_format(text: str) -> tuple[str, list[tuple[str, str, int]]]:
    name, _, body = text.partition(":")
    fields = []
    for item in body.split(";"):
        item = item.strip()
        if not item:
            continue
        type_part, _, field_name = item.rpartition(" ")
        count = 0
        if type_part.endswith("]"):
            type_part, _, n = type_part[:-1].partition("[")
            count = int(n)
        fields.append((type_part, field_name, count))
    return name, fields


class _Dtypes:
    def __init__(self, formats: dict[str, list[tuple[str, str, int]]]) -> None:
        self.formats = formats
        self.cache: dict[str, np.dtype] = {}

    def __call__(self, name: str, depth: int = 0) -> np.dtype:
        """The packed dtype of a format; a topic (depth 0) loses its trailing padding, as the logger
        does not write it."""
        key = f"{name}@{min(depth, 1)}"
        if key in self.cache:
            return self.cache[key]
        if depth > 10 or name not in self.formats:
            raise KeyError(name)
        fields = self.formats[name]
        if depth == 0 and fields and fields[-1][1].startswith("_padding"):
            fields = fields[:-1]
        parts: list[tuple[Any, ...]] = []
        for type_name, field_name, count in fields:
            base: Any = _BASIC.get(type_name)
            if base is None:
                base = self(type_name, depth + 1)
            if type_name == "char" and count:
                parts.append((field_name, f"S{count}"))
            elif count:
                parts.append((field_name, base, (count,)))
            else:
                parts.append((field_name, base))
        dtype = np.dtype(parts)
        self.cache[key] = dtype
        return dtype


def _value(type_name: str, raw: bytes) -> Any:
    base = type_name.partition("[")[0]
    if base == "char":
        return raw.split(b"\0", 1)[0].decode("utf-8", "replace")
    code = _BASIC.get(base)
    if code is None or np.dtype(code).itemsize > len(raw) or len(raw) % np.dtype(code).itemsize:
        return raw  # not a value of that type (a damaged message): kept as bytes, not a number
    values = np.frombuffer(raw, dtype=code)
    return values[0].item() if len(values) == 1 else values.tolist()


def read_ulog_topics(path: str | Path, topics: Iterable[str] = USED_TOPICS, *, warn: bool = True) -> ULog:
    """Decode the named topics (all instances), the parameters and the info messages of a ULog file."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise LogFormatError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    if len(raw) < HEADER_SIZE or not raw.startswith(MAGIC):
        raise LogFormatError("not a ULog file (the header 'ULog' magic is missing)", path=path, offset=0)
    data = np.frombuffer(raw, dtype=np.uint8)
    out = ULog(start_timestamp_us=struct.unpack_from("<Q", raw, 8)[0])
    wanted = set(topics)
    formats: dict[str, list[tuple[str, str, int]]] = {}
    subs: dict[int, tuple[str, int]] = {}
    sizes: dict[int, int | None] = {}  # msg id → expected D message size (2 + struct size); None: any
    dtypes = _Dtypes(formats)
    data_at: dict[int, list[int]] = {}
    size = len(raw)
    unpack_header = struct.Struct("<HB").unpack_from
    pos = HEADER_SIZE
    damage = out.damage

    def plausible(p: int) -> bool:
        if p + 3 > size:
            return False
        msg_size, msg_type = unpack_header(raw, p)
        if msg_type not in _KNOWN_TYPES or p + 3 + msg_size > size:
            return False
        if msg_type == ord("D"):
            msg_id = struct.unpack_from("<H", raw, p + 3)[0] if msg_size >= 2 else -1
            return msg_id in sizes and sizes[msg_id] in (None, msg_size)
        return msg_type != ord("S") or raw[p + 3 : p + 3 + len(SYNC_MAGIC)] == SYNC_MAGIC

    def described(p: int) -> bool:
        """A subscription, format, info or parameter message whose name reads as a name."""
        msg_size, msg_type = unpack_header(raw, p)
        body = raw[p + 3 : p + 3 + msg_size]
        if msg_type == ord("A"):
            name = body[3:]
        elif msg_type == ord("F"):
            name = body.partition(b":")[0]
        elif msg_type in (ord("I"), ord("P"), ord("Q")) and body:
            name = body[1 : 1 + body[0]]
            if b" " not in name:
                return False
            name = name.replace(b" ", b"").replace(b"[", b"").replace(b"]", b"")
        else:
            return False
        return 0 < len(name) <= 255 and name.replace(b"_", b"").isalnum() and name.isascii()

    def resync(p: int) -> int:
        """The next offset after ``p`` that starts three plausible messages in a row, one of them a data
        message of a subscribed topic with the right size (or that reaches the end of the file)."""
        for q in range(p + 1, size - 2):
            if raw[q + 2] not in _KNOWN_TYPES or not plausible(q):
                continue
            strong, named, r = False, 0, q
            for _ in range(3):
                if r >= size:
                    break
                if not plausible(r):
                    strong = False
                    break
                strong = strong or raw[r + 2] in (ord("D"), ord("S"))
                named += described(r)
                r = r + 3 + unpack_header(raw, r)[0]
            else:
                # three definitions, subscriptions or parameters with readable names: the definitions
                # section goes on (its subscriptions are what later data messages need)
                strong = strong or named == 3
            if strong:
                return q
        return size

    previous = HEADER_SIZE - 3  # start of the last message accepted
    current = HEADER_SIZE - 3  # start of the message being read, once accepted
    floor = HEADER_SIZE - 1  # a resynchronisation never goes back before the last one
    while pos + 3 <= size:
        previous, current = current, pos  # every path below accepts the message, except the last one
        msg_size, msg_type = unpack_header(raw, pos)
        end = pos + 3 + msg_size
        if end > size:
            damage.truncated_at = pos
            break
        if msg_type == 68:  # 'D'
            msg_id = raw[pos + 3] | (raw[pos + 4] << 8)
            expected = sizes.get(msg_id, -1)
            if expected == msg_size:
                data_at.setdefault(msg_id, []).append(pos + 5)
                pos = end
                continue
            if expected is None:  # a topic whose format this reader cannot lay out: skipped
                pos = end
                continue
        elif msg_type == 65:  # 'A'
            multi_id, msg_id = struct.unpack_from("<BH", raw, pos + 3)
            name = raw[pos + 6 : end].decode("ascii", "replace")
            try:
                sizes[msg_id] = 2 + dtypes(name).itemsize
            except (KeyError, ValueError, TypeError):
                sizes[msg_id] = None
            subs[msg_id] = (name, multi_id)
            pos = end
            continue
        elif msg_type == 70:  # 'F'
            try:
                fmt_name, fields = _parse_format(raw[pos + 3 : end].decode("ascii", "replace"))
                formats[fmt_name] = fields
            except ValueError:  # a damaged definition: its topic cannot be laid out and is skipped
                damage.add(pos, 0)
                damage.bad_records += 1
            dtypes.cache.clear()
            pos = end
            continue
        elif msg_type in (73, 80, 81):  # 'I' info, 'P' parameter, 'Q' default parameter
            if msg_size >= 1:
                key_len = raw[pos + 3]
                key = raw[pos + 4 : pos + 4 + key_len].decode("ascii", "replace")
                type_name, _, key_name = key.partition(" ")
                value = _value(type_name, raw[pos + 4 + key_len : end])
                if msg_type == 80 and isinstance(value, (int, float)):
                    out.params[key_name] = float(value)
                elif msg_type == 73:
                    out.info[key_name] = value
            pos = end
            continue
        elif msg_type in (66, 77, 76, 67, 79, 82) or (
            msg_type == 83 and raw[pos + 3 : pos + 3 + len(SYNC_MAGIC)] == SYNC_MAGIC
        ):  # 'B' 'M' 'L' 'C' 'O' 'R'
            pos = end
            continue
        # Not a valid message here: the log is damaged. The previous message's length may be what was
        # damaged, so resynchronise from just after the previous message's header.
        nxt = resync(max(previous + 2, floor))
        damage.add(min(pos, nxt), abs(nxt - pos))
        floor = nxt
        current = previous  # the message at pos was not accepted
        pos = nxt
    if pos < size and damage.truncated_at is None and size - pos >= 3:
        damage.truncated_at = pos
    for msg_id, offsets in data_at.items():
        name, multi_id = subs[msg_id]
        out.counts[name] = out.counts.get(name, 0) + len(offsets)
        if name not in wanted:
            continue
        dtype = dtypes(name)
        rows = gather_rows(data, np.asarray(offsets, dtype=np.int64), dtype.itemsize)
        out.topics[(name, multi_id)] = rows.view(dtype).ravel()
        out.offsets[(name, multi_id)] = np.asarray(offsets, dtype=np.int64) - 5
    if warn:
        damage.warn(path, "messages")
    return out


def _seconds(rec: NDArray[Any], origin_us: int) -> NDArray[np.float64]:
    return (rec["timestamp"].astype(np.int64) - origin_us) / 1e6


#: The fields this reader uses of each topic (besides ``timestamp``, which every topic needs). A topic whose
#: format definition was damaged into other names is skipped with a warning; esc_status is an error.
REQUIRED_FIELDS = {
    "esc_status": ("esc_count", "esc"),
    "battery_status": ("voltage_v", "current_a"),
    "actuator_motors": ("control",),
    "actuator_outputs": ("output",),
    "vehicle_local_position": ("z", "vz"),
}
ESC_REPORT_FIELDS = ("esc_rpm", "esc_current", "esc_voltage")


def _drop_damaged_topics(path: Path, log: ULog) -> None:
    """Topics whose format lacks the fields the reader uses (a damaged format definition)."""
    for key in list(log.topics):
        names = log.topics[key].dtype.names or ()
        missing = [f for f in ("timestamp", *REQUIRED_FIELDS.get(key[0], ())) if f not in names]
        if key[0] == "esc_status" and "esc" in names:
            inner = log.topics[key]["esc"].dtype.names or ()
            missing += [f"esc.{f}" for f in ESC_REPORT_FIELDS if f not in inner]
        if not missing:
            continue
        if key[0] == "esc_status":
            raise LogFormatError(
                f"the format definition of the esc_status topic is damaged: it lacks {', '.join(missing)}",
                path=path,
            )
        del log.topics[key]
        warnings.warn(
            f"{path}: the format definition of the {key[0]} topic is damaged (it lacks {', '.join(missing)}); "
            "that topic is skipped",
            stacklevel=3,
        )


def read_ulog(path: str | Path) -> TelemetryTable:
    """Read a PX4 ``.ulg`` into the telemetry table (one row per ESC report)."""
    path = Path(path)
    log = read_ulog_topics(path)
    _drop_damaged_topics(path, log)
    esc_status = log.get("esc_status")
    if esc_status is None:
        raise no_esc_error(path, "PX4 ULog (.ulg)", log.counts, "the esc_status topic")
    origin = log.start_timestamp_us
    t = _seconds(esc_status, origin)
    reports = esc_status["esc"]
    esc_count = esc_status["esc_count"].astype(np.int64)
    n_slots = reports.shape[1]
    report_fields = reports.dtype.names or ()
    parts: list[EscSamples] = []
    motor_of_slot: dict[int, int | None] = {}
    temps_all = reports["esc_temperature"].astype(float) if "esc_temperature" in report_fields else None
    kelvin = False
    if temps_all is not None:
        reported = temps_all[:, : max(int(esc_count.max()), 1)]
        kelvin = (
            bool(np.nanmedian(reported[reported != 0]) > KELVIN_THRESHOLD) if (reported != 0).any() else False
        )
    for j in range(n_slots):
        present = esc_count > j
        if not present.any():
            continue
        rep = reports[present, j]
        temp = temps_all[present, j] if temps_all is not None else None
        if temp is not None and kelvin:
            temp = temp - 273.15
        parts.append(
            EscSamples(
                t[present],
                np.full(int(present.sum()), j, dtype=np.int64),
                rep["esc_rpm"].astype(float) * mavlink_esc.RPM_TO_RAD_S,
                rep["esc_current"].astype(float),
                rep["esc_voltage"].astype(float),
                temp,
            )
        )
        function = int(rep["actuator_function"][-1]) if "actuator_function" in report_fields else 0
        motor_of_slot[j] = mavlink_esc.motor_for_px4_function(function, j)
    esc = EscSamples.concat(parts)
    commands: dict[int, Series] = {}
    throttle_source = "none"
    motors_topic = log.get("actuator_motors")
    if motors_topic is not None:
        tm = _seconds(motors_topic, origin)
        for motor in motor_of_slot.values():
            # actuator_motors.control[i] is Motor i+1 (not ESC slot i)
            if motor is not None and motor - 1 < motors_topic["control"].shape[1]:
                commands[motor] = (tm, np.clip(motors_topic["control"][:, motor - 1].astype(float), 0.0, 1.0))
        throttle_source = "actuator_motors"
    elif (
        "esc_setpoint_raw" in report_fields and (esc_status["esc_connectiontype"] == ESC_CONNECTION_CAN).all()
    ):
        for j, motor in motor_of_slot.items():
            if motor is None:
                continue
            present = esc_count > j
            high = float(log.params.get(f"UAVCAN_EC_MAX{j + 1}", UAVCAN_RAW_MAX) or UAVCAN_RAW_MAX)
            raw = reports[present, j]["esc_setpoint_raw"].astype(float)
            commands[motor] = (t[present], np.clip(raw / high, 0.0, 1.0))
        throttle_source = "esc_setpoint_raw (UAVCAN)"
    elif log.get("actuator_outputs") is not None:
        outputs = log.get("actuator_outputs")
        assert outputs is not None
        to = _seconds(outputs, origin)
        for motor in motor_of_slot.values():
            if motor is None:
                continue
            # the output whose PWM_MAIN_FUNCn is this motor's function (101 = Motor1), else output n = motor n
            n = next(
                (
                    k
                    for k in range(1, outputs["output"].shape[1] + 1)
                    if log.params.get(f"PWM_MAIN_FUNC{k}") == mavlink_esc.PX4_MOTOR_FUNCTION_FIRST + motor - 1
                ),
                motor,
            )
            if n > outputs["output"].shape[1]:
                continue
            low = float(log.params.get(f"PWM_MAIN_MIN{n}", log.params.get("PWM_MIN", 1000.0)))
            high = float(log.params.get(f"PWM_MAIN_MAX{n}", log.params.get("PWM_MAX", 2000.0)))
            commands[motor] = (to, mavlink_esc.throttle_from_pwm(outputs["output"][:, n - 1], low, high))
        throttle_source = "actuator_outputs[0] (PWM)"
    context: dict[str, Series] = {}
    battery: Series | None = None
    bat = log.get("battery_status")
    if bat is not None:
        tb = _seconds(bat, origin)
        battery = (tb, bat["voltage_v"].astype(float))
        context["battery_voltage_v"] = battery
        context["battery_current_a"] = (tb, bat["current_a"].astype(float))
    pos = log.get("vehicle_local_position")
    if pos is not None:
        tp = _seconds(pos, origin)
        context["alt_m"] = (tp, -pos["z"].astype(float))
        context["climb_m_s"] = (tp, -pos["vz"].astype(float))
    air = log.get("vehicle_air_data")
    if air is not None:
        names = air.dtype.names or ()
        temp_field = "ambient_temperature" if "ambient_temperature" in names else "baro_temp_celcius"
        if temp_field in names:
            context["air_temp_c"] = (_seconds(air, origin), air[temp_field].astype(float))
    status = log.get("vehicle_status")
    vehicle: dict[str, Any] = {
        k: log.info[k] for k in ("sys_name", "ver_hw", "ver_sw", "sys_os_name") if k in log.info
    }
    if status is not None and "arming_state" in (status.dtype.names or ()):
        context["armed"] = (_seconds(status, origin), (status["arming_state"] == 2).astype(float))
    for key in ("SYS_AUTOSTART", "MAV_TYPE", "CA_ROTOR_COUNT", "MOT_POLE_COUNT"):
        if key in log.params:
            vehicle[key.lower()] = log.params[key]
    rotors = int(log.params.get("CA_ROTOR_COUNT", 0) or 0)
    end_us = max(int(a["timestamp"].max()) for a in log.topics.values() if len(a))
    meta = {
        "format": "ulog",
        "params": dict(log.params),
        "vehicle": vehicle,
        "motors": list(range(1, rotors + 1)) if rotors else sorted({m for m in motor_of_slot.values() if m}),
        "message_counts": dict(log.counts),
        "esc_temperature_kelvin": kelvin,
        "throttle_source": throttle_source,
        "time_origin_boot_s": origin / 1e6,
        "duration_s": (end_us - origin) / 1e6,
        "damage": log.damage.to_dict(),
    }
    return motor_table(path, esc, motor_of_slot, commands, context, meta, battery)
