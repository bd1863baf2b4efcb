"""Steady-state rule for constant-input operation (the paper's testbed).

A sample is steady when the input voltage has not stepped (changed by more than ``step_v`` from one
sample to the next) for at least ``settle_s``. The rule carries its state between calls, so the live
agent (one sample at a time) and replay (whole arrays) run the very same code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from ..model.dynamics import last_of, previous

__all__ = ["SteadyCarry", "settling_rows", "steady_mask", "steady_mask_rows", "warm_mask"]


class Settling(Protocol):
    """The settings the steady mask reads (the step and dynamic rules')."""

    @property
    def step_v(self) -> float: ...

    @property
    def settle_s(self) -> float: ...


@dataclass(frozen=True)
class SteadyCarry:
    """What the rule remembers between calls for one motor."""

    last_voltage_v: float = float("nan")
    last_step_time_s: float = float("-inf")
    started: bool = False
    last_time_s: float = float("nan")
    last_start_time_s: float = float("-inf")


def steady_mask(
    rule: Settling,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    carry: SteadyCarry = SteadyCarry(),
) -> tuple[NDArray[np.bool_], SteadyCarry]:
    """Steady flag per sample, and the carry for the next call. Times must be increasing."""
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return np.zeros(0, dtype=bool), carry
    steady, (new,) = steady_mask_rows(
        rule, t.reshape(1, -1), np.asarray(voltage_v, dtype=float).reshape(1, -1), [carry]
    )
    return steady[0], new


def steady_mask_rows(
    rule: Settling,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    carries: list[SteadyCarry],
    lengths: list[int] | None = None,
) -> tuple[NDArray[np.bool_], list[SteadyCarry]]:
    """:func:`steady_mask` of several motors at once: rows of samples (2-D), one carry per row;
    ``lengths`` each row's number of samples (None: all; the rest is padding after them)."""
    t, v = time_s, voltage_v
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    step = ~(np.abs(v - previous(v, [c.last_voltage_v for c in carries])) <= rule.step_v)  # NaN: a step
    step[:, 0] |= ~np.array([c.started for c in carries])  # nothing is known before the first sample
    step_times = np.where(step, t, -np.inf)
    start = np.array([[c.last_step_time_s] for c in carries])
    last_step = np.maximum.accumulate(np.concatenate([start, step_times], axis=1), axis=1)[:, 1:]
    steady = (t - last_step >= rule.settle_s) & np.isfinite(v)
    news = [
        carry if last_v is None else SteadyCarry(last_voltage_v=last_v, last_step_time_s=step_s, started=True)
        for carry, last_v, step_s in zip(carries, last_of(v, counts), last_of(last_step, counts))
    ]
    return steady, news


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
    if t.size == 0:
        return np.zeros((0,) if also_settle_s is None else (2, 0), dtype=bool), carry

    def row(x: NDArray | float | None) -> NDArray | float | None:
        return x if x is None or np.ndim(x) == 0 else np.asarray(x).reshape(1, -1)

    warm, (new,), _ = settling_rows(
        t.reshape(1, -1),
        np.asarray(voltage_v, dtype=float).reshape(1, -1),
        settle_s,
        max_gap_s,
        row(step_v),  # type: ignore[arg-type]
        [carry],
        start_settle_s=row(start_settle_s),  # type: ignore[arg-type]
        restart=row(restart),  # type: ignore[arg-type]
        also_settle_s=also_settle_s,
    )
    return warm[..., 0, :], new


def settling_rows(
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    settle_s: float,
    max_gap_s: float,
    step_v: NDArray[np.float64] | float,
    carries: list[SteadyCarry],
    lengths: list[int] | None = None,
    start_settle_s: NDArray[np.float64] | float = 0.0,
    restart: NDArray[np.bool_] | None = None,
    also_settle_s: float | None = None,
) -> tuple[NDArray[np.bool_], list[SteadyCarry], NDArray[np.float64]]:
    """:func:`warm_mask` of several motors at once: rows of samples (2-D), one carry per row;
    ``lengths`` each row's number of samples (None: all; the rest is padding after them). With
    ``also_settle_s`` the mask is (2, rows, samples). Also the time since the last step [s] of each
    sample whose stream has settled since it began (NaN where it has not): a sample it is below
    ``settle_s`` for waits for a step's transient to leave the low-passes."""
    t, v = time_s, voltage_v
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    previous_t = previous(t, [c.last_time_s for c in carries])
    previous_v = previous(v, [c.last_voltage_v for c in carries])
    start = ~(t - previous_t <= max_gap_s)  # the first sample ever (NaN before it) starts a stream
    step = start | (np.abs(v - previous_v) > step_v)  # a NaN input is no step (the low-passes hold)
    if restart is not None:
        step = step | restart
    carried_start = np.array([[c.last_start_time_s] for c in carries])
    carried_step = np.array([[c.last_step_time_s] for c in carries])
    last_start = np.maximum.accumulate(
        np.concatenate([carried_start, np.where(start, t, -np.inf)], axis=1), axis=1
    )[:, 1:]
    last_step = np.maximum.accumulate(
        np.concatenate([carried_step, np.where(step, t, -np.inf)], axis=1), axis=1
    )[:, 1:]
    stream_warm = t - last_start >= np.maximum(settle_s, start_settle_s)
    warm = (t - last_step >= settle_s) & stream_warm
    since_step = np.where(stream_warm, t - last_step, np.nan)
    if also_settle_s is not None:  # a second, longer wait after the same steps and starts
        also = (t - last_step >= also_settle_s) & (
            t - last_start >= np.maximum(also_settle_s, start_settle_s)
        )
        warm = np.stack([warm, also])
    news = []
    for carry, last_v, step_s, time_s_last, start_s in zip(
        carries,
        last_of(v, counts),
        last_of(last_step, counts),
        last_of(t, counts),
        last_of(last_start, counts),
    ):
        if last_v is None:  # a row without samples
            news.append(carry)
            continue
        news.append(
            SteadyCarry(
                last_voltage_v=last_v if math.isfinite(last_v) else carry.last_voltage_v,
                last_step_time_s=step_s,
                started=True,
                last_time_s=time_s_last,
                last_start_time_s=start_s,
            )
        )
    return warm, news, since_step
