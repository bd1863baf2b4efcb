"""MAVLink telemetry logs (``.tlog``): what a ground station recorded, decoded with numpy.

A ``.tlog`` is a sequence of records ``[8-byte big-endian µs UNIX time][MAVLink 1 or 2 frame]``. Reading:

1. every ``0xFE``/``0xFD`` byte is a candidate frame start; its header gives the frame length and so the
   next record (:func:`~._logscan.follow_chain` keeps the chain, resynchronising after damage);
2. the frames of the messages the diagnosis uses are checked with their CRC (X.25 with the message's
   CRC_EXTRA from pymavlink's ``ardupilotmega`` dialect tables), vectorised over all frames at once;
3. their payloads are gathered into one byte array per message (MAVLink 2's truncated trailing zeros
   padded back) and viewed through a numpy structured dtype built from the same dialect tables.

Messages used: ``ESC_TELEMETRY_1_TO_4``/``5_TO_8``/``9_TO_12`` (ArduPilot) or ``ESC_STATUS`` (PX4),
``SERVO_OUTPUT_RAW``, ``SYS_STATUS``/``BATTERY_STATUS``, ``VFR_HUD``/``GLOBAL_POSITION_INT``,
``SCALED_PRESSURE``, ``HEARTBEAT`` and ``PARAM_VALUE``. The ESC, servo, battery and parameter messages
become motor samples through :mod:`.mavlink_messages`, the reading the live agent uses, given the whole
log's arrays at once. Times are the tlog's own record times, in seconds from the first record.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import distinct
from ..errors import DataError, LogFormatError
from . import mavlink_esc
from ._logscan import Damage, crc_x25_rows, follow_chain, gather_rows, zero_past
from .assemble import EscSamples, Series, motor_table, no_esc_error
from .mavlink_messages import READ_MESSAGES, MessageReader, Messages
from .table import TelemetryTable

__all__ = ["TlogMessages", "read_messages", "read_tlog"]

#: Messages the reader decodes.
USED_MESSAGES = (
    "ESC_TELEMETRY_1_TO_4",
    "ESC_TELEMETRY_5_TO_8",
    "ESC_TELEMETRY_9_TO_12",
    "ESC_STATUS",
    "SERVO_OUTPUT_RAW",
    "SYS_STATUS",
    "BATTERY_STATUS",
    "VFR_HUD",
    "GLOBAL_POSITION_INT",
    "SCALED_PRESSURE",
    "HEARTBEAT",
    "PARAM_VALUE",
)
MAV_TYPE_GCS = 6
MAV_MODE_FLAG_SAFETY_ARMED = 128

_STRUCT_TO_NUMPY = {
    "b": "i1",
    "B": "u1",
    "h": "<i2",
    "H": "<u2",
    "i": "<i4",
    "I": "<u4",
    "q": "<i8",
    "Q": "<u8",
    "f": "<f4",
    "d": "<f8",
    "c": "S1",
}


@dataclass(frozen=True)
class _MessageSpec:
    msgid: int
    name: str
    crc_extra: int
    dtype: np.dtype


@lru_cache(maxsize=1)
def _dialect() -> tuple[dict[int, _MessageSpec], dict[str, _MessageSpec]]:
    """Message layouts and CRC_EXTRA from pymavlink's ardupilotmega dialect (plus PX4's ESC_STATUS)."""
    from pymavlink.dialects.v20 import ardupilotmega

    by_id: dict[int, _MessageSpec] = {}
    for msgid, cls in ardupilotmega.mavlink_map.items():
        names = list(cls.ordered_fieldnames)
        tokens = re.findall(r"(\d*)([a-zA-Z])", cls.unpacker.format)
        fields: list[tuple[Any, ...]] = []
        for name, (count, code) in zip(names, tokens):
            n = int(count) if count else 1
            if code == "s":
                fields.append((name, f"S{n}"))
            elif n > 1:
                fields.append((name, _STRUCT_TO_NUMPY[code], (n,)))
            else:
                fields.append((name, _STRUCT_TO_NUMPY[code]))
        dtype = np.dtype(fields)
        if dtype.itemsize != cls.unpacker.size:  # pragma: no cover - a dialect we do not understand
            continue
        by_id[msgid] = _MessageSpec(msgid, cls.msgname, cls.crc_extra, dtype)
    if 291 not in by_id:
        # ESC_STATUS (common.xml, newer than some pymavlink releases): PX4's per-ESC speed/voltage/current.
        by_id[291] = _MessageSpec(
            291,
            "ESC_STATUS",
            10,
            np.dtype(
                [
                    ("time_usec", "<u8"),
                    ("rpm", "<i4", (4,)),
                    ("voltage", "<f4", (4,)),
                    ("current", "<f4", (4,)),
                    ("index", "u1"),
                ]
            ),
        )
    by_name = {spec.name: spec for spec in by_id.values()}
    return by_id, by_name


@dataclass
class TlogMessages:
    """Decoded messages of a tlog: per message name, a structured array of its payloads.

    ``time_us``/``sysid``/``compid`` hold each message's record time and sender, ``offsets`` the byte offset
    of its record (timestamp included); ``counts`` the number of
    frames per message name in the whole log; ``damage`` where the log was broken.
    """

    messages: dict[str, NDArray[Any]] = field(default_factory=dict)
    time_us: dict[str, NDArray[np.uint64]] = field(default_factory=dict)
    sysid: dict[str, NDArray[np.uint8]] = field(default_factory=dict)
    compid: dict[str, NDArray[np.uint8]] = field(default_factory=dict)
    offsets: dict[str, NDArray[np.int64]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    first_time_us: int = 0
    damage: Damage = field(default_factory=Damage)

    def __getitem__(self, name: str) -> NDArray[Any]:
        return self.messages[name]

    def __contains__(self, name: object) -> bool:
        return name in self.messages and len(self.messages[str(name)]) > 0


def read_messages(
    path: str | Path, names: Iterable[str] = USED_MESSAGES, *, warn: bool = True
) -> TlogMessages:
    """Decode the named messages of a tlog (every message whose CRC checks out), in file order."""
    path = Path(path)
    by_id, by_name = _dialect()
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise LogFormatError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    size = len(data)
    out = TlogMessages()
    cand = _sync_bytes(data)
    if len(cand) == 0:
        raise LogFormatError("no MAVLink frame found: not a .tlog file", path=path, offset=0)
    # Each candidate's record from its time stamp to the end of a MAVLink 2 header, gathered once:
    # bytes 0–7 the time stamp, 8 on the frame (magic, length, flags or sequence, ..., message id).
    head = gather_rows(data, cand - 8, 18)
    # Sync bytes inside payloads are weeded out before the walk: a real MAVLink 2 frame has no
    # incompatibility flag but signing, and a real record's timestamp shares its top 16 bits (2**48 µs,
    # nine years) with the log's other records.
    top = (head[:, 0].astype(np.int64) << 8) | head[:, 1]
    common = int(np.bincount(top).argmax())
    plausible = ((top == common) | (top == common + 1)) & ((head[:, 8] == 0xFE) | ((head[:, 10] & 0xFE) == 0))
    cand, head = cand[plausible], head[plausible]
    v2 = head[:, 8] == 0xFD
    plen = head[:, 9].astype(np.int64)
    signed = v2 & ((head[:, 10] & 1) != 0)
    header = np.where(v2, 10, 6)
    frame_len = header + plen + 2 + np.where(signed, 13, 0)
    next_start = cand + frame_len + 8
    msgid = np.where(
        v2,
        head[:, 15].astype(np.int64)
        | (head[:, 16].astype(np.int64) << 8)
        | (head[:, 17].astype(np.int64) << 16),
        head[:, 13].astype(np.int64),
    )

    # the bytes each message's frames were checked with (the last check of many frames), payloads included
    checked: dict[int, tuple[NDArray[np.int64], NDArray[np.uint8]]] = {}

    def frame_ok(rows: NDArray[np.int64], keep: bool = False) -> NDArray[np.bool_]:
        """CRC check of the frames ``rows`` (indices into the candidates); unknown ids fail. ``keep``: the
        frames' bytes are kept in ``checked`` for their payloads."""
        ok = np.zeros(len(rows), dtype=bool)
        ids = msgid[rows]
        for mid in distinct(ids)[0].tolist():
            spec = by_id.get(int(mid))
            if spec is None:
                continue
            sel = np.flatnonzero(ids == mid)
            r = rows[sel]
            fits = cand[r] + header[r] + plen[r] + 2 <= size
            crc_len = header[r] - 1 + plen[r]
            # from the byte after the magic: the header, the payload (its whole layout) and the CRC
            width = max(int(crc_len.max()) + 2, int(header[r].max()) - 1 + spec.dtype.itemsize)
            body = gather_rows(data, cand[r] + 1, width)  # zeros past the end of the file
            crc = crc_x25_rows(body, crc_len, spec.crc_extra)
            at = np.arange(len(r))
            stored = body[at, crc_len].astype(np.uint16) | (body[at, crc_len + 1].astype(np.uint16) << 8)
            ok[sel] = fits & (crc == stored)
            if keep:
                checked[int(mid)] = (r, body)
        return ok

    def payloads(spec: _MessageSpec, rows: NDArray[np.int64]) -> NDArray[np.uint8]:
        """The payloads of the frames ``rows`` (MAVLink 2's truncated zeros put back): cut from the bytes
        their CRC check read where it kept them, else gathered from the file."""
        kept = checked.get(spec.msgid)
        start = header[rows] - 1
        if kept is not None and len(rows) and np.array_equal(kept[0], rows) and (start == start[0]).all():
            cut = np.ascontiguousarray(kept[1][:, start[0] : start[0] + spec.dtype.itemsize])
            return zero_past(cut, plen[rows])
        return gather_rows(data, cand[rows] + header[rows], spec.dtype.itemsize, plen[rows])

    def accept(k: int) -> bool:
        if next_start[k] > size + 8:
            return False
        if int(msgid[k]) in by_id:
            return bool(frame_ok(np.array([k]))[0])
        j = int(np.searchsorted(cand, next_start[k]))
        return next_start[k] == size + 8 or (j < len(cand) and cand[j] == next_start[k])

    # Walk the chain; frames of the decoded messages whose CRC fails are taken out of the candidates
    # and the chain is walked again, so a damaged length cannot lead the walk astray.
    wanted_ids = np.array([by_name[n].msgid for n in names if n in by_name], dtype=np.int64)
    active = np.ones(len(cand), dtype=bool)
    bad_total, bad_offsets = 0, []
    for _attempt in range(10):
        live = np.flatnonzero(active)
        damage = Damage()

        def accept_live(k: int, live: NDArray[np.int64] = live) -> bool:
            return accept(int(live[k]))

        first = 0
        while first < len(live) and cand[live[first]] != 8 and not accept_live(first):
            first += 1
        chain = live[follow_chain(cand[live], next_start[live], size + 8, accept_live, damage, first=first)]
        used = np.flatnonzero(np.isin(msgid[chain], wanted_ids))
        bad = used[~frame_ok(chain[used], keep=True)]
        if len(bad) == 0:
            break
        active[chain[bad]] = False
        bad_total += len(bad)
        bad_offsets += (cand[chain[bad]] - 8).tolist()
    damage.bad_records += bad_total
    if bad_offsets:
        damage.offsets = sorted(set(damage.offsets) | set(bad_offsets))
    out.damage = damage
    if len(chain) == 0:
        raise LogFormatError("no valid MAVLink frame found: not a .tlog file", path=path, offset=0)
    stamps = np.ascontiguousarray(head[chain, :8]).view(">u8").ravel()
    out.first_time_us = int(stamps[0])
    ids = msgid[chain]
    uniq, counts = distinct(ids)
    present = set(uniq.tolist())
    for mid, n in zip(uniq.tolist(), counts.tolist()):
        spec = by_id.get(mid)
        out.counts[spec.name if spec else f"MSG{mid}"] = n
    for name in names:
        spec = by_name.get(name)
        if spec is None:
            continue
        # (a message the log does not have: no search through the records for it)
        sel = np.flatnonzero(ids == spec.msgid) if spec.msgid in present else np.zeros(0, dtype=np.intp)
        rows = chain[sel]
        payload = payloads(spec, rows)
        out.messages[name] = payload.view(spec.dtype).ravel()
        out.time_us[name] = stamps[sel]
        out.sysid[name] = np.where(v2[rows], head[rows, 13], head[rows, 11])
        out.compid[name] = np.where(v2[rows], head[rows, 14], head[rows, 12])
        out.offsets[name] = cand[rows] - 8
    if warn:
        damage.warn(path, "frames")
    return out


def _sync_bytes(data: NDArray[np.uint8]) -> NDArray[np.int64]:
    """Offsets of the ``0xFD``/``0xFE`` bytes that can start a frame: after a time stamp, with room for
    a MAVLink 2 header."""
    at = np.flatnonzero(data[8:] >= 0xFD)  # one pass over the file; 0xFF taken out after
    at = at[data[at + 8] != 0xFF].astype(np.int64) + 8
    return at[at + 10 <= len(data)]


def _params(msgs: TlogMessages, keep: NDArray[np.bool_] | None) -> tuple[dict[str, float], dict[str, float]]:
    """The log's parameters: each one's first logged value and its last."""
    if "PARAM_VALUE" not in msgs:
        return {}, {}
    pv = msgs["PARAM_VALUE"]
    if keep is not None:
        pv = pv[keep]
    first: dict[str, float] = {}
    last: dict[str, float] = {}
    for name, value in zip(pv["param_id"].tolist(), pv["param_value"].tolist()):
        key = name.split(b"\0", 1)[0].decode("ascii", "replace")
        first.setdefault(key, float(value))
        last[key] = float(value)
    return first, last


def read_tlog(path: str | Path) -> TelemetryTable:
    """Read a ``.tlog`` into the telemetry table (one row per ESC sample; see :mod:`.assemble`)."""
    path = Path(path)
    msgs = read_messages(path)
    esc_names = [n for n in mavlink_esc.ESC_TELEMETRY_MESSAGES if n in msgs]
    if not esc_names and "ESC_STATUS" not in msgs:
        raise _no_esc(path, msgs)
    # The vehicle is the system that sends ESC telemetry; other systems (ground stations) are ignored.
    senders = np.concatenate([msgs.sysid[n] for n in [*esc_names, "ESC_STATUS"] if n in msgs])
    vehicle = int(np.bincount(senders).argmax())

    def mine(name: str) -> NDArray[np.bool_] | None:
        """The vehicle's messages of a name (None: all of them)."""
        if name not in msgs:
            return None
        keep = msgs.sysid[name] == vehicle
        return None if keep.all() else keep

    def series_time(name: str) -> NDArray[np.float64]:
        keep = mine(name)
        t = msgs.time_us[name].astype(np.int64) - msgs.first_time_us
        return (t[keep] if keep is not None else t) / 1e6

    def rows(name: str) -> NDArray[Any]:
        keep = mine(name)
        return msgs[name][keep] if keep is not None else msgs[name]

    def offsets(name: str) -> NDArray[np.int64]:
        keep = mine(name)
        return msgs.offsets[name][keep] if keep is not None else msgs.offsets[name]

    # The messages' reading is the live agent's (mavlink_messages), on the whole log at once; replay knows
    # each parameter's first logged value from the start (ground stations fetch them after connecting).
    first_params, params = _params(msgs, mine("PARAM_VALUE"))
    reader = MessageReader(first_params)
    reading = reader.read(
        {
            name: Messages(series_time(name), offsets(name), rows(name))
            for name in READ_MESSAGES
            if name in msgs
        }
    )
    if not reader.esc_reported and "ESC_STATUS" not in msgs:
        raise _no_esc(path, msgs)  # ESC_TELEMETRY messages, but no ESC ever had a packet
    # the reading has mapped each row to its motor (the map can change mid-log): "slot" m - 1 is motor m
    esc = EscSamples(
        reading.time_s,
        reading.motor - 1,
        reading.omega_rad_s,
        reading.esc_current_a,
        reading.bus_voltage_v,
        reading.esc_temp_c,
    )
    motors_seen = distinct(reading.motor)[0].tolist()  # (sorted, as Python ints)
    motor_of_slot: dict[int, int | None] = {m - 1: m for m in motors_seen}
    commands = reading.commands()
    context: dict[str, Series] = {}
    battery: Series | None = None
    if len(reading.battery_time_s):
        battery = (reading.battery_time_s, reading.battery_voltage_v)
        context["battery_voltage_v"] = battery
        context["battery_current_a"] = (reading.battery_time_s, reading.battery_current_a)
    if "GLOBAL_POSITION_INT" in msgs:
        rec, t = rows("GLOBAL_POSITION_INT"), series_time("GLOBAL_POSITION_INT")
        context["alt_m"] = (t, rec["relative_alt"] / 1000.0)
        context["climb_m_s"] = (t, -rec["vz"] / 100.0)
    if "VFR_HUD" in msgs:
        rec, t = rows("VFR_HUD"), series_time("VFR_HUD")
        context.setdefault("alt_m", (t, rec["alt"].astype(float)))
        context["climb_m_s"] = (t, rec["climb"].astype(float))
    if "SCALED_PRESSURE" in msgs:
        rec, t = rows("SCALED_PRESSURE"), series_time("SCALED_PRESSURE")
        context["air_temp_c"] = (t, rec["temperature"] / 100.0)
    vehicle_info: dict[str, Any] = {"sysid": vehicle}
    if "HEARTBEAT" in msgs:
        rec, t = rows("HEARTBEAT"), series_time("HEARTBEAT")
        sel = rec["type"] != MAV_TYPE_GCS
        if sel.any():
            context["armed"] = (
                t[sel],
                ((rec["base_mode"][sel] & MAV_MODE_FLAG_SAFETY_ARMED) > 0).astype(float),
            )
            vehicle_info["mav_type"] = int(rec["type"][sel][0])
            vehicle_info["autopilot"] = int(rec["autopilot"][sel][0])
    for key in ("FRAME_CLASS", "FRAME_TYPE"):
        if key in params:
            vehicle_info[key.lower()] = int(params[key])
    end_s = (max(int(v.max()) for v in msgs.time_us.values() if len(v)) - msgs.first_time_us) / 1e6
    # an ESC_TELEMETRY message carries each ESC's last packet, without its time: up to one message
    # interval older than the message's stamp
    esc_intervals = np.concatenate(
        [np.diff(series_time(name)) for name in [*esc_names, "ESC_STATUS"] if name in msgs] or [np.zeros(0)]
    )
    positive = esc_intervals[esc_intervals > 0]
    meta = {
        "sample_time_uncertainty_s": float(np.median(positive)) if positive.size else None,
        "format": "tlog",
        "params": params,
        "vehicle": vehicle_info,
        "motors": mavlink_esc.expected_motors(params) or motors_seen,
        "message_counts": dict(msgs.counts),
        "time_origin_unix_s": msgs.first_time_us / 1e6,
        "duration_s": end_s,
        "damage": msgs.damage.to_dict(),
        "pwm_range_us": list(mavlink_esc.pwm_range(params)),
    }
    return motor_table(path, esc, motor_of_slot, commands, context, meta, battery)


def _no_esc(path: Path, msgs: TlogMessages) -> DataError:
    return no_esc_error(
        path,
        "MAVLink telemetry (.tlog)",
        msgs.counts,
        "ESC_TELEMETRY_1_TO_4/5_TO_8/9_TO_12 or ESC_STATUS",
    )
