"""Can the sensors be believed? Plausibility checks on each motor's telemetry, before any diagnosis.

Fleets fly ESCs that report RPM only, or a current that is stuck, constant (ArduPilot's stock SITL reports
0.80 A for every motor whatever the load), out of range or mis-scaled. A motor fault must never be
announced from such a signal; the sensor problem is reported instead and the motor is diagnosed from what
can be trusted (see the tree's speed-only mode).

Per motor, causal, carried between calls (live and replay run the same code):

* **stuck**: the reported value has not changed for ``stuck_s`` while the command moved by at least
  ``min_command_change`` (a real sensor's last digit moves when the load does);
* **out of range**: ESC current outside ``current_min_a``..``current_max_a``, speed outside
  0..``speed_max_rad_s``;
* **sum** (across motors, :class:`CurrentSumCheck`, :func:`sum_mismatch`): the ESC input currents' sum
  against the battery monitor's current, both smoothed over ``sum_tau_s``: a ratio outside
  1 ± ``sum_tolerance`` while the battery draws more than ``sum_min_battery_a`` marks every ESC current as
  mis-scaled (or the battery monitor: we cannot tell which, so the ESC currents are not used). The sum is
  each motor's latest reading, formed once every motor has reported (a partial sum is no sum).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError
from ..model.dynamics import ResponseCarry, first_order_responses, last_of, previous

__all__ = [
    "CurrentSumCheck",
    "PlausibilityCarry",
    "PlausibilityRule",
    "SensorIssue",
    "StuckCarry",
    "check_motor",
    "check_motor_rows",
    "stuck_mask",
    "stuck_mask_rows",
    "sum_mismatch",
]


class SensorIssue(enum.IntFlag):
    """Why a motor's signals are not trusted (bit flags, 0 = all plausible)."""

    NONE = 0
    CURRENT_MISSING = 1
    CURRENT_STUCK = 2
    CURRENT_RANGE = 4
    CURRENT_SUM = 8
    SPEED_MISSING = 16
    SPEED_STUCK = 32
    SPEED_RANGE = 64
    #: the log pairs samples with commands too loosely for the current's balance (diagnosis/pairing.py)
    CURRENT_UNPAIRED = 128

    @classmethod
    def describe(cls, code: int) -> str:
        names = [flag.name.lower() for flag in cls if flag and code & flag and flag.name]
        return ",".join(names) if names else "ok"


#: the flags that set the current (the speed) aside, as plain ints: masks for numpy on the core's hot path,
#: where an enum operand costs more than the operation (states.Code)
CURRENT_UNTRUSTED = int(
    SensorIssue.CURRENT_MISSING
    | SensorIssue.CURRENT_STUCK
    | SensorIssue.CURRENT_RANGE
    | SensorIssue.CURRENT_SUM
    | SensorIssue.CURRENT_UNPAIRED
)
SPEED_UNTRUSTED = int(SensorIssue.SPEED_MISSING | SensorIssue.SPEED_STUCK | SensorIssue.SPEED_RANGE)


@dataclass(frozen=True)
class PlausibilityRule:
    stuck_s: float = 2.0
    min_command_change: float = 0.05
    current_min_a: float = -1.0
    current_max_a: float = 200.0
    speed_max_rad_s: float = 6000.0
    sum_tolerance: float = 0.35
    sum_min_battery_a: float = 3.0
    sum_tau_s: float = 5.0
    #: a pairing error (diagnosis/pairing.py) above this share of the speed band: the current is not used
    pairing_current_share: float = 1.0
    #: ... above this share of the speed-only band: the sample is not judged
    pairing_speed_share: float = 0.5

    def __post_init__(self) -> None:
        if not (
            self.stuck_s > 0
            and self.min_command_change >= 0
            and self.current_max_a > self.current_min_a
            and self.speed_max_rad_s > 0
            and 0 < self.sum_tolerance < 1
            and self.sum_tau_s > 0
            and self.pairing_current_share > 0
            and self.pairing_speed_share > 0
        ):
            raise ConfigError(
                "inconsistent plausibility limits",
                key="plausibility",
                expected=(
                    "stuck_s > 0, current_max_a > current_min_a, 0 < sum_tolerance < 1, "
                    "pairing shares > 0, ..."
                ),
            )


@dataclass(frozen=True)
class StuckCarry:
    value: float = float("nan")
    since_s: float = float("nan")
    command_max: float = float("nan")
    command_min: float = float("nan")


def stuck_mask(
    rule: PlausibilityRule,
    time_s: NDArray[np.float64],
    value: NDArray[np.float64],
    command: NDArray[np.float64],
    carry: StuckCarry = StuckCarry(),
) -> tuple[NDArray[np.bool_], StuckCarry]:
    """True where ``value`` has been frozen for ``stuck_s`` while ``command`` (0..1) moved."""
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return np.zeros(0, bool), carry
    stuck, (new,) = stuck_mask_rows(
        rule,
        t.reshape(1, -1),
        np.asarray(value, dtype=float).reshape(1, -1),
        np.asarray(command, dtype=float).reshape(1, -1),
        [carry],
    )
    return stuck[0], new


def stuck_mask_rows(
    rule: PlausibilityRule,
    time_s: NDArray[np.float64],
    value: NDArray[np.float64],
    command: NDArray[np.float64],
    carries: list[StuckCarry],
    lengths: list[int] | None = None,
) -> tuple[NDArray[np.bool_], list[StuckCarry]]:
    """:func:`stuck_mask` of several motors at once: rows of samples (2-D), one carry per row;
    ``lengths`` each row's number of samples (None: all; the rest is padding after them)."""
    t, v = time_s, value
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    positions = np.arange(n)
    # forward-fill missing commands (hold the last one), starting from the carry's range midpoint
    fill = np.array(
        [[0.5 * (c.command_max + c.command_min) if np.isfinite(c.command_max) else 0.0] for c in carries]
    )
    finite = np.isfinite(command)
    c = command  # nothing to fill (a log's commands, mostly): each sample holds its own
    if not finite.all():
        idx = np.maximum.accumulate(np.where(finite, positions, -1), axis=1)
        c = np.where(idx >= 0, np.take_along_axis(command, np.maximum(idx, 0), axis=1), fill)
    c = np.clip(c, 0.0, 1.0)
    change = ~(v == previous(v, [k.value for k in carries]))  # NaN never equals: a new segment
    seg = np.cumsum(change, axis=1)  # segment 0 continues the carried one
    since = np.where(change, t, np.nan)
    carried_since = np.array([k.since_s for k in carries])
    since[:, 0] = np.where(change[:, 0] | ~np.isfinite(carried_since), t[:, 0], carried_since)
    idx = np.maximum.accumulate(np.where(np.isfinite(since), positions, 0), axis=1)
    since = np.take_along_axis(since, idx, axis=1)
    lift = 2.0 * seg
    run_max = np.maximum.accumulate(c + lift, axis=1) - lift
    run_min = -(np.maximum.accumulate(-c + lift, axis=1) - lift)
    carried_max = np.array([[k.command_max] for k in carries])
    carried_min = np.array([[k.command_min] for k in carries])
    first = (seg == 0) & (~change[:, :1] & np.isfinite(carried_max))
    if first.any():
        run_max = np.where(first, np.maximum(run_max, carried_max), run_max)
        run_min = np.where(first, np.minimum(run_min, carried_min), run_min)
    stuck = (t - since >= rule.stuck_s) & (run_max - run_min >= rule.min_command_change) & np.isfinite(v)
    news = [
        carry
        if last_v is None
        else StuckCarry(value=last_v, since_s=since_s, command_max=high, command_min=low)
        for carry, last_v, since_s, high, low in zip(
            carries,
            last_of(v, counts),
            last_of(since, counts),
            last_of(run_max, counts),
            last_of(run_min, counts),
        )
    ]
    return stuck, news


@dataclass(frozen=True)
class PlausibilityCarry:
    current: StuckCarry = field(default_factory=StuckCarry)
    speed: StuckCarry = field(default_factory=StuckCarry)


def check_motor(
    rule: PlausibilityRule,
    time_s: ArrayLike,
    command: ArrayLike | None,
    sensor_current_a: ArrayLike,
    omega_rad_s: ArrayLike,
    carry: PlausibilityCarry = PlausibilityCarry(),
) -> tuple[NDArray[np.int16], PlausibilityCarry]:
    """:class:`SensorIssue` flags per sample for one motor (``sensor_current_a``: the current as reported)."""
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return np.zeros(0, dtype=np.int16), carry

    def row(x: ArrayLike) -> NDArray[np.float64]:
        return np.asarray(x, dtype=float).reshape(1, -1)

    flags, (new,) = check_motor_rows(
        rule,
        row(t),
        None if command is None else row(command),
        row(sensor_current_a),
        row(omega_rad_s),
        [carry],
    )
    return flags[0], new


def check_motor_rows(
    rule: PlausibilityRule,
    time_s: NDArray[np.float64],
    command: NDArray[np.float64] | None,
    sensor_current_a: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    carries: list[PlausibilityCarry],
    lengths: list[int] | None = None,
) -> tuple[NDArray[np.int16], list[PlausibilityCarry]]:
    """:func:`check_motor` of several motors at once: rows of samples (2-D), one carry per row;
    ``lengths`` each row's number of samples (None: all; the rest is padding after them)."""
    t, i, w = time_s, sensor_current_a, omega_rad_s
    cmd = np.full(t.shape, np.nan) if command is None else command
    flags = np.zeros(t.shape, dtype=np.int16)
    flags[~np.isfinite(i)] |= int(SensorIssue.CURRENT_MISSING)
    flags[~np.isfinite(w)] |= int(SensorIssue.SPEED_MISSING)
    flags[(i < rule.current_min_a) | (i > rule.current_max_a)] |= int(SensorIssue.CURRENT_RANGE)
    flags[(w < 0) | (w > rule.speed_max_rad_s)] |= int(SensorIssue.SPEED_RANGE)
    # the current's and the speed's stuck checks in one call: the same samples and commands
    rows = t.shape[0]
    stuck, stuck_carries = stuck_mask_rows(
        rule,
        np.concatenate([t, t]),
        np.concatenate([i, w]),
        np.concatenate([cmd, cmd]),
        [c.current for c in carries] + [c.speed for c in carries],
        None if lengths is None else lengths * 2,
    )
    flags[stuck[:rows]] |= int(SensorIssue.CURRENT_STUCK)
    # a motor at rest reads 0 whatever its command
    flags[stuck[rows:] & (w > 0)] |= int(SensorIssue.SPEED_STUCK)
    news = [PlausibilityCarry(current=stuck_carries[r], speed=stuck_carries[rows + r]) for r in range(rows)]
    return flags, news


@dataclass(frozen=True)
class SumCarry:
    esc: ResponseCarry = field(default_factory=ResponseCarry)
    battery: ResponseCarry = field(default_factory=ResponseCarry)
    start_s: float = float("nan")


#: no rows (a motor without any in a call)
_NO_ROWS = np.zeros(0, dtype=np.intp)
#: the sum is judged once its averages hold this share of ``sum_tau_s``
SUM_MIN_SHARE = 0.2
#: up to this many rows (the live agent's batches) the sums are formed row by row
_SUM_LOOP_MAX = 64


def sum_mismatch(
    rule: PlausibilityRule,
    time_s: ArrayLike,
    esc_current_sum_a: ArrayLike,
    battery_current_a: ArrayLike,
    carry: SumCarry = SumCarry(),
) -> tuple[NDArray[np.bool_], NDArray[np.float64], SumCarry]:
    """Where the ESC currents' sum disagrees with the battery monitor; also returns the smoothed ratio.

    Both are averaged over ``sum_tau_s``; until that long has passed since the first sample with both,
    over all samples so far (a first reading taken in a transient would otherwise weigh for many
    seconds), and judged from :data:`SUM_MIN_SHARE` of it on.
    """
    t = np.asarray(time_s, dtype=float)
    esc_in = np.asarray(esc_current_sum_a, dtype=float)
    bat_in = np.asarray(battery_current_a, dtype=float)
    start = carry.start_s
    if not np.isfinite(start):
        both = np.flatnonzero(np.isfinite(esc_in) & np.isfinite(bat_in))
        start = float(t[both[0]]) if both.size else float("nan")
    elapsed = t - start  # NaN before a start: the low-passes then hold (NaN inputs)
    tau = np.clip(np.where(np.isfinite(elapsed), elapsed, rule.sum_tau_s), 1e-3, rule.sum_tau_s)
    (esc, bat), (esc_carry, bat_carry) = first_order_responses(
        t, np.stack([esc_in, bat_in]), tau, [carry.esc, carry.battery]
    )
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = esc / bat
    mismatch = (
        (bat > rule.sum_min_battery_a)
        & (np.abs(ratio - 1.0) > rule.sum_tolerance)
        & (elapsed >= SUM_MIN_SHARE * rule.sum_tau_s)
    )
    return mismatch, ratio, SumCarry(esc=esc_carry, battery=bat_carry, start_s=start)


class CurrentSumCheck:
    """The ESC currents' sum against the battery monitor, fed samples of any motors in arrival order.

    Replay feeds a whole log's rows (in time order) in one call, the live agent each message's samples as
    they come: the same rows give the same flags. Each row adds its motor's reading (NaN: none, the
    motor's last one stays) and is judged with the sum of every motor's latest reading and the row's
    battery current.
    """

    def __init__(self, rule: PlausibilityRule, motors: ArrayLike) -> None:
        self.rule = rule
        self.motors = [int(m) for m in np.unique(np.asarray(motors, dtype=np.int64))]
        self.latest = np.full(len(self.motors), np.nan)  # each motor's latest reading [A]
        self.carry = SumCarry()

    def update(
        self,
        time_s: ArrayLike,
        motor: ArrayLike,
        esc_current_a: ArrayLike,
        battery_current_a: ArrayLike,
        motor_rows: Mapping[int, NDArray[np.intp]] | None = None,
    ) -> NDArray[np.bool_]:
        """Whether the sum disagrees with the battery at each row (rows in time order). ``motor_rows``:
        each motor's rows (increasing) where the caller knows them (then not searched for)."""
        t = np.asarray(time_s, dtype=float)
        m = np.asarray(motor, dtype=np.int64)
        i = np.asarray(esc_current_a, dtype=float)
        total = self._sums(m, i) if t.size <= _SUM_LOOP_MAX else self._sums_vectorised(t, m, i, motor_rows)
        # the two averages start together: each only where both are known
        battery = np.asarray(battery_current_a, dtype=float)
        known = np.isfinite(total) & np.isfinite(battery)
        total, battery = np.where(known, total, np.nan), np.where(known, battery, np.nan)
        mismatch, _, self.carry = sum_mismatch(self.rule, t, total, battery, self.carry)
        return mismatch

    def _sums(self, m: NDArray[np.int64], i: NDArray[np.float64]) -> NDArray[np.float64]:
        """The sum of every motor's latest reading at each row, row by row (a few rows)."""
        slot = {number: k for k, number in enumerate(self.motors)}
        latest = self.latest.tolist()
        total = np.empty(m.size)
        for r, (number, reading) in enumerate(zip(m.tolist(), i.tolist())):
            k = slot.get(number)
            if k is not None and math.isfinite(reading):
                latest[k] = reading
            value = 0.0
            for held in latest:  # in the motors' order, as the vectorised sum adds them
                value += held
            total[r] = value
        self.latest = np.array(latest)
        return total

    def _sums_vectorised(
        self,
        t: NDArray[np.float64],
        m: NDArray[np.int64],
        i: NDArray[np.float64],
        motor_rows: Mapping[int, NDArray[np.intp]] | None = None,
    ) -> NDArray[np.float64]:
        total = np.zeros(t.shape)
        finite = np.isfinite(i)
        for k, number in enumerate(self.motors):
            # the motor's readings in this call: each is its latest from its row up to the next one's
            if motor_rows is None:
                own = np.flatnonzero((m == number) & finite)
            else:
                rows = motor_rows.get(number, _NO_ROWS)
                own = rows[finite[rows]]
            if own.size == 0:
                total += self.latest[k]  # NaN until this motor has reported: no sum yet
                continue
            total[: own[0]] += self.latest[k]  # before its first reading: the carried one
            total[own[0] :] += np.repeat(i[own], np.diff(own, append=t.size))
            self.latest[k] = i[own[-1]]
        return total
