"""Motor health as MAVLink: STATUSTEXT lines, NAMED_VALUE_INT/FLOAT and the MOTOR_HEALTH message.

* STATUSTEXT (at most 50 characters, MAVLink's field size): ``Motor 3: propeller damage (F3.1)``.
  Severity CRITICAL for a stopped motor (F2.1 phase open, F4.2 back-EMF error), WARNING for any other
  fault, for silence and implausible sensors, INFO when a motor is back to normal.
* :class:`StatustextGate` rate-limits them: one token bucket per motor (``burst`` lines, then one per
  ``interval_s``); a change that finds the bucket empty is not lost but *coalesced*: the motor's latest
  state goes out as soon as a token is back, unless it is by then the state last sent.
* NAMED_VALUE_INT ``MH_M<n>`` = announced state code; NAMED_VALUE_FLOAT ``MH_W<n>`` = measured minus
  modelled speed [rad/s] and ``MH_I<n>`` = measured minus modelled current [A] (names ≤ 10 characters).

Message objects are built with the caller's pymavlink encoder (``link.mav``); nothing here does I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..diagnosis.states import MotorState

__all__ = [
    "MAV_SEVERITY_CRITICAL",
    "MAV_SEVERITY_INFO",
    "MAV_SEVERITY_WARNING",
    "STATUSTEXT_MAX",
    "StatustextGate",
    "TokenBucket",
    "motor_health_message",
    "named_value_messages",
    "severity_for",
    "statustext_for",
    "statustext_message",
]

STATUSTEXT_MAX = 50
MAV_SEVERITY_CRITICAL = 2
MAV_SEVERITY_WARNING = 4
MAV_SEVERITY_INFO = 6
_STOPPED = frozenset({MotorState.F2_1, MotorState.F4_2, MotorState.STALLED})


def severity_for(state: MotorState) -> int:
    """MAV_SEVERITY of a state's STATUSTEXT."""
    if state in _STOPPED:
        return MAV_SEVERITY_CRITICAL
    if state == MotorState.NORMAL:
        return MAV_SEVERITY_INFO
    return MAV_SEVERITY_WARNING


def statustext_for(motor: int, state: MotorState) -> str:
    """The line for a motor's new state, at most :data:`STATUSTEXT_MAX` characters."""
    if state == MotorState.NORMAL:
        text = f"Motor {motor}: normal"
    elif state == MotorState.NO_DATA:
        text = f"Motor {motor}: no ESC telemetry"
    else:
        text = f"Motor {motor}: {state.description} ({state.label})"
    return text[:STATUSTEXT_MAX]


@dataclass
class TokenBucket:
    """``capacity`` tokens, refilled at ``rate_per_s``; ``take(now)`` spends one if there is one."""

    capacity: float
    rate_per_s: float
    tokens: float = math.nan
    stamp_s: float = math.nan

    def take(self, now_s: float) -> bool:
        if math.isnan(self.tokens):
            self.tokens, self.stamp_s = self.capacity, now_s
        self.tokens = min(self.capacity, self.tokens + max(0.0, now_s - self.stamp_s) * self.rate_per_s)
        self.stamp_s = now_s
        if self.tokens >= 1.0:
            self.tokens -= 1.0
            return True
        return False


@dataclass
class StatustextGate:
    """Per-motor rate limit for state STATUSTEXTs that never loses the latest state."""

    burst: float = 3.0
    interval_s: float = 5.0
    buckets: dict[int, TokenBucket] = field(default_factory=dict)
    last_sent: dict[int, MotorState] = field(default_factory=dict)
    pending: dict[int, MotorState] = field(default_factory=dict)
    suppressed: int = 0

    def offer(self, motor: int, state: MotorState, now_s: float) -> bool:
        """A new state for a motor: True if its line may go out now (else it waits in ``pending``)."""
        self.pending[motor] = state
        return bool(self.due(now_s, only=motor))

    def due(self, now_s: float, only: int | None = None) -> list[tuple[int, MotorState]]:
        """Pending states that may go out now (removed from ``pending``, recorded as sent)."""
        out = []
        for motor, state in list(self.pending.items()):
            if only is not None and motor != only:
                continue
            if self.last_sent.get(motor) == state:
                del self.pending[motor]  # flapped back before it could be sent: nothing to say
                continue
            bucket = self.buckets.setdefault(motor, TokenBucket(self.burst, 1.0 / self.interval_s))
            if bucket.take(now_s):
                del self.pending[motor]
                self.last_sent[motor] = state
                out.append((motor, state))
            else:
                self.suppressed += 1
        return out

    def mark_sent(self, motor: int, state: MotorState) -> None:
        """Record a state as told without a line of its own (covered by a summary line)."""
        self.pending.pop(motor, None)
        self.last_sent[motor] = state


def statustext_message(mav: Any, text: str, severity: int) -> Any:
    """A STATUSTEXT message (text cut to 50 characters, ASCII)."""
    data = text.encode("ascii", "replace")[:STATUSTEXT_MAX]
    return mav.statustext_encode(severity, data)


def _finite(x: Any) -> float:
    try:
        value = float(x)
    except (TypeError, ValueError):
        return math.nan
    return value


def named_value_messages(mav: Any, time_boot_ms: int, motor: int, state: MotorState, row: dict) -> list[Any]:
    """NAMED_VALUE_INT ``MH_M<n>`` (state code) and NAMED_VALUE_FLOAT ``MH_W<n>``/``MH_I<n>`` (model error)."""
    speed_error = _finite(row.get("omega_rad_s")) - _finite(row.get("omega_model_rad_s"))
    current_error = _finite(row.get("current_a")) - _finite(row.get("current_model_a"))
    ms = time_boot_ms & 0xFFFFFFFF
    return [
        mav.named_value_int_encode(ms, f"MH_M{motor}".encode(), int(state)),
        mav.named_value_float_encode(ms, f"MH_W{motor}".encode(), speed_error),
        mav.named_value_float_encode(ms, f"MH_I{motor}".encode(), current_error),
    ]


def motor_health_message(
    dialect: Any, time_boot_ms: int, motor: int, state: MotorState, since_s: float, fresh: bool, row: dict
) -> Any:
    """The dialect's MOTOR_HEALTH message for one motor (``dialect`` from :func:`.dialect.load`)."""
    flags = (1 if row.get("steady") else 0) | (2 if fresh else 0)
    raw = row.get("state")
    return dialect.MAVLink_motor_health_message(
        time_boot_ms & 0xFFFFFFFF,
        _finite(row.get("omega_rad_s")),
        _finite(row.get("omega_model_rad_s")),
        _finite(row.get("current_a")),
        _finite(row.get("current_model_a")),
        _finite(row.get("voltage_v")),
        since_s if math.isfinite(since_s) else 0.0,
        motor,
        int(state),
        int(raw) if raw is not None else int(MotorState.NO_DATA),
        flags,
    )
