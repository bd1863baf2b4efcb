"""ArduPilot DataFlash binary logs (``.bin``) with the record formats ArduCopter 4.x writes.

Every record is ``0xA3 0x95 <type>`` + packed little-endian fields. FMT records (type 128) describe
the others; formats, names and columns are those of a real ArduCopter log (checked against an
ArduCopter 4.7 SITL ``.bin``): ESC ``QBffffcfcf`` (per ESC, instance 0-based, RPM mechanical, Volt and
Curr at the ESC input, Temp in centi-°C), RCOU ``QHHHHHHHHHHHHHH``, BAT ``QBfffffcfBBB``, PARM ``QNff``,
MSG ``QZ``, ATT ``QffffffB``. FMTU/MULT/UNIT are left out (optional for readers).
"""

from __future__ import annotations

import math
import struct
from pathlib import Path

from ..engine import SimRecord

__all__ = ["FORMATS", "write_dataflash"]

HEAD = b"\xa3\x95"
#: name → (type id, format, columns) as in ArduPilot's LogStructure.h / AP_ESC_Telem
FORMATS: dict[str, tuple[int, str, str]] = {
    "FMT": (128, "BBnNZ", "Type,Length,Name,Format,Columns"),
    "PARM": (32, "QNff", "TimeUS,Name,Value,Default"),
    "MSG": (59, "QZ", "TimeUS,Message"),
    "RCOU": (62, "QHHHHHHHHHHHHHH", "TimeUS,C1,C2,C3,C4,C5,C6,C7,C8,C9,C10,C11,C12,C13,C14"),
    "ATT": (72, "QffffffB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,AEKF"),
    "ESC": (86, "QBffffcfcf", "TimeUS,Instance,RPM,RawRPM,Volt,Curr,Temp,CTot,MotTemp,Err"),
    "BAT": (88, "QBfffffcfBBB", "TimeUS,Inst,Volt,VoltR,Curr,CurrTot,EnrgTot,Temp,Res,RemPct,H,SH"),
}
_STRUCT = {
    "B": "B",
    "b": "b",
    "H": "H",
    "h": "h",
    "I": "I",
    "i": "i",
    "Q": "Q",
    "q": "q",
    "f": "f",
    "d": "d",
    "c": "h",
    "C": "H",
    "e": "i",
    "E": "I",
    "L": "i",
    "M": "B",
    "n": "4s",
    "N": "16s",
    "Z": "64s",
}


def _struct(fmt: str) -> struct.Struct:
    return struct.Struct("<" + "".join(_STRUCT[c] for c in fmt))


def _text(s: str, size: int) -> bytes:
    return s.encode("ascii")[:size].ljust(size, b"\0")


class _Writer:
    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.structs = {name: _struct(fmt) for name, (_, fmt, _) in FORMATS.items()}
        fmt_struct = self.structs["FMT"]
        for name, (type_id, fmt, columns) in FORMATS.items():
            length = 3 + self.structs[name].size
            self.chunks.append(
                HEAD
                + bytes([128])
                + fmt_struct.pack(type_id, length, _text(name, 4), _text(fmt, 16), _text(columns, 64))
            )

    def add(self, name: str, *values: object) -> None:
        self.chunks.append(HEAD + bytes([FORMATS[name][0]]) + self.structs[name].pack(*values))


def write_dataflash(record: SimRecord, path: Path) -> None:
    w = _Writer()
    sc = record.scenario
    w.add("MSG", 0, _text("ArduCopter V4.5.7 (mav-motor-health simulator)", 64))
    w.add("MSG", 0, _text(f"Frame: HEXA/X  scenario: {sc.name}", 64))
    for name in sorted(record.params):
        value = float(record.params[name])
        w.add("PARM", 0, _text(name, 16), value, value)
    events: list[tuple[int, int, str, tuple[object, ...]]] = []
    seq = 0
    # ArduPilot's estimate of the pack's resistance (a world's pack has its own)
    pack_ohm = 0.02 if record.world is None else record.world.battery.resistance_ohm
    for v in record.vehicle:
        us = round(v.time_s * 1e6)
        pwm = list(v.pwm_us) + [0] * (14 - len(v.pwm_us))
        events.append((us, seq, "RCOU", (us, *pwm[:14])))
        deg = [math.degrees(a) for a in (v.roll_rad, v.pitch_rad, v.yaw_rad)]
        events.append((us, seq + 1, "ATT", (us, 0.0, deg[0], 0.0, deg[1], 0.0, deg[2] % 360.0, 3)))
        wh = 0.0
        events.append(
            (
                us,
                seq + 2,
                "BAT",
                (
                    us,
                    0,
                    v.bus_voltage_v,
                    v.bus_voltage_v,
                    v.battery_current_a,
                    v.consumed_mah,
                    wh,
                    2500,
                    pack_ohm,
                    v.remaining_pct,
                    100,
                    100,
                ),
            )
        )
        seq += 3
    totals = [0.0] * sc.n_motors
    last_t = [0.0] * sc.n_motors
    for s in record.esc:
        us = round(s.time_s * 1e6)
        j = s.motor - 1
        curr = s.esc_current_ca / 100.0
        totals[j] += curr * (s.time_s - last_t[j]) / 3.6
        last_t[j] = s.time_s
        events.append(
            (
                us,
                seq,
                "ESC",
                (
                    us,
                    j,
                    float(s.rpm),
                    float(s.rpm),
                    s.voltage_cv / 100.0,
                    curr,
                    s.temp_c * 100,
                    totals[j],
                    s.motor_temp_c * 100,
                    0.0,
                ),
            )
        )
        seq += 1
    events.sort(key=lambda e: (e[0], e[1]))
    for _, _, name, values in events:
        w.add(name, *values)
    path.write_bytes(b"".join(w.chunks))
