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

__all__ = ["SteadyCarry", "steady_mask", "warm_mask"]


@dataclass(frozen=True)
class SteadyCarry:
    """What the rule remembers between calls for one motor."""

    last_voltage_v: float = float("nan")
    last_step_time_s: float = float("-inf")
    started: bool = False
    last_time_s: float = float("nan")
    last_start_time_s: float = float("-inf")


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


def warm_mask(
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    settle_s: float,
    max_gap_s: float,
    step_v: NDArray[np.float64] | float,
    carry: SteadyCarry = SteadyCarry(),
    start_settle_s: NDArray[np.float64] | float = 0.0,
    restart: NDArray[np.bool_] | None = None,
    also_settle_s: float | None = None,
) -> tuple[NDArray[np.bool_], SteadyCarry]:
    """For the averaging rule (``kind = "balance"``): True once samples have come for
    ``start_settle_s`` (per sample, like ``step_v``; at least ``settle_s``) without a gap longer than
    ``max_gap_s``, and for
    ``settle_s`` since the last input step larger than ``step_v`` (per sample): the low-passes then hold
    samples of one operating point, or of an input that moves steadily, not the sampled edge of a step.
    ``restart`` marks samples that count as a step whatever the input did (the pipeline: a motor at idle,
    whose low-passes are full of spin-down and idle when it comes back). With ``also_settle_s`` the result
    has two rows: the mask for ``settle_s`` and the one for ``also_settle_s`` (the slow look's wait)."""
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(voltage_v, dtype=float)
    if t.size == 0:
        return np.zeros((0,) if also_settle_s is None else (2, 0), dtype=bool), carry
    previous_t = np.concatenate([[carry.last_time_s], t[:-1]])
    previous_v = np.concatenate([[carry.last_voltage_v], v[:-1]])
    start = ~(t - previous_t <= max_gap_s)  # the first sample ever (NaN before it) starts a stream
    step = start | (np.abs(v - previous_v) > step_v)  # a NaN input is no step (the low-passes hold)
    if restart is not None:
        step = step | restart
    last_start = np.maximum.accumulate(
        np.concatenate([[carry.last_start_time_s], np.where(start, t, -np.inf)])
    )[1:]
    last_step = np.maximum.accumulate(np.concatenate([[carry.last_step_time_s], np.where(step, t, -np.inf)]))[
        1:
    ]
    warm = (t - last_step >= settle_s) & (t - last_start >= np.maximum(settle_s, start_settle_s))
    if also_settle_s is not None:  # a second, longer wait after the same steps and starts
        also = (t - last_step >= also_settle_s) & (
            t - last_start >= np.maximum(also_settle_s, start_settle_s)
        )
        warm = np.stack([warm, also])
    last_v = float(v[-1]) if np.isfinite(v[-1]) else carry.last_voltage_v
    return warm, SteadyCarry(
        last_voltage_v=last_v,
        last_step_time_s=float(last_step[-1]),
        started=True,
        last_time_s=float(t[-1]),
        last_start_time_s=float(last_start[-1]),
    )
