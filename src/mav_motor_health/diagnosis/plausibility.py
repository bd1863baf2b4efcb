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
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError
from ..model.dynamics import ResponseCarry, first_order_response

__all__ = [
    "CurrentSumCheck",
    "PlausibilityCarry",
    "PlausibilityRule",
    "SensorIssue",
    "StuckCarry",
    "check_motor",
    "stuck_mask",
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


CURRENT_UNTRUSTED = (
    SensorIssue.CURRENT_MISSING
    | SensorIssue.CURRENT_STUCK
    | SensorIssue.CURRENT_RANGE
    | SensorIssue.CURRENT_SUM
    | SensorIssue.CURRENT_UNPAIRED
)
SPEED_UNTRUSTED = SensorIssue.SPEED_MISSING | SensorIssue.SPEED_STUCK | SensorIssue.SPEED_RANGE


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
    v = np.asarray(value, dtype=float)
    n = t.size
    if n == 0:
        return np.zeros(0, bool), carry
    c = np.asarray(command, dtype=float)
    # forward-fill missing commands (hold the last one), starting from the carry's range midpoint
    fill = 0.5 * (carry.command_max + carry.command_min) if np.isfinite(carry.command_max) else 0.0
    idx = np.maximum.accumulate(np.where(np.isfinite(c), np.arange(n), -1))
    c = np.where(idx >= 0, c[np.maximum(idx, 0)], fill)
    c = np.clip(c, 0.0, 1.0)
    previous = np.concatenate([[carry.value], v[:-1]])
    change = ~(v == previous)  # NaN never equals: a missing value starts a new segment
    seg = np.cumsum(change)  # segment 0 continues the carried one
    since = np.where(change, t, np.nan)
    since[0] = t[0] if change[0] or not np.isfinite(carry.since_s) else carry.since_s
    idx = np.maximum.accumulate(np.where(np.isfinite(since), np.arange(n), 0))
    since = since[idx]
    lift = 2.0 * seg
    run_max = np.maximum.accumulate(c + lift) - lift
    run_min = -(np.maximum.accumulate(-c + lift) - lift)
    if not change[0] and np.isfinite(carry.command_max):
        first = seg == 0
        run_max[first] = np.maximum(run_max[first], carry.command_max)
        run_min[first] = np.minimum(run_min[first], carry.command_min)
    stuck = (t - since >= rule.stuck_s) & (run_max - run_min >= rule.min_command_change) & np.isfinite(v)
    return stuck, StuckCarry(
        value=float(v[-1]),
        since_s=float(since[-1]),
        command_max=float(run_max[-1]),
        command_min=float(run_min[-1]),
    )


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
    i = np.asarray(sensor_current_a, dtype=float)
    w = np.asarray(omega_rad_s, dtype=float)
    cmd = np.full(t.shape, np.nan) if command is None else np.asarray(command, dtype=float)
    flags = np.zeros(t.shape, dtype=np.int16)
    flags[~np.isfinite(i)] |= SensorIssue.CURRENT_MISSING
    flags[~np.isfinite(w)] |= SensorIssue.SPEED_MISSING
    flags[(i < rule.current_min_a) | (i > rule.current_max_a)] |= SensorIssue.CURRENT_RANGE
    flags[(w < 0) | (w > rule.speed_max_rad_s)] |= SensorIssue.SPEED_RANGE
    i_stuck, current_carry = stuck_mask(rule, t, i, cmd, carry.current)
    w_stuck, speed_carry = stuck_mask(rule, t, w, cmd, carry.speed)
    flags[i_stuck] |= SensorIssue.CURRENT_STUCK
    flags[w_stuck & (w > 0)] |= SensorIssue.SPEED_STUCK  # a motor at rest reads 0 whatever its command
    return flags, PlausibilityCarry(current=current_carry, speed=speed_carry)


@dataclass(frozen=True)
class SumCarry:
    esc: ResponseCarry = field(default_factory=ResponseCarry)
    battery: ResponseCarry = field(default_factory=ResponseCarry)
    start_s: float = float("nan")


#: the sum is judged once its averages hold this share of ``sum_tau_s``
SUM_MIN_SHARE = 0.2


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
    esc, esc_carry = first_order_response(t, esc_in, tau, carry.esc)
    bat, bat_carry = first_order_response(t, bat_in, tau, carry.battery)
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
    ) -> NDArray[np.bool_]:
        """Whether the sum disagrees with the battery at each row (rows in time order)."""
        t = np.asarray(time_s, dtype=float)
        m = np.asarray(motor, dtype=np.int64)
        i = np.asarray(esc_current_a, dtype=float)
        total = np.zeros(t.shape)
        positions = np.arange(t.size)
        for k, number in enumerate(self.motors):
            own = (m == number) & np.isfinite(i)
            # the position of the motor's latest reading at or before each row (−1: none in this call)
            last = np.maximum.accumulate(np.where(own, positions, -1)) if t.size else positions
            held = np.where(last >= 0, i[np.maximum(last, 0)], self.latest[k])
            total += held  # NaN until this motor has reported: no sum yet
            if t.size and last[-1] >= 0:
                self.latest[k] = i[last[-1]]
        # the two averages start together: each only where both are known
        battery = np.asarray(battery_current_a, dtype=float)
        known = np.isfinite(total) & np.isfinite(battery)
        total, battery = np.where(known, total, np.nan), np.where(known, battery, np.nan)
        mismatch, _, self.carry = sum_mismatch(self.rule, t, total, battery, self.carry)
        return mismatch
