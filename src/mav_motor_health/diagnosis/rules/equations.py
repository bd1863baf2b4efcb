"""Friction and a lighter propeller read in the torque balance (the profile's ``equation_bands``, issue 17).

The tree (:mod:`..tree`) judges the speed and current deviations, and each mixes both balances of the
model: ``Δi = (k_e·r_T − G·r_V)/D`` (:mod:`...model.balance`). More friction (F1.1) is torque the model
does not account for, ``r_T`` above 0, and a lighter propeller (F3.1) is load missing, ``r_T`` below 0;
neither moves the voltage balance ``r_V``. Their noise differs: ``r_V`` carries the error of the command
each report was paired with, ``r_T`` the current sensor's and the speed's; the deviations' bands hold
both. Read in the torque balance alone, against its own noise, those two faults stand about twice as
many σ out of the healthy spread (``benchmarks/bench_two_equations.py``; docs/flight.md, "The two
equations apart, measured").

So for each motor whose noise has the torque balance's (identification measures it, :mod:`..noise`,
"Each equation's own noise"), this rule reads ``z_T = (r_T − offset_T)/σ_T`` on the samples the tree
judged with a trusted current (NORMAL, F1.1, F3.1, F4.1, UNKNOWN; never a stall, a bad sensor, a
speed-only state), σ at the sample's input activity and pairing, grown beyond the identified conditions
and after a step as the deviations' bands are (:mod:`.bands`):

* the torque beyond ``equation_bands`` σ names F1.1 (above) or F3.1 (below), with that depth, unless the
  tree reads F4.1 deeper (an open transistor draws less current, which moves the measured torque too);
* the torque within its band: no torque fault, so the tree's F1.1 or F3.1 becomes NORMAL, and its other
  verdicts stand (F4.1 is read from the deviations as before: they see the open transistor's lost
  voltage twice, in the speed and the current, and on the held-out worlds named it more often than the
  voltage balance alone; docs/flight.md).

**An input current's ripple, and the siblings.** Where the ESC reports its input current, the motor
current in ``r_T`` is that current over the duty, and an input current holds the ripple's copper loss:
with the duty jittering by σ_d, the mean input current is ``d̄·ī + V·σ_d²/R``, not ``d̄·ī``
(``benchmarks/bench_input_ripple.py``: in the simulator's world 5 the motor's own current averages 4.1 A
in calm, moderate and gusty air alike, while the current the log gives reads 4.2, 4.9 and 11.4 A).
``r_T``'s offset then moves with the air, by several σ between calm and moderate, on all motors alike.
So the torque is judged against its siblings (:mod:`..siblings`): ``r_T`` minus the median of the other
motors' ``r_T``, against that difference's own noise (``[noise.N] torque_vs_siblings_nm ...``), which
takes off what all motors share (the ripple, and the one model's error at an operating point the
identification flight did not cover) and keeps what one motor does alone. Where the sample has no such
reference (fewer than three siblings reporting, or those beyond their identified speeds at another speed:
:mod:`..siblings`), its torque is not judged. A vehicle file from before (the torque's own noise only) is
judged in ``r_T`` itself where the ESC reports its motor's own current, and by the deviations where
``torque_residual_through_duty = 1`` marks an input current.

The sequential test (:mod:`.announce`) reads the same ``z_T`` for F1.1 and F3.1 where it is judged here
(``frame.z_torque``, NaN elsewhere). What stays with the deviations: the stop speed and the stall's
current, the speed-only states, F4.1 and UNKNOWN, and the lost-load check beyond the identified speeds
(:mod:`.judged`, which reads this rule's F3.1)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..._arrays import one_of
from ..states import MotorState
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["Equations"]

#: the tree's states this rule reads again (those it names from the speed and the current together)
REREAD = (MotorState.NORMAL, MotorState.F1_1, MotorState.F3_1, MotorState.F4_1, MotorState.UNKNOWN)
#: the faults the torque balance names
TORQUE_FAULTS = (MotorState.F1_1, MotorState.F3_1)


@dataclass(frozen=True)
class Equations(Rule):
    """Writes ``z_torque`` (NaN where not judged in the torque), and ``state`` and ``depth`` again where
    it is (module doc); nothing where the bands rule wrote no torque band."""

    name = "equations"
    reads_siblings = True
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        noise, band = frame.noise, frame.torque_band_nm
        if band is None or noise is None or frame.torque_residual_nm is None:
            return carries
        n = self.profile.equation_bands
        judged_noise = [m.torque_judged for m in noise]
        # against the siblings where the motor's noise was measured so (module doc); else the torque's own,
        # but not one read through the duty (an input current)
        siblings = np.array([m.torque_vs_siblings is not None for m in noise])[:, None]
        holds = np.array([j is not None for j in judged_noise])[:, None]
        if not holds.any():
            return carries
        offset = np.array([j.offset if j is not None else np.nan for j in judged_noise])[:, None]
        reference = frame.torque_siblings_nm
        if reference is None:  # no vehicle stage ran (a call of its own): none against the siblings
            reference = np.full(frame.shape, np.nan)
        torque = np.where(siblings, frame.torque_residual_nm - reference, frame.torque_residual_nm)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (torque - offset) / (band / n)
        judged = holds & frame.current_trusted() & np.isfinite(z)
        frame.z_torque = np.where(judged, z, np.nan)
        state, depth = frame.state, frame.depth
        reread = judged & one_of(state, REREAD)
        if not reread.any():
            return carries
        torque_depth = np.abs(z) / n
        departs = torque_depth > 1.0
        named = np.where(z > 0, MotorState.F1_1, MotorState.F3_1)
        deeper_f41 = (state == MotorState.F4_1) & (depth >= torque_depth)
        new = np.where(
            departs & ~deeper_f41,
            named,
            np.where(one_of(state, TORQUE_FAULTS), MotorState.NORMAL, state),
        ).astype(state.dtype)
        new_depth = np.where(departs & ~deeper_f41, torque_depth, np.where(new == state, depth, 1.0))
        state[reread] = new[reread]
        depth[reread] = new_depth[reread]
        return carries
