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
from ..model.dynamics import ResponseCarry, first_order_response
from ..model.params import MotorParams

__all__ = ["PairingCarry", "pairing_error_rad_s"]


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
    v = np.asarray(voltage_v, dtype=float)
    if t.size == 0:
        return np.zeros(0), carry
    previous_t = np.concatenate([[carry.time_s], t[:-1]])
    previous_v = np.concatenate([[carry.voltage_v], v[:-1]])
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.abs(v - previous_v) / (t - previous_t)
    rate = np.where(np.isfinite(rate) & (t > previous_t), rate, np.nan)  # NaN holds the low-pass
    mean_rate, rate_carry = first_order_response(t, rate, tau_s, carry.rate)
    _, d = linearised_slopes(params, omega_model_rad_s)
    error = params.k_t * np.nan_to_num(mean_rate) * pairing_s / d
    finite = np.isfinite(v)
    last = np.flatnonzero(finite)
    new = PairingCarry(
        time_s=float(t[last[-1]]) if last.size else carry.time_s,
        voltage_v=float(v[last[-1]]) if last.size else carry.voltage_v,
        rate=rate_carry,
    )
    return error, new
