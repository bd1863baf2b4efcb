"""From decoded log records to the telemetry table: one row per ESC sample, context held onto it.

Every log reader decodes its own format and then calls :func:`motor_table` with

* the ESC samples (time, ESC slot, speed, current, voltage, temperature), already in SI units;
* which motor each ESC slot drives (from the log's own parameters, see :mod:`.mavlink_esc`);
* the motor commands (throttle 0..1 per motor, with their own times);
* context signals (battery, altitude, climb rate, air temperature, armed...), each with its own times.

The ESC reports its input current (``esc_current_a``, kept as the sensor's reading); the motor's voltage
and current follow from the command with :func:`.mavlink_esc.motor_inputs`, the very function the live
agent uses, so a replayed log and the same flight streamed live give the same table.

Commands and context are paired with each ESC sample by previous-value hold (:class:`HeldValues`: the
last value at or before the sample's time, none older than :data:`COMMAND_MAX_AGE_S` for commands,
:data:`CONTEXT_MAX_AGE_S` for context), so no value from the future is ever used. The live agent pairs
its samples with the same class, fed batch by batch (:class:`.mavlink_messages.SamplePairing`): a
streamed flight and its replayed .tlog give the same table. The table's ``meta`` says how closely the
samples are paired with their commands (``command_age_s``, the held command's age, 95th percentile;
``pairing_s``, the larger of that and the reader's ``sample_time_uncertainty_s``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DataError
from . import mavlink_esc
from .table import TelemetryTable

__all__ = [
    "COMMAND_MAX_AGE_S",
    "CONTEXT_MAX_AGE_S",
    "EscSamples",
    "HeldValues",
    "Series",
    "bus_voltage_or_battery",
    "held",
    "motor_table",
    "no_esc_error",
]

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


class HeldValues:
    """Previous-value hold by time of ``signals`` signals whose values come in parts (a log: all at once;
    the live agent: batch by batch): each target time gets each signal's last value at or before it (one
    at the very same time included), none older than ``max_age_s``.

    What earlier parts said is carried (each signal's last value and its time), so parts whose times do
    not go back give what the whole gives, wherever they are split — except that a value stamped at the
    same time as a target but coming in a later part is not seen (it had not come).
    """

    def __init__(self, signals: int, max_age_s: float) -> None:
        self.max_age_s = max_age_s
        self._signals = np.arange(signals)
        #: each signal's last value and its time (NaN: none yet)
        self.time_s = np.full(signals, np.nan)
        self.value = np.full(signals, np.nan)

    def hold(
        self,
        source_time_s: ArrayLike,
        values: ArrayLike,
        target_time_s: ArrayLike,
        signal: ArrayLike | None = None,
        present: NDArray[np.bool_] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The held value at each target time and its age [s] (both NaN where none is held); then the part's
        last values are carried to the next call.

        ``values`` has a row per source time (in any order: sorted here, stably) and a column per signal;
        ``present`` marks the entries that are values (default: all, NaN included: a "no reading" is the
        latest word). ``signal`` gives each target's signal (results shaped like the targets); None: every
        signal at every target (results: a row per target, a column per signal).
        """
        t_source = np.asarray(source_time_s, dtype=float)
        v_source = np.asarray(values, dtype=float).reshape(len(t_source), len(self._signals))
        t_target = np.asarray(target_time_s, dtype=float)
        if present is not None:
            present = present.reshape(v_source.shape)
        if len(t_source) > 1 and (t_source[1:] < t_source[:-1]).any():
            order = np.argsort(t_source, kind="stable")
            t_source, v_source = t_source[order], v_source[order]
            present = present[order] if present is not None else None
        time_s, value = self._with_carried(t_source, v_source)
        # the last row at or before each target (row 0: the carried one), then the last with a value
        row = np.searchsorted(t_source, t_target, side="right")
        cols: NDArray[np.int64]
        if signal is None:  # every signal at every target: a row per target, a column per signal
            row, cols, t_target = row[:, None], self._signals, t_target[:, None]
        else:
            cols = np.asarray(signal, dtype=np.int64)
        last = _last_present(present)
        if last is not None:
            row = last[row, cols]
        age_s = t_target - time_s[row, cols]
        paired = (age_s >= 0) & (age_s <= self.max_age_s)  # NaN (none held): False
        # carry each signal's last value of this part (row 0 where the part has none)
        end = last[-1] if last is not None else len(t_source)
        self.time_s, self.value = time_s[end, self._signals], value[end, self._signals]
        return np.where(paired, value[row, cols], np.nan), np.where(paired, age_s, np.nan)

    def _with_carried(
        self, t_source: NDArray[np.float64], v_source: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each entry's time and value, a row per source time after a first row: what is carried."""
        time_s = np.empty((len(t_source) + 1, len(self._signals)))
        time_s[0], time_s[1:] = self.time_s, t_source[:, None]
        value = np.empty_like(time_s)
        value[0], value[1:] = self.value, v_source
        return time_s, value


def _last_present(present: NDArray[np.bool_] | None) -> NDArray[np.int64] | None:
    """Per row (after a first row: the carried value, which counts as one) and column of ``present``, the
    last row up to it that holds a value; None when every entry is a value."""
    if present is None:
        return None
    is_value = np.empty((len(present) + 1, present.shape[1]), dtype=bool)
    is_value[0], is_value[1:] = True, present
    return np.maximum.accumulate(np.where(is_value, np.arange(len(is_value))[:, None], 0), axis=0)


def held(
    series: Series, target_time_s: NDArray[np.float64], max_age_s: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One signal's value held at each target time, and its age [s] (NaN: none within ``max_age_s``)."""
    value, age_s = HeldValues(1, max_age_s).hold(series[0], np.asarray(series[1])[:, None], target_time_s)
    return value[:, 0], age_s[:, 0]


def bus_voltage_or_battery(
    bus_voltage_v: NDArray[np.float64], battery_voltage_v: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The ESC's bus voltage [V], the battery's where the ESC reports none (0 or NaN)."""
    return np.where(bus_voltage_v > 0, bus_voltage_v, battery_voltage_v)


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
            throttle[sel], command_age[sel] = held(series, time_s[sel], COMMAND_MAX_AGE_S)
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
        battery, _ = held(battery_voltage, time_s, CONTEXT_MAX_AGE_S)
        columns["bus_voltage_v"] = bus_voltage_or_battery(columns["bus_voltage_v"], battery)
    for name, series in context.items():
        if len(series[0]):
            columns[name], _ = held(series, time_s, CONTEXT_MAX_AGE_S)
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
