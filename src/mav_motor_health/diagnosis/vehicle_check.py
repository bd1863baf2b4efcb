"""Does the motor model describe this vehicle at all? Checked before any fault is announced.

A fault is one motor departing from the model while its siblings follow it. When *most* motors depart
from the model the same way (a bundled paper motor on a vehicle with another motor, a propeller that is
not the one fitted), the model is what is wrong, and naming a
fault on every motor would be a guess. This check keeps, per motor, the ratio of sums

    speed departure = Σ ω_measured / Σ ω_model − 1      (samples where the model sees the motor turning)

and, once enough motors have shown enough of themselves, decides for the vehicle:

- **does not fit** where more than half of the vehicle's motors depart by more than ``speed_departure``
  in the same direction: the diagnosis announces :attr:`~.states.MotorState.UNCALIBRATED` on every motor instead of faults;
- **checking** while fewer than that many motors (at least ``min_motors``) have ``min_samples`` turning
  samples over ``min_span_s``: faults are not announced yet (they are announced as soon as the
  check passes, if they still hold);
- **fits** otherwise; and always where the vehicle has fewer than ``min_motors`` motors (a single motor
  on a test stand cannot be told from its model by consensus).

The departure is dimensionless: a wrong motor type or propeller moves every motor by tens of percent (the
bundled paper motor on a real PX4 quad: −75 %; on ArduPilot SITL's hexa: −17 to −26 %), while the spread
of one motor type (KV tolerance, a few percent) and a flight's transients averaged over two seconds stay
well below the default 10 % (the simulated flights in ``sitl_logs/``, calm to gusty air: healthy motors
within ±2 %, faulty ones down to −60 %). The current is not used: in gusty air its ratio to the
steady-state model drifts by +20–30 % on healthy motors, and a current that reads wrongly on every motor
is the plausibility checks' and the identification's business. The rule is streaming: rows are fed in
time order (any motors), the carry holds a count and two sums per motor, and the live agent feeding rows one at a
time gets the same codes as replay feeding the whole log (same additions in the same order).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import distinct
from ..errors import ConfigError
from .states import MotorState

__all__ = [
    "MotorEvidence",
    "VehicleCheck",
    "VehicleCheckRule",
    "VehicleFit",
    "apply_vehicle_fit",
    "describe_vehicle_fit",
]

#: Up to this many rows (the live agent's batches) the check runs as a plain loop.
_SCALAR_MAX = 256
#: no rows (a motor without turning rows)
_NO_ROWS = np.zeros(0, dtype=np.intp)


class VehicleFit:
    """Per-row verdict codes of the vehicle check (int8)."""

    FITS = 0  # or not applicable (fewer motors than the consensus needs)
    CHECKING = 1
    SPEED_OFF = 2


@dataclass(frozen=True)
class VehicleCheckRule:
    """Settings of the vehicle check (profile section ``[vehicle_check]``)."""

    speed_departure: float = 0.10
    min_samples: int = 5
    min_span_s: float = 2.0
    min_motors: int = 3
    enabled: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.speed_departure, (int, float)) and 0 < self.speed_departure < 1):
            raise ConfigError(
                f"{self.speed_departure!r}",
                key="vehicle_check.speed_departure",
                expected="a fraction 0 < f < 1",
            )
        if not (isinstance(self.min_samples, int) and self.min_samples >= 1):
            raise ConfigError(
                f"{self.min_samples!r}", key="vehicle_check.min_samples", expected="an integer >= 1"
            )
        if not (isinstance(self.min_motors, int) and self.min_motors >= 2):
            raise ConfigError(
                f"{self.min_motors!r}", key="vehicle_check.min_motors", expected="an integer >= 2"
            )
        if not (isinstance(self.min_span_s, (int, float)) and self.min_span_s >= 0):
            raise ConfigError(
                f"{self.min_span_s!r}", key="vehicle_check.min_span_s", expected="a time >= 0 s"
            )


@dataclass
class MotorEvidence:
    """What the check has seen of one motor: its turning samples' count, sums and time span."""

    samples: int = 0
    speed_sum: float = 0.0
    speed_model_sum: float = 0.0
    first_s: float = math.inf
    last_s: float = -math.inf

    def departure(self) -> float:
        """Σ ω / Σ ω_model − 1 (NaN before the first turning sample)."""
        return self.speed_sum / self.speed_model_sum - 1.0 if self.speed_model_sum > 0 else math.nan


@dataclass
class VehicleCheck:
    """The streaming vehicle check over all motors of one vehicle.

    ``motors`` are the vehicle's motor numbers (its frame). ``stop_speed_rad_s``: below this model speed
    a motor is not turning (the tree's stop speed).
    """

    rule: VehicleCheckRule
    motors: Sequence[int]
    stop_speed_rad_s: float
    evidence: dict[int, MotorEvidence] = field(default_factory=dict)

    @property
    def applies(self) -> bool:
        return self.rule.enabled and len(self.motors) >= self.rule.min_motors

    @property
    def needed(self) -> int:
        """How many motors must have evidence for a verdict, and must agree for "does not fit"."""
        return max(self.rule.min_motors, len(self.motors) // 2 + 1)

    def update(
        self,
        time_s: ArrayLike,
        motor: ArrayLike,
        omega_rad_s: ArrayLike,
        omega_model_rad_s: ArrayLike,
        motor_rows: Mapping[int, NDArray[np.intp]] | None = None,
    ) -> NDArray[np.int8]:
        """The verdict at each row (:class:`VehicleFit` codes); rows in time order, any motors.
        ``motor_rows``: each motor's rows (increasing) where the caller knows them (then not searched
        for; every motor of the rows must have its entry)."""
        t = np.asarray(time_s, dtype=float)
        if not self.applies:
            return np.zeros(t.size, dtype=np.int8)
        m = np.asarray(motor, dtype=np.int64)
        w = np.asarray(omega_rad_s, dtype=float)
        wm = np.asarray(omega_model_rad_s, dtype=float)
        with np.errstate(invalid="ignore"):
            turning = np.isfinite(w) & np.isfinite(wm) & (wm > self.stop_speed_rad_s)
        if t.size <= _SCALAR_MAX:
            return self._update_rows(t, m, w, wm, turning)
        return self._update_arrays(t, m, w, wm, turning, motor_rows)

    def _update_rows(self, t, m, w, wm, turning) -> NDArray[np.int8]:
        # Row by row, the verdict's three counts kept up to date as one motor's evidence changes
        status = {motor: self._status(ev) for motor, ev in self.evidence.items()}
        evidenced, faster, slower = (sum(column) for column in zip((0, 0, 0), *status.values()))
        verdict = self._verdict(evidenced, faster, slower)
        out = np.empty(t.size, dtype=np.int8)
        evidence = self.evidence
        rows = zip(turning.tolist(), m.tolist(), t.tolist(), w.tolist(), wm.tolist())
        for r, (turns, motor, time_s, speed, model) in enumerate(rows):
            if turns:
                ev = evidence.get(motor)
                if ev is None:  # (not setdefault: that would build a new one for every row)
                    ev = evidence[motor] = MotorEvidence()
                ev.samples += 1
                ev.speed_sum += speed
                ev.speed_model_sum += model
                ev.first_s = min(ev.first_s, time_s)
                ev.last_s = max(ev.last_s, time_s)
                new = self._status(ev)
                old = status.get(motor, (0, 0, 0))
                if new != old:
                    status[motor] = new
                    evidenced += new[0] - old[0]
                    faster += new[1] - old[1]
                    slower += new[2] - old[2]
                    verdict = self._verdict(evidenced, faster, slower)
            out[r] = verdict
        return out

    def _status(self, ev: MotorEvidence) -> tuple[int, int, int]:
        """(has evidence, departs faster, departs slower) of one motor, as 0 or 1."""
        if ev.samples < self.rule.min_samples or ev.last_s - ev.first_s < self.rule.min_span_s:
            return (0, 0, 0)
        departure = ev.departure()
        return (1, int(departure > self.rule.speed_departure), int(departure < -self.rule.speed_departure))

    def _update_arrays(self, t, m, w, wm, turning, motor_rows=None) -> NDArray[np.int8]:
        n = t.size
        turning_rows: dict[int, NDArray[np.intp]] = {}
        if motor_rows is not None:  # each motor's turning rows from its rows
            for motor, rows in motor_rows.items():
                turning_rows[int(motor)] = rows[turning[rows]]
            seen_motors = [motor for motor, rows in turning_rows.items() if rows.size]
        else:
            seen_motors = distinct(m[turning])[0].tolist()
        motors = sorted(set(self.evidence) | {int(x) for x in seen_motors})
        # How many motors have evidence, depart faster, depart slower, at each row: each motor's share
        # changes only at its own turning rows, so the counts are sums of those changes
        changes = np.zeros((3, n), dtype=np.int64)
        before = np.zeros(3, dtype=np.int64)
        for motor in motors:
            ev = self.evidence.setdefault(motor, MotorEvidence())
            seen = (
                turning_rows.get(motor, _NO_ROWS)
                if motor_rows is not None
                else np.flatnonzero(turning & (m == motor))
            )
            # The evidence after each of the motor's turning rows (index 0: the carry, before any): the
            # additions a row-by-row run makes, in its order
            count = ev.samples + np.arange(seen.size + 1)
            speed_sum = np.cumsum(np.concatenate([[ev.speed_sum], w[seen]]))
            model_sum = np.cumsum(np.concatenate([[ev.speed_model_sum], wm[seen]]))
            # the first turning sample's time matters only once there is one (evidence needs samples)
            first = ev.first_s if seen.size == 0 else min(ev.first_s, float(t[seen[0]]))
            last = np.maximum.accumulate(np.concatenate([[ev.last_s], t[seen]]))
            has = (count >= self.rule.min_samples) & (last - first >= self.rule.min_span_s)
            with np.errstate(invalid="ignore", divide="ignore"):
                departure = np.where(has, speed_sum / model_sum - 1.0, np.nan)
                share = np.stack(
                    [
                        np.isfinite(departure),
                        departure > self.rule.speed_departure,
                        departure < -self.rule.speed_departure,
                    ]
                ).astype(np.int64)
            before += share[:, 0]
            change = np.diff(share, axis=1)
            moved = np.flatnonzero(change.any(axis=0))  # most rows change no count
            changes[:, seen[moved]] += change[:, moved]
            if seen.size:
                ev.samples, ev.speed_sum, ev.speed_model_sum = (
                    int(count[-1]),
                    float(speed_sum[-1]),
                    float(model_sum[-1]),
                )
                ev.first_s, ev.last_s = first, float(last[-1])
        counts = np.cumsum(changes, axis=1)
        counts += before[:, None]
        evidenced, faster, slower = counts
        out = np.full(n, VehicleFit.FITS, dtype=np.int8)
        out[(faster >= self.needed) | (slower >= self.needed)] = VehicleFit.SPEED_OFF
        out[evidenced < self.needed] = VehicleFit.CHECKING  # (then neither side can reach it either)
        return out

    def _verdict(self, evidenced: int, faster: int, slower: int) -> int:
        if evidenced < self.needed:
            return VehicleFit.CHECKING
        return VehicleFit.SPEED_OFF if max(faster, slower) >= self.needed else VehicleFit.FITS

    def departures(self) -> Mapping[int, float]:
        """Each motor's speed departure so far (NaN where it has not turned)."""
        return {m: ev.departure() for m, ev in sorted(self.evidence.items())}

    def describe(self, code: int, model_name: str = "the motor model") -> str:
        """One line saying what the check found (replay's output and report, the agent's log and status)."""
        return describe_vehicle_fit(code, self.departures(), model_name)


def describe_vehicle_fit(
    code: int, departures: Mapping[int, float], model_name: str = "the motor model"
) -> str:
    """One line for a verdict and the motors' speed departures (see :meth:`VehicleCheck.describe`)."""
    if code == VehicleFit.CHECKING:
        return f"checking that {model_name} describes this vehicle"
    if code == VehicleFit.FITS:
        return f"{model_name} describes this vehicle"
    values = [d for d in departures.values() if math.isfinite(d)]
    median = float(np.median(values)) if values else math.nan
    how = f"{abs(100 * median):.0f} % {'faster' if median > 0 else 'slower'}"
    return (
        f"{model_name} does not describe this vehicle: its motors turn {how} than it predicts (median "
        f"of {len(values)}), so no fault is named (UNCALIBRATED). Identify this vehicle from a healthy flight "
        "(fit LOG --out vehicle.toml) and give it with --params vehicle.toml"
    )


def apply_vehicle_fit(announced: NDArray[np.integer], verdict: NDArray[np.int8]) -> NDArray[np.int8]:
    """The announced states after the vehicle check: UNCALIBRATED where the model does not fit, and no
    fault while the check has too little evidence (NORMAL stands until it passes)."""
    a = np.asarray(announced, dtype=np.int8).copy()
    a[verdict == VehicleFit.SPEED_OFF] = MotorState.UNCALIBRATED
    fault_codes = np.array([s.is_fault for s in MotorState])
    a[(verdict == VehicleFit.CHECKING) & fault_codes[a.astype(np.int64)]] = MotorState.NORMAL
    return a
