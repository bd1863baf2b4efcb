"""The diagnosis pipeline for one motor: plausibility → model → steady rule → tree → persistence.

:func:`diagnose_motors` is the single implementation: rows of samples, one row per motor, each with the
carry from its previous call; every rule keeps its state in that carry and looks back only, so a split of
a motor's samples into calls gives the same states (but see :func:`~..model.dynamics.first_order_response`
on a call that ends on a lost sample). Replay calls it once per motor with the whole log
(:func:`diagnose_motor`); the live agent calls it with every motor's few new samples at once (see
:class:`StreamingDiagnoser`), the same code for one sample or a million. Both therefore announce the same
states.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..model.balance import BalanceCarry, balance_deviations_rows
from ..model.dynamics import ResponseCarry, first_order_responses, time_constant_s
from ..model.equations import SteadyState, current_from_speed, steady_state
from ..model.params import MotorParams
from ..model.predict import predict_steady
from ..telemetry.table import TelemetryTable
from .detection import DIRECTIONS, SequentialCarry, direction_evidence, sequential_alarms
from .noise import BandNoise, require_noise
from .pairing import PairingCarry, pairing_error_rows
from .persistence import PersistenceCarry, announce
from .plausibility import (
    CURRENT_UNTRUSTED,
    CurrentSumCheck,
    PlausibilityCarry,
    SensorIssue,
    check_motor_rows,
)
from .profile import SteadyRule, ThresholdProfile
from .stall import StallCarry, stall_mean_rows
from .states import MotorState
from .steady import SteadyCarry, steady_mask_rows, warm_mask_rows
from .tree import agreeing_departures, classify_depth
from .vehicle_check import VehicleCheck, VehicleFit, apply_vehicle_fit

__all__ = [
    "DIAGNOSIS_COLUMNS",
    "MotorBatch",
    "MotorCarry",
    "StreamingDiagnoser",
    "diagnose",
    "diagnose_motor",
    "diagnose_motors",
]

#: Columns every diagnosis result has, in this order (replay's ``diagnosis.csv``).
DIAGNOSIS_COLUMNS = (
    "time_s",
    "motor",
    "state",
    "announced",
    "steady",
    "omega_rad_s",
    "omega_model_rad_s",
    "current_a",
    "current_model_a",
    "voltage_v",
    "sensor_flags",
)

#: States a stalled motor shows whatever its input: announced from transient samples too.
_TRANSIENT_OK = (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED)
_SPEED_BROKEN = SensorIssue.SPEED_STUCK | SensorIssue.SPEED_RANGE


@dataclass(frozen=True)
class MotorCarry:
    """Everything the pipeline remembers about one motor between calls."""

    steady: SteadyCarry = field(default_factory=SteadyCarry)
    response: ResponseCarry = field(default_factory=ResponseCarry)
    speed_residual: ResponseCarry = field(default_factory=ResponseCarry)
    current_residual: ResponseCarry = field(default_factory=ResponseCarry)
    plausibility: PlausibilityCarry = field(default_factory=PlausibilityCarry)
    persistence: PersistenceCarry = field(default_factory=PersistenceCarry)
    balance: BalanceCarry = field(default_factory=BalanceCarry)
    stall: StallCarry = field(default_factory=StallCarry)
    slow_omega: ResponseCarry = field(default_factory=ResponseCarry)
    slow_current: ResponseCarry = field(default_factory=ResponseCarry)
    pairing: PairingCarry = field(default_factory=PairingCarry)
    sequential: SequentialCarry = field(default_factory=SequentialCarry)


@dataclass(frozen=True)
class MotorBatch:
    """A few new samples of one motor for :meth:`StreamingDiagnoser.update_motors` (1-D columns, the
    arguments of :func:`diagnose_motor`)."""

    time_s: NDArray[np.float64]
    voltage_v: NDArray[np.float64]
    omega_rad_s: NDArray[np.float64]
    current_a: NDArray[np.float64]
    bus_voltage_v: NDArray[np.float64] | None = None
    command: NDArray[np.float64] | None = None
    sensor_current_a: NDArray[np.float64] | None = None
    extra_flags: NDArray[np.int16] | None = None
    context: Mapping[str, NDArray[np.float64]] | None = None


def diagnose_motor(
    params: MotorParams,
    profile: ThresholdProfile,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    current_a: NDArray[np.float64],
    bus_voltage_v: NDArray[np.float64] | None = None,
    carry: MotorCarry | None = None,
    *,
    command: NDArray[np.float64] | None = None,
    sensor_current_a: NDArray[np.float64] | None = None,
    extra_flags: NDArray[np.int16] | None = None,
    context: Mapping[str, NDArray[np.float64]] | None = None,
    pairing_s: float | None = None,
    noise: BandNoise | None = None,
) -> tuple[dict[str, NDArray], MotorCarry]:
    """Diagnose one motor's samples (increasing time); returns result columns and the new carry.

    ``current_a`` is the motor current; ``sensor_current_a`` the current as the sensor reported it (the
    ESC input current), checked for plausibility; ``command`` the normalised motor command (0..1);
    ``extra_flags`` :class:`SensorIssue` flags found across motors (the currents' sum); ``context`` the
    samples' other columns (temperatures, altitude...), which a model with fitted effects
    (``params.effects``) reads; the base model ignores it, and so does the balance rule, which checks the
    base equations (a fitted effect's extra terms are not yet part of its balances). ``pairing_s`` is how
    far apart the source may have paired each sample and its command (a log's ``meta["pairing_s"]``;
    None or 0: the command of the sample's own instant), which the balance rule weighs
    (:mod:`.pairing`). ``noise``: the motor's own noise, which a profile with ``noise_bands`` sets its
    bands from (:mod:`.noise`).
    """

    def row(x: NDArray | None, dtype: type = float) -> NDArray | None:
        return None if x is None else np.asarray(x, dtype=dtype).reshape(1, -1)

    cols, (new,) = diagnose_motors(
        params,
        profile,
        row(time_s),  # type: ignore[arg-type]
        row(voltage_v),  # type: ignore[arg-type]
        row(omega_rad_s),  # type: ignore[arg-type]
        row(current_a),  # type: ignore[arg-type]
        row(bus_voltage_v),
        [carry or MotorCarry()],
        command=row(command),
        sensor_current_a=row(sensor_current_a),
        extra_flags=row(extra_flags, np.int16),
        context=None if context is None else {k: np.asarray(v).reshape(1, -1) for k, v in context.items()},
        pairing_s=pairing_s,
        noise=None if noise is None else [noise],
    )
    return {name: values[0] for name, values in cols.items()}, new


def diagnose_motors(
    params: MotorParams,
    profile: ThresholdProfile,
    time_s: NDArray[np.float64],
    voltage_v: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    current_a: NDArray[np.float64],
    bus_voltage_v: NDArray[np.float64] | None = None,
    given_carries: Sequence[MotorCarry | None] | None = None,
    lengths: Sequence[int] | None = None,
    *,
    command: NDArray[np.float64] | None = None,
    sensor_current_a: NDArray[np.float64] | None = None,
    extra_flags: NDArray[np.int16] | None = None,
    context: Mapping[str, NDArray[np.float64]] | None = None,
    pairing_s: float | None = None,
    noise: Sequence[BandNoise] | None = None,
) -> tuple[dict[str, NDArray], list[MotorCarry]]:
    """:func:`diagnose_motor` for several motors of one model at once: one row of samples per motor.

    The arguments are 2-D (motors × samples), each row one motor's samples in increasing time, with its
    own carry in ``given_carries`` (None: a new motor). Rows may hold different numbers of samples
    (``lengths``; None: all of the columns): the rest of a row is padding after its samples, which cannot
    change their results (every rule looks back only) and whose results mean nothing. Every step runs once for all rows, so a few
    samples of six motors cost about what a few samples of one did. Returns 2-D result columns and the
    rows' new carries; each row's results are those :func:`diagnose_motor` gives for that motor alone.
    ``noise``: each row's motor noise, required by a profile with ``noise_bands``.
    """
    t = np.asarray(time_s, dtype=float)
    rows, n = t.shape
    carries = [c or MotorCarry() for c in given_carries or [None] * rows]
    counts = [n] * rows if lengths is None else [int(k) for k in lengths]
    ragged = None if lengths is None else counts  # rows of different lengths (None: all full)
    if n == 0:
        return {name: np.zeros((rows, 0)) for name in _RESULT_COLUMNS}, carries
    v = np.asarray(voltage_v, dtype=float)
    omega_in = np.asarray(omega_rad_s, dtype=float)
    current_in = np.asarray(current_a, dtype=float)
    rule = profile.steady
    balance_carries = [c.balance for c in carries]
    stall_carries = [c.stall for c in carries]
    slow_carries = [c.slow_omega for c in carries] + [c.slow_current for c in carries]
    slow: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]] | None = None  # the slow look
    activity: NDArray[np.float64] | None = None
    judged_v = v
    if rule.kind == "balance":
        # volts of the rule scaled with the vehicle's bus voltage (a 12S vehicle's input moves 3.3 times
        # the volts of a 3S one for the same command)
        volts = _bus_scale(rule, bus_voltage_v, t.shape)
        bal, balance_carries = balance_deviations_rows(
            params,
            t,
            v,
            omega_in,
            current_in,
            rule.residual_tau_s,
            rule.activity_tau_s,
            balance_carries,
            counts,
            activity_ref_v=rule.activity_ref_v * volts,
            tau_max_s=rule.residual_tau_max_s,
            input_current_a=sensor_current_a if command is not None else None,
            duty=command if sensor_current_a is not None else None,
        )
        activity, judged_v = bal.activity_v, bal.voltage_v
        omega_pred, current_pred = bal.omega_model_rad_s, bal.current_model_a
        # A stalled motor: the speed itself (the lower of the sample and its low-pass, so that a
        # start-up kick does not break the run and the first slow sample counts), and the current
        # averaged since the stall began (diagnosis/stall.py: the low-pass still holds the flight's).
        stall_speed = np.fmin(omega_in, bal.omega_mean_rad_s)
        stop_speed = np.maximum(profile.stop_speed_rad_s, profile.stop_speed_fraction * omega_pred)
        stalled_like = stall_speed < stop_speed
        omega_seen = np.where(stalled_like, stall_speed, omega_pred + bal.delta_omega_rad_s)
        omega_seen = np.where(np.isfinite(omega_in), omega_seen, np.nan)
        stall_current, stall_carries = stall_mean_rows(current_in, stalled_like, stall_carries, ragged)
        current_seen = np.where(stalled_like, stall_current, current_pred + bal.delta_current_a)
        current_seen = np.where(np.isfinite(current_in), current_seen, np.nan)
        # An input step (larger than step_v plus a few times the input's zigzag, which in gusty air
        # is no step at all) puts two operating points into the low-passes: judge after settle_s. A new
        # stream (the first sample, or after a gap) waits until the activity is known too.
        step_v = rule.step_v * volts + 3.0 * np.nan_to_num(bal.zigzag_v)  # the jumps as measured, not scaled
        # A motor whose low-passed input is at idle (below min_command: spin-down, braking with its current
        # unread) restarts the wait: when it comes back the low-passes still hold the idle. The low-passed
        # input, not the sample: in gusty air single commands dip to idle and back all the time.
        at_idle = None
        if command is not None and profile.min_command > 0:
            cmd = np.asarray(command, dtype=float)
            with np.errstate(divide="ignore", invalid="ignore"):
                bus_v = np.where(cmd > 0.05, v / cmd, np.nan)  # the input is command × bus voltage
            at_idle = judged_v < profile.min_command * bus_v
        slow_on = rule.slow_factor > 0
        warm, steady_carries = warm_mask_rows(
            t,
            v,
            rule.settle_s,
            profile.persistence.max_gap_s,
            step_v,
            [c.steady for c in carries],
            counts,
            # the activity's low-pass has to fill up first, and the deviations' (longer in gusts)
            start_settle_s=np.maximum(3.0 * rule.activity_tau_s, 3.0 * bal.tau_s),
            restart=at_idle,
            also_settle_s=rule.slow_factor * rule.settle_s if slow_on else None,
        )
        if slow_on:
            warm, slow_warm = warm[0], warm[1]
        steady = warm & np.isfinite(v) & np.isfinite(omega_in)
        if slow_on:
            # The slow look: the deviations averaged slow_factor times longer, judged as long after a step
            slow_tau = rule.slow_factor * bal.tau_s
            slow_both, slow_carries = first_order_responses(
                t,
                np.concatenate([bal.delta_omega_rad_s, bal.delta_current_a]),
                slow_tau,
                slow_carries,
                counts * 2,
            )
            # only where the low-pass is not already lengthened by the activity (calm air): in gusts the
            # fast look averages long already, and a slower one would hold every gust's upset for seconds
            calm = bal.tau_s <= rule.residual_tau_s
            slow = (slow_both[:rows], slow_both[rows:], slow_warm & steady & ~stalled_like & calm)
        response_carries = [c.response for c in carries]
        residual_carries = [c.speed_residual for c in carries] + [c.current_residual for c in carries]
        omega_expected = omega_pred
    else:
        model = _steady_model(params, v, context, counts)
        if rule.kind == "dynamic" and params.J_kg_m2 is not None:
            tau = time_constant_s(params, model.omega_rad_s)
            omega_pred, response_carries = first_order_responses(
                t, model.omega_rad_s, tau, [c.response for c in carries], counts
            )
            turning = omega_pred > 0
            # Current from the torque balance (eq. 7 plus the inertia's share, J·dω/dt with dω/dt of the
            # first-order response), not from eq. 2: eq. 2 would turn every sampled command jitter into
            # current jitter divided by R (6 A per volt on the paper's motor).
            accel = (model.omega_rad_s - omega_pred) / tau
            current_pred = np.where(
                turning,
                current_from_speed(params, omega_pred) + params.J_kg_m2 * accel / params.k_t,
                model.current_a,
            )
            lag = rule.lag_fraction
            # The input is known only at the samples: a sample is quasi-steady where the response has
            # caught up with the steady state and the input has not stepped since the last samples (a
            # command that jumps between samples hides what the motor saw in between).
            held, steady_carries = steady_mask_rows(rule, t, v, [c.steady for c in carries], counts)
            steady = (
                held
                & (np.abs(omega_pred - model.omega_rad_s) <= lag * profile.speed_band_rad_s)
                & (np.abs(current_pred - model.current_a) <= lag * profile.current_halfwidth_a(v))
            )
        else:
            omega_pred, current_pred = model.omega_rad_s, model.current_a
            steady, steady_carries = steady_mask_rows(rule, t, v, [c.steady for c in carries], counts)
            response_carries = [c.response for c in carries]
        omega_seen, current_seen, residual_carries = _lowpass_residuals(
            rule.residual_tau_s, t, omega_in, current_in, omega_pred, current_pred, carries, counts
        )
        omega_expected = np.minimum(omega_pred, model.omega_rad_s)
    reported = current_in if sensor_current_a is None else np.asarray(sensor_current_a, dtype=float)
    flags, plausibility_carries = check_motor_rows(
        profile.plausibility,
        t,
        None if command is None else np.asarray(command, dtype=float),
        reported,
        omega_in,
        [c.plausibility for c in carries],
        ragged,
    )
    if extra_flags is not None:
        flags = flags | extra_flags
    speed_band: NDArray[np.float64] | float
    if profile.noise_bands > 0:
        speed_band, current_band = _noise_bands(profile, noise, activity, t.shape)
        current_band_below = current_band.copy()
    else:
        speed_band, current_band, current_band_below = profile.bands(judged_v, activity)
    pairing_error = np.full(t.shape, np.nan)
    pairing_carries = [c.pairing for c in carries]
    if rule.kind == "balance" and pairing_s:
        # a command paired loosely with its sample: the current is not used where the voltage error it
        # could cause is a sizeable part of the speed band, nothing is judged where it is a sizeable part
        # of the speed-only band (diagnosis/pairing.py)
        pairing_error, pairing_carries = pairing_error_rows(
            params, t, v, omega_pred, pairing_s, bal.tau_s, pairing_carries, ragged
        )
        plaus = profile.plausibility
        flags = np.where(
            pairing_error > plaus.pairing_current_share * np.asarray(speed_band, dtype=float),
            flags | SensorIssue.CURRENT_UNPAIRED,
            flags,
        ).astype(np.int16)
        speed_only_band = profile.speed_only_band(speed_band, omega_pred)
        steady = steady & ~(pairing_error > plaus.pairing_speed_share * speed_only_band)
    current_trusted = ((flags & CURRENT_UNTRUSTED) == 0) & np.isfinite(current_in)
    state, depth = classify_depth(
        profile,
        omega_rad_s=omega_seen,
        omega_model_rad_s=omega_pred,
        current_a=current_seen,
        current_model_a=current_pred,
        voltage_v=judged_v,
        bus_voltage_v=bus_voltage_v,
        current_trusted=current_trusted,
        omega_expected_rad_s=omega_expected,
        activity_v=activity,
        # No fault turns the motor faster than V/k_e (tree rule 2). The balance rule judges the model plus
        # a low-passed deviation, not a measured speed: its band is the deviation's noise, which the
        # physical cap does not bound, so it keeps the full band.
        omega_free_rad_s=None if rule.kind == "balance" else v / params.k_e,
        bands=(speed_band, current_band, current_band_below),
        stall_split_a=_stall_split(profile, noise, bus_voltage_v, t.shape),
    )
    if slow is not None and profile.slow_band_fraction > 0:
        # Where the tree sees nothing, a small lasting departure may still show in the longer averages:
        # named where speed and current agree on a fault, against the narrowed bands
        slow_w, slow_i, ready = slow
        candidates = ready & (state == MotorState.NORMAL) & current_trusted
        if np.any(candidates):
            fraction = profile.slow_band_fraction
            slow_state, slow_depth = agreeing_departures(
                slow_w,
                slow_i,
                fraction * np.asarray(speed_band, dtype=float),
                fraction * np.where(slow_i < 0, current_band_below, current_band),
                profile.joint_band_sum or 2.0,
            )
            use = candidates & (slow_state != MotorState.NORMAL)
            state[use] = slow_state[use]
            depth[use] = slow_depth[use]
    state[(flags & _SPEED_BROKEN) != 0] = MotorState.SENSOR_FAULT  # never a motor fault from a bad sensor
    if profile.range_margin > 0 and noise is not None and profile.noise_bands > 0:
        # beyond the speeds identification checked the model at: not judged (a stall still is, below)
        known = np.stack([n.known(omega_pred[r], profile.range_margin) for r, n in enumerate(noise)])
        steady = steady & (known | np.isin(state, _TRANSIENT_OK))
    eligible = (steady | np.isin(state, _TRANSIENT_OK)) & (state != MotorState.NO_DATA)
    if command is not None and profile.min_command > 0:
        idle = np.asarray(command, dtype=float) < profile.min_command  # idle and spin-up: not judged
        eligible &= ~idle
        steady = steady & ~idle
    depth[state == MotorState.SENSOR_FAULT] = 1.0
    persistence = profile.persistence
    max_depth = persistence.max_depth
    rate = np.minimum(depth, max_depth) if max_depth > 1 else None
    hold_s, hold_per_activity_s = persistence.hold_s(), persistence.hold_per_activity_s()
    # the fault directions are the sequential test's (detection.py) where the profile has one;
    # persistence keeps the rest (stalls, sensor faults)
    sequential = profile.detection.on and rule.kind == "balance"
    persisted = state
    if sequential:
        persisted = np.where(np.isin(state, DIRECTIONS), MotorState.NORMAL, state).astype(state.dtype)
    announced = np.zeros(t.shape, dtype=np.int8)
    persistence_carries = []
    for r, (carry, count) in enumerate(zip(carries, counts)):
        announced[r, :count], persistence_carry = announce(
            hold_s,
            t[r, :count],
            persisted[r, :count],
            eligible[r, :count],
            carry.persistence,
            persistence.max_gap_s,
            hold_per_activity_s=hold_per_activity_s,
            activity=None if activity is None else activity[r, :count],
            rate=None if rate is None else rate[r, :count],
        )
        persistence_carries.append(persistence_carry)
    detection_level = np.full(t.shape, np.nan)
    sequential_carries = [c.sequential for c in carries]
    if sequential:
        with np.errstate(divide="ignore", invalid="ignore"):
            evidence = direction_evidence(
                (omega_seen - omega_pred) / (np.asarray(speed_band, dtype=float) / profile.noise_bands),
                (current_seen - current_pred) / (current_band / profile.noise_bands),
                current_trusted,
                profile.noise_bands,
            )
        # judged: the steady samples the tree named a motor state on (not a stall, a bad sensor, no data)
        judged = steady & ~np.isin(state, _NOT_DIRECTIONS)
        observation_s = 2.0 * bal.tau_s
        for r, count in enumerate(counts):
            found, detection_level[r, :count], sequential_carries[r] = sequential_alarms(
                profile.detection,
                t[r, :count],
                evidence[:, r, :count],
                observation_s[r, :count],
                judged[r, :count],
                carries[r].sequential,
                persistence.max_gap_s,
                rule.residual_tau_s,
            )
            # a stall, a bad sensor (persistence) come before a direction
            mine = announced[r, :count]
            announced[r, :count] = np.where(mine == MotorState.NORMAL, found, mine)
    columns: dict[str, NDArray] = {
        "state": state,
        "announced": announced,
        "steady": steady,
        "omega_model_rad_s": omega_pred,
        "current_model_a": current_pred,
        "sensor_flags": flags,
        "omega_judged_rad_s": omega_seen,
        "current_judged_a": current_seen,
        "speed_band_rad_s": np.broadcast_to(speed_band, t.shape).astype(float),
        "current_band_a": current_band,
        "current_band_below_a": current_band_below,
        "input_activity_v": np.full(t.shape, np.nan) if activity is None else activity,
        "depth": depth,
        "omega_slow_judged_rad_s": np.full(t.shape, np.nan) if slow is None else omega_pred + slow[0],
        "current_slow_judged_a": np.full(t.shape, np.nan) if slow is None else current_pred + slow[1],
        "slow_ready": np.zeros(t.shape, dtype=bool) if slow is None else slow[2],
        "pairing_error_rad_s": pairing_error,
        "detection_level": detection_level,
    }
    new_carries = [
        MotorCarry(
            steady=steady_carries[r],
            response=response_carries[r],
            speed_residual=residual_carries[r],
            current_residual=residual_carries[rows + r],
            plausibility=plausibility_carries[r],
            persistence=persistence_carries[r],
            balance=balance_carries[r],
            stall=stall_carries[r],
            slow_omega=slow_carries[r],
            slow_current=slow_carries[rows + r],
            pairing=pairing_carries[r],
            sequential=sequential_carries[r],
        )
        for r in range(rows)
    ]
    return columns, new_carries


#: the result columns of :func:`diagnose_motors`
_RESULT_COLUMNS = (
    "state",
    "announced",
    "steady",
    "omega_model_rad_s",
    "current_model_a",
    "sensor_flags",
    "omega_judged_rad_s",
    "current_judged_a",
    "speed_band_rad_s",
    "current_band_a",
    "current_band_below_a",
    "input_activity_v",
    "depth",
    "omega_slow_judged_rad_s",
    "current_slow_judged_a",
    "slow_ready",
    "pairing_error_rad_s",
    "detection_level",
)

#: states the sequential test does not judge (persistence announces them)
_NOT_DIRECTIONS = (
    MotorState.F2_1,
    MotorState.F4_2,
    MotorState.STALLED,
    MotorState.SENSOR_FAULT,
    MotorState.NO_DATA,
)


def _bus_scale(
    rule: SteadyRule, bus_voltage_v: NDArray[np.float64] | None, shape: tuple[int, ...]
) -> NDArray[np.float64] | float:
    """What the rule's volts (``step_v``, ``activity_ref_v``) are multiplied by at each sample: the bus
    voltage over ``bus_ref_v`` where the rule scales with it and the sample has one, else 1."""
    if not rule.bus_ref_v > 0 or bus_voltage_v is None:
        return 1.0
    bus = np.broadcast_to(np.asarray(bus_voltage_v, dtype=float), shape)
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(bus) & (bus > 0), bus / rule.bus_ref_v, 1.0)


def _stall_split(
    profile: ThresholdProfile,
    noise: Sequence[BandNoise] | None,
    bus_voltage_v: NDArray[np.float64] | None,
    shape: tuple[int, ...],
) -> NDArray[np.float64] | None:
    """The F2.1/F4.2 split of each row where the profile scales it with the motor's typical current and
    the motor's noise has one; None: the profile's split everywhere."""
    if not (profile.stall_split_typical > 0 and noise):
        return None
    typical = np.array([n.current_typical_a for n in noise], dtype=float)
    if not np.isfinite(typical).any():
        return None
    fallback = np.broadcast_to(np.asarray(profile.stall_split(bus_voltage_v), dtype=float), shape)
    own = profile.stall_split_typical * typical[:, None]
    return np.where(np.isfinite(own), own, fallback)


def _noise_bands(
    profile: ThresholdProfile,
    noise: Sequence[BandNoise] | None,
    activity: NDArray[np.float64] | None,
    shape: tuple[int, ...],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The speed and current bands of each row: ``noise_bands`` times its motor's σ(activity)."""
    if noise is None or len(noise) != shape[0]:
        raise ValueError(f"profile {profile.name!r} needs each motor's noise (noise_bands); none given")
    a = np.zeros(shape) if activity is None else activity
    speed, current = np.empty(shape), np.empty(shape)
    for r, motor_noise in enumerate(noise):
        speed[r], current[r] = motor_noise.sigmas(a[r])
    return profile.noise_bands * speed, profile.noise_bands * current


def _steady_model(
    params: MotorParams,
    v: NDArray[np.float64],
    context: Mapping[str, NDArray[np.float64]] | None,
    counts: list[int],
) -> SteadyState:
    """The steady state at each sample: the base model for all rows at once, a model with fitted effects
    row by row (its context is per motor)."""
    if not params.effects:
        return steady_state(params, v)
    omega, current = np.full(v.shape, np.nan), np.full(v.shape, np.nan)
    for r, count in enumerate(counts):
        row_context = None if context is None else {k: np.asarray(x)[r, :count] for k, x in context.items()}
        model = predict_steady(params, v[r, :count], row_context)
        omega[r, :count], current[r, :count] = model.omega_rad_s, model.current_a
    return SteadyState(omega, current)


def _lowpass_residuals(
    tau_s: float,
    t: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    current_a: NDArray[np.float64],
    omega_pred: NDArray[np.float64],
    current_pred: NDArray[np.float64],
    carries: list[MotorCarry],
    counts: list[int],
) -> tuple[NDArray[np.float64], NDArray[np.float64], list[ResponseCarry]]:
    """The measurements as the tree judges them for the step and dynamic rules: the prediction plus the
    low-passed residual (no low-pass with ``tau_s`` = 0); the carries: speed residuals, then currents."""
    residual_carries = [c.speed_residual for c in carries] + [c.current_residual for c in carries]
    omega_seen, current_seen = omega_rad_s, current_a
    if tau_s > 0:
        # Commands are sampled, the motor sees every control cycle in between: the residual carries the
        # aliased control noise. Low-passing the residual (not the measurement) keeps a fault's lasting
        # offset and averages that noise, as the paper's moving average did for the current.
        rows = t.shape[0]
        residuals, residual_carries = first_order_responses(
            t,
            np.concatenate([omega_seen - omega_pred, current_seen - current_pred]),
            tau_s,
            residual_carries,
            counts * 2,
        )
        omega_seen = np.where(np.isfinite(omega_seen), omega_pred + residuals[:rows], np.nan)
        current_seen = np.where(np.isfinite(current_seen), current_pred + residuals[rows:], np.nan)
    return omega_seen, current_seen, residual_carries


def _current_sum_flags(table: TelemetryTable, profile: ThresholdProfile) -> NDArray[np.int16] | None:
    """CURRENT_SUM flags per row where the ESC currents' sum disagrees with the battery monitor; none where
    the table's calibration says the vehicle's ESCs and battery monitor are not related
    (``meta["esc_sum_checked"]`` False, :func:`~..model.vehicle.esc_sum_checked`)."""
    esc = table.get("esc_current_a")
    battery = table.get("battery_current_a")
    checked = table.meta.get("esc_sum_checked", True)
    if esc is None or battery is None or not checked or not np.isfinite(battery).any():
        return None
    order = np.argsort(table["time_s"], kind="stable")
    check = CurrentSumCheck(profile.plausibility, table.motors())
    mismatch = check.update(table["time_s"][order], table["motor"][order], esc[order], battery[order])
    flags = np.zeros(len(table), dtype=np.int16)
    flags[order[mismatch]] = SensorIssue.CURRENT_SUM
    return flags


def diagnose(
    table: TelemetryTable,
    params: MotorParams | dict[int, MotorParams],
    profile: ThresholdProfile,
    noise: Mapping[int, BandNoise] | None = None,
) -> TelemetryTable:
    """Diagnose every motor of a telemetry table; returns a table with :data:`DIAGNOSIS_COLUMNS` first.

    ``params`` is one motor model for all motors, or a model per motor number; ``noise`` each motor's
    noise (:mod:`.noise`), which a profile with ``noise_bands`` requires (a clear error names the first
    motor without it).
    """
    ordered = table.sorted_by_motor_time()
    if profile.noise_bands > 0:
        noise = require_noise(noise, [int(m) for m in ordered.motors()], profile.name)
    voltage = ordered.voltage_v()
    bus = ordered.get("bus_voltage_v")
    command = ordered.get("throttle")
    sensor_current = ordered.get("esc_current_a")
    sum_flags = _current_sum_flags(ordered, profile)
    n = len(ordered)
    out: dict[str, NDArray] = {
        "state": np.zeros(n, dtype=np.int8),
        "announced": np.zeros(n, dtype=np.int8),
        "steady": np.zeros(n, dtype=bool),
        "omega_model_rad_s": np.full(n, np.nan),
        "current_model_a": np.full(n, np.nan),
        "sensor_flags": np.zeros(n, dtype=np.int16),
        "omega_judged_rad_s": np.full(n, np.nan),
        "current_judged_a": np.full(n, np.nan),
        "speed_band_rad_s": np.full(n, np.nan),
        "current_band_a": np.full(n, np.nan),
        "current_band_below_a": np.full(n, np.nan),
        "input_activity_v": np.full(n, np.nan),
        "depth": np.ones(n),
        "omega_slow_judged_rad_s": np.full(n, np.nan),
        "current_slow_judged_a": np.full(n, np.nan),
        "slow_ready": np.zeros(n, dtype=bool),
        "pairing_error_rad_s": np.full(n, np.nan),
        "detection_level": np.full(n, np.nan),
    }
    motors = ordered["motor"]
    pairing = table.meta.get("pairing_s")

    def part(values: NDArray | None, sel: NDArray) -> NDArray | None:
        return None if values is None else values[sel]

    omega_all, current_all = ordered["omega_rad_s"], ordered["current_a"]
    for motor in ordered.motors():
        rows = np.flatnonzero(motors == motor)
        # Rows without a measurement (an ESC slot that repeated its last packet in a .tlog, a gap in a
        # log) are not samples: the live agent never sees them, and the core must not count them either
        # (its input activity scales with the sample interval, and a 10 Hz ESC in 50 Hz messages would
        # look like a 50 Hz one). They read NO_DATA and keep the state announced before them.
        measured = np.isfinite(omega_all[rows]) | np.isfinite(current_all[rows])
        sel, unmeasured = rows[measured], rows[~measured]
        if unmeasured.size:
            out["state"][unmeasured] = MotorState.NO_DATA
        if sel.size == 0:
            continue
        motor_params = params[motor] if isinstance(params, dict) else params
        context = None
        if motor_params.effects:
            context = {
                name: np.asarray(ordered[name][sel], dtype=float)
                for name in ordered.names
                if ordered[name].dtype.kind in "biuf"
            }
        cols, _ = diagnose_motor(
            motor_params,
            profile,
            ordered["time_s"][sel],
            voltage[sel],
            ordered["omega_rad_s"][sel],
            ordered["current_a"][sel],
            part(bus, sel),
            command=part(command, sel),
            sensor_current_a=part(sensor_current, sel),
            extra_flags=part(sum_flags, sel),
            context=context,
            pairing_s=None if pairing is None else float(pairing),
            noise=None if noise is None else noise.get(int(motor)),
        )
        for name, values in cols.items():
            out[name][sel] = values
        if unmeasured.size:
            before = np.searchsorted(sel, unmeasured) - 1  # the last measured row before each
            out["announced"][unmeasured] = np.where(
                before >= 0, out["announced"][sel[np.maximum(before, 0)]], MotorState.NORMAL
            )
    # Before any fault is announced: does the model describe this vehicle at all? Rows in the order the
    # live agent receives them (time, then motor number within one message).
    check = StreamingDiagnoser.vehicle_check_for(profile, vehicle_motors(table))
    order = np.lexsort((motors, ordered["time_s"]))
    vehicle_fit = np.zeros(n, dtype=np.int8)
    vehicle_fit[order] = check.update(
        ordered["time_s"][order], motors[order], omega_all[order], out["omega_model_rad_s"][order]
    )
    out["announced"] = apply_vehicle_fit(out["announced"], vehicle_fit)
    final = int(vehicle_fit[order[-1]]) if n else VehicleFit.FITS
    meta = dict(table.meta)
    meta["vehicle_check"] = {
        "verdict": final,
        "applies": check.applies,
        "departures": {int(m): float(d) for m, d in check.departures().items()},
    }
    result = {name: ordered[name] for name in ("time_s", "motor")}
    result.update(
        state=out["state"],
        announced=out["announced"],
        steady=out["steady"],
        omega_rad_s=ordered["omega_rad_s"],
        omega_model_rad_s=out["omega_model_rad_s"],
        current_a=ordered["current_a"],
        current_model_a=out["current_model_a"],
        voltage_v=voltage,
        sensor_flags=out["sensor_flags"],
        omega_judged_rad_s=out["omega_judged_rad_s"],
        current_judged_a=out["current_judged_a"],
        speed_band_rad_s=out["speed_band_rad_s"],
        current_band_a=out["current_band_a"],
        current_band_below_a=out["current_band_below_a"],
        input_activity_v=out["input_activity_v"],
        depth=out["depth"],
        omega_slow_judged_rad_s=out["omega_slow_judged_rad_s"],
        current_slow_judged_a=out["current_slow_judged_a"],
        slow_ready=out["slow_ready"],
        pairing_error_rad_s=out["pairing_error_rad_s"],
        detection_level=out["detection_level"],
        vehicle_fit=vehicle_fit,
    )
    for name in ordered.names:
        result.setdefault(name, ordered[name])
    return TelemetryTable(result, source=table.source, meta=meta)


def vehicle_motors(table: TelemetryTable) -> list[int]:
    """The vehicle's motor numbers: its frame where the log says, else the motors in the table; none for a
    bench file whose "motors" are different motor/propeller pairs (a dict in its meta)."""
    named = table.meta.get("motors")
    if isinstance(named, Mapping):
        return []
    if named:
        return [int(m) for m in named]
    return [int(m) for m in table.motors()]


class StreamingDiagnoser:
    """Sample-by-sample diagnosis for the live agent: the same :func:`diagnose_motor`, carried per motor."""

    def __init__(
        self,
        params: MotorParams | dict[int, MotorParams],
        profile: ThresholdProfile,
        motors: Sequence[int] = (),
        noise: Mapping[int, BandNoise] | None = None,
    ) -> None:
        self.params = params
        self.profile = profile
        self.noise = dict(noise or {})
        if profile.noise_bands > 0:  # refused now, not at the first sample in flight
            require_noise(self.noise, list(motors), profile.name)
        self.carries: dict[int, MotorCarry] = {}
        self.vehicle = self.vehicle_check_for(profile, motors)

    @staticmethod
    def vehicle_check_for(profile: ThresholdProfile, motors: Sequence[int]) -> VehicleCheck:
        """The vehicle check of ``motors`` (the vehicle's frame; none: the check does not apply)."""
        return VehicleCheck(profile.vehicle_check, list(motors), profile.stop_speed_rad_s)

    def judge_vehicle(
        self,
        time_s: NDArray[np.float64],
        motor: NDArray[np.integer],
        omega_rad_s: NDArray[np.float64],
        omega_model_rad_s: NDArray[np.float64],
        announced: NDArray[np.integer],
    ) -> tuple[NDArray[np.int8], NDArray[np.int8]]:
        """Rows of any motors in arrival order (time, then motor): the vehicle check's verdict at each and
        the announced states under it (as :func:`diagnose` does for a whole log)."""
        verdict = self.vehicle.update(time_s, motor, omega_rad_s, omega_model_rad_s)
        return verdict, apply_vehicle_fit(announced, verdict)

    def update(
        self,
        motor: int,
        time_s: float,
        voltage_v: float,
        omega_rad_s: float,
        current_a: float,
        bus_voltage_v: float | None = None,
        *,
        command: float | None = None,
        sensor_current_a: float | None = None,
        extra_flags: int = 0,
        context: Mapping[str, float] | None = None,
    ) -> dict[str, object]:
        """Diagnose one new sample of one motor; returns the result row (state codes as ints).

        Samples of all motors come in the order they arrive (time, then motor): the vehicle check runs
        across them as :func:`diagnose` runs it over a whole log. ``context`` gives the sample's other
        variables for a model with effects.
        """

        def one(x: float | None) -> NDArray[np.float64] | None:
            return None if x is None else np.array([x], dtype=float)

        cols = self.update_many(
            motor,
            np.array([time_s]),
            np.array([voltage_v]),
            np.array([omega_rad_s]),
            np.array([current_a]),
            one(bus_voltage_v),
            command=one(command),
            sensor_current_a=one(sensor_current_a),
            extra_flags=np.array([extra_flags], dtype=np.int16),
            context=None if context is None else {k: np.array([v], dtype=float) for k, v in context.items()},
        )
        cols["vehicle_fit"], cols["announced"] = self.judge_vehicle(
            np.array([time_s]),
            np.array([motor]),
            np.array([omega_rad_s], dtype=float),
            cols["omega_model_rad_s"],
            cols["announced"],
        )
        return {
            "time_s": time_s,
            "motor": motor,
            "omega_rad_s": omega_rad_s,
            "current_a": current_a,
            "voltage_v": voltage_v,
            **{k: v[0].item() for k, v in cols.items()},
        }

    def update_many(
        self,
        motor: int,
        time_s: NDArray[np.float64],
        voltage_v: NDArray[np.float64],
        omega_rad_s: NDArray[np.float64],
        current_a: NDArray[np.float64],
        bus_voltage_v: NDArray[np.float64] | None = None,
        *,
        command: NDArray[np.float64] | None = None,
        sensor_current_a: NDArray[np.float64] | None = None,
        extra_flags: NDArray[np.int16] | None = None,
        context: Mapping[str, NDArray[np.float64]] | None = None,
        pairing_s: float | None = None,
    ) -> dict[str, NDArray]:
        """Diagnose a few new samples of one motor at once (same results as one by one, less overhead).

        ``pairing_s``: how far apart the source pairs samples and commands (None: at the same instant;
        the live agent pairs each ESC packet with the command of its message).
        """
        motor_params = self.params[motor] if isinstance(self.params, dict) else self.params

        def arr(x: NDArray | None) -> NDArray[np.float64] | None:
            return None if x is None else np.asarray(x, dtype=float)

        cols, self.carries[motor] = diagnose_motor(
            motor_params,
            self.profile,
            np.asarray(time_s, dtype=float),
            np.asarray(voltage_v, dtype=float),
            np.asarray(omega_rad_s, dtype=float),
            np.asarray(current_a, dtype=float),
            arr(bus_voltage_v),
            self.carries.get(motor),
            command=arr(command),
            sensor_current_a=arr(sensor_current_a),
            extra_flags=extra_flags,
            context=context,
            pairing_s=pairing_s,
            noise=self._noise_of([motor])[0] if self.profile.noise_bands > 0 else None,
        )
        return cols

    def _noise_of(self, motors: list[int]) -> list[BandNoise]:
        return list(require_noise(self.noise, motors, self.profile.name).values())

    def update_motors(
        self, batches: Mapping[int, MotorBatch], pairing_s: float | None = None
    ) -> dict[int, dict[str, NDArray]]:
        """Diagnose a few new samples of several motors in one core call (:func:`diagnose_motors`): the
        same results as :meth:`update_many` motor by motor, for about the cost of one motor. Motors with
        different models, a model with fitted effects, or batches with different columns are diagnosed
        motor by motor."""
        groups: dict[tuple[int, tuple[bool, ...]], list[int]] = {}
        alone: list[list[int]] = []
        for motor, batch in batches.items():
            motor_params = self.params[motor] if isinstance(self.params, dict) else self.params
            if motor_params.effects:  # its context is per motor
                alone.append([motor])
                continue
            given = tuple(
                getattr(batch, name) is not None
                for name in ("bus_voltage_v", "command", "sensor_current_a", "extra_flags")
            )
            groups.setdefault((id(motor_params), given), []).append(motor)
        results: dict[int, dict[str, NDArray]] = {}
        for motors in [*groups.values(), *alone]:
            if len(motors) == 1:
                b = batches[motors[0]]
                results[motors[0]] = self.update_many(
                    motors[0],
                    b.time_s,
                    b.voltage_v,
                    b.omega_rad_s,
                    b.current_a,
                    b.bus_voltage_v,
                    command=b.command,
                    sensor_current_a=b.sensor_current_a,
                    extra_flags=b.extra_flags,
                    context=b.context,
                    pairing_s=pairing_s,
                )
                continue
            results.update(self._update_rows(motors, [batches[m] for m in motors], pairing_s))
        return {motor: results[motor] for motor in batches}

    def _update_rows(
        self, motors: list[int], batches: list[MotorBatch], pairing_s: float | None
    ) -> dict[int, dict[str, NDArray]]:
        counts = [np.asarray(b.time_s).size for b in batches]
        width = max(counts)

        def rows(name: str, dtype: type = float, pad: float = np.nan) -> NDArray | None:
            if getattr(batches[0], name) is None:
                return None
            out: NDArray = np.full((len(batches), width), pad, dtype=dtype)
            for r, (batch, count) in enumerate(zip(batches, counts)):
                out[r, :count] = getattr(batch, name)
            return out

        time_s = rows("time_s")
        assert time_s is not None
        for r, count in enumerate(counts):  # padding: the row's last time (no interval), no values
            time_s[r, count:] = time_s[r, count - 1] if count else 0.0
        motor_params = self.params[motors[0]] if isinstance(self.params, dict) else self.params
        cols, carries = diagnose_motors(
            motor_params,
            self.profile,
            time_s,
            rows("voltage_v"),  # type: ignore[arg-type]
            rows("omega_rad_s"),  # type: ignore[arg-type]
            rows("current_a"),  # type: ignore[arg-type]
            rows("bus_voltage_v"),
            [self.carries.get(m) for m in motors],
            counts,
            command=rows("command"),
            sensor_current_a=rows("sensor_current_a"),
            extra_flags=rows("extra_flags", np.int16, 0),
            pairing_s=pairing_s,
            noise=self._noise_of(motors) if self.profile.noise_bands > 0 else None,
        )
        results = {}
        for r, (motor, count, carry) in enumerate(zip(motors, counts, carries)):
            self.carries[motor] = carry
            results[motor] = {name: values[r, :count] for name, values in cols.items()}
        return results

    def announced(self, motor: int) -> MotorState:
        carry = self.carries.get(motor)
        return MotorState(carry.persistence.announced if carry else MotorState.NORMAL)
