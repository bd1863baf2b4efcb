"""From decoded log records to the telemetry table: one row per ESC sample, context held onto it.

Every log reader decodes its own format and then calls :func:`motor_table` with

* the ESC samples (time, ESC slot, speed, current, voltage, temperature), already in SI units;
* which motor each ESC slot drives (from the log's own parameters, see :mod:`.mavlink_esc`);
* the motor commands (throttle 0..1 per motor, with their own times);
* context signals (battery, altitude, climb rate, air temperature, armed...), each with its own times.

The ESC reports its input current (``esc_current_a``, kept as the sensor's reading); the motor's voltage
and current follow from the command with :func:`.mavlink_esc.motor_inputs`, the very function the live
agent uses, so a replayed log and the same flight streamed live give the same table.

Commands and context are aligned to each ESC sample by previous-value hold (the last value at or before
the sample), so no value from the future is ever used — the same view the live agent has. The table's
``meta`` says how closely the samples are paired with their commands (``command_age_s``, the held
command's age, 95th percentile; ``pairing_s``, the larger of that and the reader's
``sample_time_uncertainty_s``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import DataError
from . import mavlink_esc
from ._logscan import hold_previous
from .table import TelemetryTable

__all__ = ["COMMAND_MAX_AGE_S", "CONTEXT_MAX_AGE_S", "EscSamples", "Series", "motor_table", "no_esc_error"]

#: A motor command older than this is not used for a sample (the output stream stopped).
COMMAND_MAX_AGE_S = 1.0
#: A context value older than this is not used.
CONTEXT_MAX_AGE_S = 5.0

Series = tuple[NDArray[np.float64], NDArray[np.float64]]


@dataclass(frozen=True)
class EscSamples:
    """ESC telemetry of one log, long format: one entry per (message, ESC slot)."""

    time_s: NDArray[np.float64]
    slot: NDArray[np.int64]  # 0-based ESC index as the log numbers it
    omega_rad_s: NDArray[np.float64]
    current_a: NDArray[np.float64]
    bus_voltage_v: NDArray[np.float64]
    esc_temp_c: NDArray[np.float64] | None = None
    motor_temp_c: NDArray[np.float64] | None = None

    @classmethod
    def concat(cls, parts: list[EscSamples]) -> EscSamples:
        """One table of several message groups' samples (a part without temperatures gets NaN)."""
        return cls(
            np.concatenate([p.time_s for p in parts]),
            np.concatenate([p.slot for p in parts]),
            np.concatenate([p.omega_rad_s for p in parts]),
            np.concatenate([p.current_a for p in parts]),
            np.concatenate([p.bus_voltage_v for p in parts]),
            np.concatenate(
                [p.esc_temp_c if p.esc_temp_c is not None else np.full(len(p.time_s), np.nan) for p in parts]
            ),
        )


#: ESC indices an autopilot numbers (ArduPilot and PX4: at most 32 ESCs)
MAX_ESC_SLOTS = 32


def _sorted_series(series: Series) -> Series:
    t, v = np.asarray(series[0], dtype=float), np.asarray(series[1], dtype=float)
    if len(t) > 1 and np.any(np.diff(t) < 0):
        order = np.argsort(t, kind="stable")
        t, v = t[order], v[order]
    return t, v


def motor_table(
    path: Path,
    esc: EscSamples,
    motor_of_slot: Mapping[int, int | None],
    commands: Mapping[int, Series],
    context: Mapping[str, Series],
    meta: Mapping[str, Any],
    battery_voltage: Series | None = None,
) -> TelemetryTable:
    """The telemetry table of one log.

    ``motor_of_slot`` maps ESC slots to motor numbers (None: the slot drives no motor; its samples are
    dropped). ``commands`` maps a motor number to its throttle series. Where the ESC reports no voltage
    (0 or NaN), the battery voltage stands in for ``bus_voltage_v``.
    """
    slots = np.asarray(esc.slot, dtype=np.int64)
    # an ESC index outside 0..31 is a damaged record (autopilots number at most 32 ESCs): dropped
    in_range = (slots >= 0) & (slots < MAX_ESC_SLOTS)
    slot_motor = np.zeros(MAX_ESC_SLOTS, dtype=np.int64)
    for slot in np.unique(slots[in_range]).tolist():
        slot_motor[slot] = motor_of_slot.get(int(slot)) or 0
    motors_all = np.where(in_range, slot_motor[np.clip(slots, 0, MAX_ESC_SLOTS - 1)], 0)
    keep = np.flatnonzero(motors_all > 0)
    # Rows ordered by motor, then time: logs write ESC samples in time order, so a stable sort by motor
    # is enough; otherwise sort by both.
    t_kept = esc.time_s[keep]
    if len(t_kept) < 2 or np.all(np.diff(t_kept) >= 0):
        keep = keep[np.argsort(motors_all[keep], kind="stable")]
    else:
        keep = keep[np.lexsort((t_kept, motors_all[keep]))]
    time_s = esc.time_s[keep]
    motors = motors_all[keep]
    columns: dict[str, NDArray[Any]] = {
        "time_s": time_s,
        "motor": motors,
        "omega_rad_s": esc.omega_rad_s[keep],
        "current_a": esc.current_a[keep],
        "esc_current_a": esc.current_a[keep],
        "bus_voltage_v": esc.bus_voltage_v[keep].astype(float),
    }
    if esc.esc_temp_c is not None:
        columns["esc_temp_c"] = esc.esc_temp_c[keep]
    if esc.motor_temp_c is not None:
        columns["motor_temp_c"] = esc.motor_temp_c[keep]
    throttle = np.full(len(time_s), np.nan)
    command_age = np.full(len(time_s), np.nan)
    for m, series in commands.items():
        sel = motors == m
        if sel.any():
            t, v = _sorted_series(series)
            throttle[sel] = hold_previous(t, v, time_s[sel], COMMAND_MAX_AGE_S)
            command_age[sel] = time_s[sel] - hold_previous(t, t, time_s[sel], COMMAND_MAX_AGE_S)
    columns["throttle"] = throttle
    meta = dict(meta)
    # How far the command paired with a sample may be from the one the motor had when it was measured:
    # the held command's age (95th percentile), or how uncertain the sample's own time is if that is more
    # (the reader says: a .tlog's ESC packet is up to one message interval older than its stamp). The
    # balance rule needs them within a few milliseconds in gusty flight (docs/flight.md, section 6,
    # "Through the logs").
    ages = command_age[np.isfinite(command_age)]
    if ages.size:
        meta["command_age_s"] = float(np.percentile(ages, 95))
        meta["pairing_s"] = max(meta["command_age_s"], float(meta.get("sample_time_uncertainty_s") or 0.0))
    if battery_voltage is not None and len(battery_voltage[0]):
        t, v = _sorted_series(battery_voltage)
        battery = hold_previous(t, v, time_s, CONTEXT_MAX_AGE_S)
        bus = columns["bus_voltage_v"]
        missing = ~(bus > 0)
        bus[missing] = battery[missing]
    for name, series in context.items():
        if len(series[0]):
            t, v = _sorted_series(series)
            columns[name] = hold_previous(t, v, time_s, CONTEXT_MAX_AGE_S)
    # What the motor sees, exactly as the live agent computes it (ESC as an ideal PWM stage):
    # voltage_v = throttle × bus voltage, current_a = ESC current / throttle (NaN at a tiny command).
    columns["voltage_v"], columns["current_a"] = mavlink_esc.motor_inputs(
        throttle, columns["bus_voltage_v"], columns["esc_current_a"]
    )
    return TelemetryTable(columns, source=str(path), meta=meta)


def no_esc_error(path: Path, fmt: str, counts: Mapping[str, int], wanted: str) -> DataError:
    """The error for a log without ESC telemetry: what the log holds and what the diagnosis needs."""
    held = ", ".join(f"{name} ×{n}" for name, n in sorted(counts.items(), key=lambda kv: -kv[1])[:15])
    more = f" and {len(counts) - 15} more types" if len(counts) > 15 else ""
    return DataError(
        f"no ESC telemetry in this {fmt} log. It holds: {held or 'no decodable records'}{more}. "
        f"The diagnosis needs per-motor speed and current from the ESCs ({wanted}); enable ESC telemetry "
        "logging on the vehicle",
        path=path,
    )
