"""ESC telemetry as real ESCs report it: each ESC on its own clock, noisy, quantised, with dropouts.

* rate: each ESC reports at its own rate (drawn from ``rate_hz``, e.g. 10–50 Hz) with a clock error of
  a few per cent, a random phase and jitter — the ESCs are not synchronised;
* noise: speed uniform ±``speed_noise_rad_s`` (the paper's ±10 rad/s); current uniform with a half-width
  growing with the input voltage from ±0.15 A at 4 V to ±1.0 A at 11 V (section III.B, the same
  :class:`~mav_motor_health.sim.steady.SensorNoise` the steady-state tools use);
* quantisation as MAVLink carries it: integer rpm, current in cA, voltage in cV, integer °C;
* dropouts: single lost samples with probability ``dropout``, and rare bursts of ``burst_s`` seconds;
* the current is the ESC's *input* current, sensed as a shunt on its DC side senses it: the instantaneous
  ``duty × motor current`` (negative while the motor brakes), through a first-order filter
  (``current_filter_s``, 20 ms by default), reported unsigned. In steady state the filter changes
  nothing; where the command zigzags, the reading is the mean of the product, which is what the battery
  sees too (the ESC currents add up to the battery current), not the sample's duty times the mean motor
  current.

The motor current in the CSV is the reading divided by the sample's duty, as the telemetry sources derive
it (:func:`mav_motor_health.model.esc.motor_current_a`).

A randomised world (:mod:`.worlds`) senses the current its own way (:class:`CurrentSensing`): the input
or the motor (phase) current, averaged over the report interval or through a filter, with a gain error
and an offset, or not at all (a constant reading). Its samples carry the autopilot's *command* besides
the duty, and the motor current in them is the reading divided by the command, as a reader of a real log
would compute it (the reader knows the command, not the duty).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..model.vehicle import CURRENT_SIDES
from .steady import SensorNoise

__all__ = ["CURRENT_AVERAGING", "CurrentSensing", "EscSample", "EscSensors", "SensorSpec"]

RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
#: how a world's ESC averages its current: over each report interval, or through a first-order filter
CURRENT_AVERAGING = ("interval", "filter")


@dataclass(frozen=True)
class CurrentSensing:
    """How an ESC senses and reports its current (a randomised world's; see :mod:`.worlds`).

    ``side`` "input" (battery side, duty × motor current), "motor" (phase current) or "unusable" (a
    constant ``constant_a``, as 4-in-1 ESCs without per-motor sensing report); the names are those of
    :data:`mav_motor_health.model.vehicle.CURRENT_SIDES`. ``averaging`` "interval" (the mean since the
    last report) or "filter" (first order, ``filter_s``). The reading is ``gain × true + offset_a`` plus
    the noise, reported unsigned.
    """

    side: str = "input"
    averaging: str = "filter"
    filter_s: float = 0.02
    gain: float = 1.0
    offset_a: float = 0.0
    constant_a: float = 0.0

    def __post_init__(self) -> None:
        if self.side not in CURRENT_SIDES:
            raise ValueError(f"current side {self.side!r}: expected one of {CURRENT_SIDES}")
        if self.averaging not in CURRENT_AVERAGING:
            raise ValueError(f"current averaging {self.averaging!r}: expected one of {CURRENT_AVERAGING}")


@dataclass(frozen=True)
class SensorSpec:
    rate_hz: tuple[float, float] = (40.0, 40.0)
    clock_error: float = 0.02
    jitter: float = 0.05
    speed_noise_rad_s: float = 10.0
    current_noise_low_a: float = 0.15
    current_noise_high_a: float = 1.0
    dropout: float = 0.0
    burst_per_hour: float = 0.0
    burst_s: float = 1.0
    #: time constant of the ESC's current-sense filter [s] (0: none)
    current_filter_s: float = 0.02
    #: input voltages [V] at which the current noise has its low and high half-widths
    current_noise_voltage_v: tuple[float, float] = (4.0, 11.0)
    #: a world's current sensing; None: the input current through ``current_filter_s``, no gain error
    current_sensing: CurrentSensing | None = None


class EscSample(NamedTuple):
    """One quantised ESC report (a named tuple: millions are made in a long flight)."""

    time_s: float
    motor: int
    rpm: int
    esc_current_ca: int
    motor_current_ca: int
    voltage_cv: int
    temp_c: int
    motor_temp_c: int
    duty: float
    #: how many reports this ESC has sent (ESC_TELEMETRY "count")
    reports: int
    #: the autopilot's command (0..1 of the PWM range); it differs from the duty where the ESC has an idle
    #: offset (a world's). NaN where unknown: the duty stands in (:attr:`throttle`)
    command: float = math.nan

    @property
    def throttle(self) -> float:
        """The command as the autopilot logs it."""
        return self.duty if math.isnan(self.command) else self.command


class EscSensors:
    def __init__(self, spec: SensorSpec, n: int, rng: np.random.Generator) -> None:
        self.spec, self.n, self.rng = spec, n, rng
        lo, hi = spec.rate_hz
        rates = rng.uniform(lo, hi, n) * (1.0 + rng.uniform(-spec.clock_error, spec.clock_error, n))
        self.period_s = 1.0 / rates
        self.next_s = rng.uniform(0.0, 1.0, n) * self.period_s
        self.counts = np.zeros(n, dtype=np.int64)
        self.noise = SensorNoise(
            speed_rad_s=spec.speed_noise_rad_s,
            current_low_a=spec.current_noise_low_a,
            current_high_a=spec.current_noise_high_a,
            voltage_low_v=spec.current_noise_voltage_v[0],
            voltage_high_v=spec.current_noise_voltage_v[1],
        )
        self._burst_until = np.full(n, -1.0)
        self._next_min_s = float(self.next_s.min())
        self._filtered_a: NDArray[np.float64] | None = None
        # a world's interval averaging: the integral of the current and the time since the last report
        self._sum_a_s = np.zeros(n)
        self._elapsed_s = np.zeros(n)

    def due(self, time_s: float) -> NDArray[np.bool_]:
        return self.next_s <= time_s

    def sample(
        self,
        time_s: float,
        dt: float,
        omega_rad_s: NDArray[np.float64],
        motor_current_a: NDArray[np.float64],
        duty: NDArray[np.float64],
        bus_voltage_v: float,
        esc_temp_c: NDArray[np.float64],
        motor_temp_c: NDArray[np.float64],
        command: NDArray[np.float64] | None = None,
    ) -> list[EscSample]:
        """Reports of every ESC whose clock ticked by ``time_s`` (call once per simulation step).

        ``command`` is the autopilot's command where an ESC map makes it differ from ``duty``."""
        sensing = self.spec.current_sensing
        if sensing is None:
            # The ESC senses its input current (duty × motor current, signed) through a first-order filter.
            input_a = duty * motor_current_a
            tau = self.spec.current_filter_s
        else:
            input_a = duty * motor_current_a if sensing.side == "input" else motor_current_a
            tau = sensing.filter_s if sensing.averaging == "filter" else 0.0
            self._sum_a_s += input_a * dt
            self._elapsed_s += dt
        if tau > 0 and self._filtered_a is not None:
            self._filtered_a += (input_a - self._filtered_a) * (1.0 - math.exp(-dt / tau))
        else:
            self._filtered_a = np.array(input_a, dtype=float)
        sensed_a = self._filtered_a
        if time_s < self._next_min_s:
            return []
        due = np.flatnonzero(self.next_s <= time_s)
        spec, rng = self.spec, self.rng
        jitter = 1.0 + rng.uniform(-spec.jitter, spec.jitter, due.size)
        self.next_s[due] += self.period_s[due] * jitter
        behind = self.next_s[due] <= time_s  # a long step: do not report twice
        self.next_s[due[behind]] = time_s + self.period_s[due[behind]]
        if spec.burst_per_hour > 0:
            start = rng.random(due.size) < spec.burst_per_hour * self.period_s[due] / 3600.0
            self._burst_until[due[start]] = time_s + spec.burst_s
        kept = (rng.random(due.size) >= spec.dropout) & (self._burst_until[due] < time_s)
        d = duty[due]
        noise = rng.uniform(-1.0, 1.0, (2, due.size))
        w = omega_rad_s[due] + noise[0] * spec.speed_noise_rad_s
        # the noise as the paper measured it on the motor current, seen through the duty
        i_half = self.noise.current_halfwidth_a(d * bus_voltage_v)
        if sensing is None:
            c = d
            esc_a = sensed_a[due] + d * noise[1] * i_half
            esc_ca = np.rint(np.maximum(esc_a, 0.0) * 100.0)
            motor_ca = np.where(
                d > 0.02,
                np.rint(esc_ca / np.maximum(d, 0.02)),
                np.rint((motor_current_a[due] + noise[1] * i_half) * 100.0),
            )
        else:
            c = d if command is None else command[due]
            esc_ca = self._world_reading_ca(sensing, due, sensed_a, d, noise[1] * i_half)
            # as a reader of the log computes it: the reading over the command (it does not know the duty)
            motor_ca = np.where(c > 0.02, np.rint(esc_ca / np.maximum(c, 0.02)), esc_ca)
        rpm = np.maximum(np.rint(w * RAD_S_TO_RPM), 0.0)
        volt_cv = round(bus_voltage_v * 100.0)
        self._next_min_s = float(self.next_s.min())
        out = []
        counts = self.counts
        for k, j in enumerate(due.tolist()):
            if not kept[k]:
                continue
            counts[j] += 1
            out.append(
                EscSample(
                    time_s,
                    j + 1,
                    int(rpm[k]),
                    int(esc_ca[k]),
                    int(motor_ca[k]),
                    volt_cv,
                    round(float(esc_temp_c[j])),
                    round(float(motor_temp_c[j])),
                    float(d[k]),
                    int(counts[j]),
                    float(c[k]),
                )
            )
        return out

    def _world_reading_ca(
        self,
        sensing: CurrentSensing,
        due: NDArray[np.intp],
        sensed_a: NDArray[np.float64],
        duty: NDArray[np.float64],
        motor_noise_a: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """A world's current reading [cA] of the ESCs ``due`` to report (their interval averages reset)."""
        if sensing.averaging == "interval":
            mean_a = self._sum_a_s[due] / np.maximum(self._elapsed_s[due], 1e-12)
            self._sum_a_s[due] = 0.0
            self._elapsed_s[due] = 0.0
        else:
            mean_a = sensed_a[due]
        if sensing.side == "unusable":
            reading = np.full(due.size, sensing.constant_a)
        else:
            # the noise is the motor current's; an input-side sensor sees it through the duty
            seen = duty * motor_noise_a if sensing.side == "input" else motor_noise_a
            reading = sensing.gain * mean_a + sensing.offset_a + seen
        return np.rint(np.maximum(reading, 0.0) * 100.0)
