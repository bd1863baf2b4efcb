"""Each motor's torque balance against its siblings' (issue 17): the vehicle stage of the pipeline, between
the rules that compare each motor with its model and the rule that judges the torque balance
(:mod:`.rules.equations`).

Why. What moves the torque balance ``r_T`` of a healthy motor moves it on all six alike: an ESC that
reports its input current adds the duty ripple's copper loss, ``V·σ_d²/R``, and the ripple grows with
the air (``benchmarks/bench_input_ripple.py``); the one motor model shared by six motors leaves the same
error at an operating point the identification flight did not cover; the battery and the air are the
same for all. Friction (F1.1) or a lighter propeller (F3.1) moves one motor. So where the vehicle's
noise has it, the torque is judged as ``r_T`` minus the median of the other motors' ``r_T``, against
that difference's own healthy noise (``[noise.N] torque_vs_siblings_nm ...``, measured by
identification like the torque's own, :mod:`.noise`). What it gained and cost on the held-out worlds:
docs/flight.md, "The torque balance against its siblings".

The reference of a sample of motor m at time t is the median of the other motors' latest residuals that
reached the core before it, in the order the live agent receives samples (time, then motor number: a
sibling's sample of the same instant counts where its number is lower) and are at most the sample's own
low-pass time old (``frame.low_pass_s``: an older value is not of the same air). Where fewer than all
but one of the vehicle's other motors have one, there is none (NaN) and the torque is not judged there:
one motor without a residual (its ESC silent, a lost packet) is tolerated, two are not. Replay calls
:meth:`SiblingTorque.reference` once with every motor's whole log; the live agent with each batch, the
latest value of every motor carried between calls: both give the same references.

The same stage takes a second look across motors where the profile grows its bands beyond the noise's
conditions as the siblings run (``conditions_siblings``, :mod:`.rules.bands`): each motor's low-passed
square of its deviations in its identified σ, speed and current, whose siblings' median says how wide
healthy deviations run in the air all six share right now. :class:`VehicleStage` carries one
:class:`SiblingTorque` (the latest values of every motor) per quantity, :data:`STAGE_QUANTITIES`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["STAGE_QUANTITIES", "SiblingTorque", "VehicleStage", "median_of_finite"]

#: what the vehicle stage takes across motors: the frame's value each motor gives, and the frame's field
#: its siblings' reference goes to (rules/base.py, :class:`~.rules.base.Frame`)
STAGE_QUANTITIES = (
    ("torque_residual_nm", "torque_siblings_nm"),
    ("live_z2_speed", "siblings_z2_speed"),
    ("live_z2_current", "siblings_z2_current"),
)


@dataclass
class SiblingTorque:
    """The vehicle stage's state: the vehicle's motors and each one's latest finite torque residual."""

    #: the vehicle's motor numbers (its frame); motors seen in a call and not listed are added
    motors: list[int] = field(default_factory=list)
    latest_time_s: dict[int, float] = field(default_factory=dict)
    latest_nm: dict[int, float] = field(default_factory=dict)

    def reference(
        self,
        motors: Sequence[int],
        time_s: NDArray[np.float64],
        residual_nm: NDArray[np.float64],
        counts: Sequence[int],
        max_age_s: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """The siblings' reference at each sample of rows of motors (module doc): ``time_s``,
        ``residual_nm`` and ``max_age_s`` 2-D, one row per motor of ``motors``, each row's first
        ``counts`` samples its own (the rest padding: NaN in the result). Advances the carried latest
        values."""
        rows, width = np.shape(time_s)
        out = np.full((rows, width), np.nan)
        for m in motors:
            if m not in self.motors:
                self.motors.append(int(m))
        if len(self.motors) < 2 or rows == 0:
            return out
        column = {m: j for j, m in enumerate(self.motors)}
        valid = np.arange(width)[None, :] < np.asarray(counts)[:, None]
        r_at, c_at = np.nonzero(valid)
        carried = [m for m in self.motors if m in self.latest_time_s]
        # the stream: each motor's carried latest value first, then the call's samples
        t = np.concatenate([[self.latest_time_s[m] for m in carried], time_s[r_at, c_at]])
        v = np.concatenate([[self.latest_nm[m] for m in carried], residual_nm[r_at, c_at]])
        who = np.concatenate(
            [[column[m] for m in carried], np.asarray([column[int(m)] for m in motors])[r_at]]
        ).astype(np.intp)
        age_limit = np.concatenate([np.full(len(carried), -np.inf), max_age_s[r_at, c_at]])
        order = np.lexsort((np.asarray(self.motors)[who], t))  # arrival: time, then motor number
        t, v, who, age_limit = t[order], v[order], who[order], age_limit[order]
        k = np.arange(t.size)
        others = np.full((t.size, len(self.motors)), np.nan)
        for j in range(len(self.motors)):
            last = np.maximum.accumulate(np.where((who == j) & np.isfinite(v), k, -1))
            have = last >= 0
            at = np.maximum(last, 0)
            fresh = have & (t - t[at] <= age_limit) & (who != j)
            others[:, j] = np.where(fresh, v[at], np.nan)
            if have[-1]:
                self.latest_time_s[self.motors[j]] = float(t[at[-1]])
                self.latest_nm[self.motors[j]] = float(v[at[-1]])
        need = max(1, len(self.motors) - 2)  # all but one of the other motors
        reference = median_of_finite(others, need)
        back = np.empty(t.size, dtype=np.intp)
        back[order] = k
        out[r_at, c_at] = reference[back[len(carried) :]]
        return out


@dataclass
class VehicleStage:
    """The vehicle stage's state: for each quantity of :data:`STAGE_QUANTITIES` a motor gives, every
    motor's latest value (a :class:`SiblingTorque` each, made at the quantity's first values)."""

    #: the vehicle's motor numbers (its frame)
    motors: list[int] = field(default_factory=list)
    #: the frame fields of :data:`STAGE_QUANTITIES` the stage takes (what a rule after it reads)
    quantities: tuple[str, ...] = ()
    latest: dict[str, SiblingTorque] = field(default_factory=dict)

    def of(self, quantity: str) -> SiblingTorque:
        """The latest values of ``quantity`` (a frame field of :data:`STAGE_QUANTITIES`)."""
        if quantity not in self.latest:
            self.latest[quantity] = SiblingTorque(list(self.motors))
        return self.latest[quantity]


def median_of_finite(values: NDArray[np.float64], need: int) -> NDArray[np.float64]:
    """Each row's median of its finite values; NaN where fewer than ``need`` are finite."""
    count = np.sum(np.isfinite(values), axis=1)
    ranked = np.sort(values, axis=1)  # NaN last
    lo = np.take_along_axis(ranked, np.maximum((count - 1) // 2, 0)[:, None], axis=1)[:, 0]
    hi = np.take_along_axis(ranked, np.maximum(count // 2, 0)[:, None], axis=1)[:, 0]
    return np.where(count >= max(need, 1), 0.5 * (lo + hi), np.nan)
