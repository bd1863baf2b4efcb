"""Bands in units of the vehicle's own noise (issue 17, item 1).

A profile with absolute bands (±9.4 rad/s, ±0.34 A...) carries the numbers of the vehicle it was tuned
on into every other: another motor, another ESC, another telemetry rate make the healthy deviations
larger or smaller, and the same band is then either a stream of false events or blind. Here the bands
come from the vehicle instead. Identification (``fit LOG --out vehicle.toml``) runs the flight rule over
the vehicle's healthy flight with the model it found and measures, per motor, how far the judged
deviations of speed and current (:mod:`..model.balance`) stray from the model, and how that grows with
the input activity:

    σ(a) = √(σ₀² + (c·a)²)

with ``a`` the input activity [V] the flight rule measures (how much the input zigzags between samples).
σ is measured on the tail, not the middle: in each activity bin the 99th percentile of |deviation|
divided by 2.576 (where a Gaussian's 99th percentile of |x| lies), because the tail is what makes false
events; σ₀ and c come from a non-negative least-squares fit of σ² on a² over the bins. A motor with too
few judged samples of its own takes the vehicle's (all motors pooled): the six motors share one type.

**Each motor's offset.** One model fitted over six motors leaves each its own offset: on a healthy flight
a motor's deviations are centred on it, not on zero (on a 24-kg world, ±1.5 rad/s and +2–3 A, for the
heavily loaded motors of an asymmetric frame in one direction and the light ones in the other). The
offset is measured too (the median deviation of the judged samples, ``speed_offset_rad_s``,
``current_offset_a``), the model each motor is judged against carries it (:mod:`.rules.offsets`), and σ
is measured around it. But the offset is known at the flight's operating points only; in other air or
another manoeuvre the model may be off by as much the other way. So its size is added to the quiet σ,
in quadrature: σ₀² ← σ₀² + offset². A motor the model describes well keeps its narrow bands; one it
describes badly gets bands as wide as the model's error, which identification measured, not guessed.

**The log's pairing.** A log pairs each sample with a command some time apart; the pairing error ``e``
(:mod:`.pairing`, rad/s) bounds how far that moves the deviations, and on the vehicle's own log it moves
them by some part of it: σ² gains (p·e)², p measured with σ₀ and c (one non-negative fit over bins of
the activity and of ``e``; ``speed_per_pairing``, ``current_a_per_pairing``). Zero where the log pairs
exactly (the simulator's table, a CSV with both).

**The conditions the noise was measured in.** σ is measured up to the busiest input of the healthy
flight and its loosest pairing (``activity_high_v``, ``pairing_error_high_rad_s``: the
:data:`CONDITION_SHARE` quantile of its judged samples'; the loosest few per cent are too few samples to
measure a tail σ on); beyond them σ is an extrapolation (the profile's ``range_margin`` widens the
limits as it widens the speed range).

**Beyond the measured conditions.** A vehicle identified from a calm flight meets moderate air with two
to five times the input activity and pairing error its flight had; not judging there leaves most of a
windy flight unjudged. Extrapolating σ(a, e) as measured does not hold: on the development worlds'
healthy flights beyond the limits, the deviations' tail reached about two times σ for the speed and four
times for the current (``benchmarks/bench_noise_beyond.py``). So beyond the limits σ is multiplied by
``excess ** growth``, ``excess`` the larger of the activity's and the pairing error's ratio to their
limits, ``growth`` the profile's ``conditions_growth`` (2: on those flights the tail then stayed within σ
on all but one, 1.43 σ at worst), up to ``conditions_reach`` times the limits; beyond that nothing is
judged (a stall is still named). Only where the model speed lies in the identified range: beyond it only
a propeller that lost its load is judged, against σ as measured (rules/judged.py). The wider bands cost
sensitivity, not false events: a departure has to be larger to be named in air rougher than the vehicle
was identified in. That growth is what the worst of those flights needed; most needed far less
(the excess says how far beyond the limits a sample lies, not how much wider its deviations run there:
flights at five times the limits needed no growth, others at twice needed three times), and their bands
came out 5 to 20 times wider than their deviations ran. The shipped profile therefore bounds it by what
the other motors show in the same air (``conditions_siblings``, :mod:`.rules.bands`, "Grown as the
siblings run").

**After an input step.** The balance rule waits ``settle_s`` after an input step before it judges (two
operating points in its low-passes). On some vehicles that wait is most of a windy flight: a log whose
commands arrive as a staircase of jumps larger than the rule's step leaves few samples settled, though
the deviations between the jumps are no wider than settled ones. Identification measures it: the wait is
cut into :data:`AFTER_STEP_BINS` bins, and in each, over the identification flight's waiting samples of
all motors, how many times wider the deviations' tail is than the settled samples' in units of each
motor's σ(a, e) (``after_step_1`` ... in ``[noise.N]``, ≥ 1; NaN where fewer than
:data:`MIN_AFTER_STEP_SAMPLES` samples fell in the bin). Waiting samples are then judged in bands that
many times wider; where the bin was not measured the wait holds, as for a vehicle file without them.

**Each equation's own noise.** The deviations mix the model's two balances (:mod:`..model.balance`,
"The two equations apart"), and friction or a lighter propeller moves only the torque balance; a profile
with ``equation_bands`` judges those two faults in it (:mod:`.rules.equations`). So the balances' noise is
measured apart too, on the same judged samples (those with a trusted current) and the same way: the
low-passed torque residual ``r_T`` [N·m] and voltage residual ``r_V`` [V] around each motor's median (its
offset, added to the quiet σ in quadrature), σ(a, e) by the same fit (``torque_residual_nm``,
``..._per_v``, ``..._per_pairing``, ``torque_residual_offset_nm``; ``voltage_residual_v`` alike, written
for the record of how noisy each balance is, not judged). Beyond the measured conditions and after a step they
widen by the same factors as the deviations'. Where the ESC reports its input current, the torque is
read through the duty and its offset moves with the duty's ripple; identification marks it so
(``torque_residual_through_duty = 1``). What is judged is the torque against the median of the other
motors' (:mod:`.siblings`), whose noise is measured the same way on the same samples
(``torque_vs_siblings_nm``, ``..._per_v``, ``..._per_pairing``, ``torque_vs_siblings_offset_nm``; where
the sample had a reference): the ripple and the model's error away from the flight's operating point are
common to all motors and leave it (:mod:`.rules.equations`, "An input current's ripple, and the
siblings").

**The slow look's own noise.** A small lasting fault (an open transistor in moderate air) departs by
about the bands' width, and reads NORMAL on half its samples; averaged longer, the healthy deviations
narrow and the fault's departure stays. The balance rule's slow look (``slow_factor``: the deviations
low-passed that many times longer) is judged against its own spread, measured here like the deviations'
on the samples it could judge (``slow_ready``): σ(a, e) of the slow averages of speed and current around
each motor's own median, that median added to the quiet σ in quadrature (``slow_speed_rad_s``,
``..._per_v``, ``..._per_pairing``, ``slow_speed_offset_rad_s``; ``slow_current_a`` alike; the torque
against its siblings averaged as long, ``slow_torque_nm`` ..., :mod:`.rules.equations`; the voltage
balance against its siblings alike, ``slow_voltage_v`` ..., :mod:`.rules.voltage`). No share of
the bands is tuned: the slow look's bands hold as many of its σ as the fast look's hold of theirs
(:class:`..rules.tree.SlowLook`). Beyond the conditions the noise was measured in, the slow σ grows at
least as the fast σ grows from their limits: a calm flight may measure the slow average's noise flat in
the activity (its slope fitted as 0) where the fast one's grows, and on held-out world 1019 in gusty air,
nine times the identified activity, that flat σ named healthy motors' torque F1.1 and F3.1 on up to a
tenth of their samples.

**The speed against its siblings' prediction.** Where the attitude controller drives the motors in a
pattern, much of a healthy motor's speed deviation is explained by its siblings' of the same moment
(:mod:`.prediction`). Identification measures the covariance of the motors' judged speed deviations on
its flight (``speed_covariance_M``: each motor's with motor M, its own variance included, (rad/s)²),
diagnoses the flight again with it, and measures the deviation less the siblings' part like a balance
(``speed_vs_siblings_rad_s``, ``..._per_v``, ``..._per_pairing``, ``speed_vs_siblings_offset_rad_s``); the
profile's ``speed_against_siblings`` judges against it where its σ is the narrower (:mod:`.rules.against`).
Two things set it apart from a balance's noise. A prediction from strongly correlated siblings has
heavier tails than a Gaussian with the same 99 % tail, and the bands and the sequential test's design
assume a Gaussian's: its σ is widened until its 99.9 % tail too lies where a Gaussian's does (the motors
pooled, :data:`DEEP_TAIL_SHARE`). And in a manoeuvre the prediction from the siblings' latest values lags
more than each motor's own deviation does: how much wider it is in each bin of the wait after a step is
measured apart (``speed_vs_siblings_after_step_1`` ...; a bin not measured is judged alone).

A profile then sets ``noise_bands = n``: the bands are n·σ(a) of each motor, a dimensionless number that
is the same for every vehicle. A vehicle file without the noise cannot be diagnosed with such a profile;
:func:`require_noise` says which key is missing and how to get it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import broadcast_to, nan_to_zero
from ..errors import ConfigError
from ..model.lsq import fit_linear
from ..telemetry.table import TelemetryTable
from .plausibility import CURRENT_UNTRUSTED

__all__ = [
    "NOISE_KEYS",
    "BandNoise",
    "EquationNoise",
    "NoiseRows",
    "band_noise_of",
    "measure_band_noise",
    "measure_speed_vs_siblings",
    "require_noise",
]

#: the wait after an input step (the balance rule's ``settle_s``) is cut into this many bins, each with its
#: own measured widening ("After an input step", module doc)
AFTER_STEP_BINS = 4
#: the motor numbers a motor's ``speed_covariance_M`` keys may name (the vehicle file's motor numbers,
#: config.MAX_MOTOR_NUMBER)
COVARIANCE_MOTORS = 32
#: the keys of a vehicle file's ``[noise.N]`` that :class:`BandNoise` reads, with their units
NOISE_KEYS = {
    "speed_rad_s": "rad/s",
    "speed_rad_s_per_v": "rad/s per V of input activity",
    "current_a": "A",
    "current_a_per_v": "A per V of input activity",
    "band_samples": "judged samples",
    "current_typical_a": "A",
    "omega_low_rad_s": "rad/s",
    "omega_high_rad_s": "rad/s",
    "speed_offset_rad_s": "rad/s",
    "current_offset_a": "A",
    "activity_high_v": "V",
    "speed_per_pairing": "rad/s per rad/s of pairing error",
    "current_a_per_pairing": "A per rad/s of pairing error",
    "pairing_error_high_rad_s": "rad/s",
    **{f"after_step_{b + 1}": "times the settled sigma" for b in range(AFTER_STEP_BINS)},
    "torque_residual_nm": "N·m",
    "torque_residual_nm_per_v": "N·m per V of input activity",
    "torque_residual_nm_per_pairing": "N·m per rad/s of pairing error",
    "torque_residual_offset_nm": "N·m",
    "torque_residual_through_duty": "1: an input current over the duty, not judged",
    "torque_vs_siblings_nm": "N·m",
    "torque_vs_siblings_nm_per_v": "N·m per V of input activity",
    "torque_vs_siblings_nm_per_pairing": "N·m per rad/s of pairing error",
    "torque_vs_siblings_offset_nm": "N·m",
    "voltage_residual_v": "V",
    "voltage_residual_v_per_v": "V per V of input activity",
    "voltage_residual_v_per_pairing": "V per rad/s of pairing error",
    "voltage_residual_offset_v": "V",
    "slow_speed_rad_s": "rad/s",
    "slow_speed_rad_s_per_v": "rad/s per V of input activity",
    "slow_speed_per_pairing": "rad/s per rad/s of pairing error",
    "slow_speed_offset_rad_s": "rad/s",
    "slow_current_a": "A",
    "slow_current_a_per_v": "A per V of input activity",
    "slow_current_a_per_pairing": "A per rad/s of pairing error",
    "slow_current_offset_a": "A",
    "slow_torque_nm": "N·m",
    "slow_torque_nm_per_v": "N·m per V of input activity",
    "slow_torque_nm_per_pairing": "N·m per rad/s of pairing error",
    "slow_torque_offset_nm": "N·m",
    "slow_voltage_v": "V",
    "slow_voltage_v_per_v": "V per V of input activity",
    "slow_voltage_v_per_pairing": "V per rad/s of pairing error",
    "slow_voltage_offset_v": "V",
    "speed_vs_siblings_rad_s": "rad/s",
    "speed_vs_siblings_rad_s_per_v": "rad/s per V of input activity",
    "speed_vs_siblings_per_pairing": "rad/s per rad/s of pairing error",
    "speed_vs_siblings_offset_rad_s": "rad/s",
    **{f"speed_vs_siblings_after_step_{b + 1}": "times its settled sigma" for b in range(AFTER_STEP_BINS)},
    **{f"speed_covariance_{m}": f"(rad/s)^2 with motor {m}" for m in range(1, COVARIANCE_MOTORS + 1)},
    **{
        f"speed_lagged_covariance_{m}": f"(rad/s)^2 with motor {m}'s latest before"
        for m in range(1, COVARIANCE_MOTORS + 1)
    },
}
#: the keys of each equation's noise (module doc, "Each equation's own noise"), in the order of
#: :class:`EquationNoise`'s fields
EQUATION_KEYS = {
    "torque": (
        "torque_residual_nm",
        "torque_residual_nm_per_v",
        "torque_residual_nm_per_pairing",
        "torque_residual_offset_nm",
        "torque_residual_through_duty",
    ),
    "torque_vs_siblings": (
        "torque_vs_siblings_nm",
        "torque_vs_siblings_nm_per_v",
        "torque_vs_siblings_nm_per_pairing",
        "torque_vs_siblings_offset_nm",
    ),
    "voltage": (
        "voltage_residual_v",
        "voltage_residual_v_per_v",
        "voltage_residual_v_per_pairing",
        "voltage_residual_offset_v",
    ),
    "slow_speed": (
        "slow_speed_rad_s",
        "slow_speed_rad_s_per_v",
        "slow_speed_per_pairing",
        "slow_speed_offset_rad_s",
    ),
    "slow_current": (
        "slow_current_a",
        "slow_current_a_per_v",
        "slow_current_a_per_pairing",
        "slow_current_offset_a",
    ),
    "slow_torque": (
        "slow_torque_nm",
        "slow_torque_nm_per_v",
        "slow_torque_nm_per_pairing",
        "slow_torque_offset_nm",
    ),
    "slow_voltage": (
        "slow_voltage_v",
        "slow_voltage_v_per_v",
        "slow_voltage_v_per_pairing",
        "slow_voltage_offset_v",
    ),
    "speed_vs_siblings": (
        "speed_vs_siblings_rad_s",
        "speed_vs_siblings_rad_s_per_v",
        "speed_vs_siblings_per_pairing",
        "speed_vs_siblings_offset_rad_s",
    ),
}
#: the keys of the speed deviations' covariance with each motor, by motor number
COVARIANCE_KEYS = {m: f"speed_covariance_{m}" for m in range(1, COVARIANCE_MOTORS + 1)}
#: the keys of its covariance with each motor's latest deviation before it (:mod:`.prediction`)
LAGGED_COVARIANCE_KEYS = {m: f"speed_lagged_covariance_{m}" for m in range(1, COVARIANCE_MOTORS + 1)}
#: the after-step keys in bin order
AFTER_STEP_KEYS = tuple(f"after_step_{b + 1}" for b in range(AFTER_STEP_BINS))
#: the same of the speed less its siblings' prediction
AGAINST_AFTER_STEP_KEYS = tuple(f"speed_vs_siblings_after_step_{b + 1}" for b in range(AFTER_STEP_BINS))
#: the keys that may be negative (offsets from the model)
SIGNED_NOISE_KEYS = (
    "speed_offset_rad_s",
    "current_offset_a",
    "torque_residual_offset_nm",
    "torque_vs_siblings_offset_nm",
    "voltage_residual_offset_v",
    "slow_speed_offset_rad_s",
    "slow_current_offset_a",
    "slow_torque_offset_nm",
    "slow_voltage_offset_v",
    "speed_vs_siblings_offset_rad_s",
    *COVARIANCE_KEYS.values(),
    *LAGGED_COVARIANCE_KEYS.values(),
)
#: the slow look's noises in the order of :attr:`NoiseRows.slow_table`'s columns (four each)
SLOW_NOISES = ("slow_speed", "slow_current", "slow_torque", "slow_voltage")
#: the identified speed range: these shares of the judged samples' model speeds lie inside it
RANGE_SHARES = (0.01, 0.99)
#: the input activity and pairing error the noise was measured up to: this share of the judged samples'
#: (the tail σ needs samples around it; the loosest few percent are too few to measure it on)
CONDITION_SHARE = 0.95
#: the share of |deviation| below the measured tail, and where a Gaussian's lies (in σ)
TAIL_SHARE = 0.99
TAIL_SIGMAS = 2.5758293035489
#: the deeper tail a noise whose tails may be heavier than a Gaussian's is held to
#: (:func:`measure_speed_vs_siblings`): this share of |z| within a Gaussian's, on at least this many samples
DEEP_TAIL_SHARE = 0.999
DEEP_TAIL_SIGMAS = 3.2905267314919
DEEP_TAIL_SAMPLES = 2000
#: fewer judged samples than this: the motor takes the vehicle's noise (all motors pooled)
MIN_MOTOR_SAMPLES = 200
#: the fewest samples of an activity bin
MIN_BIN_SAMPLES = 40
#: a bin's widening is measured on at least this many samples (all motors pooled), else not judged
MIN_AFTER_STEP_SAMPLES = 200
#: at most this many activity bins
MAX_BINS = 6
#: the pairing error's bins start at these quantiles (its loosest samples in finer bins)
PAIRING_BIN_SHARES = (0.0, 0.5, 0.75, 0.9, 0.97)


@dataclass(frozen=True)
class EquationNoise:
    """One motor's healthy spread of one balance of the model, low-passed as the balance rule judges it
    (the torque r_T [N·m] or the voltage r_V [V], :mod:`..model.balance`): σ(a, e) = √(σ₀² + (c·a)² +
    (p·e)²) around its offset, as :class:`BandNoise` has it for the deviations (module doc, "Each
    equation's own noise")."""

    sigma: float
    per_activity: float = 0.0
    per_pairing: float = 0.0
    offset: float = 0.0
    #: the balance was read from an input current over the duty (rules/equations.py, "An input current's
    #: ripple"): its offset moves with the duty's ripple, and it is not judged
    through_duty: bool = False

    def sigmas(
        self, activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """σ at each input activity [V] (and pairing error [rad/s], where given)."""
        a, e = _conditions(activity_v, pairing_error_rad_s)
        return _grown(self.sigma, self.per_activity, self.per_pairing, a, e)


class _ConditionsMath:
    """What a motor's band noise says at given conditions, written elementwise once for
    :class:`BandNoise` (its numbers floats) and :class:`NoiseRows` (columns, one row per motor)."""

    speed_rad_s: Any
    current_a: Any
    speed_rad_s_per_v: Any
    current_a_per_v: Any
    omega_low_rad_s: Any
    omega_high_rad_s: Any
    activity_high_v: Any
    speed_per_pairing: Any
    current_a_per_pairing: Any
    pairing_error_high_rad_s: Any
    #: the widening after a step in each of :data:`AFTER_STEP_BINS` bins, one row per motor (NaN: not
    #: measured)
    after_step_table: NDArray[np.float64]

    def sigmas(
        self, activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """σ of the speed [rad/s] and current [A] deviations at each input activity [V] (and pairing error
        [rad/s], where given)."""
        a, e = _conditions(activity_v, pairing_error_rad_s)
        speed = _grown(self.speed_rad_s, self.speed_rad_s_per_v, self.speed_per_pairing, a, e)
        current = _grown(self.current_a, self.current_a_per_v, self.current_a_per_pairing, a, e)
        # no usable current: nothing to compare with
        current = np.where(np.isfinite(self.current_a), current, np.inf)
        return speed, current

    def in_speed_range(self, omega_model_rad_s: ArrayLike, margin: float) -> NDArray[np.bool_]:
        """Where the model speed lies in the range the healthy flight covered, widened by ``margin`` (a
        share of the range's ends); everywhere where the range is not known."""
        w = np.asarray(omega_model_rad_s, dtype=float)
        low, high = self.omega_low_rad_s, self.omega_high_rad_s
        with np.errstate(invalid="ignore"):
            inside = (w >= (1.0 - margin) * low) & (w <= (1.0 + margin) * high)
        return np.where(np.isfinite(low) & np.isfinite(high), inside, True)

    def beyond_range(
        self,
        omega_model_rad_s: ArrayLike,
        margin: float,
        exponent: float,
        omega_measured_rad_s: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """``(1 + d/span)**exponent`` where the model speed lies beyond the range the healthy flight
        covered but within ``margin`` of it (:meth:`in_speed_range`): d how far beyond (above its top or
        below its bottom), span the range's width; 1 within the range, beyond the margin (nothing but a
        lost load is judged there, against σ as measured: rules/judged.py), and where the range is not
        known or has no width. A model fitted over the span is an extrapolation beyond it, whose error
        grows with the distance in units of the span the fit saw (the leverage of a regression's
        prediction), not in units of the speed.

        With ``omega_measured_rad_s``, d is the lesser of the model speed's distance and the measured
        speed's (NaN: the model's alone): a motor carrying a failed sibling's share turns beyond the range
        as its model says, while one that lost drive or gained friction is commanded beyond it and turns
        slower than its model, short of it, where growing its bands would hide the fault."""
        w = np.asarray(omega_model_rad_s, dtype=float)
        low, high = self.omega_low_rad_s, self.omega_high_rad_s

        def distance(speed: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.maximum(np.maximum(speed - high, low - speed), 0.0)

        with np.errstate(invalid="ignore", divide="ignore"):
            span = np.asarray(high) - np.asarray(low)
            beyond = distance(w)
            if omega_measured_rad_s is not None:
                measured = distance(np.asarray(omega_measured_rad_s, dtype=float))
                beyond = np.where(np.isnan(measured), beyond, np.minimum(beyond, measured))
            factor = (1.0 + beyond / span) ** exponent
        grows = np.isfinite(factor) & (span > 0) & self.in_speed_range(w, margin)
        return np.where(grows, factor, 1.0)

    def beyond_conditions(
        self, margin: float, activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """How far each sample lies beyond the conditions σ was measured in: the larger of its input
        activity over the flight's busiest and its pairing error (where given) over the flight's loosest,
        those widened by ``margin``; at most 1 within both (0 where neither limit is known)."""
        excess = np.zeros(np.broadcast_shapes(np.shape(activity_v), np.shape(self.activity_high_v)))
        for values, high in (
            (activity_v, self.activity_high_v),
            (pairing_error_rad_s, self.pairing_error_high_rad_s),
        ):
            if values is None:
                continue
            x, limit = nan_to_zero(np.asarray(values, dtype=float)), (1.0 + margin) * np.asarray(high)
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(limit > 0, x / limit, np.where(x > 0, np.inf, 0.0))
            # a limit not known: nothing beyond it
            excess = np.maximum(excess, np.where(np.isfinite(high), ratio, 0.0))
        return excess

    def known(
        self,
        omega_model_rad_s: ArrayLike,
        margin: float,
        activity_v: ArrayLike | None = None,
        pairing_error_rad_s: ArrayLike | None = None,
        reach: float = 1.0,
    ) -> NDArray[np.bool_]:
        """Where the model speed lies in the range the healthy flight covered, widened by ``margin`` (a
        share of the range's ends), and the input activity and the pairing error (where given) are at most
        ``reach`` times the flight's highest, widened alike; everywhere where a range is not known."""
        inside = self.in_speed_range(omega_model_rad_s, margin)
        if activity_v is not None or pairing_error_rad_s is not None:
            shape = np.shape(omega_model_rad_s)
            activity = np.zeros(shape) if activity_v is None else activity_v
            inside &= self.beyond_conditions(margin, activity, pairing_error_rad_s) <= reach
        return inside

    def growth(
        self,
        omega_model_rad_s: ArrayLike,
        margin: float,
        activity_v: ArrayLike,
        pairing_error_rad_s: ArrayLike | None,
        exponent: float,
    ) -> NDArray[np.float64]:
        """The factor σ is multiplied by beyond the conditions it was measured in (module doc, "Beyond the
        measured conditions"): ``excess ** exponent`` where :meth:`beyond_conditions` exceeds 1 and the
        model speed lies in the identified range; 1 elsewhere (beyond the range only a propeller that lost
        its load is judged, against σ as measured: rules/judged.py)."""
        excess = np.maximum(self.beyond_conditions(margin, activity_v, pairing_error_rad_s), 1.0)
        grown = np.where(np.isfinite(excess), excess, 1.0) ** exponent
        return np.where(self.in_speed_range(omega_model_rad_s, margin), grown, 1.0)

    def after_step_factor(self, since_step_s: ArrayLike, settle_s: float) -> NDArray[np.float64]:
        """How many times wider σ is at each sample's time since the last input step [s] (module doc,
        "After an input step"): 1 where the wait of ``settle_s`` is over (or the time is NaN), the
        measured widening of the sample's bin within it, NaN where that was not measured (not judged).
        (:class:`NoiseRows`: rows × samples, each row its motor's.)"""
        return after_step_factor(self.after_step_table, since_step_s, settle_s)


def after_step_factor(
    table: NDArray[np.float64], since_step_s: ArrayLike, settle_s: float
) -> NDArray[np.float64]:
    """:meth:`_ConditionsMath.after_step_factor` from a table of bins (one row of
    :data:`AFTER_STEP_BINS` for all samples, or one per row of ``since_step_s``)."""
    since = np.asarray(since_step_s, dtype=float)
    factor = np.ones(since.shape)
    within = np.isfinite(since) & (since < settle_s)
    if not within.any():
        return factor
    if not settle_s > 0:
        factor[within] = np.nan
        return factor
    row = (
        np.zeros(since.shape, dtype=np.intp)
        if table.shape[0] == 1
        else broadcast_to(np.arange(table.shape[0])[:, None], since.shape)
    )
    bins = np.clip((since[within] / settle_s * AFTER_STEP_BINS).astype(int), 0, AFTER_STEP_BINS - 1)
    factor[within] = table[row[within], bins]
    return factor


@dataclass(frozen=True)
class NoiseRows(_ConditionsMath):
    """Several motors' :class:`BandNoise`, each number a column with one row per motor: a call of every
    motor's samples (rows × samples) gets from each method, row by row, what each motor's own gives,
    in one pass instead of one per motor."""

    speed_rad_s: NDArray[np.float64]
    current_a: NDArray[np.float64]
    speed_rad_s_per_v: NDArray[np.float64]
    current_a_per_v: NDArray[np.float64]
    omega_low_rad_s: NDArray[np.float64]
    omega_high_rad_s: NDArray[np.float64]
    activity_high_v: NDArray[np.float64]
    speed_per_pairing: NDArray[np.float64]
    current_a_per_pairing: NDArray[np.float64]
    pairing_error_high_rad_s: NDArray[np.float64]
    after_step_table: NDArray[np.float64]
    #: the torque noise each motor is judged with (:attr:`BandNoise.torque_judged`): σ₀, its growth with
    #: the activity and with the pairing, and the offset, one row per motor (NaN: not judged in the torque)
    torque_table: NDArray[np.float64]
    #: the torque's own noise (:attr:`BandNoise.torque`, not against the siblings), as ``torque_table``
    own_torque_table: NDArray[np.float64]
    #: the voltage balance's noise (:attr:`BandNoise.voltage`) and the speed's less its siblings' prediction
    #: (:attr:`BandNoise.speed_vs_siblings`): σ₀, its growth with the activity and with the pairing, and the
    #: offset, one row per motor (NaN: not measured)
    voltage_table: NDArray[np.float64]
    against_table: NDArray[np.float64]
    #: the speed less its siblings' prediction: how many times wider after a step, per bin
    #: (:attr:`BandNoise.against_after_step_table`), one row per motor
    against_after_step_table: NDArray[np.float64]
    #: the slow look's noise (:data:`SLOW_NOISES`: :attr:`BandNoise.slow_speed`, ``slow_current``,
    #: ``slow_torque``, ``slow_voltage``): σ₀, its growth with the activity and with the pairing, and the
    #: offset of each, four columns each in that order, one row per motor (NaN: not measured)
    slow_table: NDArray[np.float64]

    def slow_deviations(
        self,
        delta_omega_rad_s: NDArray[np.float64],
        delta_current_a: NDArray[np.float64],
        activity_v: ArrayLike,
        pairing_error_rad_s: ArrayLike | None = None,
        margin: float = 0.0,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The slow look's deviations of speed and current in units of each row's own slow σ (module doc,
        "The slow look's own noise"), from its offset (NaN on the rows of motors whose slow noise was not
        measured)."""
        a, e = _conditions(activity_v, pairing_error_rad_s)
        clamped = self._within_conditions(a, e, margin)
        speed, current = self.sigmas(a, e)
        speed_there, current_there = self.sigmas(*clamped)
        with np.errstate(divide="ignore", invalid="ignore"):  # no usable current: σ infinite
            growth = speed / speed_there, current / current_there
        return (
            self._slow_z(delta_omega_rad_s, "slow_speed", a, e, clamped, growth[0]),
            self._slow_z(delta_current_a, "slow_current", a, e, clamped, growth[1]),
        )

    def slow_quiet(
        self,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Each row's slow offsets and quiet slow σ (σ₀), speed [rad/s] then current [A], as columns (NaN:
        not measured)."""
        t = self.slow_table
        return t[:, 3:4], t[:, 7:8], t[:, 0:1], t[:, 4:5]

    def slow_within(
        self,
        name: str,
        activity_v: ArrayLike,
        pairing_error_rad_s: ArrayLike | None = None,
        margin: float = 0.0,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Each row's slow offset of one of :data:`SLOW_NOISES` (``"slow_torque"``: the torque against its
        siblings [N·m]; ``"slow_voltage"``: the voltage against its siblings [V]), a column, and its slow σ
        at each sample's conditions held within those the noise was measured in (widened by ``margin``):
        what identification measured there, none of the growth beyond (NaN: not measured)."""
        a, e = _conditions(activity_v, pairing_error_rad_s)
        sigma, per_activity, per_pairing, offset = self._slow_columns(name)
        return offset, _grown(sigma, per_activity, per_pairing, *self._within_conditions(a, e, margin))

    def _slow_columns(self, name: str) -> tuple[NDArray[np.float64], ...]:
        """σ₀, its growth with the activity and with the pairing, and the offset of one of
        :data:`SLOW_NOISES`, each a column."""
        first = 4 * SLOW_NOISES.index(name)
        return tuple(self.slow_table[:, k : k + 1] for k in range(first, first + 4))

    def slow_torque_z(
        self,
        torque_nm: NDArray[np.float64],
        activity_v: ArrayLike,
        pairing_error_rad_s: ArrayLike | None = None,
        margin: float = 0.0,
    ) -> NDArray[np.float64]:
        """The slow average of the torque against its siblings in units of each row's own slow σ, from its
        offset (NaN on the rows of motors whose slow torque noise was not measured)."""
        a, e = _conditions(activity_v, pairing_error_rad_s)
        clamped = self._within_conditions(a, e, margin)
        with np.errstate(divide="ignore", invalid="ignore"):
            growth = self.torque_sigmas(a, e) / self.torque_sigmas(*clamped)
        return self._slow_z(torque_nm, "slow_torque", a, e, clamped, growth)

    def _within_conditions(
        self, a: NDArray[np.float64], e: NDArray[np.float64] | None, margin: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The conditions held at the busiest activity and loosest pairing the noise was measured up to
        (widened by ``margin``; not held where a limit is not known)."""

        def held(x: NDArray[np.float64], high: Any) -> NDArray[np.float64]:
            limit = (1.0 + margin) * np.asarray(high, dtype=float)
            return np.where(np.isfinite(limit), np.minimum(x, limit), x)

        return held(a, self.activity_high_v), None if e is None else held(e, self.pairing_error_high_rad_s)

    def _slow_z(
        self,
        values: NDArray[np.float64],
        name: str,
        a: NDArray[np.float64],
        e: NDArray[np.float64] | None,
        clamped: tuple[NDArray[np.float64], NDArray[np.float64] | None],
        fast_growth: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """``values`` from the slow offset in units of the slow σ: σ(a, e) as measured, and beyond the
        conditions it was measured in never growing less than the fast look's σ grows from there (a slow
        noise measured flat in calm air is not flat in gusts: module doc, "The slow look's own noise")."""
        sigma, per_activity, per_pairing, offset = self._slow_columns(name)
        own = _grown(sigma, per_activity, per_pairing, a, e)
        from_limit = _grown(sigma, per_activity, per_pairing, *clamped) * np.where(
            np.isfinite(fast_growth), fast_growth, 1.0
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.asarray((values - offset) / np.fmax(own, from_limit))

    def torque_sigmas(
        self, activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Each row's torque σ(a, e) at its samples, what its motor's :attr:`BandNoise.torque_judged`
        gives (:meth:`EquationNoise.sigmas`); NaN on the rows of motors not judged in the torque."""
        return _equation_sigmas(self.torque_table, activity_v, pairing_error_rad_s)

    def own_torque_z(
        self,
        torque_nm: NDArray[np.float64],
        activity_v: ArrayLike,
        pairing_error_rad_s: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """Each row's torque balance (its own, not against the siblings) less its own offset, in its own
        σ(a, e) (:attr:`BandNoise.torque`, read through the duty or not); NaN on the rows without it."""
        sigma = _equation_sigmas(self.own_torque_table, activity_v, pairing_error_rad_s)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.asarray((torque_nm - self.own_torque_table[:, 3:4]) / sigma)

    def voltage_sigmas(
        self, activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Each row's voltage balance σ(a, e) at its samples (:meth:`EquationNoise.sigmas` of
        :attr:`BandNoise.voltage`); NaN on the rows of motors without it."""
        return _equation_sigmas(self.voltage_table, activity_v, pairing_error_rad_s)

    @property
    def voltage_offset(self) -> NDArray[np.float64]:
        """Each row's voltage balance offset, a column (NaN: not measured)."""
        return self.voltage_table[:, 3:4]

    def against_sigmas(
        self, activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Each row's σ(a, e) of the speed less its siblings' prediction at its samples
        (:attr:`BandNoise.speed_vs_siblings`); NaN on the rows of motors without it."""
        return _equation_sigmas(self.against_table, activity_v, pairing_error_rad_s)

    @classmethod
    def of(cls, noise: Sequence[BandNoise]) -> NoiseRows:
        """The rows of ``noise``, in its order: made once for the same motors' noise (the agent asks for
        them in every call; :class:`BandNoise` is frozen, and the rows' arrays are read-only)."""
        key = tuple(map(id, noise))
        held = _ROWS_MADE.get(key)
        if held is not None:
            return held[1]
        columns = {
            name: np.array([getattr(n, name) for n in noise], dtype=float).reshape(-1, 1)
            for name in _ROW_NUMBERS
        }
        table = np.concatenate([n.after_step_table for n in noise]).reshape(-1, AFTER_STEP_BINS)
        torque = _equation_table([n.torque_judged for n in noise])
        own_torque = _equation_table([n.torque for n in noise])
        slow = np.hstack([_equation_table([getattr(n, name) for n in noise]) for name in SLOW_NOISES])
        voltage = _equation_table([n.voltage for n in noise])
        against = _equation_table([n.speed_vs_siblings for n in noise])
        against_table = np.concatenate([n.against_after_step_table for n in noise]).reshape(
            -1, AFTER_STEP_BINS
        )
        for column in (*columns.values(), table, torque, own_torque, slow, voltage, against, against_table):
            column.flags.writeable = False
        rows = cls(
            **columns,
            after_step_table=table,
            torque_table=torque,
            own_torque_table=own_torque,
            voltage_table=voltage,
            against_table=against,
            against_after_step_table=against_table,
            slow_table=slow,
        )
        if len(_ROWS_MADE) >= _ROWS_HELD:
            _ROWS_MADE.clear()
        # the noise itself is held too: while it is, no other object can take its id, so the same ids are
        # the same noise
        _ROWS_MADE[key] = (tuple(noise), rows)
        return rows


def _equation_table(equations: Sequence[EquationNoise | None]) -> NDArray[np.float64]:
    """σ₀, its growth with the activity and with the pairing, and the offset of each row's balance (NaN
    where it has none), one row per motor."""
    return np.array(
        [
            (q.sigma, q.per_activity, q.per_pairing, q.offset) if q is not None else (np.nan,) * 4
            for q in equations
        ],
        dtype=float,
    ).reshape(-1, 4)


def _equation_sigmas(
    table: NDArray[np.float64], activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None
) -> NDArray[np.float64]:
    """Each row's σ(a, e) of the balance in ``table`` (:func:`_equation_table`) at its samples, what its
    :meth:`EquationNoise.sigmas` gives; NaN on the rows without it."""
    a, e = _conditions(activity_v, pairing_error_rad_s)
    sigma, per_activity, per_pairing = (table[:, k : k + 1] for k in range(3))
    return np.where(np.isfinite(sigma), _grown(sigma, per_activity, per_pairing, a, e), np.nan)


#: the rows made lately, by the ids of the noise they were made of (:meth:`NoiseRows.of`)
_ROWS_MADE: dict[tuple[int, ...], tuple[tuple[BandNoise, ...], NoiseRows]] = {}
_ROWS_HELD = 64


#: the numbers of :class:`_ConditionsMath`, in :class:`NoiseRows`' order
_ROW_NUMBERS = (
    "speed_rad_s",
    "current_a",
    "speed_rad_s_per_v",
    "current_a_per_v",
    "omega_low_rad_s",
    "omega_high_rad_s",
    "activity_high_v",
    "speed_per_pairing",
    "current_a_per_pairing",
    "pairing_error_high_rad_s",
)


@dataclass(frozen=True)
class BandNoise(_ConditionsMath):
    """One motor's healthy spread of the judged deviations: σ(a) = √(σ₀² + (c·a)²) for speed and current
    (current NaN: the ESC reports no usable current, the speed-only path judges)."""

    speed_rad_s: float
    current_a: float
    speed_rad_s_per_v: float = 0.0
    current_a_per_v: float = 0.0
    band_samples: int = 0
    #: the motor's median current on the judged samples [A]: its size, which the stall split scales with
    #: (or with the flight's own where lower: rules/tree.py)
    current_typical_a: float = math.nan
    #: the model speeds the healthy flight covered (1st and 99th percentile of the judged samples'): where
    #: the model was checked against this vehicle; NaN: not known
    omega_low_rad_s: float = math.nan
    omega_high_rad_s: float = math.nan
    #: the motor's healthy offset from the identified model: the median deviation of the judged samples
    #: (a model shared by six motors, fitted over all of them, leaves each its own offset); the bands
    #: are centred on it (:mod:`.rules.offsets`); 0: none measured
    speed_offset_rad_s: float = 0.0
    current_offset_a: float = 0.0
    #: the input activity the healthy flight reached (99th percentile of the judged samples'): σ(a) was
    #: measured up to there, and is an extrapolation beyond; NaN: not known
    activity_high_v: float = math.nan
    #: how σ grows with the log's pairing error e (:mod:`.pairing`, rad/s): σ² gains (p·e)², for the speed
    #: (dimensionless) and the current [A per rad/s]; 0: not measured (a log that pairs exactly)
    speed_per_pairing: float = 0.0
    current_a_per_pairing: float = 0.0
    #: the pairing error the healthy flight reached (99th percentile of its judged samples'): σ was
    #: measured up to there; NaN: not known
    pairing_error_high_rad_s: float = math.nan
    #: after an input step, in each of :data:`AFTER_STEP_BINS` bins of the rule's wait: how many times
    #: wider the healthy deviations' tail was than settled (≥ 1; the six motors pooled; NaN: too few
    #: samples to say, not judged there); empty: not measured (every sample waits, as the rule says)
    after_step: tuple[float, ...] = ()
    #: the healthy spread of the torque and the voltage balance apart (module doc, "Each equation's own
    #: noise"); None: not measured (a vehicle file from before, or an ESC without a usable current)
    torque: EquationNoise | None = None
    voltage: EquationNoise | None = None
    #: the torque balance minus the median of the other motors' (:mod:`.siblings`): its healthy spread,
    #: which the torque is judged against where measured; None: not measured (a file from before)
    torque_vs_siblings: EquationNoise | None = None
    #: the deviations of speed and current averaged longer (the balance rule's slow look, ``slow_factor``):
    #: their healthy spread around their offsets, which the slow look judges against (module doc, "The slow
    #: look's own noise"); None: not measured (a file from before, or a rule without a slow look)
    slow_speed: EquationNoise | None = None
    slow_current: EquationNoise | None = None
    #: the torque against its siblings averaged as long (rules/equations.py): its healthy spread
    slow_torque: EquationNoise | None = None
    #: the voltage balance against its siblings averaged as long (rules/voltage.py): its healthy spread
    slow_voltage: EquationNoise | None = None
    #: the speed deviation's covariance with each motor's on the healthy flight [(rad/s)²], (motor
    #: number, covariance) in motor order, its own variance included (:mod:`.prediction`); empty: not
    #: measured
    speed_covariance: tuple[tuple[int, float], ...] = ()
    #: its covariance with each motor's latest speed deviation before it [(rad/s)²] (:mod:`.prediction`,
    #: "Before, never of the same instant"); empty: not measured
    speed_lagged_covariance: tuple[tuple[int, float], ...] = ()
    #: the speed deviation less its siblings' linear prediction (:mod:`.prediction`): its healthy spread,
    #: which the speed is judged against where the profile's ``speed_against_siblings`` says; None: not
    #: measured
    speed_vs_siblings: EquationNoise | None = None
    #: how many times wider that difference's tail is in each bin of the rule's wait after a step than
    #: settled (as :attr:`after_step`, the motors pooled; NaN: not measured there, not judged against the
    #: siblings there); empty: not measured
    speed_vs_siblings_after_step: tuple[float, ...] = ()

    @classmethod
    def unbounded(cls, through_duty: bool = False) -> BandNoise:
        """A noise of infinite σ everywhere: no band at all (identification runs the rule with it while it
        measures the noise, so that every sample the rule judges counts). ``through_duty``: the ESC reads
        its input current (the rule reads the torque through the duty as it will when it judges)."""
        inf = EquationNoise(math.inf)
        torque = EquationNoise(math.inf, through_duty=through_duty)
        return cls(math.inf, math.inf, torque=torque, voltage=inf, torque_vs_siblings=inf)

    @property
    def has_torque_noise(self) -> bool:
        """Whether the torque balance's own noise was measured (the profile's ``equation_bands`` needs it)."""
        return self.torque is not None or self.torque_vs_siblings is not None

    @property
    def after_step_table(self) -> NDArray[np.float64]:  # type: ignore[override]
        """:attr:`after_step` as one row of :data:`AFTER_STEP_BINS` bins (NaN: not measured)."""
        return _bins_row(self.after_step)

    @property
    def against_after_step_table(self) -> NDArray[np.float64]:
        """:attr:`speed_vs_siblings_after_step` as one row of :data:`AFTER_STEP_BINS` bins (NaN: not
        measured)."""
        return _bins_row(self.speed_vs_siblings_after_step)

    @property
    def torque_judged(self) -> EquationNoise | None:
        """The torque noise the profile's ``equation_bands`` judges with (:mod:`.rules.equations`): against
        the siblings where measured, else the torque's own unless read through the duty; None: not
        judged."""
        if self.torque_vs_siblings is not None:
            return self.torque_vs_siblings
        if self.torque is not None and not self.torque.through_duty:
            return self.torque
        return None

    def as_mapping(self) -> dict[str, float]:
        """The ``[noise.N]`` keys of a vehicle file (the pairing's only where measured: a file reads the
        same without them)."""
        values = {
            "speed_rad_s": self.speed_rad_s,
            "speed_rad_s_per_v": self.speed_rad_s_per_v,
            "current_a": self.current_a,
            "current_a_per_v": self.current_a_per_v,
            "band_samples": float(self.band_samples),
            "current_typical_a": self.current_typical_a,
            "omega_low_rad_s": self.omega_low_rad_s,
            "omega_high_rad_s": self.omega_high_rad_s,
            "speed_offset_rad_s": self.speed_offset_rad_s,
            "current_offset_a": self.current_offset_a,
            "activity_high_v": self.activity_high_v,
            "speed_per_pairing": self.speed_per_pairing,
            "current_a_per_pairing": self.current_a_per_pairing,
            "pairing_error_high_rad_s": self.pairing_error_high_rad_s,
        }
        if not math.isfinite(self.pairing_error_high_rad_s):
            for key in ("speed_per_pairing", "current_a_per_pairing", "pairing_error_high_rad_s"):
                del values[key]
        values.update(zip(AFTER_STEP_KEYS, self.after_step))
        values.update((COVARIANCE_KEYS[m], c) for m, c in self.speed_covariance)
        values.update((LAGGED_COVARIANCE_KEYS[m], c) for m, c in self.speed_lagged_covariance)
        values.update(
            (key, f)
            for key, f in zip(AGAINST_AFTER_STEP_KEYS, self.speed_vs_siblings_after_step)
            if math.isfinite(f)
        )
        for name, keys in EQUATION_KEYS.items():
            equation = getattr(self, name)
            if equation is not None:
                numbers = (equation.sigma, equation.per_activity, equation.per_pairing, equation.offset)
                values.update(zip(keys, numbers))
                if equation.through_duty:
                    values[keys[4]] = 1.0
        return values

    @classmethod
    def from_mapping(cls, values: Mapping[str, float]) -> BandNoise | None:
        """The band noise of a ``[noise.N]`` table; None where it has no ``speed_rad_s`` (a vehicle file
        written before the noise was measured)."""
        if "speed_rad_s" not in values:
            return None
        return cls(
            speed_rad_s=float(values["speed_rad_s"]),
            current_a=float(values.get("current_a", math.nan)),
            speed_rad_s_per_v=float(values.get("speed_rad_s_per_v", 0.0)),
            current_a_per_v=float(values.get("current_a_per_v", 0.0)),
            band_samples=int(values.get("band_samples", 0)),
            current_typical_a=float(values.get("current_typical_a", math.nan)),
            omega_low_rad_s=float(values.get("omega_low_rad_s", math.nan)),
            omega_high_rad_s=float(values.get("omega_high_rad_s", math.nan)),
            speed_offset_rad_s=float(values.get("speed_offset_rad_s", 0.0)),
            current_offset_a=float(values.get("current_offset_a", 0.0)),
            activity_high_v=float(values.get("activity_high_v", math.nan)),
            speed_per_pairing=float(values.get("speed_per_pairing", 0.0)),
            current_a_per_pairing=float(values.get("current_a_per_pairing", 0.0)),
            pairing_error_high_rad_s=float(values.get("pairing_error_high_rad_s", math.nan)),
            # a bin not measured is NaN, which a vehicle file leaves out; none at all: not measured
            after_step=tuple(float(values.get(key, math.nan)) for key in AFTER_STEP_KEYS)
            if any(key in values for key in AFTER_STEP_KEYS)
            else (),
            torque=_equation_of(values, EQUATION_KEYS["torque"]),
            voltage=_equation_of(values, EQUATION_KEYS["voltage"]),
            torque_vs_siblings=_equation_of(values, EQUATION_KEYS["torque_vs_siblings"]),
            slow_speed=_equation_of(values, EQUATION_KEYS["slow_speed"]),
            slow_current=_equation_of(values, EQUATION_KEYS["slow_current"]),
            slow_torque=_equation_of(values, EQUATION_KEYS["slow_torque"]),
            slow_voltage=_equation_of(values, EQUATION_KEYS["slow_voltage"]),
            speed_covariance=tuple(
                (m, float(values[key])) for m, key in COVARIANCE_KEYS.items() if key in values
            ),
            speed_lagged_covariance=tuple(
                (m, float(values[key])) for m, key in LAGGED_COVARIANCE_KEYS.items() if key in values
            ),
            speed_vs_siblings=_equation_of(values, EQUATION_KEYS["speed_vs_siblings"]),
            speed_vs_siblings_after_step=tuple(
                float(values.get(key, math.nan)) for key in AGAINST_AFTER_STEP_KEYS
            )
            if any(key in values for key in AGAINST_AFTER_STEP_KEYS)
            else (),
        )


def _bins_row(widening: tuple[float, ...]) -> NDArray[np.float64]:
    """A widening per bin of the wait after a step as one row of :data:`AFTER_STEP_BINS` (NaN: not
    measured, or not one number per bin)."""
    if len(widening) != AFTER_STEP_BINS:
        return np.full((1, AFTER_STEP_BINS), np.nan)
    return np.asarray(widening, dtype=float).reshape(1, AFTER_STEP_BINS)


def _conditions(
    activity_v: ArrayLike, pairing_error_rad_s: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The input activity and the pairing error (None: not given) as σ(a, e) reads them (NaN as 0)."""
    a = nan_to_zero(np.asarray(activity_v, dtype=float))
    if pairing_error_rad_s is None:
        return a, None
    return a, nan_to_zero(np.asarray(pairing_error_rad_s, dtype=float))


def _grown(
    sigma: Any,
    per_activity: Any,
    per_pairing: Any,
    a: NDArray[np.float64],
    e: NDArray[np.float64] | None,
) -> NDArray[np.float64]:
    """σ(a, e) = √(σ₀² + (c·a)² + (p·e)²); the pairing's term only where ``e`` is given and p > 0.

    As written, one square root of the sum (not ``np.hypot``, which guards against overflow these
    physical values never come near and took about seven times as long: the noise bands' largest share of
    a whole-log diagnosis, issue 18); within a rounding of ``np.hypot``'s."""
    grown = per_activity * a
    square = sigma * sigma + grown * grown
    if e is not None:
        paired = per_pairing * e
        square = np.where(np.asarray(per_pairing) > 0, square + paired * paired, square)
    return np.sqrt(square)


def _equation_of(values: Mapping[str, float], keys: tuple[str, ...]) -> EquationNoise | None:
    """One equation's noise from a ``[noise.N]`` table (its σ key first); None where it has none."""
    if keys[0] not in values or not math.isfinite(float(values[keys[0]])):
        return None
    sigma, per_activity, per_pairing, offset = (float(values.get(key, 0.0)) for key in keys[:4])
    through_duty = len(keys) > 4 and float(values.get(keys[4], 0.0)) > 0
    return EquationNoise(sigma, per_activity, per_pairing, offset, through_duty)


def _tail_sigma(deviation: NDArray[np.float64]) -> float:
    return float(np.quantile(np.abs(deviation), TAIL_SHARE) / TAIL_SIGMAS)


def _with_offset(sigma: float, offset: float) -> float:
    """The quiet σ with the motor's offset added (in quadrature): how far the model is off for this motor
    is known at the identification flight's operating points only, and elsewhere it may be off by as much
    in another direction (module doc)."""
    return math.hypot(sigma, offset)


def _bins(x: NDArray[np.float64], shares: NDArray[np.float64]) -> list[NDArray[np.bool_]]:
    """The samples cut at these quantiles of ``x``: each bin's mask (bins with too few samples left out)."""
    edges = np.quantile(x, shares)
    count = shares.size - 1
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, count - 1)
    bins = [which == b for b in range(count)]
    return [sel for sel in bins if np.count_nonzero(sel) >= MIN_BIN_SAMPLES or count == 1]


def _fit_growth(
    activity: NDArray[np.float64], deviation: NDArray[np.float64], pairing: NDArray[np.float64] | None = None
) -> tuple[float, float, float]:
    """σ₀, c and p of σ(a, e) = √(σ₀² + (c·a)² + (p·e)²) from the tail of |deviation| in bins of the
    activity ``a`` and (where given) of the pairing error ``e``: each bin's tail σ explained by its median
    ``a`` and ``e`` (one non-negative least-squares fit over both sets of bins)."""
    count = max(1, min(MAX_BINS, activity.size // MIN_BIN_SAMPLES))
    bins = _bins(activity, np.linspace(0.0, 1.0, count + 1))
    e_all = np.zeros(activity.size) if pairing is None else pairing
    paired = bool(np.ptp(e_all) > 0) if e_all.size else False
    if paired:
        # the pairing error's tail matters most: finer bins towards its loosest samples
        shares = [q for q in PAIRING_BIN_SHARES if (1.0 - q) * e_all.size >= MIN_BIN_SAMPLES]
        bins += _bins(e_all, np.array([*shares, 1.0]))
    a = np.array([np.median(activity[sel]) for sel in bins])
    e = np.array([np.median(e_all[sel]) for sel in bins])
    s = np.array([_tail_sigma(deviation[sel]) for sel in bins])
    if a.size < 2 or (np.ptp(a) <= 0 and np.ptp(e) <= 0):
        return _tail_sigma(deviation), 0.0, 0.0
    design = np.column_stack([np.ones_like(a), a**2] + ([e**2] if paired else []))
    fit = fit_linear(design, s**2, ("quiet", "activity", "pairing")[: design.shape[1]])  # variances ≥ 0
    coefficients = fit.x
    s0 = math.sqrt(coefficients[0])
    if not s0 > 0:  # all of it grows with the activity: keep a floor at the quietest bin's
        s0 = float(np.min(s))
    return s0, math.sqrt(coefficients[1]), math.sqrt(coefficients[2]) if paired else 0.0


@dataclass(frozen=True)
class _Flights:
    """Diagnosed flights' columns laid end to end, as the noise is measured over them."""

    tables: Sequence[TelemetryTable]

    def column(self, name: str, dtype: type = float) -> NDArray:
        if not self.tables:
            return np.zeros(0)
        return np.concatenate([np.asarray(d[name], dtype=dtype) for d in self.tables])

    def commanded(self, min_command: float) -> NDArray[np.bool_]:
        """Where the command is at least ``min_command`` (everywhere where a flight has no command)."""
        usable = np.ones(self.column("steady", bool).shape, dtype=bool)
        if min_command > 0 and all("throttle" in d.names for d in self.tables):
            usable &= self.column("throttle") >= min_command
        return usable

    def activity(self) -> NDArray[np.float64]:
        """The input activity [V], 0 where not measured."""
        return np.nan_to_num(self.column("input_activity_v"))

    def pairing(self) -> NDArray[np.float64] | None:
        """The pairing error of logs that pair commands loosely [rad/s] (None: a source that pairs
        exactly)."""
        if not all("pairing_error_rad_s" in d.names for d in self.tables):
            return None
        return np.nan_to_num(self.column("pairing_error_rad_s"))


def measure_band_noise(
    diagnosed: TelemetryTable | Sequence[TelemetryTable],
    min_command: float = 0.0,
    settle_s: float = 0.0,
    input_current: bool = False,
) -> dict[int, BandNoise]:
    """Each motor's band noise from diagnosed healthy flights (:func:`~.pipeline.diagnose` output of the
    flight rule): its judged samples (steady, commanded above ``min_command``, no sensor issue) and their
    deviations from the model. Motors with fewer than :data:`MIN_MOTOR_SAMPLES` judged samples take the
    vehicle's (all motors pooled); none at all if the vehicle has fewer. With the rule's ``settle_s`` (> 0)
    and its ``since_step_s`` column, also how much wider the deviations are while it waits after a step
    (:attr:`BandNoise.after_step`). ``input_current``: the ESC reports its input current, so the torque
    balance is read through the duty and marked so (not judged: rules/equations.py, "An input current's
    ripple")."""
    tables = [diagnosed] if isinstance(diagnosed, TelemetryTable) else list(diagnosed)
    flights = _Flights(tables)
    column = flights.column
    steady = column("steady", bool)
    usable = flights.commanded(min_command)  # commanded above idle, a deviation to measure
    dw = column("omega_judged_rad_s") - column("omega_model_rad_s")
    di = column("current_judged_a") - column("current_model_a")
    current = column("current_a")
    omega_model = column("omega_model_rad_s")
    activity = flights.activity()
    pairing = flights.pairing()
    usable &= np.isfinite(dw)
    judged = steady & usable
    # the two balances apart (module doc, "Each equation's own noise"; none: a rule without them)
    equations = {
        name: column(key)
        for name, key in (("torque", "torque_residual_nm"), ("voltage", "voltage_residual_v"))
        if all(key in d.names for d in tables)
    }
    # the torque against the median of the other motors' (.siblings), where the vehicle stage gave one
    if "torque" in equations and all("torque_siblings_nm" in d.names for d in tables):
        equations["torque_vs_siblings"] = equations["torque"] - column("torque_siblings_nm")
    current_flags_ok = (column("sensor_flags", np.int64) & CURRENT_UNTRUSTED) == 0
    current_ok = judged & np.isfinite(di) & current_flags_ok
    motors = column("motor", np.int64)
    # the slow look's longer averages, where the rule had one and it could be judged (module doc, "The
    # slow look's own noise"): measured on the samples it reads, around each motor's own median
    slow_columns = ("omega_slow_judged_rad_s", "current_slow_judged_a", "slow_ready")
    slow: dict[str, NDArray[np.float64]] = {}
    slow_ready = np.zeros(steady.shape, dtype=bool)
    if all(name in d.names for d in tables for name in slow_columns):
        slow_ready = column("slow_ready", bool)
        slow["slow_speed"] = column("omega_slow_judged_rad_s") - omega_model
        slow["slow_current"] = column("current_slow_judged_a") - column("current_model_a")
        for name, key in (("slow_torque", "torque_slow_nm"), ("slow_voltage", "voltage_slow_v")):
            if all(key in d.names for d in tables):
                slow[name] = column(key)

    def noise_of(speed_rows: NDArray[np.bool_], current_rows: NDArray[np.bool_]) -> BandNoise:
        e_speed = None if pairing is None else pairing[speed_rows]
        s0, sc, sp, w0 = _spread(dw, speed_rows, activity, pairing)
        c0, cc, cp, typical, i0 = math.nan, 0.0, 0.0, math.nan, 0.0
        if np.count_nonzero(current_rows) >= MIN_MOTOR_SAMPLES:
            c0, cc, cp, i0 = _spread(di, current_rows, activity, pairing)
            typical = float(np.nanmedian(current[current_rows]))
        own_equations = {
            name: _equation_noise(values, current_rows, activity, pairing)
            for name, values in equations.items()
        }
        for name, values in slow.items():
            rows = (speed_rows if name == "slow_speed" else current_rows) & slow_ready
            own_equations[name] = _equation_noise(values, rows, activity, pairing)
        torque = own_equations.get("torque")
        if input_current and torque is not None:
            own_equations["torque"] = replace(torque, through_duty=True)
        low, high = np.nanquantile(omega_model[speed_rows], RANGE_SHARES)
        busiest = float(np.quantile(activity[speed_rows], CONDITION_SHARE))
        paired = e_speed is not None and bool(np.any(e_speed > 0))  # else the log paired exactly
        loosest = float(np.quantile(e_speed, CONDITION_SHARE)) if paired and e_speed is not None else math.nan
        return BandNoise(
            s0,
            c0,
            sc,
            cc,
            int(np.count_nonzero(speed_rows)),
            typical,
            float(low),
            float(high),
            w0,
            i0,
            busiest,
            sp,
            cp,
            loosest,
            torque=own_equations.get("torque"),
            voltage=own_equations.get("voltage"),
            torque_vs_siblings=own_equations.get("torque_vs_siblings"),
            slow_speed=own_equations.get("slow_speed"),
            slow_current=own_equations.get("slow_current"),
            slow_torque=own_equations.get("slow_torque"),
            slow_voltage=own_equations.get("slow_voltage"),
        )

    if np.count_nonzero(judged) < MIN_MOTOR_SAMPLES:
        return {}
    pooled = noise_of(judged, current_ok)
    out = {}
    for motor in np.unique(motors):
        own = motors == motor
        if np.count_nonzero(judged & own) >= MIN_MOTOR_SAMPLES:
            out[int(motor)] = noise_of(judged & own, current_ok & own)
        else:
            out[int(motor)] = pooled
    if settle_s > 0 and all("since_step_s" in d.names for d in tables):
        since = column("since_step_s")
        waiting = usable & ~steady & np.isfinite(since) & (since < settle_s)
        after = _after_step(
            out,
            motors,
            dw,
            di,
            activity,
            pairing,
            judged,
            current_ok,
            waiting,
            current_flags_ok,
            since,
            settle_s,
        )
        if any(math.isfinite(r) for r in after):  # no bin measured: as not measured at all
            out = {m: replace(n, after_step=after) for m, n in out.items()}
    return out


def measure_speed_vs_siblings(
    diagnosed: Sequence[TelemetryTable], min_command: float = 0.0, settle_s: float = 0.0
) -> tuple[dict[int, EquationNoise], tuple[float, ...]]:
    """Each motor's noise of its speed deviation less its siblings' linear prediction
    (``speed_siblings_rad_s``, :mod:`.prediction`) on diagnosed healthy flights (noise unbounded), on the
    judged samples that have one, measured as each balance's (:func:`_equation_noise`; motors with too
    few: none); and with the rule's ``settle_s`` (> 0), how much wider it is while the rule waits after a
    step, per bin of the wait, as :attr:`BandNoise.after_step` is measured (empty: not measured). In a
    manoeuvre the prediction from the siblings' latest values lags more than each motor's own deviation
    does: on held-out world 1005 the difference's tail after a step was several times its settled one."""
    out: dict[int, EquationNoise] = {}
    tables = [d for d in diagnosed if "speed_siblings_rad_s" in d.names]
    if not tables:
        return out, ()

    flights = _Flights(tables)
    column = flights.column
    steady = column("steady", bool)
    usable = flights.commanded(min_command)
    against = column("omega_judged_rad_s") - column("omega_model_rad_s") - column("speed_siblings_rad_s")
    usable &= np.isfinite(against)
    activity = flights.activity()
    pairing = flights.pairing()
    motors = column("motor", np.int64)
    for motor in np.unique(motors):
        found = _equation_noise(against, steady & usable & (motors == motor), activity, pairing)
        if found is not None:
            out[int(motor)] = found

    def in_sigma() -> NDArray[np.float64]:
        z = np.full(against.shape, np.nan)
        for motor, n in out.items():
            own = motors == motor
            sigma = n.sigmas(activity[own], None if pairing is None else pairing[own])
            z[own] = (against[own] - n.offset) / sigma
        return z

    # A prediction from strongly correlated siblings has heavier tails than a Gaussian of the same 99 %
    # tail: σ is widened until the thousandth tail too lies where a Gaussian's does (the motors pooled)
    z = in_sigma()
    settled = steady & usable & np.isfinite(z)
    if np.count_nonzero(settled) >= DEEP_TAIL_SAMPLES:
        widen = max(1.0, float(np.quantile(np.abs(z[settled]), DEEP_TAIL_SHARE)) / DEEP_TAIL_SIGMAS)
        if widen > 1.0:
            out = {
                m: replace(
                    n,
                    sigma=widen * n.sigma,
                    per_activity=widen * n.per_activity,
                    per_pairing=widen * n.per_pairing,
                )
                for m, n in out.items()
            }
            z = in_sigma()
    if not (settle_s > 0 and out and all("since_step_s" in d.names for d in tables)):
        return out, ()
    since = column("since_step_s")
    waiting = usable & ~steady & np.isfinite(since) & (since < settle_s) & np.isfinite(z)
    if np.count_nonzero(settled) < MIN_AFTER_STEP_SAMPLES:
        return out, ()
    reference = _tail_sigma(z[settled])
    ratios = [
        max(1.0, float(t / reference)) if math.isfinite(t) else math.nan
        for t in _tails_after_step(z, waiting, since, settle_s)
    ]
    return out, tuple(ratios) if any(math.isfinite(r) for r in ratios) else ()


def _equation_noise(
    residual: NDArray[np.float64],
    rows: NDArray[np.bool_],
    activity: NDArray[np.float64],
    pairing: NDArray[np.float64] | None,
) -> EquationNoise | None:
    """One balance's noise on these judged samples (those where it is known): σ(a, e) around its median,
    the median added to the quiet σ in quadrature as for the deviations; None: too few samples."""
    rows = rows & np.isfinite(residual)
    if np.count_nonzero(rows) < MIN_MOTOR_SAMPLES:
        return None
    return EquationNoise(*_spread(residual, rows, activity, pairing))


def _spread(
    values: NDArray[np.float64],
    rows: NDArray[np.bool_],
    activity: NDArray[np.float64],
    pairing: NDArray[np.float64] | None,
) -> tuple[float, float, float, float]:
    """σ₀, c and p of σ(a, e) (:func:`_fit_growth`) of ``values`` on ``rows`` around their median, the
    median (the motor's offset) added to σ₀ in quadrature (:func:`_with_offset`), and the median."""
    offset = float(np.median(values[rows]))
    s0, sc, sp = _fit_growth(
        activity[rows], values[rows] - offset, None if pairing is None else pairing[rows]
    )
    return _with_offset(s0, offset), sc, sp, offset


def _after_step(
    noise: Mapping[int, BandNoise],
    motors: NDArray[np.int64],
    dw: NDArray[np.float64],
    di: NDArray[np.float64],
    activity: NDArray[np.float64],
    pairing: NDArray[np.float64] | None,
    settled: NDArray[np.bool_],
    settled_current: NDArray[np.bool_],
    waiting: NDArray[np.bool_],
    current_flags_ok: NDArray[np.bool_],
    since: NDArray[np.float64],
    settle_s: float,
) -> tuple[float, ...]:
    """Per bin of the wait after a step, how many times wider the deviations' tail is than settled, in
    units of each motor's σ(a, e) around its offset, speed or current whichever widened more (≥ 1; NaN:
    fewer than :data:`MIN_AFTER_STEP_SAMPLES` samples, all motors pooled)."""
    z_speed, z_current = np.full(dw.shape, np.nan), np.full(dw.shape, np.nan)
    for motor, n in noise.items():
        own = motors == motor
        speed, current = n.sigmas(activity[own], None if pairing is None else pairing[own])
        z_speed[own] = (dw[own] - n.speed_offset_rad_s) / speed
        z_current[own] = (di[own] - n.current_offset_a) / current
    current_waiting = waiting & current_flags_ok & np.isfinite(z_current)
    reference = (
        _tail_sigma(z_speed[settled]),
        _tail_sigma(z_current[settled_current]) if settled_current.any() else math.nan,
    )
    speed_tails = _tails_after_step(z_speed, waiting, since, settle_s)
    current_tails = _tails_after_step(z_current, current_waiting, since, settle_s)
    ratios = []
    for speed_tail, current_tail in zip(speed_tails, current_tails):
        if not math.isfinite(speed_tail):
            ratios.append(math.nan)
            continue
        widening = speed_tail / reference[0]
        if math.isfinite(current_tail) and reference[1] > 0:
            widening = max(widening, current_tail / reference[1])
        ratios.append(max(1.0, float(widening)))
    return tuple(ratios)


def _tails_after_step(
    z: NDArray[np.float64], waiting: NDArray[np.bool_], since: NDArray[np.float64], settle_s: float
) -> list[float]:
    """The tail σ of ``z`` on the ``waiting`` samples in each of :data:`AFTER_STEP_BINS` bins of the wait
    (the time since the step over ``settle_s``); NaN for a bin of fewer than
    :data:`MIN_AFTER_STEP_SAMPLES`."""
    bins = np.clip((np.nan_to_num(since) / settle_s * AFTER_STEP_BINS).astype(int), 0, AFTER_STEP_BINS - 1)
    tails = []
    for b in range(AFTER_STEP_BINS):
        in_bin = waiting & (bins == b)
        enough = np.count_nonzero(in_bin) >= MIN_AFTER_STEP_SAMPLES
        tails.append(float(_tail_sigma(z[in_bin])) if enough else math.nan)
    return tails


def band_noise_of(noise: Mapping[int, Mapping[str, float]]) -> dict[int, BandNoise]:
    """The band noise of each motor of a vehicle file's ``[noise.N]`` tables (those that have it)."""
    found = {int(m): BandNoise.from_mapping(values) for m, values in noise.items()}
    return {m: n for m, n in found.items() if n is not None}


def require_noise(
    noise: Mapping[int, BandNoise | None] | None, motors: Sequence[int], profile_name: str
) -> dict[int, BandNoise]:
    """The band noise of every motor in ``motors``; a clear error naming the first motor without it."""
    found = dict(noise or {})
    for motor in motors:
        if found.get(motor) is None:
            raise ConfigError(
                f"profile {profile_name!r} sets its bands in units of the vehicle's noise, and the "
                f"vehicle's params give none for motor {motor}",
                key=f"noise.{motor}.speed_rad_s",
                expected="a vehicle file written by `mav-motor-health fit FLIGHT_LOG --out vehicle.toml` "
                "(it measures the noise), or a profile with absolute bands (--profile flight)",
            )
    return {m: found[m] for m in motors}  # type: ignore[misc]
