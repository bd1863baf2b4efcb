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
streamed flight and its replayed .tlog give the same table.

How closely each sample is paired with its command is the column ``pairing_s`` [s], one value per
sample, worked out causally from the samples and commands before it (so the live agent, batch by batch,
gets the values replay gets; :func:`pairing_uncertainty`):

    pairing_s = max(command age, stamp uncertainty)

* the *command age* is the held command's age (:class:`HeldValues`): the motor's command may have moved
  since the command paired with the sample was sent (NaN where no command is held: no voltage either);
* the *stamp uncertainty* is how much older than its stamp the measurement may be. Where the reader says
  its ESC samples are stamped by the message that carried them (``sample_time_uncertainty_s`` in the
  reader's meta: a .tlog's ESC_TELEMETRY/ESC_STATUS carry each ESC's *last* packet without its time; the
  live agent reads the same messages), it is the interval of the motor's ESC messages: a packet the
  message calls new came after the message before it. As the interval of one message is what the
  reading of the link makes of it (a stalled read: one message a whole stall after the one before, the
  rest of its read none), it is the mean over the motor's messages of the last second
  (:class:`MessageIntervals`; stale rows — repeated packets — count as messages), the causal counterpart
  of the reader's ``sample_time_uncertainty_s`` (the median interval over the whole log); 0 for a motor's
  first message (nothing to compare with). Where samples carry their own time (a .bin's ESC records, a
  ULog's ``esc_status``) it is 0.

The command's age alone is the column ``command_age_s`` [s] (NaN where no command is held): a stall is
weighed against it, whether the motor had stopped before the command it is paired with was logged
(:mod:`..diagnosis.stall`, "A stall the paired command may predate").

Why the larger of the two, not their sum: the stamp is the moment both are known at; the command was sent
``age`` before it and the packet measured at most ``interval`` before it, so the two moments are both in
the last ``max(age, interval)`` before the stamp and no further apart than that. The balance rule weighs
each sample with the 95th percentile of the last second's values (:mod:`..diagnosis.pairing`). Why per sample and not a
whole-log statistic: the live agent cannot know a statistic of the whole flight, and a sample paired with
a command sent just before it is well paired whatever the others are. A source that pairs each sample
with the command of its own instant (the simulator's table, a CSV with both) has no such column: the
balance rule's pairing guard (:mod:`..diagnosis.pairing`) then does nothing.

How far each sample's command went between it and the motor's sample before is the column
``input_excursion_v`` [V] (:class:`CommandExcursions`): the farthest the motor's commands since the sample
before went beyond the two held commands (the one held at that sample and at this one), times the bus
voltage. A command that dips and comes back between two ESC reports (10 Hz telemetry in 50 Hz command
messages) leaves both held commands alike, so the change from one sample to the next says nothing of
it, while the motor's current and speed followed the dip and a low-pass still holds it; the balance rule
can take the excursion into its input activity or its pairing guard (profile options, off in the shipped
profiles: docs/flight.md, "A command dip between two ESC reports, measured"). It is 0 where the
command went no farther than the two held ones (a command of the sample's own instant: a simulator's
table, a CSV, a .bin whose ESC samples come with each command), NaN on rows without a measurement.

The table's ``meta`` keeps a whole-log summary for the readers' warnings and the report
(``command_age_s``, the held command's age, 95th percentile; ``pairing_s``, the larger of that and the
reader's ``sample_time_uncertainty_s``); the diagnosis uses the column.
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
    "INTERVAL_WINDOW_S",
    "CommandExcursions",
    "EscSamples",
    "HeldValues",
    "MessageIntervals",
    "Series",
    "bus_voltage_or_battery",
    "excursion_v",
    "held",
    "motor_table",
    "no_esc_error",
    "pairing_uncertainty",
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
        row = _search_right(t_source, t_target)
        cols: NDArray[np.int64]
        if signal is None:  # every signal at every target: a row per target, a column per signal
            row, cols, t_target = row[:, None], self._signals, t_target[:, None]
        else:
            cols = np.asarray(signal, dtype=np.int64)
        last = _last_present(present)
        if last is None and signal is None:  # a row per target, a column per signal: column by column
            held_value, held_age = self._hold_columns(time_s, value, row[:, 0], t_target[:, 0])
            end = len(t_source)
            self.time_s, self.value = time_s[end, self._signals], value[end, self._signals]
            return held_value.T, held_age.T
        if last is not None:
            row = last[row, cols]
        age_s = t_target - time_s[row, cols]
        paired = (age_s >= 0) & (age_s <= self.max_age_s)  # NaN (none held): False
        # carry each signal's last value of this part (row 0 where the part has none)
        end = last[-1] if last is not None else len(t_source)
        self.time_s, self.value = time_s[end, self._signals], value[end, self._signals]
        return np.where(paired, value[row, cols], np.nan), np.where(paired, age_s, np.nan)

    def _hold_columns(
        self,
        time_s: NDArray[np.float64],
        value: NDArray[np.float64],
        rows: NDArray[np.intp],
        targets: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`hold` where every entry is a value and every signal is wanted at every target: the held
        values and ages, a row per signal. The signals share their source times (only the carried first
        row differs), so each target's age is worked out once and only the targets that hold a carried
        value (row 0) get their own signal's."""
        signals = len(self._signals)
        held_value, held_age = np.empty((signals, len(targets))), np.empty((signals, len(targets)))
        age = targets - np.ascontiguousarray(time_s[:, 0]).take(rows)
        paired = (age >= 0) & (age <= self.max_age_s)  # NaN (none held): False
        carried = np.flatnonzero(rows == 0)  # targets before the part's first source time
        for c in range(signals):
            age_c, paired_c = age, paired
            if c > 0 and carried.size:
                age_c, paired_c = age.copy(), paired.copy()
                age_c[carried] = targets[carried] - time_s[0, c]
                paired_c[carried] = (age_c[carried] >= 0) & (age_c[carried] <= self.max_age_s)
            np.copyto(held_value[c], np.nan)
            np.copyto(held_value[c], np.ascontiguousarray(value[:, c]).take(rows), where=paired_c)
            np.copyto(held_age[c], np.nan)
            np.copyto(held_age[c], age_c, where=paired_c)
        return held_value, held_age

    def _with_carried(
        self, t_source: NDArray[np.float64], v_source: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each entry's time and value, a row per source time after a first row: what is carried."""
        time_s = np.empty((len(t_source) + 1, len(self._signals)))
        time_s[0], time_s[1:] = self.time_s, t_source[:, None]
        value = np.empty_like(time_s)
        value[0], value[1:] = self.value, v_source
        return time_s, value


#: how far back the interval of a motor's ESC messages is averaged [s]
INTERVAL_WINDOW_S = 1.0


class MessageIntervals:
    """How often each signal's entries come (a motor's ESC messages), causally, for entries that come in
    parts (a log: all at once; the live agent: batch by batch): per entry, the mean time between the
    signal's entries over the last ``window_s`` (the time since the entry before the window's first, over
    the window's number of entries), NaN for a signal's very first entry. Each signal's recent times are
    carried, so parts give what the whole gives. Within a part the entries of one signal are taken in time
    order (stably).

    The mean over a second, not the time since the one entry before: a link stamps messages when they are
    read, and a stalled read makes its first message look a whole stall apart from the one before and the
    rest none; the mean over the window is the messages' interval as sent (the .tlog reader's
    ``sample_time_uncertainty_s`` is likewise their median interval over the whole log). With
    ``window_s`` 0, the time since the entry before (ties share it: a batch of one stamp).
    """

    def __init__(self, signals: int, window_s: float = INTERVAL_WINDOW_S) -> None:
        self.window_s = window_s
        #: each signal's times of the last window and the one entry before it
        self.recent: list[NDArray[np.float64]] = [np.zeros(0) for _ in range(signals)]

    def since_previous(self, time_s: ArrayLike, signal: ArrayLike) -> NDArray[np.float64]:
        """Per entry (time, signal: 0-based), the mean interval of its signal's entries [s] (class doc)."""
        t = np.asarray(time_s, dtype=float)
        sig = np.asarray(signal, dtype=np.int64)
        out = np.empty(t.shape)
        if t.size == 0:
            return out
        # by signal, then time, ties in the order given (a log's table is so already)
        grouped = t.size < 2 or _grouped_in_time(sig, t)
        order = None if grouped else np.lexsort((t, sig))
        ts, ss = (t, sig) if order is None else (t[order], sig[order])
        bounds = np.flatnonzero(np.diff(ss)) + 1
        means = np.empty(ts.shape)
        done: list[tuple[NDArray[np.float64], int, int]] = []  # signals worked out: times, where
        for a, b in zip([0, *bounds.tolist()], [*bounds.tolist(), ts.size]):
            carried = self.recent[int(ss[a])]
            times = np.concatenate((carried, ts[a:b]))
            same = next(
                (d for d in done if d[2] - d[1] == b - a and np.array_equal(d[0], times)), None
            )  # the same carried and new times
            if same is not None:  # a signal with the very same times (ESCs of one message): the same
                means[a:b] = means[same[1] : same[2]]
                self.recent[int(ss[a])] = self.recent[int(ss[same[1]])]
                continue
            done.append((times, a, b))
            at = np.arange(carried.size, times.size)
            first = np.minimum(np.searchsorted(times, times[at] - self.window_s, side="left"), at)
            with np.errstate(divide="ignore", invalid="ignore"):
                means[a:b] = np.where(
                    first >= 1,
                    (times[at] - times[np.maximum(first - 1, 0)]) / (at - first + 1),
                    (times[at] - times[0]) / at,  # no entry before the window: from the very first
                )
            keep = max(int(np.searchsorted(times, times[-1] - self.window_s, side="left")) - 1, 0)
            self.recent[int(ss[a])] = times[keep:]
        if order is None:  # already in the entries' order
            return means
        out[order] = means
        return out


class CommandExcursions:
    """Per sample of a signal (a motor), how far the signal's values (its commands) since the signal's
    sample before went beyond the two held values, the one held at that sample and the one held at this
    one (module doc, ``input_excursion_v``), in the values' units; 0 where they did not (or no value was
    held at the sample before). Values and samples come in parts (a log: all at once; the live agent:
    batch by batch); what earlier parts left (the value held at the last sample, the values since) is
    carried, so parts whose times do not go back give what the whole gives, except that a value stamped
    at a sample's very time but coming in a later part counts for the next sample (as
    :class:`HeldValues`, it had not come). Every signal of a part is worked out in one pass."""

    def __init__(self, signals: int) -> None:
        #: each signal's value held at its last sample (NaN: none yet)
        self.held = np.full(signals, np.nan)
        #: each signal's values since its last sample: lowest, highest, last (NaN: none)
        self.pending = np.full((3, signals), np.nan)

    def beyond_held(
        self, value_time_s: ArrayLike, values: ArrayLike, sample_signal: ArrayLike, sample_time_s: ArrayLike
    ) -> NDArray[np.float64]:
        """The excursion at each sample (``sample_signal``: 0-based; each signal's samples in increasing
        time, signals in any order), from the values (a row per time, in increasing time; a column per
        signal; NaN: none in that message)."""
        vt = np.asarray(value_time_s, dtype=float)
        signals, n = self.held.size, vt.size
        sig = np.asarray(sample_signal, dtype=np.int64)
        st = np.asarray(sample_time_s, dtype=float)
        # the signals' values laid end to end, a NaN after each signal's (where a run of rows that ends at
        # the part's end stops, and what a run with no row reads): row r of signal s at s·(n + 1) + r
        flat = np.full((signals, n + 1), np.nan)
        flat[:, :n] = np.asarray(values, dtype=float).reshape(n, signals).T
        # per signal and row: the row of its last value up to the row before (-1: none yet, read as the NaN)
        last_row = np.full((signals, n + 1), -1, dtype=np.int64)
        np.maximum.accumulate(
            np.where(np.isfinite(flat[:, :n]), np.arange(n), -1), axis=1, out=last_row[:, 1:]
        )
        low, high, last = self.pending
        out = np.zeros(st.size)
        since = np.zeros(signals, dtype=np.int64)  # each signal's first row after its last sample
        if st.size:
            # the samples by signal, then time (ties in the order given); each one's values are the rows
            # from the signal's sample before (or the part's start) up to its time, its own time included
            order = np.lexsort((st, sig))
            s, end = sig[order], np.searchsorted(vt, st[order], side="right")
            first = np.ones(s.size, dtype=bool)
            first[1:] = s[1:] != s[:-1]
            base = s * (n + 1)
            stop = base + end
            start = np.empty(s.size, dtype=np.int64)
            start[0] = base[0]
            start[1:] = np.where(first[1:], base[1:], stop[:-1])
            # each sample's rows reduced where it has any (NaN where none): only those windows go to
            # reduceat, so that what it also reduces between two of them (the odd places, dropped) is
            # empty within a signal; with every sample's window there, each sample without a row reduced
            # from the row before's end to its signal's last row, at each such sample (quadratic: on a
            # 60-minute log, commands at 10 Hz and ESCs at 25-50 Hz, 1.6 s of a 2.2-s read)
            rows_in = start < stop
            bounds = np.column_stack([start[rows_in], stop[rows_in]]).ravel()
            lowest, highest = np.full(s.size, np.nan), np.full(s.size, np.nan)
            if bounds.size:
                lowest[rows_in] = np.fmin.reduceat(flat.ravel(), bounds)[::2]
                highest[rows_in] = np.fmax.reduceat(flat.ravel(), bounds)[::2]
            lowest = np.where(first, np.fmin(lowest, low[s]), lowest)  # with the values carried
            highest = np.where(first, np.fmax(highest, high[s]), highest)
            # held at each sample: the last value up to it, else the last carried since the sample before,
            # else the one held at the sample before
            carried = np.where(np.isnan(last[s]), self.held[s], last[s])
            row = last_row[s, end]
            held_now = np.where(row >= 0, flat[s, row], carried)
            held_before = np.empty(s.size)
            held_before[1:] = held_now[:-1]
            held_before = np.where(first, self.held[s], held_before)
            above = highest - np.fmax(held_before, held_now)
            below = np.fmin(held_before, held_now) - lowest
            # no value since the sample before: NaN, so 0; nothing held at the sample before (the first
            # sample, values only since): nothing to go beyond
            out[order] = np.where(np.isnan(held_before), 0.0, np.fmax(np.fmax(above, below), 0.0))
            # carried: the value held at each signal's last sample; its values since start afresh
            final = np.ones(s.size, dtype=bool)
            final[:-1] = first[1:]
            done = s[final]
            self.held[done] = held_now[final]
            low[done] = high[done] = last[done] = np.nan
            since[done] = end[final]
        # each signal's values after its last sample (all of them for a signal with none) join what it
        # carries: the rows from ``since`` to its NaN (the NaN alone where there are none)
        nan_at = np.arange(signals) * (n + 1) + n
        after = np.empty(2 * signals, dtype=np.int64)
        after[0::2] = np.where(since < n, nan_at - n + since, nan_at)
        after[1::2] = nan_at
        if n:
            low[:] = np.fmin(low, np.fmin.reduceat(flat.ravel(), after)[::2])
            high[:] = np.fmax(high, np.fmax.reduceat(flat.ravel(), after)[::2])
            row = last_row[np.arange(signals), n]
            fresh = row >= since
            last[fresh] = flat[fresh, row[fresh]]
        return out


def _search_right(t_source: NDArray[np.float64], t_target: NDArray[np.float64]) -> NDArray[np.int64]:
    """``np.searchsorted(t_source, t_target, side="right")`` (``t_source`` sorted) for targets made of runs
    in increasing time (a table's motors, by motor then time): each run merged with the sources, and looked
    up once for runs of the very same times (the motors one message stamps)."""
    if t_target.ndim != 1 or t_target.size < 2 * t_source.size or not np.isfinite(t_source).all():
        return np.searchsorted(t_source, t_target, side="right")
    breaks = np.flatnonzero(t_target[1:] < t_target[:-1]) + 1
    if breaks.size > 64 or not np.isfinite(t_target).all():
        return np.searchsorted(t_source, t_target, side="right")
    out = np.empty(t_target.shape, dtype=np.intp)
    done: list[tuple[int, int]] = []
    for a, b in zip([0, *breaks.tolist()], [*breaks.tolist(), t_target.size]):
        run = t_target[a:b]
        same = next(
            (d for d in done if d[1] - d[0] == b - a and np.array_equal(t_target[d[0] : d[1]], run)), None
        )
        if same is not None:
            out[a:b] = out[same[0] : same[1]]
            continue
        # the sources at or before each target: source i counts from the first target not below it on
        counted_from = np.searchsorted(run, t_source, side="left")
        out[a:b] = np.cumsum(np.bincount(counted_from, minlength=run.size + 1)[: run.size])
        done.append((a, b))
    return out


def _grouped_in_time(signal: NDArray[np.int64], time_s: NDArray[np.float64]) -> bool:
    """Whether entries are already ordered by signal, then time (what a stable sort would leave as it is)."""
    step = np.diff(signal)
    return bool((step >= 0).all() and ((step > 0) | (np.diff(time_s) >= 0)).all())


def held_together(
    series: Mapping[str, Series], target_time_s: NDArray[np.float64], max_age_s: float
) -> dict[str, NDArray[np.float64]]:
    """:func:`held` of several signals at once (values only): signals that share their times (the same
    array: fields of one message) are looked up together."""
    groups: dict[int, list[str]] = {}
    for name, (times, _) in series.items():
        groups.setdefault(id(times), []).append(name)
    # a value held at a time depends on that time alone: runs of the very same times (the motors one
    # message stamps) are looked up once and copied
    targets, runs = _distinct_runs(np.asarray(target_time_s, dtype=float))
    out = {}
    for names in groups.values():
        times = series[names[0]][0]
        values = np.column_stack([np.asarray(series[name][1], dtype=float) for name in names])
        value, _ = HeldValues(len(names), max_age_s).hold(times, values, targets)
        for k, name in enumerate(names):
            out[name] = value[:, k] if runs is None else _copied_runs(value[:, k], runs)
    return out


#: :func:`_distinct_runs` looks for repeated runs among at most this many runs of increasing times
_MAX_RUNS = 64


def _distinct_runs(
    time_s: NDArray[np.float64],
) -> tuple[NDArray[np.float64], list[tuple[int, int, int]] | None]:
    """Times made of runs in increasing time (a table's motors, by motor then time) with each run that
    repeats an earlier one left out, and where each run's values are in them (start, end, start there);
    the times themselves and None where no run repeats (or there are too many runs to look)."""
    breaks = np.flatnonzero(time_s[1:] < time_s[:-1]) + 1
    if breaks.size == 0 or breaks.size > _MAX_RUNS:
        return time_s, None
    runs: list[tuple[int, int, int]] = []
    kept: list[tuple[int, int, int]] = []  # the distinct runs: where in the times, where in the kept ones
    size = 0
    for a, b in zip([0, *breaks.tolist()], [*breaks.tolist(), time_s.size]):
        same = next(
            (at for ka, kb, at in kept if kb - ka == b - a and np.array_equal(time_s[ka:kb], time_s[a:b])),
            None,
        )
        if same is None:
            same = size
            kept.append((a, b, size))
            size += b - a
        runs.append((a, b, same))
    if len(kept) == len(runs):
        return time_s, None
    return np.concatenate([time_s[a:b] for a, b, _ in kept]), runs


def _copied_runs(values: NDArray[np.float64], runs: list[tuple[int, int, int]]) -> NDArray[np.float64]:
    """:func:`_distinct_runs`' values put back in every run."""
    out = np.empty(runs[-1][1])
    for a, b, at in runs:
        out[a:b] = values[at : at + b - a]
    return out


def pairing_uncertainty(
    command_age_s: ArrayLike, message_interval_s: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Each sample's pairing uncertainty [s] (the module doc): the larger of its held command's age (NaN:
    no command, NaN out) and, where the samples are stamped by the message that carried them, the interval
    of the motor's messages (:class:`MessageIntervals`; NaN, a first message: 0); ``message_interval_s``
    None: samples with their own time."""
    age = np.asarray(command_age_s, dtype=float)
    if message_interval_s is None:
        return age.copy()
    interval = np.asarray(message_interval_s, dtype=float)
    return np.maximum(age, np.where(np.isnan(interval), 0.0, interval))


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
    stamped_by_message: bool | None = None,
) -> TelemetryTable:
    """The telemetry table of one log.

    ``motor_of_slot`` maps ESC slots to motor numbers (None: the slot drives no motor; its samples are
    dropped). ``commands`` maps a motor number to its throttle series. Where the ESC reports no voltage
    (0 or NaN), the battery voltage stands in for ``bus_voltage_v``. ``stamped_by_message``: the ESC
    samples are stamped by the message that carried each ESC's last packet (the module doc; None: where
    the reader gives a ``sample_time_uncertainty_s``, as the .tlog reader does). Every ESC row counts
    there, a repeated packet's (no measurement) too.
    """
    if stamped_by_message is None:
        stamped_by_message = bool(meta.get("sample_time_uncertainty_s"))
    slots = np.asarray(esc.slot, dtype=np.int64)
    # an ESC index outside 0..31 is a damaged record (autopilots number at most 32 ESCs): dropped
    in_range = (slots >= 0) & (slots < MAX_ESC_SLOTS)
    slot_motor = np.zeros(MAX_ESC_SLOTS, dtype=np.int64)
    for slot in np.flatnonzero(np.bincount(slots[in_range], minlength=MAX_ESC_SLOTS)).tolist():
        slot_motor[slot] = motor_of_slot.get(int(slot)) or 0
    motors_all = np.where(in_range, slot_motor[np.clip(slots, 0, MAX_ESC_SLOTS - 1)], 0)
    keep = np.flatnonzero(motors_all > 0)
    # Rows ordered by motor, then time: logs write ESC samples in time order, or each motor's in time
    # order, so a stable sort by motor is enough; otherwise sort by both.
    t_kept, m_kept = esc.time_s[keep], motors_all[keep]
    by_motor = np.argsort(m_kept.astype(np.uint8) if m_kept.max(initial=0) < 256 else m_kept, kind="stable")
    if _grouped_in_time(m_kept[by_motor], t_kept[by_motor]):
        keep = keep[by_motor]  # what sorting by motor, then time, gives
    else:
        keep = keep[np.lexsort((t_kept, m_kept))]
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
    # how far each sample's command went beyond the two held ones since the motor's sample before (in
    # throttle here, in volts once the bus voltage is known); rows without a measurement are no samples
    measured = np.isfinite(columns["omega_rad_s"]) | np.isfinite(columns["current_a"])
    excursion = np.where(measured, 0.0, np.nan)  # a motor with no commands: nothing seen to move
    for m, series in commands.items():
        sel = np.flatnonzero((motors == m) & measured)
        if sel.size:
            excursion[sel] = CommandExcursions(1).beyond_held(
                series[0], series[1], np.zeros(sel.size), time_s[sel]
            )
    interval = None
    if stamped_by_message:
        interval = MessageIntervals(int(motors.max(initial=0))).since_previous(time_s, motors - 1)
    columns["pairing_s"] = pairing_uncertainty(command_age, interval)
    columns["command_age_s"] = command_age
    meta = dict(meta)
    # A summary of the pairing for the warnings and the report (the diagnosis weighs each sample's own
    # ``pairing_s``): the held command's age (95th percentile), or how uncertain the sample's own time is if
    # that is more (the reader says: a .tlog's ESC packet is up to one message interval older than its
    # stamp). The balance rule needs them within a few milliseconds in gusty flight (docs/flight.md,
    # section 6, "Through the logs").
    ages = command_age[np.isfinite(command_age)]
    if ages.size:
        meta["command_age_s"] = float(np.percentile(ages, 95))
        meta["pairing_s"] = max(meta["command_age_s"], float(meta.get("sample_time_uncertainty_s") or 0.0))
    # the context held at each sample, signals that share their times looked up together
    wanted = {name: series for name, series in context.items() if len(series[0])}
    with_battery = battery_voltage is not None and len(battery_voltage[0]) > 0
    if with_battery:
        wanted[" battery"] = battery_voltage  # type: ignore[assignment]
    found = held_together(wanted, time_s, CONTEXT_MAX_AGE_S)
    if with_battery:
        columns["bus_voltage_v"] = bus_voltage_or_battery(columns["bus_voltage_v"], found.pop(" battery"))
    for name in context:
        if name in found:
            columns[name] = found[name]
    # What the motor sees, exactly as the live agent computes it (ESC as an ideal PWM stage):
    # voltage_v = throttle × bus voltage, current_a = ESC current / throttle (NaN at a tiny command).
    columns["voltage_v"], columns["current_a"] = mavlink_esc.motor_inputs(
        throttle, columns["bus_voltage_v"], columns["esc_current_a"]
    )
    columns["input_excursion_v"] = excursion_v(excursion, columns["bus_voltage_v"])
    return TelemetryTable(columns, source=str(path), meta=meta)


def excursion_v(excursion: ArrayLike, bus_voltage_v: ArrayLike) -> NDArray[np.float64]:
    """``input_excursion_v`` (module doc) from the excursion in throttle: times the bus voltage (the ESC as
    an ideal PWM stage, as :func:`.mavlink_esc.motor_inputs`); 0 where the bus voltage is unknown, NaN
    where the excursion is (no sample)."""
    e = np.asarray(excursion, dtype=float)
    bus = np.asarray(bus_voltage_v, dtype=float)
    return np.where(np.isfinite(bus) & (bus > 0), e * bus, np.where(np.isnan(e), np.nan, 0.0))


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
