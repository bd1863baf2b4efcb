"""Steady-state rule for constant-input operation (the paper's testbed).

A sample is steady when the input voltage has not stepped (changed by more than ``step_v`` from one
sample to the next) for at least ``settle_s``. The rule carries its state between calls, so the live
agent (one sample at a time) and replay (whole arrays) run the very same code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .profile import SteadyRule

__all__ = ["SteadyCarry", "steady_mask"]


@dataclass(frozen=True)
class SteadyCarry:
    """What the rule remembers between calls for one motor."""

    last_voltage_v: float = float("nan")
    last_step_time_s: float = float("-inf")
    started: bool = False


def steady_mask(
    rule: SteadyRule,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    carry: SteadyCarry = SteadyCarry(),
) -> tuple[NDArray[np.bool_], SteadyCarry]:
    """Steady flag per sample, and the carry for the next call. Times must be increasing."""
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(voltage_v, dtype=float)
    if t.size == 0:
        return np.zeros(0, dtype=bool), carry
    previous = np.concatenate([[carry.last_voltage_v], v[:-1]])
    step = ~(np.abs(v - previous) <= rule.step_v)  # NaN on either side counts as a step
    if not carry.started:
        step[0] = True  # nothing is known before the first sample
    step_times = np.where(step, t, -np.inf)
    last_step = np.maximum.accumulate(np.concatenate([[carry.last_step_time_s], step_times]))[1:]
    steady = (t - last_step >= rule.settle_s) & np.isfinite(v)
    return steady, SteadyCarry(
        last_voltage_v=float(v[-1]), last_step_time_s=float(last_step[-1]), started=True
    )
