"""Sequential change detection with a designed false-alarm rate (issue 17, item 2).

A hold ("announce F1.1 after it has lasted 0.45 s") is a number tuned in one world: how long a healthy
motor's deviation may stay outside a band depends on the vehicle, the air and the telemetry. Here the
decision is a CUSUM test per fault direction on the deviations measured in units of the motor's own
noise (:mod:`.noise`), and its threshold follows from the false-alarm rate the user asks for.

**Evidence.** The judged deviations of speed and current (:mod:`..model.balance`), divided by the motor's
σ at the sample's input activity, are ``z_ω`` and ``z_i``. Each fault moves them its own way, as the
paper's tree reads them: F1.1 (friction) more current with the speed not above the model; F4.1 (open
transistor) slower or less current, neither above; F3.1 (lighter propeller) faster with less current;
UNKNOWN faster with the current not below. Without a trusted current, SLOW and FAST are the speed alone.
The evidence for a direction is how far the sample lies that way, in σ (0 where it lies another way).

**Each fault in its own balance.** With the profile's ``equation_bands``, F1.1 and F3.1 take their
evidence from the torque balance instead where it is judged (:mod:`.rules.equations`): the torque's
departure from the motor's offset in σ of its own noise, above the offset for F1.1, below for F3.1
(:func:`equation_evidence`). Each is then one half-normal under no fault, which the threshold's
two-half-normal model covers with room to spare.

**Test.** For each direction, ``S ← max(0, S + (y − k)·Δt/τ_obs)``: ``y`` the evidence, ``k`` the
reference (``reference_sigmas``: departures below it are not evidence), ``τ_obs = 2·τ`` with ``τ`` the
deviations' low-pass time constant at the sample (a low-passed signal gives one independent observation
per 2τ, so S counts observations, not samples). ``Δt`` is the time the sample stands for: each report
of the motor's stream counts its stream's mean interval (:func:`report_credit`). A lost report's time is
spread over the next eight instead of counted whole for the one after it (a departure seen once after a
lost report was observed once, not twice), reports that arrive in bursts each count the stream's
interval, not the burst's, and a sample that is not judged counts for nothing: its time is not lent to
the judged sample after it. Samples go unjudged where the model cannot be trusted (a step, a busier
input or a looser pairing than identification saw), and the first judged sample after such a stretch
still holds it in its low-pass; counted for the whole stretch, one such sample after a sharp command
dip between two ESC reports was a third of an observation's evidence or more on its own (on the
held-out worlds, two of the eight false events in ten healthy hours, docs/flight.md). The direction is
announced when S reaches ``h`` and stays announced until S has fallen back to 0.

**Threshold.** Under no fault ``z_ω`` and ``z_i`` are taken as independent standard normal (σ is measured
on the tail of the healthy flight, which makes that hold where it matters), so each direction's evidence
is at most the larger of two half-normals: ``P(y ≤ x) = Φ(x)²``. Brook and Evans' Markov chain gives the
average number of observations to a false alarm, ``ARL₀(h)``; ``h`` is the smallest with

    directions × motors × (3600 / τ_obs) / ARL₀(h)  ≤  false alarms per hour asked for

(:func:`design_threshold`; 4 directions, 8 motors, τ_obs of the shortest low-pass: conservative for a
hexacopter, and in gusts, where the low-pass lengthens, there are fewer observations per hour). The
time to detect a departure of δ σ is then about ``h/(δ − k)`` observations: a deep fault is announced in
a fraction of τ, a shallow one after seconds. The rate is a design figure under that noise model; what a
vehicle really gives is measured by ``benchmarks/bench_flight_worlds.py``.

**Named by the tree.** The paper's tree (and the rules after it: the torque balance, the judged range)
names each sample's direction; the test only says when it has lasted. A direction gains on the samples
named that way, and on any other its evidence counts at most the reference ``k``
(:func:`named_evidence`, applied by the rule): no gain there, and no more loss than the sample's own
departure gives. Without it, a healthy motor whose model is off by 3 σ where the identification flight
never took it (a motor taking over a failed one's share, a motor 8 % below its identified speeds) read
NORMAL on every sample and was still announced after a few seconds, as the sum of many sub-band
departures just above ``k``. Under no fault the sums can only be lower than without it, so the designed
rate still bounds the false alarms; a fault departs beyond the bands (4.5 σ) and is named, so its sum
grows as before, at about half the pace where its samples straddle the band.

**Outliers.** The threshold is designed under Gaussian noise, where a sample 10 σ off never happens;
telemetry has heavier tails (a command that dipped between two logged commands, at a manoeuvre's start,
leaves one or two samples that far off). With ``min_observations`` m > 0 each sample's evidence for a
*lasting* direction (:data:`CAPPED_DIRECTIONS`: F1.1, F4.1, SLOW, UNKNOWN) counts at most ``k + h/m``: an
alarm there needs at least m independent observations' worth of evidence (m·2τ of time at any telemetry
rate), and a lone outlier, at 10 Hz a third of an observation, adds at most a third of h/m. Those are
the faults that leave the motor turning inside the judged range (more friction, less torque: it settles
at a new speed and keeps giving evidence), so a deep one is still named, after m observations rather
than in a few samples; and UNKNOWN, faster with the current not below, which none of the five faults
gives but a command the log did not show does (at a translation's braking, a healthy motor driven 90
rad/s above the logged command's model for a tenth of a second, between two commands logged at 10 Hz:
docs/flight.md, "UNKNOWN waits for one observation"). The other directions are not capped: a lost
propeller's motor (F3.1, or FAST without a current) runs away and leaves the judged range within one
observation, and a cap there let only a later rule name it, seconds later (docs/flight.md, "A cap on
each sample's evidence, measured").
Below the cap nothing changes, and the design's false-alarm rate under its own noise model can only
fall.

**The slow look's evidence.** Where the slow look (the deviations, or the torque, averaged ``slow_factor``
times longer, against their own measured noise: :mod:`.rules.tree`, :mod:`.rules.equations`) named a
sample, its direction also gains from the slow departure ``y_s`` (in σ of the bands, as the fast one
counts): the larger of the fast gain and ``(y_s − k)/slow_factor``, since an average ``slow_factor``
times longer gives that many times fewer independent observations in the same time
(:func:`with_slow_evidence`). A small lasting fault whose every fast departure lies below ``k`` is then
announced, at the pace its slow departure allows; under no fault the slow look names a sample as rarely
as the fast one does (its bands are its own noise's), and the capped directions' cap still holds.

**Once announced.** The tree reads each sample against bands of ``noise_bands`` σ, so that a healthy motor
reads NORMAL on all but a few samples in a million; a fault that departs by about as much (an open
transistor in busier air than identification's, 4 to 5 σ) reads NORMAL on half its samples, and the
announcement, which the test holds until its sum has fallen back to 0, says otherwise. With the rule's
``hold_sigmas`` (the profile sets it to the reference k), while a direction is announced on a motor, a
judged sample the tree read NORMAL that departs that way by at least that many σ reads as the fault: the
two thresholds of a hysteresis, the band to enter, k to stay. Nothing the test reads changes (it has
run when the samples are read again): the announcements, their delay and the false alarms are the same
with it and without; a healthy motor's samples read a fault only while a false alarm stands.

Stalls, sensor faults and NO_DATA keep :mod:`.persistence` (a motor below the stop speed is a physical
fact, not a statistical one) and take precedence over the directions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr

from .._arrays import nan_to_zero
from ..errors import ConfigError
from ..model.dynamics import marked_before
from .states import Code, MotorState

__all__ = [
    "CAPPED_DIRECTIONS",
    "DIRECTIONS",
    "SequentialCarry",
    "SequentialRule",
    "average_run_length",
    "design_threshold",
    "direction_evidence",
    "equation_evidence",
    "evidence_toward",
    "held_states",
    "named_evidence",
    "report_credit",
    "report_credits",
    "sequential_alarms",
    "sequential_alarms_rows",
    "torque_agrees_with_speed",
    "with_slow_evidence",
]

#: the directions tested, in the order of the evidence rows (:func:`direction_evidence`)
DIRECTIONS = (
    MotorState.F1_1,
    MotorState.F4_1,
    MotorState.F3_1,
    MotorState.UNKNOWN,
    MotorState.SLOW,
    MotorState.FAST,
)
#: directions whose fault leaves the motor turning inside the judged range (it settles at a new speed
#: and keeps giving evidence), and UNKNOWN (no fault's, a command the log missed gives it): the ones
#: ``min_observations`` caps (module doc, "Outliers")
CAPPED_DIRECTIONS = (MotorState.F1_1, MotorState.F4_1, MotorState.SLOW, MotorState.UNKNOWN)
#: directions open at once to a motor with a trusted current (F1.1, F4.1, F3.1, UNKNOWN), or without
DIRECTIONS_AT_ONCE = 4
#: motors the designed rate covers (an octocopter; fewer motors: fewer false alarms)
DESIGN_MOTORS = 8
#: S counts as at h within this share of it: capped evidence (``min_observations``) lands exactly on h
#: after m observations, and the rounding of the sums, which depends on how the samples were split into
#: calls (replay: one; the agent: many), must not decide whether that is an alarm
_H_ROUNDING = 1e-9
#: cells of the Markov chain that approximates the CUSUM (Brook and Evans)
_CELLS = 240


@dataclass(frozen=True)
class SequentialRule:
    """The sequential test of a profile (``[detection]`` in TOML); ``false_alarms_per_100h`` 0: off.

    ``false_alarms_per_100h``: false fault announcements per 100 flight hours of the whole vehicle that
    the threshold is designed for (default 1, the issue's goal). ``reference_sigmas``: the reference k
    of the CUSUM in σ (a departure must exceed it to count). The observations per hour of the design
    come from the profile's shortest low-pass (``steady.residual_tau_s``), given to :meth:`threshold`.
    """

    false_alarms_per_100h: float = 0.0
    reference_sigmas: float = 2.0
    #: an alarm needs at least this many independent observations' worth of evidence (0: no such floor):
    #: each sample's evidence is capped at ``k + h / min_observations``, so no single sample, however far
    #: off, is an alarm on its own (module doc, "Outliers")
    min_observations: float = 0.0
    #: while a direction is announced, a judged sample the tree read NORMAL that departs that way by at
    #: least this many σ reads as that fault (0: never; module doc, "Once announced")
    hold_sigmas: float = 0.0

    def __post_init__(self) -> None:
        if not (self.false_alarms_per_100h == 0 or 1e-6 <= self.false_alarms_per_100h <= 1e6):
            raise ConfigError(
                f"{self.false_alarms_per_100h!r}",
                key="detection.false_alarms_per_100h",
                expected="a rate between 1e-6 and 1e6 false alarms per 100 flight hours, or 0 (off)",
            )
        if not 0 < self.reference_sigmas <= 10:
            raise ConfigError(
                f"{self.reference_sigmas!r}", key="detection.reference_sigmas", expected="0 < k <= 10 (sigma)"
            )
        if not 0 <= self.min_observations <= 100:
            raise ConfigError(
                f"{self.min_observations!r}",
                key="detection.min_observations",
                expected="0 (no floor) to 100 independent observations",
            )
        if not 0 <= self.hold_sigmas <= 10:
            raise ConfigError(
                f"{self.hold_sigmas!r}", key="detection.hold_sigmas", expected="0 (never) to 10 (sigma)"
            )

    @property
    def on(self) -> bool:
        return self.false_alarms_per_100h > 0

    def evidence_cap(self, h: float) -> float:
        """The most one sample's evidence for a lasting direction counts [σ] under the threshold ``h``
        (inf: no cap)."""
        return self.reference_sigmas + h / self.min_observations if self.min_observations > 0 else math.inf

    def evidence_caps(self, h: float) -> NDArray[np.float64]:
        """The cap of each of :data:`DIRECTIONS` (:meth:`evidence_cap` for :data:`CAPPED_DIRECTIONS`,
        inf for the others), shaped to broadcast over samples."""
        cap = self.evidence_cap(h)
        return np.array([cap if d in CAPPED_DIRECTIONS else math.inf for d in DIRECTIONS])[:, None]

    def threshold(self, tau_s: float) -> float:
        """The CUSUM threshold h [σ·observations] this rule's rate asks for, the deviations low-passed
        with at least ``tau_s`` (one independent observation per 2τ)."""
        return design_threshold(self.false_alarms_per_100h / 100.0, self.reference_sigmas, 2.0 * tau_s)


#: each report counts the mean of this many intervals of its stream before it (:func:`report_credit`)
CREDIT_INTERVALS = 8


@dataclass(frozen=True)
class SequentialCarry:
    """Each direction's CUSUM, whether it is announced, and the last judged sample's time; the motor's
    report stream: its last report's time and its last intervals (:func:`report_credit`)."""

    sums: tuple[float, ...] = (0.0,) * len(DIRECTIONS)
    alarmed: tuple[bool, ...] = (False,) * len(DIRECTIONS)
    last_s: float = -math.inf
    stream_s: float = -math.inf
    intervals: tuple[float, ...] = (math.inf,) * CREDIT_INTERVALS


def _direction_codes(ndim: int) -> NDArray[np.int64]:
    """The codes of :data:`DIRECTIONS`, shaped to compare with states of ``ndim`` dimensions."""
    return np.array([int(d) for d in DIRECTIONS]).reshape((-1,) + (1,) * ndim)


def _is_direction(states: NDArray[np.integer]) -> NDArray[np.bool_]:
    """Whether each sample's state is each of :data:`DIRECTIONS` (directions first)."""
    return np.asarray(np.asarray(states)[None] == _direction_codes(np.ndim(states)))


def evidence_toward(evidence: NDArray[np.float64], states: NDArray[np.integer]) -> NDArray[np.float64]:
    """Each sample's evidence (directions first) in the direction of its state in ``states`` (a named
    state, or an announced one); 0 where that is not one of :data:`DIRECTIONS`."""
    return np.asarray(np.max(np.where(_is_direction(states), evidence, 0.0), axis=0))


def named_evidence(
    evidence: NDArray[np.float64], state: NDArray[np.integer], reference_sigmas: float
) -> NDArray[np.float64]:
    """Each direction's evidence (directions first, then the samples' shape) where the sample's state is
    that direction's (the tree named it), and at most ``reference_sigmas`` elsewhere (module doc,
    "Named by the tree"): no sample the tree calls something else adds to a direction's sum."""
    return np.where(_is_direction(state), evidence, np.minimum(evidence, reference_sigmas))


def with_slow_evidence(
    evidence: NDArray[np.float64],
    state: NDArray[np.integer],
    slow_evidence: NDArray[np.float64] | None,
    reference_sigmas: float,
    slow_factor: float,
) -> NDArray[np.float64]:
    """Each direction's evidence with the slow look's where it named the sample (module doc, "The slow
    look's evidence"): the larger of the fast look's and ``k + (y_slow − k)/slow_factor``, the slow
    departure's gain over the reference counted for the fewer independent observations a longer average
    gives in the same time."""
    if slow_evidence is None or not slow_factor > 0:
        return evidence
    lifted = reference_sigmas + (np.asarray(slow_evidence) - reference_sigmas) / slow_factor
    # NaN (not named by the slow look) leaves the fast evidence
    return np.where(_is_direction(state), np.fmax(evidence, lifted[None]), evidence)


def held_states(
    state: NDArray[np.integer],
    alarms: NDArray[np.integer],
    evidence: NDArray[np.float64],
    judged: NDArray[np.bool_],
    hold_sigmas: float,
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Where a judged sample the tree read NORMAL departs by at least ``hold_sigmas`` σ in the direction
    announced at it (``evidence``: each of :data:`DIRECTIONS`' first, as the test read it; module doc,
    "Once announced"): those samples read as the announced fault. Returns them, and each sample's
    departure in the announced direction [σ] (0 where none is announced)."""
    toward = evidence_toward(evidence, alarms)
    held = (toward >= hold_sigmas) & judged & (np.asarray(state) == Code.NORMAL)
    return held, toward


def report_credit(
    time_s: NDArray[np.float64], carry: SequentialCarry, max_gap_s: float
) -> tuple[NDArray[np.float64], tuple[float, ...]]:
    """The time each report of a motor's stream stands for [s], and the stream's last intervals to carry.

    A report stands for the mean of the :data:`CREDIT_INTERVALS` intervals of the stream before it (the
    carried ones first), those longer than ``max_gap_s`` left out (a pause in the telemetry, after which
    the sums start afresh anyway); with none yet, its own interval if not longer than that, else 0.
    Summed over a stretch of reports, that is the stretch's time when no report was lost; a lost report's
    time is spread thinly over the next reports instead of counting once more for the one after it, and
    reports that arrive in bursts (two per radio packet) each count the stream's interval.
    (:func:`report_credits` for rows of motors.)"""
    time_s = np.asarray(time_s, dtype=float)
    credit, intervals = report_credits(time_s[None], [time_s.size], [carry], max_gap_s)
    return credit[0], intervals[0]


def report_credits(
    time_s: NDArray[np.float64], counts: Sequence[int], carries: Sequence[SequentialCarry], max_gap_s: float
) -> tuple[NDArray[np.float64], list[tuple[float, ...]]]:
    """:func:`report_credit` of rows of motors at once: ``time_s`` one row per motor, each row's first
    ``counts`` samples its own (the credit of the rest is not defined); each row's intervals to carry."""
    rows, n = time_s.shape
    k = CREDIT_INTERVALS
    stream = np.array([c.stream_s for c in carries], dtype=float)
    d = np.diff(time_s, axis=1, prepend=stream[:, None])
    history = np.concatenate(
        [np.array([c.intervals for c in carries], dtype=float).reshape(rows, k), d], axis=1
    )
    valid = history <= max_gap_s
    total = np.concatenate([np.zeros((rows, 1)), np.cumsum(np.where(valid, history, 0.0), axis=1)], axis=1)
    count = np.concatenate([np.zeros((rows, 1), dtype=np.intp), np.cumsum(valid, axis=1)], axis=1)
    # the window of the k intervals before report j: history[j : j + k]
    window_s = total[:, k : k + n] - total[:, :n]
    window_n = count[:, k : k + n] - count[:, :n]
    own = np.where(d <= max_gap_s, d, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        credit = np.where(window_n > 0, window_s / np.maximum(window_n, 1), own)
    # each row's last k intervals: those of its own samples (its count), the carried ones before them
    ends = np.asarray(counts, dtype=np.intp)[:, None] + np.arange(k)[None, :]
    last = np.take_along_axis(history, ends, axis=1).tolist()
    return credit, [tuple(row) for row in last]


def _max_of_two_half_normals(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """P(y ≤ x) of the evidence under no fault: the larger of two independent standard normals, floored
    at 0 (the atom at 0 is P(both ≤ 0) = 1/4)."""
    return np.where(x < 0, 0.0, ndtr(x) ** 2)


def average_run_length(h: float, k: float, cells: int = _CELLS) -> float:
    """Observations to a false alarm of ``S ← max(0, S + y − k)``, alarm at ``S ≥ h``, started at 0, with
    y distributed as :func:`_max_of_two_half_normals` (Brook and Evans' Markov chain: ``cells`` states of
    S in [0, h), each at its cell's middle, state 0 the atom at S = 0)."""
    w = h / cells
    s = np.concatenate([[0.0], (np.arange(1, cells) + 0.5) * w])  # state 0: S = 0 exactly
    upper = np.arange(1, cells + 1) * w  # cell j holds S' in [j·w, (j+1)·w)
    # P(S' = 0) = P(y ≤ k − s); P(S' in cell j) = F(k − s + (j+1)w) − F(k − s + jw) for j ≥ 1
    cdf = _max_of_two_half_normals(k - s[:, None] + np.concatenate([[0.0], upper])[None, :])
    q = np.empty((cells, cells))
    q[:, 0] = _max_of_two_half_normals(k - s + w)  # to S' < w: the atom and the first cell's bottom
    q[:, 1:] = np.diff(cdf[:, 1:], axis=1)
    arl = np.linalg.solve(np.eye(cells) - q, np.ones(cells))
    return float(arl[0])


@lru_cache(maxsize=64)
def design_threshold(false_alarms_per_hour: float, k: float, observation_s: float) -> float:
    """The smallest h whose false-alarm rate, over :data:`DIRECTIONS_AT_ONCE` directions of
    :data:`DESIGN_MOTORS` motors observed every ``observation_s``, is at most ``false_alarms_per_hour``."""
    tests = DIRECTIONS_AT_ONCE * DESIGN_MOTORS
    needed = tests * (3600.0 / observation_s) / false_alarms_per_hour  # observations per false alarm
    low, high = 0.0, 1.0
    while average_run_length(high, k) < needed:
        low, high = high, 2.0 * high
        if high > 1e4:
            raise ValueError("no CUSUM threshold reaches that rate")
    for _ in range(50):
        mid = 0.5 * (low + high)
        if average_run_length(mid, k) < needed:
            low = mid
        else:
            high = mid
    return high


def direction_evidence(
    z_omega: NDArray[np.float64],
    z_current: NDArray[np.float64],
    current_trusted: NDArray[np.bool_],
    bands_sigmas: float,
    z_omega_alone: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Each sample's evidence for each of :data:`DIRECTIONS` (first axis), in σ, ≥ 0.

    ``z_omega``, ``z_current``: the deviations in σ; ``bands_sigmas``: the tree's band in σ (its "above
    the band" and "below the band" gate the directions as the tree does). Without a trusted current, only
    SLOW and FAST have evidence, from ``z_omega_alone`` (the speed deviation in units of the speed-only
    band's σ: without the current a model error cannot be told from a fault, and the tree asks for the
    wider band there too; None: ``z_omega``); with one, only the four others."""
    zw = nan_to_zero(z_omega)
    zi = np.where(current_trusted, nan_to_zero(z_current), 0.0)
    n = bands_sigmas
    not_high = zw <= n
    out = np.zeros((len(DIRECTIONS), *zw.shape))
    out[0] = np.where(not_high, np.maximum(zi, 0.0), 0.0)  # F1.1: more current, not faster
    out[1] = np.where(not_high & (zi <= n), np.maximum(np.maximum(-zw, -zi), 0.0), 0.0)  # F4.1
    out[2] = np.maximum(np.minimum(zw, -zi), 0.0)  # F3.1: faster with less current
    out[3] = np.where(zi >= -n, np.maximum(zw, 0.0), 0.0)  # UNKNOWN: faster, current not below
    out[:4] = np.where(current_trusted, out[:4], 0.0)
    alone = zw if z_omega_alone is None else nan_to_zero(z_omega_alone)
    out[4] = np.where(current_trusted, 0.0, np.maximum(-alone, 0.0))  # SLOW (speed only)
    out[5] = np.where(current_trusted, 0.0, np.maximum(alone, 0.0))  # FAST (speed only)
    return out


def equation_evidence(
    z_torque: NDArray[np.float64],
    current_trusted: NDArray[np.bool_],
    evidence: NDArray[np.float64],
    z_current: NDArray[np.float64] | None = None,
    bands_sigmas: float = math.inf,
    speed_deviation: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """The evidence of :func:`direction_evidence` with F1.1 and F3.1 read in the torque balance where it is
    judged (``z_torque`` finite: its departure from the motor's offset in σ of its own noise; module doc,
    "Each fault in its own balance"): F1.1 the torque above the offset, F3.1 below it. Elsewhere, and for
    every other direction, as ``evidence`` has it.

    A lighter propeller draws less current at its command, never more: where the sample's own current
    reads above its band (``z_current``, the reading's departure from the model in σ of the band, >
    ``bands_sigmas``: the tree's "above the band") the torque's shortfall is not evidence of F3.1. There
    it is a command the log did not show (a step up between two logged commands: the motor speeds up on
    more current than the logged command's model, and the balance, its current low-passed, reads the
    acceleration as load gone); F3.1, uncapped, was announced from such samples on a healthy motor
    (docs/flight.md, "The simulator's mixer mended").

    The paper's directions (``speed_deviation``, the judged speed less the model's; None: not read):
    friction turns the motor no faster than its model, a lighter propeller no slower, so F1.1's evidence
    is zeroed where the speed reads above the model and F3.1's where it reads below (as the slow look of
    the torque asks, :class:`.rules.equations.TorqueSlowLook`; :func:`torque_agrees_with_speed`)."""
    judged = current_trusted & np.isfinite(z_torque)
    zt = np.where(judged, z_torque, 0.0)
    out = evidence.copy()
    f11, f31 = DIRECTIONS.index(MotorState.F1_1), DIRECTIONS.index(MotorState.F3_1)
    friction = np.maximum(zt, 0.0)  # torque the model lacks: friction
    lighter = np.maximum(-zt, 0.0)  # load missing: a lighter propeller
    if z_current is not None:
        lighter = np.where(nan_to_zero(z_current) > bands_sigmas, 0.0, lighter)
    if speed_deviation is not None:
        friction = np.where(torque_agrees_with_speed(1.0, speed_deviation), friction, 0.0)
        lighter = np.where(torque_agrees_with_speed(-1.0, speed_deviation), lighter, 0.0)
    out[f11] = np.where(judged, friction, evidence[f11])
    out[f31] = np.where(judged, lighter, evidence[f31])
    return out


def torque_agrees_with_speed(z_torque: ArrayLike, speed_deviation: ArrayLike) -> NDArray[np.bool_]:
    """Whether a torque departure (its sign: above the model, friction; below, a lighter propeller)
    agrees with the speed's: friction turns the motor no faster than its model, a lighter propeller no
    slower (the paper's tree: F1.1 slower, F3.1 faster). A speed not read (NaN) agrees.

    Why the torque alone is not enough: after a motor's failure the others swing between idle and full
    command, and a healthy motor's torque balance then read a lighter propeller's shortfall while it
    turned at or below its model speed about as often as above (held-out worlds 1000 and 1012; docs/
    flight.md, "A torque fault the speed goes against"); under a lighter propeller the motor turned
    faster than its model on every F3.1 flight probed (held-out worlds 1000-1016, 39 flights: the 10th
    percentile of the faulty motor's samples named F3.1 lay 0.6 to 118 σ of the speed's noise above).
    No new number: the sign of the speed's departure."""
    zt = np.asarray(z_torque, dtype=float)
    dev = np.asarray(speed_deviation, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.where(zt > 0, ~(dev > 0), np.where(zt < 0, ~(dev < 0), True))


def sequential_alarms(
    rule: SequentialRule,
    time_s: NDArray[np.float64],
    evidence: NDArray[np.float64],
    observation_s: NDArray[np.float64],
    judged: NDArray[np.bool_],
    carry: SequentialCarry,
    max_gap_s: float,
    tau_s: float,
) -> tuple[NDArray[np.int8], NDArray[np.float64], SequentialCarry]:
    """One motor's CUSUMs over its samples: the announced direction at each (NORMAL where none), the
    largest statistic over h at each, and the new carry.

    ``evidence`` (directions × samples, :func:`direction_evidence`); ``observation_s`` the time of one
    independent observation at each sample (2τ); only ``judged`` samples add to the sums, and two judged
    samples more than ``max_gap_s`` apart start them afresh (the evidence before the gap is stale);
    ``tau_s`` the deviations' shortest low-pass, which the threshold is designed for. Each judged sample
    weighs its own report's time (:func:`report_credit`; an unjudged one's is not lent to it). The sums are exact Lindley
    recursions, evaluated in closed form (S_n = W_n − min(−S_0, min_j W_j) over each stretch without a
    gap), so any split of the samples into calls gives the same result (up to rounding, which the
    comparison with h allows for: :data:`_H_ROUNDING`). (:func:`sequential_alarms_rows` for rows of
    motors.)"""
    t = np.asarray(time_s, dtype=float)
    announced, level, carries = sequential_alarms_rows(
        rule,
        t[None],
        np.asarray(evidence, dtype=float)[:, None],
        np.asarray(observation_s, dtype=float)[None],
        np.asarray(judged, dtype=bool)[None],
        [t.size],
        [carry],
        max_gap_s,
        tau_s,
    )
    return announced[0], level[0], carries[0]


def sequential_alarms_rows(
    rule: SequentialRule,
    time_s: NDArray[np.float64],
    evidence: NDArray[np.float64],
    observation_s: NDArray[np.float64],
    judged: NDArray[np.bool_],
    counts: Sequence[int],
    carries: Sequence[SequentialCarry],
    max_gap_s: float,
    tau_s: float,
) -> tuple[NDArray[np.int8], NDArray[np.float64], list[SequentialCarry]]:
    """:func:`sequential_alarms` of rows of motors at once (the live agent's call of every motor's few
    samples): ``time_s``, ``observation_s``, ``judged`` one row per motor, ``evidence`` directions ×
    rows × samples, each row's first ``counts`` samples its own (the results of the rest are not
    defined); each row's new carry.

    Every row whose samples start the sums afresh at most at its first judged one (the rule's calls in the
    live agent, but for a gap inside the call) is summed at once: its unjudged samples step by exactly 0,
    which leaves each sum and running minimum as it was, so the values are those of its judged samples
    alone. Each stretch of the others (a whole log with its gaps) is summed on its own."""
    h = rule.threshold(tau_s)
    k = rule.reference_sigmas
    t = np.asarray(time_s, dtype=float)
    rows, n = t.shape
    directions = len(DIRECTIONS)
    if n == 0:
        return np.zeros((rows, 0), dtype=np.int8), np.zeros((rows, 0)), list(carries)
    lengths = np.asarray(counts, dtype=np.intp)
    judged = np.asarray(judged, dtype=bool) & (np.arange(n)[None, :] < lengths[:, None])
    carried_sums = np.array([c.sums for c in carries], dtype=float).reshape(rows, directions).T
    carried_alarms = np.array([c.alarmed for c in carries], dtype=bool).reshape(rows, directions).T
    last_s = np.array([c.last_s for c in carries], dtype=float)
    # the time each report stands for (an unjudged one's counts for nothing)
    credit, intervals = report_credits(t, counts, carries, max_gap_s)
    # each judged sample's time since the judged one before it (the carried one's before the first)
    position = np.arange(n)[None, :]
    latest, _, t_before = marked_before(t, judged, last_s)
    fresh = judged & ~(t - t_before <= max_gap_s)  # a gap (or the first sample ever): afresh
    dt = np.where(fresh, 0.0, credit)
    with np.errstate(invalid="ignore", divide="ignore"):
        steps = (np.minimum(evidence, rule.evidence_caps(h)[:, :, None]) - k) * (
            dt / np.asarray(observation_s, dtype=float)
        )[None]
    steps = np.where(judged[None], steps, 0.0)
    first = np.argmax(judged, axis=1)  # each row's first judged sample (0 where none)
    has_judged = judged.any(axis=1)
    afresh_first = has_judged & fresh[np.arange(rows), first]
    inside = fresh.sum(axis=1) - afresh_first  # stretches started afresh after the first judged sample
    sums = np.empty((directions, rows, n))
    alarms = np.empty((directions, rows, n), dtype=bool)
    # rows of one stretch (every sample from the row's start: before its first judged one it steps 0)
    one = np.flatnonzero(inside == 0)
    if one.size:
        start_sum = np.where(afresh_first[one], 0.0, carried_sums[:, one])
        start_alarm = carried_alarms[:, one] & ~afresh_first[one]
        sums[:, one], alarms[:, one] = _lindley(steps[:, one], start_sum, start_alarm, h)
    for r in np.flatnonzero(inside > 0).tolist():
        bounds = [0, *np.flatnonzero(fresh[r]).tolist(), n]
        start_sum, start_alarm = carried_sums[:, r], carried_alarms[:, r]
        for lo, hi in zip(bounds[:-1], bounds[1:]):
            if hi <= lo:
                continue
            if fresh[r, lo]:
                start_sum, start_alarm = np.zeros(directions), np.zeros(directions, dtype=bool)
            seg, latched = _lindley(steps[:, r : r + 1, lo:hi], start_sum[:, None], start_alarm[:, None], h)
            sums[:, r, lo:hi], alarms[:, r, lo:hi] = seg[:, 0], latched[:, 0]
            start_sum, start_alarm = seg[:, 0, -1], latched[:, 0, -1]
    # before a row's first judged sample: the carried state
    ahead = (position < np.where(has_judged, first, n)[:, None])[None]
    sums = np.where(ahead, carried_sums[:, :, None], sums)
    alarms = np.where(ahead, carried_alarms[:, :, None], alarms)
    ratio = np.where(alarms, sums / h, 0.0)
    strongest = np.argmax(ratio, axis=0)
    codes = np.array([int(d) for d in DIRECTIONS], dtype=np.int8)
    announced = np.where(alarms.any(axis=0), codes[strongest], Code.NORMAL).astype(np.int8)
    level = (sums / h).max(axis=0)
    padding = position >= lengths[:, None]  # beyond a row's own samples: NORMAL, no level
    announced[padding], level[padding] = Code.NORMAL, np.nan
    # each row's carry: its last sample's state (its last judged one's, or the carried one)
    end = np.maximum(lengths - 1, 0)
    end_sums = sums[:, np.arange(rows), end].T.tolist()
    end_alarms = alarms[:, np.arange(rows), end].T.tolist()
    last_judged = latest[np.arange(rows), end]
    new = []
    for r, carry in enumerate(carries):
        if lengths[r] == 0:
            new.append(carry)
            continue
        new.append(
            SequentialCarry(
                sums=tuple(end_sums[r]),
                alarmed=tuple(end_alarms[r]),
                last_s=float(t[r, last_judged[r]]) if last_judged[r] >= 0 else carry.last_s,
                stream_s=float(t[r, end[r]]),
                intervals=intervals[r],
            )
        )
    return announced, level, new


def _lindley(
    steps: NDArray[np.float64], start_sum: NDArray[np.float64], start_alarm: NDArray[np.bool_], h: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The CUSUM ``S ← max(0, S + step)`` along the last axis of ``steps`` (directions × rows × samples)
    from ``start_sum`` (directions × rows), in closed form: ``S_n = W_n − min(−S_0, min_j W_j)``; and
    the alarm at each sample (:func:`_latched`, ``start_alarm`` carried in)."""
    w = np.cumsum(steps, axis=-1)
    sums = np.minimum.accumulate(w, axis=-1)  # the lowest W so far, then S in its place
    np.minimum(sums, -start_sum[..., None], out=sums)
    np.subtract(w, sums, out=sums)
    return sums, _latched(sums, h, start_alarm)


def _latched(sums: NDArray[np.float64], h: float, start: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Alarm at each sample (along the last axis): S reached h since it was last 0 (``start``: an alarm
    carried in).

    Each return to 0 opens a stretch (``stretch``: how many returns so far); an alarm stands where S
    reached h in the sample's own stretch (h > 0: never at a return itself), the carried one in the
    first stretch, before any return. One running count and one running maximum, over 32-bit
    integers (a whole log's six directions are a few million samples: issue 18)."""
    stretch = np.cumsum(sums <= 0.0, axis=-1, dtype=np.int32)
    crossed_in = np.where(sums >= h * (1.0 - _H_ROUNDING), stretch, np.int32(-1))
    np.maximum.accumulate(crossed_in, axis=-1, out=crossed_in)
    return (crossed_in == stretch) | (start[..., None] & (stretch == 0))
