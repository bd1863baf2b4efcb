"""The diagnosis pipeline for one motor: plausibility → model → steady rule → tree → persistence.

:func:`diagnose_motor` is the single implementation. Replay calls it once per motor with whole arrays;
the live agent calls it with each new sample and the carry from the previous call (see
:class:`StreamingDiagnoser`). Both therefore announce exactly the same states.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..model.balance import BalanceCarry, balance_deviations
from ..model.dynamics import ResponseCarry, first_order_response, time_constant_s
from ..model.equations import current_from_speed, steady_state
from ..model.params import MotorParams
from ..model.predict import predict_steady
from ..telemetry.table import TelemetryTable
from .pairing import PairingCarry, pairing_error_rad_s
from .persistence import PersistenceCarry, announce
from .plausibility import (
    CURRENT_UNTRUSTED,
    CurrentSumCheck,
    PlausibilityCarry,
    SensorIssue,
    check_motor,
)
from .profile import ThresholdProfile
from .stall import StallCarry, stall_mean
from .states import MotorState
from .steady import SteadyCarry, steady_mask, warm_mask
from .tree import agreeing_departures, classify_depth
from .vehicle_check import VehicleCheck, VehicleFit, apply_vehicle_fit

__all__ = ["DIAGNOSIS_COLUMNS", "MotorCarry", "StreamingDiagnoser", "diagnose", "diagnose_motor"]

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
    (:mod:`.pairing`).
    """
    carry = carry or MotorCarry()
    t = np.asarray(time_s, dtype=float)
    v = np.asarray(voltage_v, dtype=float)
    rule = profile.steady
    balance_carry = carry.balance
    stall_carry = carry.stall
    slow_carries = (carry.slow_omega, carry.slow_current)
    slow: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]] | None = None  # the slow look
    activity: NDArray[np.float64] | None = None
    judged_v = v
    if rule.kind == "balance":
        omega_in = np.asarray(omega_rad_s, dtype=float)
        bal, balance_carry = balance_deviations(
            params,
            t,
            v,
            omega_in,
            np.asarray(current_a, dtype=float),
            rule.residual_tau_s,
            rule.activity_tau_s,
            carry.balance,
            activity_ref_v=rule.activity_ref_v,
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
        stall_current, stall_carry = stall_mean(np.asarray(current_a, dtype=float), stalled_like, carry.stall)
        current_seen = np.where(stalled_like, stall_current, current_pred + bal.delta_current_a)
        current_seen = np.where(np.isfinite(np.asarray(current_a, dtype=float)), current_seen, np.nan)
        # An input step (larger than step_v plus a few times the input's zigzag, which in gusty air
        # is no step at all) puts two operating points into the low-passes: judge after settle_s. A new
        # stream (the first sample, or after a gap) waits until the activity is known too.
        step_v = rule.step_v + 3.0 * np.nan_to_num(bal.zigzag_v)  # the jumps as measured, not scaled
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
        warm, steady_carry = warm_mask(
            t,
            v,
            rule.settle_s,
            profile.persistence.max_gap_s,
            step_v,
            carry.steady,
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
            slow_w, slow_carry_w = first_order_response(t, bal.delta_omega_rad_s, slow_tau, carry.slow_omega)
            slow_i, slow_carry_i = first_order_response(t, bal.delta_current_a, slow_tau, carry.slow_current)
            # only where the low-pass is not already lengthened by the activity (calm air): in gusts the
            # fast look averages long already, and a slower one would hold every gust's upset for seconds
            calm = bal.tau_s <= rule.residual_tau_s
            slow = (slow_w, slow_i, slow_warm & steady & ~stalled_like & calm)
            slow_carries = (slow_carry_w, slow_carry_i)
        response_carry = carry.response
        speed_carry, current_carry = carry.speed_residual, carry.current_residual
        omega_expected = omega_pred
    else:
        model = predict_steady(params, v, context) if params.effects else steady_state(params, v)
        if rule.kind == "dynamic" and params.J_kg_m2 is not None:
            tau = time_constant_s(params, model.omega_rad_s)
            omega_pred, response_carry = first_order_response(t, model.omega_rad_s, tau, carry.response)
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
            held, steady_carry = steady_mask(rule, t, v, carry.steady)
            steady = (
                held
                & (np.abs(omega_pred - model.omega_rad_s) <= lag * profile.speed_band_rad_s)
                & (np.abs(current_pred - model.current_a) <= lag * profile.current_halfwidth_a(v))
            )
        else:
            omega_pred, current_pred = model.omega_rad_s, model.current_a
            steady, steady_carry = steady_mask(rule, t, v, carry.steady)
            response_carry = carry.response
        omega_seen, current_seen, speed_carry, current_carry = _lowpass_residuals(
            rule.residual_tau_s, t, omega_rad_s, current_a, omega_pred, current_pred, carry
        )
        omega_expected = np.minimum(omega_pred, model.omega_rad_s)
    reported = current_a if sensor_current_a is None else sensor_current_a
    flags, plausibility_carry = check_motor(
        profile.plausibility, t, command, reported, omega_rad_s, carry.plausibility
    )
    if extra_flags is not None:
        flags = flags | extra_flags
    speed_band = profile.speed_band(activity)
    pairing_error = np.full(t.shape, np.nan)
    pairing_carry = carry.pairing
    if rule.kind == "balance" and pairing_s:
        # a command paired loosely with its sample: the current is not used where the voltage error it
        # could cause is a sizeable part of the speed band, nothing is judged where it is a sizeable part
        # of the speed-only band (diagnosis/pairing.py)
        pairing_error, pairing_carry = pairing_error_rad_s(
            params, t, v, omega_pred, pairing_s, bal.tau_s, carry.pairing
        )
        plaus = profile.plausibility
        flags = np.where(
            pairing_error > plaus.pairing_current_share * np.asarray(speed_band, dtype=float),
            flags | SensorIssue.CURRENT_UNPAIRED,
            flags,
        ).astype(np.int16)
        speed_only_band = profile.speed_only_band(speed_band, omega_pred)
        steady = steady & ~(pairing_error > plaus.pairing_speed_share * speed_only_band)
    current_trusted = ((flags & CURRENT_UNTRUSTED) == 0) & np.isfinite(current_a)
    current_band = profile.current_halfwidth_a(judged_v, activity)
    current_band_below = profile.current_halfwidth_a(judged_v, activity, below=True)
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
    eligible = (steady | np.isin(state, _TRANSIENT_OK)) & (state != MotorState.NO_DATA)
    if command is not None and profile.min_command > 0:
        idle = np.asarray(command, dtype=float) < profile.min_command  # idle and spin-up: not judged
        eligible &= ~idle
        steady = steady & ~idle
    depth[state == MotorState.SENSOR_FAULT] = 1.0
    max_depth = profile.persistence.max_depth
    announced, persistence_carry = announce(
        profile.persistence.hold_s(),
        t,
        state,
        eligible,
        carry.persistence,
        profile.persistence.max_gap_s,
        hold_per_activity_s=profile.persistence.hold_per_activity_s(),
        activity=activity,
        rate=np.minimum(depth, max_depth) if max_depth > 1 else None,
    )
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
    }
    new_carry = MotorCarry(
        steady=steady_carry,
        response=response_carry,
        speed_residual=speed_carry,
        current_residual=current_carry,
        plausibility=plausibility_carry,
        persistence=persistence_carry,
        balance=balance_carry,
        stall=stall_carry,
        slow_omega=slow_carries[0],
        slow_current=slow_carries[1],
        pairing=pairing_carry,
    )
    return columns, new_carry


def _lowpass_residuals(
    tau_s: float,
    t: NDArray[np.float64],
    omega_rad_s: NDArray[np.float64],
    current_a: NDArray[np.float64],
    omega_pred: NDArray[np.float64],
    current_pred: NDArray[np.float64],
    carry: MotorCarry,
) -> tuple[NDArray[np.float64], NDArray[np.float64], ResponseCarry, ResponseCarry]:
    """The measurements as the tree judges them for the step and dynamic rules: the prediction plus the
    low-passed residual (no low-pass with ``tau_s`` = 0)."""
    speed_carry, current_carry = carry.speed_residual, carry.current_residual
    omega_seen = np.asarray(omega_rad_s, dtype=float)
    current_seen = np.asarray(current_a, dtype=float)
    if tau_s > 0:
        # Commands are sampled, the motor sees every control cycle in between: the residual carries the
        # aliased control noise. Low-passing the residual (not the measurement) keeps a fault's lasting
        # offset and averages that noise, as the paper's moving average did for the current.
        speed_res, speed_carry = first_order_response(t, omega_seen - omega_pred, tau_s, speed_carry)
        current_res, current_carry = first_order_response(
            t, current_seen - current_pred, tau_s, current_carry
        )
        omega_seen = np.where(np.isfinite(omega_seen), omega_pred + speed_res, np.nan)
        current_seen = np.where(np.isfinite(current_seen), current_pred + current_res, np.nan)
    return omega_seen, current_seen, speed_carry, current_carry


def _current_sum_flags(table: TelemetryTable, profile: ThresholdProfile) -> NDArray[np.int16] | None:
    """CURRENT_SUM flags per row where the ESC currents' sum disagrees with the battery monitor."""
    esc = table.get("esc_current_a")
    battery = table.get("battery_current_a")
    if esc is None or battery is None or not np.isfinite(battery).any():
        return None
    order = np.argsort(table["time_s"], kind="stable")
    check = CurrentSumCheck(profile.plausibility, table.motors())
    mismatch = check.update(table["time_s"][order], table["motor"][order], esc[order], battery[order])
    flags = np.zeros(len(table), dtype=np.int16)
    flags[order[mismatch]] = SensorIssue.CURRENT_SUM
    return flags


def diagnose(
    table: TelemetryTable, params: MotorParams | dict[int, MotorParams], profile: ThresholdProfile
) -> TelemetryTable:
    """Diagnose every motor of a telemetry table; returns a table with :data:`DIAGNOSIS_COLUMNS` first.

    ``params`` is one motor model for all motors, or a model per motor number.
    """
    ordered = table.sorted_by_motor_time()
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
    ) -> None:
        self.params = params
        self.profile = profile
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
        )
        return cols

    def announced(self, motor: int) -> MotorState:
        carry = self.carries.get(motor)
        return MotorState(carry.persistence.announced if carry else MotorState.NORMAL)
