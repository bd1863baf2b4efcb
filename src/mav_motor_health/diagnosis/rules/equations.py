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

* the torque beyond ``equation_bands`` σ names F1.1 (above) or F3.1 (below), with that depth; below,
  unless the tree reads F4.1 deeper (an open transistor draws less current, which can lower the measured
  torque too). Above, an open transistor is no reading: it takes voltage from the motor, not torque, and
  on the open-transistor flights probed (held-out worlds 1003, 1011, 1014 in calm and moderate air;
  development worlds 3 and 6) the faulty motor's torque stayed within about 1 σ of its model, 10th to
  90th percentile (docs/flight.md, "Friction above the torque's band is not an open transistor"). Where
  the speed is judged against its siblings (:mod:`.against`), friction's lower speed crosses its narrowed
  band first and the tree reads F4.1, deeper than the torque; the torque above its band still names
  friction;
* a sample the tree named F4.1 (slower, the current not above its band), whose torque stays within its
  band: friction slows a motor too, by torque added where an open transistor loses voltage. So it is F1.1
  where the torque departs up by more of its own σ than the voltage balance does (``z_T > max(z_V, 0)``;
  the voltage balance in its own measured noise, ``[noise.N] voltage_residual_v ...``, grown beyond the
  identified conditions and after a step as the torque's band is), F4.1 elsewhere, with the tree's depth
  either way. On the development worlds' flights in moderate air, the faulty motor's samples the tree read
  F4.1 had ``z_T`` ≈ 4, ``z_V`` ≈ 0 under friction and ``z_T`` ≈ −0.5, ``z_V`` ≈ 2 under an open transistor
  (docs/flight.md, "Friction above the torque's band is not an open transistor");
* a torque departure the speed's goes against (friction with the motor above its model speed, a lighter
  propeller below it: :func:`..detection.torque_agrees_with_speed`) is no torque fault, as within its
  band below; the sequential test reads the same gate;
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

**The slow look.** With the profile's slow look (``steady.slow_factor``, ``slow_band_fraction``) the
torque against its siblings is also averaged over the steady samples ``slow_factor`` times longer than
the deviations' low-pass (``torque_slow_nm``), and identification measures that average's own noise like
the torque's (``[noise.N] slow_torque_nm ...``, :mod:`..noise`). Where the torque read NORMAL and the
slow look may judge, the average in its own σ beyond as many σ as the torque's band holds of the torque's
σ at the sample (grown beyond the identified conditions alike) names friction (above) or a lighter
propeller (below) (:class:`TorqueSlowLook`, after the deviations' slow look, which names an open
transistor first: its lost current lowers the measured torque too): in gusty air, where the fast torque's band is several times the healthy spread, a
friction of the paper's strength reads NORMAL on every sample and stands out of the slow average's
noise by tens of σ. The sequential test counts its departure for the fewer observations a longer average
gives (:mod:`..detection`, "The slow look's evidence").

**The torque's slow look as its siblings run** (``torque_slow_siblings``). The slow look's reach is the
fast torque band's in units of its σ, and beyond the identification flight's conditions that band grows
(:mod:`.bands`): in gusty air by two to seven times, so the reach ran from 8 to 30 slow σ while the
healthy motors' slow averages stayed within about ±1 of theirs (10th to 90th percentile) and friction's
stood 5 to 9 out (held-out world 1016, gusty, the faulty motor read NORMAL on every sample; docs/
flight.md, "The torque's slow look as its siblings run"). How far healthy slow torque averages part in the
air of the moment, the five siblings show: :class:`~.bands.LiveNoise` averages each motor's own torque
residual as this rule averages the torque against its siblings (the same time constant, over its judged
samples in its identified speeds), the vehicle stage gives the spread of the other motors' averages
around their median (:mod:`..siblings`, "The siblings' spread": what the six share, the ripple among it,
drops out of a spread), :class:`~.bands.SiblingBands` low-passes that spread over the motor's judged
samples in its identified speeds (``conditions_siblings_s``, as it does the fast torque's spread: the
spread of five values at one instant is itself noisy, and taken as it stood it let a healthy motor on
held-out world 1019 announce friction in moderate air), and the slow look's band is at most
``equation_bands · slow_band_fraction · m`` times the low-passed spread (m = ``torque_slow_siblings``),
never below as many of the motor's own slow σ at the sample's activity and pairing held within those the
identification flight reached (what it measured there, none of the growth beyond): the narrower of the
two. The siblings take the place of the extrapolation beyond the measured conditions, never of what was
measured: a spread low-passed over seconds does not follow one motor's upset at an input step, which
the slow average holds for a second or more and its measured σ at that activity covers (held-out world
1013, a healthy motor in calm air: a step put 18 quiet σ in its slow torque average for a moment, and a
band of the siblings' spread with the quiet σ as its floor announced friction). Only where the motor lies
in its identified speeds (by its model speed or the speed it turns), as the deviations' slow look bounds
its own (:mod:`.tree`), and where three siblings give a value; unlike that look, in the wait after an
input step too: in gusty air a step is seldom 2.4 s away (on world 1016's flight 97 % of the samples lay
in that wait), and the floor above holds what identification measured the steps to add. A motor's own
departure never widens its own band.

The sequential test (:mod:`.announce`) reads the same ``z_T`` for F1.1 and F3.1 where it is judged here
(``frame.z_torque``, NaN elsewhere). What stays with the deviations: the stop speed and the stall's
current, the speed-only states, F4.1 and UNKNOWN, and the lost-load check beyond the identified speeds
(:mod:`.judged`, which reads this rule's F3.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..._arrays import one_of
from ..detection import torque_agrees_with_speed
from ..states import Code, MotorState
from .bands import slow_average
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["Equations", "TorqueSlowLook"]

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

    def new_carry(self) -> Any:
        # the slow averages' last counted time and value: the torque's, then the voltage's (rules/voltage.py)
        return (math.nan,) * 4

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        torque_carries = self._torque(frame, [tuple(c[:2]) for c in carries])
        voltage_carries = self._slow_voltage(frame, [tuple(c[2:4]) for c in carries])
        return [tuple(t) + tuple(v) for t, v in zip(torque_carries, voltage_carries)]

    def _torque(self, frame: Frame, carries: list[Any]) -> list[Any]:
        """The torque balance read (class doc); each row's carry of its slow average advanced."""
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
        # averaged wherever a torque against the siblings is read, judged or not (identification measures
        # the average's noise with no band at all)
        available = holds & siblings & frame.current_trusted() & np.isfinite(torque)
        torque_slow, carries = self._slow_average(frame, torque, available, carries)
        if torque_slow is not None:
            frame.torque_slow_nm = torque_slow
        reread = judged & one_of(state, REREAD)
        if not reread.any():
            return carries
        torque_depth = np.abs(z) / n
        # a departure the speed's goes against is no torque fault (detection.torque_agrees_with_speed)
        departs = torque_depth > 1.0
        if frame.omega_judged_rad_s is not None and frame.omega_model_rad_s is not None:
            departs &= torque_agrees_with_speed(z, frame.omega_judged_rad_s - frame.omega_model_rad_s)
        named = np.where(z > 0, Code.F1_1, Code.F3_1)
        # only a torque below its band may be an open transistor's (module doc): above, it is friction
        deeper_f41 = (state == Code.F4_1) & (depth >= torque_depth) & (z < 0)
        new = np.where(
            departs & ~deeper_f41,
            named,
            np.where(one_of(state, TORQUE_FAULTS), Code.NORMAL, state),
        ).astype(state.dtype)
        new_depth = np.where(departs & ~deeper_f41, torque_depth, np.where(new == state, depth, 1.0))
        # a slower motor the tree named an open transistor: torque added rather than voltage lost where the
        # torque departs up by more of its σ than the voltage balance does (module doc); its depth stays
        z_voltage = self._voltage_z(frame, band)
        if z_voltage is not None:
            with np.errstate(invalid="ignore"):
                torque_added = (new == Code.F4_1) & (z > 0) & (z > z_voltage)
            new[torque_added] = Code.F1_1
        state[reread] = new[reread]
        depth[reread] = new_depth[reread]
        return carries

    def _voltage_z(self, frame: Frame, band: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The voltage balance's departure from its offset in its own σ at each sample, grown as the
        torque's band is (beyond the identified conditions, after a step); NaN on a motor whose noise has
        no voltage balance's; None where none has, or the balance rule wrote no voltage residual."""
        noise, residual = frame.noise or (), frame.voltage_residual_v
        if residual is None or all(m.voltage is None for m in noise):
            return None
        a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
        e = frame.pairing_error_rad_s
        rows = frame.noise_as_rows()
        with np.errstate(divide="ignore", invalid="ignore"):
            # the torque's band over its σ at the conditions: the growth both balances share
            grown = band / (self.profile.equation_bands * rows.torque_sigmas(a, e))
            return (residual - rows.voltage_offset) / (rows.voltage_sigmas(a, e) * grown)

    def _slow_voltage(self, frame: Frame, carries: list[Any]) -> list[Any]:
        """``frame.voltage_slow_v``: the voltage residual less the median of its siblings' (the vehicle
        stage's), averaged as the torque against its siblings is, wherever the current is trusted and the
        motor's noise has the voltage's (identification measures the average's noise, rules/voltage.py);
        each row's carry advanced. Nothing where the stage gave no siblings' voltage."""
        reference, residual, noise = frame.voltage_siblings_v, frame.voltage_residual_v, frame.noise
        if reference is None or residual is None or noise is None:
            return carries
        voltage = residual - reference
        holds = np.array([m.voltage is not None for m in noise])[:, None]
        available = holds & frame.current_trusted() & np.isfinite(voltage)
        averaged, carries = self._slow_average(frame, voltage, available, carries)
        frame.voltage_slow_v = averaged
        return carries

    def _slow_average(
        self, frame: Frame, values: NDArray[np.float64], available: NDArray[np.bool_], carries: list[Any]
    ) -> tuple[NDArray[np.float64] | None, list[Any]]:
        """``values`` averaged over the steady samples with ``slow_factor`` times the deviations' low-pass
        time (module doc, "The slow look"), NaN where not counted, and each row's carry advanced; None and
        the carries as given where the profile has no slow look."""
        if frame.slow is None:
            return None, carries
        width = frame.shape[1]
        counted = available & frame.steady & (np.arange(width)[None, :] < np.asarray(frame.counts)[:, None])
        return slow_average(frame, values, counted, carries)


@dataclass(frozen=True)
class TorqueSlowLook(Rule):
    """Where a sample still reads NORMAL after the slow look of the deviations (an open transistor is
    theirs: it named it first), the torque's slow average (``torque_slow_nm``, written by
    :class:`Equations`) against its own measured noise, in as many σ as the torque's band holds of the
    torque's σ at the sample: beyond, friction (above, the slow speed average not above the model) or a
    lighter propeller (below, not below it), with that depth and its slow evidence (module doc, "The slow
    look")."""

    name = "torque_slow_look"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        slow, averaged, band = frame.slow, frame.torque_slow_nm, frame.torque_band_nm
        fraction = self.profile.slow_band_fraction
        if slow is None or averaged is None or band is None or frame.z_torque is None or frame.noise is None:
            return carries
        if not fraction > 0:
            return carries
        state = frame.state
        judged = np.isfinite(frame.z_torque) & np.isfinite(averaged)
        candidates = judged & slow.ready & (state == Code.NORMAL)
        if not candidates.any():
            return carries
        rows = frame.noise_as_rows()
        a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
        e = frame.pairing_error_rad_s
        z = rows.slow_torque_z(averaged, a, e, self.profile.range_margin)
        with np.errstate(divide="ignore", invalid="ignore"):
            reach = fraction * band / rows.torque_sigmas(a, e)
            slow_depth = np.abs(z) / reach
        theirs = self._as_siblings_run(frame, averaged)
        if theirs is not None:
            # the narrower of the two bands: the larger share of it (NaN: the motor's own)
            slow_depth = np.where(np.isfinite(theirs) & ~(theirs <= slow_depth), theirs, slow_depth)
        # the paper's directions in the slow averages too: friction turns the motor no faster than its
        # model, a lighter propeller no slower (an open transistor's lost current lowers the torque read
        # through the duty, and the motor slows: not a lighter propeller)
        z_speed, _ = frame.slow_deviation_z()
        with np.errstate(invalid="ignore"):
            agrees = np.where(z > 0, z_speed <= 0, z_speed >= 0)
        named = candidates & (slow_depth > 1.0) & agrees
        if not named.any():
            return carries
        state[named] = np.where(z[named] > 0, Code.F1_1, Code.F3_1)
        frame.depth[named] = slow_depth[named]
        # in σ of the band, as the test counts the torque's own departure (z_torque)
        frame.note_slow_evidence(named, slow_depth * self.profile.equation_bands)
        return carries

    def _as_siblings_run(self, frame: Frame, averaged: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Each sample's slow torque departure as a share of the band its siblings give (module doc, "The
        torque's slow look as its siblings run"): ``equation_bands · slow_band_fraction · m`` times the
        spread of their slow torque averages (the vehicle stage's, low-passed by :class:`~.bands.
        SiblingBands`), never below the motor's own slow σ at the sample's conditions held within those
        identification measured; NaN where the siblings give none and beyond the motor's identified speeds; None: the profile does
        not bound it so, or the stage gave no spread."""
        spread = frame.torque_slow_spread_low_nm
        profile = self.profile
        if spread is None or not profile.torque_slow_as_siblings:
            return None
        rows = frame.noise_as_rows()
        a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
        offset, measured = rows.slow_within("slow_torque", a, frame.pairing_error_rad_s, profile.range_margin)
        reach = profile.equation_bands * profile.slow_band_fraction * profile.torque_slow_siblings
        # in the identified speeds by the model speed or the speed it turns (rules/tree.py, the same rule)
        turning = frame.omega_mean_rad_s if frame.omega_mean_rad_s is not None else frame.omega_rad_s
        within = rows.in_speed_range(frame.omega_model_rad_s, 0.0) | rows.in_speed_range(turning, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            # (np.maximum, not fmax: where the siblings give no spread, NaN, the motor's own band)
            share = np.abs(averaged - offset) / (reach * np.maximum(spread, measured))
        return np.where(within, share, np.nan)
