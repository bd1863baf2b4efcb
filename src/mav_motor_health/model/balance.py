"""The model's two equations as balances, averaged over time: a flight rule that needs no steady state.

In flight the input moves faster than the telemetry samples it, so the speed a sampled input *should*
give (the steady state, or its first-order response) is mostly guesswork. The model's equations, though,
hold at every instant, and ESC telemetry reports speed, current and (with the command) input voltage of
the same instant:

* electrical (eq. 1, inductance neglected): ``r_V = V − R·i − k_e·ω``, the voltage the model cannot
  account for (zero for a healthy motor at every instant, whatever the input does);
* mechanical (eq. 2 with the inertia): ``r_T = k_t·i − (C_p·ω^k + B·ω + T_f) − J·dω/dt``, the torque it
  cannot account for.

Both are low-passed with a time constant ``tau_s`` (the current sense and the sampling jitter make single
samples noisy); the low-passed ``J·dω/dt`` is ``J·(ω − ω̄)/tau_s`` exactly, so the inertia term needs no
numerical derivative. A fault shows as a lasting offset: extra friction (F1.1) as torque, a trimmed
propeller (F3.1) as missing torque, an open transistor (F4.1, a higher effective resistance) as voltage.

To keep the paper's tree and its bands, the two offsets are turned into the deviations of speed and
current they would cause in steady state at the (low-passed) input ``V̄``. Linearising the model there,
with ``G = k·C_p·ω^(k−1) + B`` and ``D = k_t·k_e + R·G``:

    Δω = −(k_t·r_V + R·r_T) / D          Δi = −(k_e·Δω + r_V) / R   (= (k_e·r_T − G·r_V) / D)

(Δω comes from ``k_t·r_V + R·r_T``, which has no current in it: a current sensor that is noisy or
mis-scaled does not move the speed residual.) The tree then judges ``ω_model(V̄) + Δω`` and
``i_model(V̄) + Δi`` against ``ω_model(V̄)`` and ``i_model(V̄)``: on a testbed at constant input this is
the paper's comparison; in flight it is the same comparison without needing the input to stand still.

The two equations apart. Δω and Δi each mix both balances; the result also carries the two apart,
low-passed as they are: ``torque_residual_nm``, the mean of ``k_t·(i − i_load(ω))`` less the inertia term
(the mechanical balance ``r_T`` with the measured current, no input in it), and ``voltage_residual_v``,
the ``r_V`` that Δi uses. Which of the two a motor departs in says which effect the model misses: extra
friction (F1.1) or a lighter propeller (F3.1) is torque (``r_T`` above or below 0) with ``r_V`` near 0,
an open transistor (F4.1) is voltage (``r_V`` above 0) with ``r_T`` near 0. Their noise differs: ``r_V``
carries the error of the command each report was paired with (a command that jitters between reports
moves ``V``); ``r_T`` needs no command where the ESC reports its motor current (where it reports its input
current ``s``, the torque reads the motor current as the electrical balance below does, ``mean(s)/mean(d)``,
and the command's jitter enters there too; the mean of ``s/d`` would take a report averaged over a command
dip, divided by the dip's small duty, for hundreds of amperes: docs/flight.md, "The torque through the
duty as a ratio of means"). Δi combines
them, ``(k_e·r_T − G·r_V)/D``, so its band holds both noises while a fault moves one
(docs/flight.md, "The two equations apart, measured").

The current enters through ``r_V`` only, weighted as the sensor weights it. An ESC reports its *input*
current ``s``, the average of ``d·i`` (duty times motor current) as a shunt on its DC side sees it; where
the command zigzags between control steps, duty and current rise and fall together, and ``s/d`` of a
single sample is not the motor current (it reads high). But ``d·(V − k_e·ω) − R·s`` averages to
``mean(d)·r_V`` for a lasting ``r_V`` whatever ``d`` and ``i`` do, so with ``input_current_a`` and
``duty``:

    r_V = mean(d·(V − k_e·ω) − R·s) / mean(d)

and without them (a motor current, a testbed) ``d = 1`` and ``s = i``, the balance above.

Most ESCs report their current unsigned: a motor that brakes (its back-EMF above the input, the current
flowing back) reads 0, not its negative current, and the mean of the readings sits above the mean
current. The balance therefore uses the mean the readings imply when the zeros are taken for what they
are, readings at or below zero (:func:`censored_mean`). (With the ESC averaging its input current before
it reports, such zeros are rare, about 3 % of the readings in the simulator's gusty air; an ESC that
reports single unaveraged samples reads many more.)

The *input activity* (:func:`input_activity`) measures how much the input zigzags between samples: the
balances' noise grows with it (a command that moves between samples leaves the sensed current behind),
so the flight rule averages longer and the flight profile widens its bands with it. Where the source says
how far the input went beyond the two samples' inputs in between (``input_excursion_v``, a command that
dipped and came back between two ESC reports, telemetry/assemble.py) and the rule passes it (the
profile option ``steady.excursion_weight``, off in the shipped profiles), that excursion ``e`` is a zigzag
of ``e²`` (down ``e`` and up again), whichever is larger. The balance rule
scales it by √(sample interval / 40 ms): the noise of an average grows as √(interval) for the same
averaging time, so an ESC that reports at 10 Hz counts as more active than one at 50 Hz with the same
input.

What the balance rule allows an input step beyond its zigzag (``zigzag_v``) is the activity as measured,
or, where the rule asks (``steady.step_over_changes``, off in the shipped profiles), the zigzag over the
input's *changes* (:func:`change_zigzag_rows`): the command's changes, however many ESC reports repeat one
command in between. A log pairs each report with the latest command it has; where an ESC reports five
times per logged command, most samples repeat an input, and the samples' zigzag sees a change next to a
repeat, never two changes in a row (docs/flight.md, "The step's allowance over the command's changes").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr, ndtri

from .._arrays import broadcast_to, nan_to_zero
from .dynamics import ResponseCarry, first_order_responses, last_of, latest_marked, previous
from .equations import current_from_speed, steady_state
from .params import MotorParams

__all__ = [
    "ActivityCarry",
    "BalanceCarry",
    "BalanceResult",
    "balance_deviations",
    "balance_deviations_rows",
    "censored_mean",
    "input_activity",
    "input_activity_rows",
    "linearised_slopes",
]

FloatArray = NDArray[np.float64]

#: the input activity falls this many times slower than it rises (see :func:`input_activity`)
SLOW_FALL = 6.0
#: the balance rule scales the activity by √(sample interval / this): 40 ms, an ESC reporting at 25 Hz
INTERVAL_REF_S = 0.04
#: time constant of the low-passed sample interval [s]
INTERVAL_TAU_S = 2.0
#: a longer silence is a gap in the telemetry (a dropout), not its rate: it leaves the interval as it was
MAX_INTERVAL_S = 0.25


@dataclass(frozen=True)
class ActivityCarry:
    """The input activity's low-pass and the last input and change seen."""

    response: ResponseCarry = field(default_factory=ResponseCarry)
    slow: ResponseCarry = field(default_factory=ResponseCarry)
    last_v: float = float("nan")
    last_dv: float = float("nan")
    #: the zigzag over the input's changes (:func:`change_zigzag_rows`): its two low-passes and the last change
    changes: ResponseCarry = field(default_factory=ResponseCarry)
    changes_slow: ResponseCarry = field(default_factory=ResponseCarry)
    last_change_v: float = float("nan")
    last_command: float = float("nan")


@dataclass(frozen=True)
class BalanceCarry:
    """Low-pass states carried between calls (one per averaged quantity)."""

    voltage: ResponseCarry = field(default_factory=ResponseCarry)
    omega: ResponseCarry = field(default_factory=ResponseCarry)
    current: ResponseCarry = field(default_factory=ResponseCarry)
    speed_balance: ResponseCarry = field(default_factory=ResponseCarry)
    electrical: ResponseCarry = field(default_factory=ResponseCarry)
    mechanical: ResponseCarry = field(default_factory=ResponseCarry)
    zero_current: ResponseCarry = field(default_factory=ResponseCarry)
    sensed: ResponseCarry = field(default_factory=ResponseCarry)
    weight: ResponseCarry = field(default_factory=ResponseCarry)
    interval: ResponseCarry = field(default_factory=ResponseCarry)
    activity: ActivityCarry = field(default_factory=ActivityCarry)


@dataclass(frozen=True)
class BalanceResult:
    voltage_v: FloatArray  # low-passed input voltage V̄
    omega_model_rad_s: FloatArray  # model speed at V̄
    current_model_a: FloatArray  # model current at V̄
    delta_omega_rad_s: FloatArray  # steady-state speed deviation the residuals imply
    delta_current_a: FloatArray  # steady-state current deviation the residuals imply
    omega_mean_rad_s: FloatArray  # low-passed measured speed
    current_mean_a: FloatArray  # low-passed measured current
    activity_v: FloatArray  # the input activity, scaled by √(sample interval / INTERVAL_REF_S)
    zigzag_v: FloatArray  # how far the input jumps (the activity as measured, or over its changes): a step's allowance
    tau_s: FloatArray  # the low-pass time constant at each sample
    torque_residual_nm: FloatArray  # low-passed r_T, the torque the model cannot account for
    voltage_residual_v: FloatArray  # low-passed r_V, the voltage the model cannot account for


def input_activity(
    time_s: ArrayLike, voltage_v: ArrayLike, tau_s: float, carry: ActivityCarry | None = None
) -> tuple[FloatArray, ActivityCarry]:
    """How much the input zigzags between samples [V], per sample.

    ``sqrt(low-pass of max(0, −ΔV_n·ΔV_(n−1)))`` with ΔV the change from one sample to the next: an input
    that goes up then down (or down then up) between three samples has moved faster than the samples
    show, and that is what makes the balances noisy. A manoeuvre's step or ramp (successive changes of
    the same sign) adds nothing. The low-pass rises with ``tau_s`` and falls with ``SLOW_FALL × tau_s``
    (the larger of a fast and a slow low-pass): a lull of a few seconds in gusty air does not narrow the
    bands while the air is still gusty.
    """
    t = np.asarray(time_s, dtype=float)
    if t.size == 0:
        return np.zeros(0), carry or ActivityCarry()
    activity, (new,) = input_activity_rows(
        t.reshape(1, -1), np.asarray(voltage_v, dtype=float).reshape(1, -1), tau_s, [carry or ActivityCarry()]
    )
    return activity[0], new


def input_activity_rows(
    time_s: FloatArray,
    voltage_v: FloatArray,
    tau_s: float,
    carries: list[ActivityCarry],
    lengths: list[int] | None = None,
) -> tuple[FloatArray, list[ActivityCarry]]:
    """:func:`input_activity` of several motors at once: rows of samples (2-D), one carry per row;
    ``lengths`` each row's number of samples (None: all; the rest is padding after them)."""
    t, v = time_s, voltage_v
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    zigzag, dv = _zigzag_rows(v, carries)
    # the fast and the slow low-pass in one call: the same samples, two time constants
    both, responses = first_order_responses(
        t,
        np.concatenate([zigzag, zigzag]),
        np.repeat([tau_s, SLOW_FALL * tau_s], rows).reshape(-1, 1),
        [c.response for c in carries] + [c.slow for c in carries],
        counts * 2,
    )
    return _activity_rows(v, dv, both, responses, carries, counts)


def _zigzag_rows(v: FloatArray, carries: list[ActivityCarry]) -> tuple[FloatArray, FloatArray]:
    """:func:`input_activity_rows`' input to its low-passes, ``max(0, −ΔV_n·ΔV_(n−1))`` (0 where not
    finite), and the changes ΔV."""
    dv = v - previous(v, [c.last_v for c in carries])
    prev_dv = previous(dv, [c.last_dv for c in carries])
    zigzag = np.maximum(0.0, -dv * prev_dv)
    return np.where(np.isfinite(zigzag), zigzag, 0.0), dv


def change_zigzag_rows(
    dv: FloatArray,
    command: FloatArray | None,
    excursion_v: FloatArray | None,
    carries: list[ActivityCarry],
    counts: list[int],
) -> tuple[FloatArray, list[float], list[float]]:
    """The zigzag over the input's changes: ``max(0, −ΔV_n·ΔV_last)`` at each sample whose input changed,
    ``ΔV_last`` the last change before it, however many samples repeated one input in between, and held
    from one change to the next (a step in time that the low-pass averages over time, as it averages the
    samples' zigzag; 0 before the first); each row's last change and last command (the carries' where
    none). With ``command`` (what the log paired each sample with) the input changed where the command
    did: the bus voltage moves the input a little at every sample, and a jump of the command next to such
    a wobble is no zigzag.

    A log pairs each ESC report with the latest command it has: where the ESC reports several times per
    command (held-out world 1009: 50 Hz reports, commands at 10 Hz), most samples repeat an input and
    :func:`_zigzag_rows` sees a change next to a repeat, never two changes, while the command jumps by a
    fifth of the bus between its updates (``balance_deviations_rows``' ``zigzag_v``, the step threshold's
    allowance: docs/flight.md, "The step's allowance over the command's changes"). An excursion (the input
    went and came back between two samples) is a change and a zigzag of ``e²``, as in :func:`_zigzag_rows`.
    """
    rows = dv.shape[0]
    changed = np.isfinite(dv) & (dv != 0.0)
    last_command = [c.last_command for c in carries]
    if command is not None:
        cmd = np.asarray(command, dtype=float)
        changed &= ~(cmd == previous(cmd, last_command))  # (NaN before the first: a change)
        last_command = [
            old if new is None or not math.isfinite(new) else new
            for old, new in zip(last_command, last_of(cmd, counts))
        ]
    carried = np.array([c.last_change_v for c in carries], dtype=float)[:, None]
    place, before = latest_marked(changed)  # each sample's latest change, and the one before it
    last = np.where(before >= 0, np.take_along_axis(dv, np.maximum(before, 0), axis=1), carried)
    zigzag = np.maximum(0.0, nan_to_zero(-dv * last))
    ends = place[:, -1]
    final = np.where(ends >= 0, dv[np.arange(rows), np.maximum(ends, 0)], carried[:, 0])
    if excursion_v is not None:
        e2 = nan_to_zero(np.asarray(excursion_v, dtype=float)) ** 2
        zigzag = np.fmax(zigzag, e2)
        place, _ = latest_marked(changed | (e2 > 0))
    # held between changes: the value at the latest change, the carried one before the call's first
    held = np.array([nan_to_zero(np.asarray(c.changes.input, dtype=float)) for c in carries], dtype=float)
    held = np.where(place >= 0, np.take_along_axis(zigzag, np.maximum(place, 0), axis=1), held[:, None])
    return held, final.tolist(), last_command


def _activity_rows(
    v: FloatArray,
    dv: FloatArray,
    both: FloatArray,
    responses: list[ResponseCarry],
    carries: list[ActivityCarry],
    counts: list[int],
) -> tuple[FloatArray, list[ActivityCarry]]:
    """:func:`input_activity_rows`' result from its two low-passes (``both``: the fast rows, then the slow
    ones; ``responses`` their carries, alike)."""
    rows = len(carries)
    activity = np.sqrt(np.maximum(np.maximum(both[:rows], both[rows:]), 0.0))
    news = []
    for r, (carry, last_v, last_dv) in enumerate(zip(carries, last_of(v, counts), last_of(dv, counts))):
        if last_v is None:  # a row without samples
            news.append(carry)
            continue
        news.append(
            ActivityCarry(
                response=responses[r],
                slow=responses[rows + r],
                last_v=last_v if math.isfinite(last_v) else carry.last_v,
                last_dv=last_dv if math.isfinite(last_dv) else 0.0,
            )
        )
    return activity, news


#: below this mean duty the ESC's input current says too little about the motor's (see model/esc.py)
MIN_MEAN_DUTY = 0.05

#: above this share of zero readings the censored mean is not trusted further (most readings say nothing)
MAX_ZERO_SHARE = 0.9


def censored_mean(mean_a: ArrayLike, zero_share: ArrayLike) -> FloatArray:
    """The mean of a current whose negative values read 0, from the readings' mean and share of zeros.

    Taking the current as normal with mean μ and deviation σ, a reading ``max(i, 0)`` is zero with
    probability ``p = Φ(−μ/σ)`` and has the mean ``m = σ·(z·Φ(z) + φ(z))`` with ``z = μ/σ``: the share of
    zeros gives ``z = Φ⁻¹(1 − p)``, the mean then ``σ`` and ``μ = z·σ``. With no zeros the mean is the
    readings' mean; ``p`` is held below :data:`MAX_ZERO_SHARE`.
    """
    m = np.asarray(mean_a, dtype=float)
    p = np.clip(np.asarray(zero_share, dtype=float), 0.0, MAX_ZERO_SHARE)
    censored = p > 1e-6
    if censored.all() or m.ndim == 0 or p.shape != m.shape:
        z = ndtri(1.0 - np.where(censored, p, 0.5))
        pdf = np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
        sigma = m / (z * ndtr(z) + pdf)
        return np.where(censored & np.isfinite(p), z * sigma, m)
    # the same, worked out only where there are zeros (the rest keep the readings' mean)
    out = m.copy()
    at = np.flatnonzero(censored)
    if at.size:
        share, mean = p.ravel()[at], m.ravel()[at]
        z = ndtri(1.0 - share)
        pdf = np.exp(-0.5 * z * z) / np.sqrt(2.0 * np.pi)
        sigma = mean / (z * ndtr(z) + pdf)
        out.ravel()[at] = np.where(np.isfinite(share), z * sigma, mean)
    return out


def linearised_slopes(params: MotorParams, omega_rad_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``G = k·C_p·ω^(k−1) + B`` and ``D = k_t·k_e + R·G`` at the model speed ``ω`` (negative read as 0):
    a lasting voltage ``r_V`` moves the steady speed by ``−k_t·r_V/D`` (see the module doc)."""
    p = params
    w = np.maximum(np.asarray(omega_rad_s, dtype=float), 0.0)
    g = p.k * p.C_p * w ** (p.k - 1.0) + p.B
    return g, p.k_t * p.k_e + p.R_ohm * g


def balance_deviations(
    params: MotorParams,
    time_s: ArrayLike,
    voltage_v: ArrayLike,
    omega_rad_s: ArrayLike,
    current_a: ArrayLike,
    tau_s: float,
    activity_tau_s: float,
    carry: BalanceCarry | None = None,
    *,
    activity_ref_v: float = 0.0,
    tau_max_s: float = 2.0,
    input_current_a: ArrayLike | None = None,
    duty: ArrayLike | None = None,
    input_excursion_v: ArrayLike | None = None,
    torque_through_duty: bool = False,
) -> tuple[BalanceResult, BalanceCarry]:
    """Low-passed balances and the steady-state deviations they imply (see the module doc).

    With ``activity_ref_v`` > 0 the low-pass lengthens with the input activity ``a``:
    ``tau_s·max(1, a/activity_ref_v)``, at most ``tau_max_s`` (a zigzagging input needs more samples
    for the same certainty).

    ``current_a`` is the motor current. Given ``input_current_a`` (the ESC's reading of its input current)
    and ``duty`` (the command, 0..1), the electrical balance uses those, weighted by the duty (see the
    module doc), and ``current_a`` only says where a current is known. ``input_excursion_v``: how far the
    input went beyond the two samples' inputs in between (module doc, "input activity"; None: not at all).
    ``torque_through_duty``: ``current_a`` is ``input_current_a`` over the duty, and the torque reads the
    motor current as ``mean(input_current_a)/mean(duty)`` (module doc, "The two equations apart").

    NaN speed or current (a lost sample, a missing sensor) hold the low-passes; Δi is NaN where the
    current is NaN, Δω needs only voltage and speed.
    """
    t = np.asarray(time_s, dtype=float)

    def row(x: ArrayLike | None) -> FloatArray | None:
        return None if x is None else np.asarray(x, dtype=float).reshape(1, -1)

    if t.size == 0:
        empty = np.zeros(0)
        return BalanceResult(*([empty] * len(_RESULT_FIELDS))), carry or BalanceCarry()
    result, (new,) = balance_deviations_rows(
        params,
        t.reshape(1, -1),
        row(voltage_v),  # type: ignore[arg-type]
        row(omega_rad_s),  # type: ignore[arg-type]
        row(current_a),  # type: ignore[arg-type]
        tau_s,
        activity_tau_s,
        [carry or BalanceCarry()],
        activity_ref_v=activity_ref_v,
        tau_max_s=tau_max_s,
        input_current_a=row(input_current_a),
        duty=row(duty),
        input_excursion_v=row(input_excursion_v),
        torque_through_duty=[torque_through_duty],
    )
    return BalanceResult(*(np.asarray(getattr(result, f))[0] for f in _RESULT_FIELDS)), new


_RESULT_FIELDS = (
    "voltage_v",
    "omega_model_rad_s",
    "current_model_a",
    "delta_omega_rad_s",
    "delta_current_a",
    "omega_mean_rad_s",
    "current_mean_a",
    "activity_v",
    "zigzag_v",
    "tau_s",
    "torque_residual_nm",
    "voltage_residual_v",
)

#: the balance rule's low-passed quantities, in the order of :func:`balance_deviations_rows`' one call
_AVERAGED = (
    "voltage",
    "omega",
    "current",
    "sensed",
    "weight",
    "zero_current",
    "speed_balance",
    "electrical",
    "mechanical",
)


def balance_deviations_rows(
    params: MotorParams,
    time_s: FloatArray,
    voltage_v: FloatArray,
    omega_rad_s: FloatArray,
    current_a: FloatArray,
    tau_s: float,
    activity_tau_s: float,
    carries: list[BalanceCarry],
    lengths: list[int] | None = None,
    *,
    activity_ref_v: float | FloatArray = 0.0,
    tau_max_s: float = 2.0,
    input_current_a: FloatArray | None = None,
    duty: FloatArray | None = None,
    input_excursion_v: FloatArray | None = None,
    torque_through_duty: Sequence[bool] | None = None,
    command: FloatArray | None = None,
    zigzag_over_changes: bool = False,
) -> tuple[BalanceResult, list[BalanceCarry]]:
    """:func:`balance_deviations` of several motors of one model at once: rows of samples (2-D), one
    carry per row; ``lengths`` each row's number of samples (None: all; the rest is padding after them).
    The nine low-passes of each row run in one call. ``input_excursion_v``: how far each sample's input
    went beyond the two held inputs since the sample before (module doc, "input activity"; None: not
    at all). ``torque_through_duty``: per row, whether ``current_a`` is an input current over the duty
    (``input_current_a`` and ``duty`` given): the torque then reads the motor current as
    ``mean(s)/mean(d)`` (module doc, "The two equations apart"); None: no row. ``zigzag_over_changes``:
    the result's ``zigzag_v`` (the balance rule's step allowance) is the zigzag over the changes of
    ``command`` (:func:`change_zigzag_rows`; the command None: over the input's changes), not the
    activity as measured (module doc)."""
    t, v, w, i = time_s, voltage_v, omega_rad_s, current_a
    rows, n = t.shape
    counts = [n] * rows if lengths is None else lengths
    p = params
    # The balances average samples: an ESC that reports less often averages fewer of them in the same
    # time, and its noise is larger by √(interval); the activity that sets bands and low-pass says so.
    gaps = t - previous(t, [c.voltage.time_s for c in carries])
    gaps = np.where(gaps <= MAX_INTERVAL_S, gaps, np.nan)  # NaN holds the low-pass
    # the input activity's two low-passes (input_activity_rows) and the interval's in one call
    activity_carries = [c.activity for c in carries]
    zigzag_in, dv = _zigzag_rows(v, activity_carries)
    excursion = None
    if input_excursion_v is not None:
        # an input that went and came back between two samples zigzagged by its excursion e (down e and
        # up e: −ΔV_n·ΔV_(n−1) = e²), though both samples' inputs are alike
        excursion = nan_to_zero(np.asarray(input_excursion_v, dtype=float))
        zigzag_in = np.fmax(zigzag_in, excursion * excursion)
    # the step's allowance where asked (``zigzag_over_changes``): the zigzag over the command's changes,
    # low-passed as the activity is, in the same call; else the activity as measured
    targets, taus = [zigzag_in, zigzag_in, gaps], [activity_tau_s, SLOW_FALL * activity_tau_s, INTERVAL_TAU_S]
    responses = (
        [c.response for c in activity_carries]
        + [c.slow for c in activity_carries]
        + [c.interval for c in carries]
    )
    if zigzag_over_changes:
        changes_in, last_changes, last_commands = change_zigzag_rows(
            dv, command, excursion, activity_carries, counts
        )
        targets += [changes_in, changes_in]
        taus += [activity_tau_s, SLOW_FALL * activity_tau_s]
        responses += [c.changes for c in activity_carries] + [c.changes_slow for c in activity_carries]
    low_passed, low_pass_carries = first_order_responses(
        t,
        np.concatenate(targets),
        np.repeat(taus, rows).reshape(-1, 1),
        responses,
        counts * len(targets),
    )
    activity, c_a = _activity_rows(
        v, dv, low_passed[: 2 * rows], low_pass_carries[: 2 * rows], activity_carries, counts
    )
    interval, c_dt = low_passed[2 * rows : 3 * rows], low_pass_carries[2 * rows : 3 * rows]
    interval = np.where(np.isfinite(interval) & (interval > 0), interval, INTERVAL_REF_S)
    zigzag = activity
    if zigzag_over_changes:
        changes = low_passed[3 * rows :]
        zigzag = np.sqrt(np.maximum(np.maximum(changes[:rows], changes[rows:]), 0.0))
        c_a = [
            replace(
                c,
                changes=low_pass_carries[3 * rows + r],
                changes_slow=low_pass_carries[4 * rows + r],
                last_change_v=x,
                last_command=y,
            )
            for r, (c, x, y) in enumerate(zip(c_a, last_changes, last_commands))
        ]
    activity = activity * np.sqrt(interval / INTERVAL_REF_S)
    tau: FloatArray | float = tau_s
    if np.any(np.asarray(activity_ref_v) > 0):  # (per sample where the rule scales with the bus voltage)
        tau = np.clip(tau_s * activity / activity_ref_v, tau_s, max(tau_s, tau_max_s))
    load_a = current_from_speed(p, w)  # the current the load needs at the measured speed
    # Δω from the combination k_t·r_V + R·r_T, which has no current in it.
    speed_balance = p.k_t * (v - p.k_e * w) - p.R_ohm * p.k_t * load_a
    # The current enters through the electrical balance, weighted as the sensor weights it: an ESC reports
    # its input current s = d·i (sensed and averaged as a shunt does) and d·(V − k_e·ω − R·i) = d·r_V, so
    # mean(d·(V − k_e·ω) − R·s) = mean(d)·r_V for a lasting r_V, however d and i zigzag together (see the
    # module doc); a motor current is the case d = 1.
    if input_current_a is not None and duty is not None:
        sensed = np.asarray(input_current_a, dtype=float)
        weight = np.clip(np.asarray(duty, dtype=float), 0.0, 1.0)
    else:
        sensed, weight = i, np.ones_like(t)
    weight = np.where(np.isfinite(sensed), weight, np.nan)
    zero = np.where(np.isfinite(sensed), (sensed == 0.0).astype(float), np.nan)
    electrical = weight * (v - p.k_e * w) - p.R_ohm * sensed
    # the torque the model cannot account for, less J·dω/dt; where the current is an input current over
    # the duty it is read as the electrical balance reads it, mean(s)/mean(d), not as the mean of s/d
    # (module doc, "The two equations apart"): there only the load's torque is averaged here
    through_duty = None
    given = input_current_a is not None and duty is not None
    if torque_through_duty is not None and given and any(torque_through_duty):
        through_duty = np.asarray(torque_through_duty, dtype=bool).reshape(-1, 1)
    mechanical = p.k_t * (i - load_a)
    if through_duty is not None:
        # the load's torque held where the current reading is (as s and d are, and the motor current's
        # k_t·(i − load) is): averaged over the samples the current is averaged over, not others
        mechanical = np.where(through_duty, np.where(np.isfinite(i), -p.k_t * load_a, np.nan), mechanical)
    # every low-pass of every row at once (the stall current: every current reading)
    k = len(_AVERAGED)
    means, averaged = first_order_responses(
        t,  # each motor's times and time constants, shared by its nine quantities
        np.concatenate([v, w, i, sensed, weight, zero, speed_balance, electrical, mechanical]),
        tau,
        [getattr(c, name) for name in _AVERAGED for c in carries],
        counts * k,
    )
    v_mean, w_mean, i_mean, s_mean, d_mean, zero_share, sb_mean, e_mean, m_mean = means.reshape(k, rows, n)
    inertia = p.J_kg_m2 or 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        accel_torque = inertia * (w - w_mean) / tau
    accel_torque = np.where(np.isfinite(accel_torque), accel_torque, 0.0)
    sb_mean = sb_mean - p.R_ohm * accel_torque
    # unsigned readings: the zeros were currents at or below zero (see the module doc)
    e_mean = e_mean - p.R_ohm * (censored_mean(s_mean, zero_share) - s_mean)
    mean_duty = np.where(d_mean >= MIN_MEAN_DUTY, d_mean, np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        rv_mean = e_mean / mean_duty
        if through_duty is not None:
            m_mean = np.where(through_duty, m_mean + p.k_t * s_mean / mean_duty, m_mean)
    model = steady_state(p, v_mean)
    _, d = linearised_slopes(p, model.omega_rad_s)
    delta_w = -sb_mean / d
    # the current at the deviated speed, from eq. 1: Δi = −(k_e·Δω + r_V)/R (= (k_e·r_T − G·r_V)/D)
    delta_i = -(p.k_e * delta_w + rv_mean) / p.R_ohm
    current_known = np.isfinite(i)
    delta_i = np.where(current_known, delta_i, np.nan)
    # the two equations apart (module doc, "The two equations apart")
    torque = np.where(current_known, m_mean - accel_torque, np.nan)
    rv_mean = np.where(current_known, rv_mean, np.nan)
    result = BalanceResult(
        voltage_v=v_mean,
        omega_model_rad_s=model.omega_rad_s,
        current_model_a=model.current_a,
        delta_omega_rad_s=delta_w,
        delta_current_a=delta_i,
        omega_mean_rad_s=w_mean,
        current_mean_a=i_mean,
        activity_v=activity,
        zigzag_v=zigzag,
        tau_s=broadcast_to(np.asarray(tau, dtype=float), t.shape),
        torque_residual_nm=torque,
        voltage_residual_v=rv_mean,
    )
    news = [
        BalanceCarry(
            **{name: averaged[j * rows + r] for j, name in enumerate(_AVERAGED)},
            interval=c_dt[r],
            activity=c_a[r],
        )
        for r in range(rows)
    ]
    return result, news
