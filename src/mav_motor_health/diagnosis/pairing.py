"""How far a log's pairing of ESC samples with motor commands can move the balance rule, per sample.

A log gives each ESC sample the motor command of another moment than the sample's: a ``.tlog`` the ESC's
last packet beside the command of the message's moment, a ``.bin`` the latest RCOU record. The reader
measures how far apart the two can be (the table's ``meta["pairing_s"]``, :mod:`..telemetry.assemble`).
Over that time the command moves by about its mean rate of change times ``pairing_s``, so the voltage
the balance rule uses can be off by

    u = low-pass(|ΔV/Δt|) · pairing_s

(low-passed as the balances are). In the balance rule a voltage error δV moves the speed deviation by
``k_t·δV/D`` and the current deviation by ``G·δV/D`` (:func:`~..model.balance.linearised_slopes`): the
direction of an open transistor (F4.1), which is what loosely paired logs are misread as. The *pairing
error* is that speed, ``k_t·u/D`` [rad/s]; the pipeline compares it with the bands
(:attr:`~.plausibility.PlausibilityRule.pairing_current_share`, ``pairing_speed_share``): where it is a
sizeable part of the speed band the current is not used (the tree falls back to speed alone, with its
wider band), where it is a sizeable part of even that band the sample is not judged.

A source that pairs each sample with the command of its own instant (the simulator's table, the live
agent) has no pairing error.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.balance import linearised_slopes
from ..model.dynamics import ResponseCarry, first_order_responses, previous
from ..model.params import MotorParams

__all__ = ["PairingCarry", "pairing_error_rad_s", "pairing_error_rows"]


@dataclass(frozen=True)
class PairingCarry:
    """The last sample seen and the low-pass of the input's rate of change."""

    time_s: float = float("nan")
    voltage_v: float = float("nan")
    rate: ResponseCarry = field(default_factory=ResponseCarry)


def pairing_error_rad_s(
    params: MotorParams,
    time_s: ArrayLike,
    voltage_v: ArrayLike,
    omega_model_rad_s: ArrayLike,
    pairing_s: float,
    tau_s: ArrayLike,
    carry: PairingCarry | None = None,
) -> tuple[NDArray[np.float64], PairingCarry]:
    """The speed deviation a command ``pairing_s`` off could cause, per sample (see the module doc)."""
    carry = carry or PairingCarry()
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return np.zeros(0), carry

    def row(x: ArrayLike) -> NDArray[np.float64]:
        return np.broadcast_to(np.asarray(x, dtype=float), t.shape).reshape(1, -1)

    error, (new,) = pairing_error_rows(
        params, row(t), row(voltage_v), row(omega_model_rad_s), pairing_s, row(tau_s), [carry]
    )
    return error[0], new


def pairing_error_rows(
    params: MotorParams,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    omega_model_rad_s: NDArray[np.float64],
    pairing_s: float,
    tau_s: NDArray[np.float64],
    carries: list[PairingCarry],
    lengths: list[int] | None = None,
) -> tuple[NDArray[np.float64], list[PairingCarry]]:
    """:func:`pairing_error_rad_s` of several motors at once: rows of samples (2-D), one carry per row;
    ``lengths`` each row's number of samples (None: all; the rest is padding after them)."""
    t, v = time_s, voltage_v
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    previous_t = previous(t, [c.time_s for c in carries])
    previous_v = previous(v, [c.voltage_v for c in carries])
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.abs(v - previous_v) / (t - previous_t)
    rate = np.where(np.isfinite(rate) & (t > previous_t), rate, np.nan)  # NaN holds the low-pass
    mean_rate, rate_carries = first_order_responses(t, rate, tau_s, [c.rate for c in carries], counts)
    _, d = linearised_slopes(params, omega_model_rad_s)
    error = params.k_t * np.nan_to_num(mean_rate) * pairing_s / d
    finite = np.isfinite(v)
    news = []
    for r, (carry, count) in enumerate(zip(carries, counts)):
        last = np.flatnonzero(finite[r, :count])
        news.append(
            PairingCarry(
                time_s=float(t[r, last[-1]]) if last.size else carry.time_s,
                voltage_v=float(v[r, last[-1]]) if last.size else carry.voltage_v,
                rate=rate_carries[r],
            )
        )
    return error, news
