"""The diagnosis pipeline: a loop over the profile's rules (:attr:`.profile.ThresholdProfile.rules`:
comparison with the model → sensors → bands → pairing → tree → [vehicle stage] → torque balance → slow
look → judged → sequential test → persistence; :mod:`.rules`).

The vehicle stage (:mod:`.siblings`) is the one step that looks across motors: before the first rule
that reads the other motors' values (the torque judged against its siblings'; with the profile's
``conditions_siblings``, the bands, which then come before it), every motor's call is run up to it
(:func:`start_motors`, a :class:`StartedCall`), the siblings' references are worked out over all of them
in the order the samples arrive (:func:`run_vehicle_stage`), and then each call finishes. It runs only
where a motor's noise was measured against its siblings or the profile grows its bands as they run
(:func:`vehicle_stage`).

:func:`start_motors` with :meth:`StartedCall.finish` is the single implementation (:func:`diagnose_motors`
runs both, without the stage): rows of samples, one row per motor, each with the carry from its previous
call; every rule keeps its state in that carry and looks back only, so a split of a motor's samples into
calls gives the same states (but see :func:`~..model.dynamics.first_order_response` on a call that ends
on a lost sample). Replay (:func:`diagnose`) starts one call per motor with the whole log, runs the
vehicle stage over them and finishes each; the live agent does the same with every motor's few new
samples at once (see :class:`StreamingDiagnoser`), the same code for one sample or a million. Both
therefore announce the same states, where the agent's batches come in the order the samples arrive.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._arrays import broadcast_to, part_bounds
from ..model.params import MotorParams, MotorRows, same_type
from ..telemetry.table import TelemetryTable
from .noise import BandNoise, require_noise
from .plausibility import CurrentSumCheck, SensorIssue
from .prediction import MIN_COVARIANCE_SAMPLES, SiblingPrediction
from .profile import ThresholdProfile
from .rules.base import Frame, Rule
from .siblings import PREDICTED, SPREAD, STAGE_QUANTITIES, STAGE_SPREADS, VehicleStage
from .states import MotorState
from .vehicle_check import VehicleCheck, VehicleFit, apply_vehicle_fit

__all__ = [
    "BATCH_COLUMNS",
    "DIAGNOSIS_COLUMNS",
    "RESIDUAL_COLUMNS",
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


@dataclass(frozen=True)
class MotorCarry:
    """Everything the pipeline remembers about one motor between calls: each rule's own carry, by the
    rule's name (:attr:`.profile.ThresholdProfile.rules`)."""

    rules: Mapping[str, Any] = field(default_factory=dict)

    def of(self, rule: Rule) -> Any:
        """``rule``'s carry (its new one before the motor's first sample)."""
        carry = self.rules.get(rule.name)
        return rule.new_carry() if carry is None else carry

    @property
    def announced(self) -> MotorState:
        """The state announced after the last sample."""
        persistence = self.rules.get("persistence")
        return MotorState(persistence.announced if persistence is not None else MotorState.NORMAL)


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
    #: each sample's pairing with its command [s] (the table's ``pairing_s``; None: of its own instant)
    pairing_s: NDArray[np.float64] | None = None
    #: how far each sample's input went beyond the two held inputs since the sample before [V] (the
    #: table's ``input_excursion_v``; None: not at all, the command of each sample's own instant)
    input_excursion_v: NDArray[np.float64] | None = None
    #: each sample's held command's age [s] (the table's ``command_age_s``; None: not known, its pairing
    #: stands in: diagnosis/stall.py, "A stall the paired command may predate")
    command_age_s: NDArray[np.float64] | None = None

    @classmethod
    def of_columns(cls, columns: Mapping[str, NDArray[Any]], rows: NDArray[np.intp]) -> MotorBatch:
        """The samples ``rows`` of one motor in a telemetry table's ``columns`` (by name, as calibrated:
        :data:`BATCH_COLUMNS`; those absent None), with no extra sensor flags."""
        fields: dict[str, Any] = {
            name: np.asarray(columns[column], dtype=float)[rows]
            for name, column in BATCH_COLUMNS.items()
            if column in columns
        }
        return cls(**fields, extra_flags=np.zeros(np.size(rows), dtype=np.int16))


#: :class:`MotorBatch`'s inputs and the telemetry table's columns they are (the live agent's batches, and
#: :meth:`MotorBatch.of_columns`)
BATCH_COLUMNS = {
    "time_s": "time_s",
    "voltage_v": "voltage_v",
    "omega_rad_s": "omega_rad_s",
    "current_a": "current_a",
    "bus_voltage_v": "bus_voltage_v",
    "command": "throttle",
    "sensor_current_a": "esc_current_a",
    "pairing_s": "pairing_s",
    "input_excursion_v": "input_excursion_v",
    "command_age_s": "command_age_s",
}

#: :class:`MotorBatch`'s float columns that :meth:`StreamingDiagnoser.update_rows` takes as rows
_ROW_INPUTS = (
    "time_s",
    "voltage_v",
    "omega_rad_s",
    "current_a",
    "bus_voltage_v",
    "command",
    "sensor_current_a",
    "pairing_s",
    "input_excursion_v",
    "command_age_s",
)

#: a source's pairing of samples with commands [s]: one number for all samples, or one per sample
Pairing = float | NDArray[np.float64] | None


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
    pairing_s: Pairing = None,
    input_excursion_v: NDArray[np.float64] | None = None,
    noise: BandNoise | None = None,
    command_age_s: NDArray[np.float64] | None = None,
) -> tuple[dict[str, NDArray], MotorCarry]:
    """Diagnose one motor's samples (increasing time); returns result columns and the new carry.

    ``current_a`` is the motor current; ``sensor_current_a`` the current as the sensor reported it (the
    ESC input current), checked for plausibility; ``command`` the normalised motor command (0..1);
    ``extra_flags`` :class:`SensorIssue` flags found across motors (the currents' sum); ``context`` the
    samples' other columns (temperatures, altitude...), which a model with fitted effects
    (``params.effects``) reads; the base model ignores it, and so does the balance rule, which checks the
    base equations (a fitted effect's extra terms are not yet part of its balances). ``pairing_s`` is how
    far apart the source may have paired each sample and its command [s], which the balance rule weighs
    (:mod:`.pairing`): one value per sample (a log table's ``pairing_s`` column, the live agent's samples'),
    or one number for all (None or 0: the command of the sample's own instant). ``input_excursion_v``
    how far each sample's input went beyond the two held inputs since the sample before [V] (a log
    table's column of that name, telemetry/assemble.py), which the balance rule and its pairing guard
    weigh where the profile asks them to (``steady.excursion_weight``, ``excursion_pairing_weight``; off
    in the shipped profiles; None: not at all), and one larger than a step restarts its wait after a step
    in every profile (:mod:`.rules.balance`). ``command_age_s``: each sample's held command's age (a log
    table's column of that name; None: not known, ``pairing_s`` stands in), which tells a stall from a
    command the log did not show (:mod:`.stall`). ``noise``: the motor's own noise, which a profile with ``noise_bands`` sets its
    bands from (:mod:`.noise`). A motor alone has no siblings (:mod:`.siblings`): :func:`start_motor`
    and :meth:`StartedCall.finish` with the vehicle stage between them judge the torque against them.
    """
    cols, (new,) = start_motor(
        params,
        profile,
        time_s,
        voltage_v,
        omega_rad_s,
        current_a,
        bus_voltage_v,
        carry,
        command=command,
        sensor_current_a=sensor_current_a,
        extra_flags=extra_flags,
        context=context,
        pairing_s=pairing_s,
        input_excursion_v=input_excursion_v,
        noise=noise,
        command_age_s=command_age_s,
    ).finish()
    return {name: values[0] for name, values in cols.items()}, new


def start_motor(
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
    pairing_s: Pairing = None,
    input_excursion_v: NDArray[np.float64] | None = None,
    noise: BandNoise | None = None,
    command_age_s: NDArray[np.float64] | None = None,
) -> StartedCall:
    """:func:`diagnose_motor` (the same arguments) run up to the vehicle stage: a call of one row."""

    def row(x: NDArray | None, dtype: type = float) -> NDArray | None:
        return None if x is None else np.asarray(x, dtype=dtype).reshape(1, -1)

    return start_motors(
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
        pairing_s=pairing_s if pairing_s is None or np.ndim(pairing_s) == 0 else row(np.asarray(pairing_s)),
        input_excursion_v=row(input_excursion_v),
        noise=None if noise is None else [noise],
        command_age_s=row(command_age_s),
    )


def vehicle_stage(
    motors: Sequence[int], noise: Mapping[int, BandNoise] | None, profile: ThresholdProfile
) -> VehicleStage | None:
    """The vehicle stage of ``motors`` (:mod:`.siblings`), with what it takes across them: the torque
    where a motor is judged against its siblings' (its noise was measured so), the deviations' live
    noise where ``profile`` grows its bands as the siblings run (``conditions_siblings``), each motor's slow
    torque average where its slow look is bounded by the siblings' spread (``torque_slow_siblings``), the
    voltage residual and each motor's slow voltage average's mean square where an open transistor is read
    in them (``voltage_slow_siblings``, :mod:`.rules.voltage`) and the noise has the voltage's, the speed
    deviation where it judges the speed against the siblings' prediction (``speed_against_siblings``) and
    the noise gives their covariance (:mod:`.prediction`; a sibling departing by more than the sequential
    test's reference σ is left out of the others'); None: none of them, no stage. Motors not in
    ``motors`` join the stage when their samples come (:mod:`.siblings`)."""
    quantities: list[str] = []
    prediction = None
    if noise:
        if any(n.torque_vs_siblings is not None for n in noise.values()):
            quantities.append("torque_residual_nm")
        if profile.grows_as_siblings:
            quantities += ["live_z2_speed", "live_z2_current"]
        if profile.slow_as_siblings:
            quantities += ["slow_ms_speed", "slow_ms_current"]
        if profile.torque_slow_as_siblings and "torque_residual_nm" in quantities:
            quantities.append("torque_slow_raw_nm")
        if profile.voltage_slow_as_siblings and any(n.voltage is not None for n in noise.values()):
            # the voltage against its siblings, averaged slowly (rules/equations.py), where an open
            # transistor is read in it (rules/voltage.py; identification's profile does, and measures its
            # noise so): a profile without that look leaves the voltage to each motor
            quantities += ["voltage_residual_v", "slow_ms_voltage"]
        if profile.speed_against_siblings > 0:
            prediction = SiblingPrediction.of(
                {m: n.speed_covariance for m, n in noise.items()},
                {m: n.speed_lagged_covariance for m, n in noise.items()},
                profile.detection.reference_sigmas,
            )
            if prediction is not None:
                quantities.append(PREDICTED)
            else:
                _warn_without_prediction(profile)
    if not quantities:
        return None
    # the balances against siblings at the motor's own speed, within the margin the model is trusted beyond
    # its identified speeds (siblings.py, "Beyond the identified speeds")
    alike = {q: profile.range_margin for q in RESIDUAL_QUANTITIES} if profile.range_margin > 0 else {}
    # the siblings' torque spread, where the bands grow with it (rules/bands.py), and their slow torque
    # averages' spread, where the torque's slow look is bounded by it (rules/equations.py)
    spreads: tuple[str, ...] = ("torque_residual_nm",) if profile.torque_siblings_spread > 0 else ()
    spreads += ("torque_slow_raw_nm",)
    return VehicleStage(
        [int(m) for m in motors],
        tuple(quantities),
        alike=alike,
        prediction=prediction,
        spreads=tuple(s for s in spreads if s in quantities),
    )


#: the stage's quantities taken at the motor's own speed beyond the identified ones (the balances' residuals
#: and the torque's slow average: siblings.py, "Beyond the identified speeds")
RESIDUAL_QUANTITIES = ("torque_residual_nm", "torque_slow_raw_nm", "voltage_residual_v")


def _warn_without_prediction(profile: ThresholdProfile) -> None:
    """Say once (Python's warnings show each place once) that a profile judging the speed against the
    siblings' prediction has a vehicle file without what the prediction needs, and how to get it."""
    tau_s = float(getattr(profile.steady, "residual_tau_s", 0.0))
    warnings.warn(
        f"profile {profile.name!r} judges the speed against its siblings' prediction "
        "(speed_against_siblings), and the vehicle's noise has no noise.N.speed_covariance_M and "
        "speed_lagged_covariance_M for three or more motors (a file written before they were measured, or "
        "an identification flight too short or reporting too slowly to measure them: each motor needs "
        f"{MIN_COVARIANCE_SAMPLES} judged samples with every sibling's report of the {tau_s:g} s before): "
        "each motor's speed is judged on its own; `mav-motor-health fit FLIGHT_LOG --out vehicle.toml` "
        "measures them where the flight allows",
        UserWarning,
        stacklevel=3,
    )


#: what the vehicle stage gives (its result's key) and the frame field each goes to
_STAGE_OUTPUTS = STAGE_QUANTITIES + tuple((name + SPREAD, into) for name, into in STAGE_SPREADS)


def run_vehicle_stage(
    stage: VehicleStage | None, calls: Sequence[tuple[Sequence[int], StartedCall]]
) -> list[tuple[dict[str, NDArray], list[MotorCarry]]]:
    """Finish started calls of a vehicle's motors (each with its rows' motor numbers) with the vehicle
    stage between (:mod:`.siblings`): the siblings' reference of every row for each quantity the calls
    give (:data:`~.siblings.STAGE_QUANTITIES`), from every call's samples together in the order they
    arrive and the latest ones carried in ``stage`` (None: no stage, the calls finished without one)."""
    staged = [(motors, call) for motors, call in calls if stage is not None and call.feeds_siblings]
    references: dict[int, dict[str, NDArray[np.float64]]] = {id(call): {} for _, call in staged}
    if staged:
        assert stage is not None
        frames = [call.frame for _, call in staged]
        width = max(f.shape[1] for f in frames if f is not None)

        def stacked(name: str | Callable[[Frame], Any], fill: float | bool = np.nan) -> NDArray[Any]:
            """A frame field (or what ``name`` gives of each frame) of every call, rows stacked."""
            out = np.full((sum(f.shape[0] for f in frames if f is not None), width), fill)
            r = 0
            for f in frames:
                assert f is not None
                values = getattr(f, name) if isinstance(name, str) else name(f)
                if values is not None:
                    out[r : r + f.shape[0], : f.shape[1]] = values
                r += f.shape[0]
            return out

        counts = [k for f in frames if f is not None for k in f.counts]
        every = [int(m) for motors, _ in staged for m in motors]
        given = {
            name: stacked(name)
            for name, _ in STAGE_QUANTITIES
            if name in stage.quantities and any(getattr(f, name) is not None for f in frames)
        }
        if "torque_residual_nm" in given:
            # a sibling in its own step's transient is no reference for the others' torque (siblings.py,
            # "A sibling in its own step's transient")
            in_transient = stacked(_torque_transient, False)
            given["torque_residual_nm"] = np.where(in_transient, np.nan, given["torque_residual_nm"])
        found = stage.references(
            every,
            stacked("time_s"),
            given,
            counts,
            stacked("low_pass_s"),
            # each sample's model speed, and whether its motor's model was identified there
            stacked("omega_model_rad_s") if stage.alike or stage.prediction else None,
            stacked("within_identified_speeds", False) if stage.alike or stage.prediction else None,
        )
        for name, into in _STAGE_OUTPUTS:
            if name not in found:
                continue
            r = 0
            for _, call in staged:
                assert call.frame is not None
                rows, n = call.frame.shape
                references[id(call)][into] = found[name][r : r + rows, :n]
                r += rows
    return [call.finish(references.get(id(call))) for _, call in calls]


def _torque_transient(frame: Frame) -> NDArray[np.bool_]:
    """Where each row's motor waits after its own input step (within the rule's ``settle_s``) and its own
    torque balance departs from its offset by more than the band it is judged in there: ``equation_bands``
    (else ``noise_bands``) times its torque σ at the sample's activity and pairing, widened after the step as identification
    measured (not grown by the air); such a torque is the step's transient, no reference for its siblings
    (siblings.py, "A sibling in its own step's transient"). Nowhere on a motor whose noise has no torque's."""
    settle_s = float(getattr(frame.profile.steady, "settle_s", 0.0))
    if (
        frame.noise is None
        or frame.torque_residual_nm is None
        or frame.since_step_s is None
        or not settle_s > 0
        or not frame.profile.noise_bands > 0
    ):
        return np.zeros(frame.shape, dtype=bool)
    activity = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
    z = frame.noise_as_rows().own_torque_z(frame.torque_residual_nm, activity, frame.pairing_error_rad_s)
    after = frame.after_step_factor
    with np.errstate(invalid="ignore"):
        if after is not None:  # (NaN: the widening there not measured; the band as settled)
            z = z / np.where(np.isfinite(after), after, 1.0)
        bands = frame.profile.equation_bands or frame.profile.noise_bands
        return (frame.since_step_s < settle_s) & (np.abs(z) > bands)


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
    pairing_s: Pairing = None,
    input_excursion_v: NDArray[np.float64] | None = None,
    noise: Sequence[BandNoise] | None = None,
    command_age_s: NDArray[np.float64] | None = None,
) -> tuple[dict[str, NDArray], list[MotorCarry]]:
    """:func:`diagnose_motor` for several motors of one model at once: one row of samples per motor.

    The arguments are 2-D (motors × samples), each row one motor's samples in increasing time, with its
    own carry in ``given_carries`` (None: a new motor); ``pairing_s`` one number or 2-D like the samples. Rows may hold different numbers of samples
    (``lengths``; None: all of the columns): the rest of a row is padding after its samples, which cannot
    change their results (every rule looks back only) and whose results mean nothing. Every step runs once for all rows, so a few
    samples of six motors cost about what a few samples of one did. Returns 2-D result columns and the
    rows' new carries; each row's results are those :func:`diagnose_motor` gives for that motor alone.
    ``noise``: each row's motor noise, required by a profile with ``noise_bands``.

    Without the vehicle stage in between (:class:`StartedCall`), a torque judged against its siblings is
    not judged (:mod:`.siblings`): :func:`diagnose` and :class:`StreamingDiagnoser` run the stage.
    """
    return start_motors(
        params,
        profile,
        time_s,
        voltage_v,
        omega_rad_s,
        current_a,
        bus_voltage_v,
        given_carries,
        lengths,
        command=command,
        sensor_current_a=sensor_current_a,
        extra_flags=extra_flags,
        context=context,
        pairing_s=pairing_s,
        input_excursion_v=input_excursion_v,
        noise=noise,
        command_age_s=command_age_s,
    ).finish()


@dataclass
class StartedCall:
    """A core call run up to the rule that reads the motors' siblings (:mod:`.siblings`): its frame, the
    carries given, the rules' new carries so far, and the rules still to run. :meth:`finish` runs them
    (with the siblings' torque reference, where the vehicle stage gives one)."""

    frame: Frame | None
    carries: list[MotorCarry]
    new: list[dict[str, Any]]
    rest: tuple[Rule, ...]

    @property
    def feeds_siblings(self) -> bool:
        """Whether the call has samples and a rule still to run reads the siblings' reference (the
        vehicle stage takes its rows)."""
        return self.frame is not None and any(rule.reads_siblings for rule in self.rest)

    def finish(
        self, references: Mapping[str, NDArray[np.float64]] | None = None
    ) -> tuple[dict[str, NDArray], list[MotorCarry]]:
        """The rest of the rules, with the siblings' references (2-D like the frame, by the frame field
        of :data:`~.siblings.STAGE_QUANTITIES` each goes to; None or missing: none); returns the call's
        result columns and the rows' new carries."""
        frame = self.frame
        if frame is None:
            return {name: np.zeros((len(self.carries), 0)) for name in _RESULT_COLUMNS}, self.carries
        for _, into in _STAGE_OUTPUTS:
            setattr(frame, into, None if references is None else references.get(into))
        _run_rules(frame, self.rest, self.carries, self.new)
        return _result_columns(frame), [MotorCarry(rules) for rules in self.new]


def start_motors(
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
    pairing_s: Pairing = None,
    input_excursion_v: NDArray[np.float64] | None = None,
    noise: Sequence[BandNoise] | None = None,
    command_age_s: NDArray[np.float64] | None = None,
) -> StartedCall:
    """:func:`diagnose_motors` (the same arguments) run up to the vehicle stage (:class:`StartedCall`)."""
    t = np.asarray(time_s, dtype=float)
    rows, n = t.shape
    carries = [c or MotorCarry() for c in given_carries or [None] * rows]
    counts = [n] * rows if lengths is None else [int(k) for k in lengths]
    if n == 0:
        return StartedCall(None, carries, [], ())

    def floats(x: NDArray | None) -> NDArray[np.float64] | None:
        return None if x is None else np.asarray(x, dtype=float)

    frame = Frame(
        params,
        profile,
        t,
        np.asarray(voltage_v, dtype=float),
        np.asarray(omega_rad_s, dtype=float),
        np.asarray(current_a, dtype=float),
        counts,
        ragged=None if lengths is None else counts,  # rows of different lengths (None: all full)
        bus_voltage_v=bus_voltage_v,
        command=floats(command),
        sensor_current_a=floats(sensor_current_a),
        extra_flags=extra_flags,
        context=context,
        pairing_s=pairing_s
        if pairing_s is None or np.ndim(pairing_s) == 0
        else floats(np.asarray(pairing_s)),
        input_excursion_v=floats(input_excursion_v),
        command_age_s=floats(command_age_s),
        noise=noise,
    )
    rules = profile.rules
    stage = next((i for i, rule in enumerate(rules) if rule.reads_siblings), len(rules))
    new: list[dict[str, Any]] = [{} for _ in range(rows)]
    _run_rules(frame, rules[:stage], carries, new)
    return StartedCall(frame, carries, new, rules[stage:])


def _run_rules(
    frame: Frame, rules: Sequence[Rule], carries: list[MotorCarry], new: list[dict[str, Any]]
) -> None:
    """Advance ``frame`` by ``rules`` in order, each row's new carries into ``new``."""
    for rule in rules:
        judged = rule.judge(frame, [c.of(rule) for c in carries])
        for r, carry in enumerate(judged):
            new[r][rule.name] = carry


def _result_columns(frame: Frame) -> dict[str, NDArray]:
    """The frame as :data:`_RESULT_COLUMNS` (NaN or False where a rule did not run)."""
    shape = frame.shape
    slow = frame.slow

    def nan_unless(values: NDArray | None) -> NDArray:
        return np.full(shape, np.nan) if values is None else values

    return {
        "state": frame.state,
        "announced": frame.announced,
        "steady": frame.steady,
        "omega_model_rad_s": frame.omega_model_rad_s,
        "current_model_a": frame.current_model_a,
        "sensor_flags": frame.sensor_flags,
        "omega_judged_rad_s": frame.omega_judged_rad_s,
        "current_judged_a": frame.current_judged_a,
        "speed_band_rad_s": broadcast_to(frame.speed_band_rad_s, shape).astype(float),
        "current_band_a": frame.current_band_a,
        "current_band_below_a": frame.current_band_below_a,
        "input_activity_v": nan_unless(frame.activity_v),
        "depth": frame.depth,
        "omega_slow_judged_rad_s": nan_unless(
            None if slow is None else frame.omega_model_rad_s + slow.delta_omega_rad_s
        ),
        "current_slow_judged_a": nan_unless(
            None if slow is None else frame.current_model_a + slow.delta_current_a
        ),
        "slow_ready": np.zeros(shape, dtype=bool) if slow is None else slow.ready,
        "pairing_error_rad_s": nan_unless(frame.pairing_error_rad_s),
        "detection_level": nan_unless(frame.detection_level),
        "since_step_s": nan_unless(frame.since_step_s),
        "torque_residual_nm": nan_unless(frame.torque_residual_nm),
        "torque_siblings_nm": nan_unless(frame.torque_siblings_nm),
        "voltage_residual_v": nan_unless(frame.voltage_residual_v),
        "torque_slow_nm": nan_unless(frame.torque_slow_nm),
        "voltage_slow_v": nan_unless(frame.voltage_slow_v),
        "speed_siblings_rad_s": nan_unless(frame.speed_siblings_rad_s),
        "torque_band_nm": nan_unless(frame.torque_band_nm),
    }


#: The balance rule's two equations apart, low-passed (model/balance.py, "The two equations apart"), and
#: the median of the other motors' torque (:mod:`.siblings`): which equation a motor departs in, and
#: whether alone, in every event's evidence (replay and agent).
RESIDUAL_COLUMNS = ("torque_residual_nm", "torque_siblings_nm", "voltage_residual_v")

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
    "since_step_s",
    *RESIDUAL_COLUMNS,
    "torque_slow_nm",
    "voltage_slow_v",
    "speed_siblings_rad_s",
    "torque_band_nm",
)


def _current_sum_flags(
    table: TelemetryTable,
    profile: ThresholdProfile,
    by_time: NDArray[np.intp] | None = None,
    motor_rows: Mapping[int, NDArray[np.intp]] | None = None,
) -> NDArray[np.int16] | None:
    """CURRENT_SUM flags per row where the ESC currents' sum disagrees with the battery monitor; none where
    the table's calibration says the vehicle's ESCs and battery monitor are not related
    (``meta["esc_sum_checked"]`` False, :func:`~..model.vehicle.esc_sum_checked`)."""
    esc = table.get("esc_current_a")
    battery = table.get("battery_current_a")
    checked = table.meta.get("esc_sum_checked", True)
    if esc is None or battery is None or not checked or not np.isfinite(battery).any():
        return None
    order = np.argsort(table["time_s"], kind="stable") if by_time is None else by_time
    check = CurrentSumCheck(profile.plausibility, table.motors())
    mismatch = check.update(
        table["time_s"][order], table["motor"][order], esc[order], battery[order], motor_rows
    )
    flags = np.zeros(len(table), dtype=np.int16)
    flags[order[mismatch]] = SensorIssue.CURRENT_SUM
    return flags


def _motor_rows_in_time(
    motor: NDArray[np.int64], by_time: NDArray[np.intp]
) -> dict[int, NDArray[np.intp]] | None:
    """Each motor's rows in the time order ``by_time`` (a stable sort by time of a table by motor, then
    time), increasing: where its block of the table went (the inverse of the sort, cut by motor). None
    where the table is not grouped by motor."""
    if len(motor) == 0 or not (motor[1:] >= motor[:-1]).all():
        return None
    position = np.empty(len(motor), dtype=np.intp)
    position[by_time] = np.arange(len(motor))
    starts = np.flatnonzero(np.concatenate(([True], motor[1:] != motor[:-1])))
    ends = np.append(starts[1:], len(motor))
    return {int(motor[a]): position[a:b] for a, b in zip(starts.tolist(), ends.tolist())}


#: :func:`diagnose` takes a log in consecutive parts of about this many samples (every motor's together; of
#: 2^16, 2^17 and 2^18, 2^18 took the least CPU on a fitted vehicle's hour run once, 2^16 the least memory)
LOG_PART = 1 << 18


def _log_parts(
    time_s: NDArray[np.float64], measured_rows: Mapping[int, NDArray[np.intp]]
) -> list[dict[int, tuple[int, int]]]:
    """Consecutive parts of a log, cut between instants, of one size and as many as is nearest to parts of
    :data:`LOG_PART` samples: for each part, each motor's first and last + 1 place in its
    ``measured_rows`` (rows of ``time_s`` in increasing time). One part where the log holds fewer than
    two parts' samples, or a time is not finite."""
    whole = [{m: (0, rows.size) for m, rows in measured_rows.items()}]
    times = {m: time_s[rows] for m, rows in measured_rows.items()}
    total = sum(t.size for t in times.values())
    if total <= 2 * LOG_PART:
        return whole
    size = -(-total // round(total / LOG_PART))  # parts of one size, the nearest count to LOG_PART's
    bounds = part_bounds(list(times.values()), size)
    if bounds is None:
        return whole
    return [
        {m: (int(at[k]), int(at[k + 1])) for m, at in zip(times, bounds)} for k in range(bounds.shape[1] - 1)
    ]


def _keep(
    out: dict[str, NDArray],
    sel: NDArray[np.intp] | slice,
    carries: dict[int, MotorCarry | None],
    motor: int,
    done: tuple[dict[str, NDArray], list[MotorCarry]],
) -> None:
    """A finished call's results into ``out`` at the rows ``sel``, and the motor's new carry."""
    cols, new = done
    for name, values in cols.items():
        out[name][sel] = values[0]
    carries[motor] = new[0]


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
    # rows in the order the live agent receives them (time, then motor number within one message): the
    # table is by motor, then time, so a stable sort by time alone gives that order
    by_time = np.argsort(ordered["time_s"], kind="stable")
    in_time = _motor_rows_in_time(ordered["motor"], by_time)
    sum_flags = _current_sum_flags(ordered, profile, by_time, in_time)
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
        "since_step_s": np.full(n, np.nan),
        "torque_residual_nm": np.full(n, np.nan),
        "torque_siblings_nm": np.full(n, np.nan),
        "voltage_residual_v": np.full(n, np.nan),
        "torque_slow_nm": np.full(n, np.nan),
        "voltage_slow_v": np.full(n, np.nan),
        "speed_siblings_rad_s": np.full(n, np.nan),
        "torque_band_nm": np.full(n, np.nan),
    }
    motors = ordered["motor"]
    # each sample's pairing with its command (a log's column, telemetry/assemble.py); a table without
    # the column: the meta's one number where a source gives one, else none (the command of the instant)
    pairing_column = ordered.get("pairing_s")
    pairing = table.meta.get("pairing_s")
    # how far each sample's input went between it and the sample before (a log's column; none: not at all)
    excursion_column = ordered.get("input_excursion_v")
    # each sample's held command's age (a log's column; none: its pairing stands in, diagnosis/stall.py)
    age_column = ordered.get("command_age_s")

    def part(values: NDArray | None, sel: NDArray | slice) -> NDArray | None:
        return None if values is None else values[sel].copy()

    omega_all, current_all = ordered["omega_rad_s"], ordered["current_a"]
    # the vehicle stage (the siblings' torque, .siblings) runs over every motor's samples of a part at
    # once; none for a bench file's "motors" (different motors, not one vehicle's) or a vehicle judged
    # without it, whose motors finish one by one (one motor's arrays alive at a time)
    frame_motors = vehicle_motors(table)
    stage = vehicle_stage(frame_motors, noise, profile) if frame_motors else None
    # each motor's measured rows (in time), and the rows without a measurement
    measured_rows: dict[int, NDArray[np.intp]] = {}
    unmeasured_rows: dict[int, NDArray[np.intp]] = {}
    for motor in ordered.motors():
        rows = np.flatnonzero(motors == motor)
        # Rows without a measurement (an ESC slot that repeated its last packet in a .tlog, a gap in a
        # log) are not samples: the live agent never sees them, and the core must not count them either
        # (its input activity scales with the sample interval, and a 10 Hz ESC in 50 Hz messages would
        # look like a 50 Hz one). They read NO_DATA and keep the state announced before them.
        measured = np.isfinite(omega_all[rows]) | np.isfinite(current_all[rows])
        unmeasured_rows[int(motor)] = rows[~measured]
        out["state"][rows[~measured]] = MotorState.NO_DATA
        if measured.any():
            measured_rows[int(motor)] = rows[measured]
    # The log in consecutive parts of about LOG_PART samples, cut between instants (the core's carries
    # take each part on from the one before, as the live agent's batches are taken on): the arrays of a
    # part stay small and are used again, instead of every rule's arrays of every motor's whole log at
    # once (hundreds of MB for an hour, each page touched anew: issue 18)
    carries: dict[int, MotorCarry | None] = {m: None for m in measured_rows}
    for bounds in _log_parts(ordered["time_s"], measured_rows):
        started: list[tuple[int, NDArray[np.intp] | slice, StartedCall]] = []
        for motor, rows in measured_rows.items():
            lo, hi = bounds[motor]
            if hi <= lo:
                continue
            sel: NDArray[np.intp] | slice = rows[lo:hi]
            first, last = int(rows[lo]), int(rows[hi - 1])
            if last - first + 1 == hi - lo:  # one run of rows (the table is by motor): a block
                sel = slice(first, last + 1)
            motor_params = params[motor] if isinstance(params, dict) else params
            context = None
            if motor_params.effects:
                context = {
                    name: np.asarray(ordered[name][sel].copy(), dtype=float)
                    for name in ordered.names
                    if ordered[name].dtype.kind in "biuf"
                }
            call = start_motor(
                motor_params,
                profile,
                ordered["time_s"][sel].copy(),
                voltage[sel].copy(),
                ordered["omega_rad_s"][sel].copy(),
                ordered["current_a"][sel].copy(),
                part(bus, sel),
                carries[motor],
                command=part(command, sel),
                sensor_current_a=part(sensor_current, sel),
                extra_flags=part(sum_flags, sel),
                context=context,
                pairing_s=(
                    pairing_column[sel].copy()
                    if pairing_column is not None
                    else (None if pairing is None else float(pairing))
                ),
                input_excursion_v=part(excursion_column, sel),
                noise=None if noise is None else noise.get(motor),
                command_age_s=part(age_column, sel),
            )
            if stage is None:  # finished at once: one motor's arrays alive at a time
                _keep(out, sel, carries, motor, call.finish())
            else:
                started.append((motor, sel, call))
        if started:
            finished = run_vehicle_stage(stage, [([m], call) for m, _, call in started])
            for (motor, sel, _), done in zip(started, finished):
                _keep(out, sel, carries, motor, done)
    for motor, unmeasured in unmeasured_rows.items():
        if unmeasured.size == 0 or motor not in measured_rows:
            continue
        sel = measured_rows[motor]
        before = np.searchsorted(sel, unmeasured) - 1  # the last measured row before each
        out["announced"][unmeasured] = np.where(
            before >= 0, out["announced"][sel[np.maximum(before, 0)]], MotorState.NORMAL
        )
    # Before any fault is announced: does the model describe this vehicle at all? Rows in the order the
    # live agent receives them (time, then motor number within one message).
    check = StreamingDiagnoser.vehicle_check_for(profile, vehicle_motors(table))
    order = by_time
    vehicle_fit = np.zeros(n, dtype=np.int8)
    vehicle_fit[order] = check.update(
        ordered["time_s"][order],
        motors[order],
        omega_all[order],
        out["omega_model_rad_s"][order],
        in_time,
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
        since_step_s=out["since_step_s"],
        torque_residual_nm=out["torque_residual_nm"],
        torque_siblings_nm=out["torque_siblings_nm"],
        voltage_residual_v=out["voltage_residual_v"],
        torque_slow_nm=out["torque_slow_nm"],
        voltage_slow_v=out["voltage_slow_v"],
        speed_siblings_rad_s=out["speed_siblings_rad_s"],
        torque_band_nm=out["torque_band_nm"],
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
        #: the models of motors diagnosed in one call, as rows (:class:`~..model.params.MotorRows`)
        self._rows: dict[tuple[int, ...], MotorParams] = {}
        self.vehicle = self.vehicle_check_for(profile, motors)
        #: the vehicle stage's latest values of every motor (.siblings; None: no stage for this vehicle)
        self.siblings = vehicle_stage(motors, self.noise, profile)

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
        pairing_s: Pairing = None,
    ) -> dict[str, NDArray]:
        """Diagnose a few new samples of one motor at once (same results as one by one, less overhead).

        ``pairing_s``: how far apart the source pairs each sample and its command (one per sample, as the
        live agent's samples give it, or one number; None: at the same instant).
        """
        batch = MotorBatch(
            time_s,
            voltage_v,
            omega_rad_s,
            current_a,
            bus_voltage_v,
            command,
            sensor_current_a,
            extra_flags,
            context,
        )
        call = self._start_many(motor, batch, pairing_s)
        (cols,) = self._finish([([motor], call)])
        return {name: values[0] for name, values in cols.items()}

    def _finish(self, calls: list[tuple[list[int], StartedCall]]) -> list[dict[str, NDArray]]:
        """Started calls finished with the vehicle stage between (:func:`run_vehicle_stage`): each call's
        2-D result columns; the motors' carries kept."""
        results = []
        for (motors, _), (cols, carries) in zip(calls, run_vehicle_stage(self.siblings, calls)):
            for motor, carry in zip(motors, carries):
                self.carries[motor] = carry
            results.append(cols)
        return results

    def _noise_of(self, motors: list[int]) -> list[BandNoise]:
        return list(require_noise(self.noise, motors, self.profile.name).values())

    def update_motors(
        self, batches: Mapping[int, MotorBatch], pairing_s: float | None = None
    ) -> dict[int, dict[str, NDArray]]:
        """Diagnose a few new samples of several motors in one core call (:func:`diagnose_motors`): the
        same results as :meth:`update_many` motor by motor, for about the cost of one motor. Motors whose
        models differ only in R and k_e (identification's per-motor models of one type) go in one call,
        their models as rows (:class:`~..model.params.MotorRows`); motors of different types, a model with
        fitted effects, or batches with different columns are diagnosed motor by motor. A batch's own
        ``pairing_s`` (per sample) takes the place of the call's."""
        groups: dict[tuple[int, tuple[bool, ...]], list[int]] = {}
        types: dict[int, MotorParams] = {}
        alone: list[list[int]] = []
        for motor, batch in batches.items():
            motor_params = self.params[motor] if isinstance(self.params, dict) else self.params
            if motor_params.effects:  # its context is per motor
                alone.append([motor])
                continue
            given = tuple(
                getattr(batch, name) is not None
                for name in (
                    "bus_voltage_v",
                    "command",
                    "sensor_current_a",
                    "extra_flags",
                    "pairing_s",
                    "input_excursion_v",
                    "command_age_s",
                )
            )
            # one call for the motors of one type (their models differ at most in R and k_e)
            kind = next((m for m in types if same_type(types[m], motor_params)), motor)
            types.setdefault(kind, motor_params)
            groups.setdefault((kind, given), []).append(motor)
        calls: list[tuple[list[int], StartedCall]] = []
        counts: dict[int, int] = {}
        for motors in [*groups.values(), *alone]:
            for m in motors:
                counts[m] = np.asarray(batches[m].time_s).size
            if len(motors) == 1:
                b = batches[motors[0]]
                calls.append(
                    (
                        motors,
                        self._start_many(motors[0], b, b.pairing_s if b.pairing_s is not None else pairing_s),
                    )
                )
            else:
                calls.append((motors, self._start_batches(motors, [batches[m] for m in motors], pairing_s)))
        results: dict[int, dict[str, NDArray]] = {}
        for (motors, _), cols in zip(calls, self._finish(calls)):
            for r, motor in enumerate(motors):
                results[motor] = {name: values[r, : counts[motor]] for name, values in cols.items()}
        return {motor: results[motor] for motor in batches}

    def _start_many(self, motor: int, b: MotorBatch, pairing_s: Pairing) -> StartedCall:
        motor_params = self.params[motor] if isinstance(self.params, dict) else self.params

        def arr(x: NDArray | None) -> NDArray[np.float64] | None:
            return None if x is None else np.asarray(x, dtype=float)

        return start_motor(
            motor_params,
            self.profile,
            np.asarray(b.time_s, dtype=float),
            np.asarray(b.voltage_v, dtype=float),
            np.asarray(b.omega_rad_s, dtype=float),
            np.asarray(b.current_a, dtype=float),
            arr(b.bus_voltage_v),
            self.carries.get(motor),
            command=arr(b.command),
            sensor_current_a=arr(b.sensor_current_a),
            extra_flags=b.extra_flags,
            context=b.context,
            pairing_s=pairing_s,
            input_excursion_v=arr(b.input_excursion_v),
            noise=self._noise_of([motor])[0] if self.profile.noise_bands > 0 else None,
            command_age_s=arr(b.command_age_s),
        )

    def _start_batches(
        self, motors: list[int], batches: list[MotorBatch], pairing_s: float | None
    ) -> StartedCall:
        counts = [np.asarray(b.time_s).size for b in batches]
        width = max(counts)
        # where each batch's samples go in the rows (row r's first counts[r] places), all at once
        at = np.arange(sum(counts)) + np.repeat(
            np.arange(len(counts)) * width - np.cumsum([0, *counts[:-1]]), counts
        )

        def rows(name: str, dtype: type = float, pad: float = np.nan) -> NDArray | None:
            if getattr(batches[0], name) is None:
                return None
            out: NDArray = np.full((len(batches), width), pad, dtype=dtype)
            out.ravel()[at] = np.concatenate([getattr(batch, name) for batch in batches])
            return out

        columns = {name: rows(name) for name in _ROW_INPUTS}
        columns["extra_flags"] = rows("extra_flags", np.int16, 0)
        return self._start_rows(motors, columns, counts, pairing_s if batches[0].pairing_s is None else None)

    def together(self, motors: Sequence[int]) -> bool:
        """Whether :meth:`update_motors` diagnoses these motors' batches (the same columns given) in one
        core call, :meth:`update_rows`' (two or more motors of one type without fitted effects: their
        models differ at most in R and k_e, :func:`~..model.params.same_type`)."""
        if len(motors) < 2:
            return False
        if not isinstance(self.params, dict):
            return not self.params.effects
        first = self.params[motors[0]]
        return not first.effects and all(same_type(first, self.params[m]) for m in motors)

    def update_rows(
        self,
        motors: Sequence[int],
        columns: Mapping[str, NDArray | None],
        counts: Sequence[int],
        pairing_s: float | None = None,
    ) -> dict[str, NDArray]:
        """The core call of :meth:`update_motors` for motors that go :meth:`together`, their samples given
        as rows already: one row per motor (``columns``: :class:`MotorBatch`'s names, 2-D; after each
        row's ``counts`` samples NaN, ``extra_flags`` 0, and the times, whatever they hold, are padded here
        with the row's last, in place). Returns 2-D results (the padding's mean nothing). The live agent
        lays its samples out so directly, without a batch per motor in between."""
        (cols,) = self._finish([(list(motors), self._start_rows(motors, columns, counts, pairing_s))])
        return cols

    def _start_rows(
        self,
        motors: Sequence[int],
        columns: Mapping[str, NDArray | None],
        counts: Sequence[int],
        pairing_s: float | None = None,
    ) -> StartedCall:
        time_s = columns["time_s"]
        assert time_s is not None
        if min(counts) < time_s.shape[1]:  # padding: the row's last time (no interval), no values
            for r, count in enumerate(counts):
                time_s[r, count:] = time_s[r, count - 1] if count else 0.0
        params = self.params
        if isinstance(params, dict):
            key = tuple(motors)
            motor_params = self._rows.get(key)
            if motor_params is None:
                motor_params = self._rows[key] = MotorRows.of([params[m] for m in motors])
        else:
            motor_params = params
        pairing = columns.get("pairing_s")
        return start_motors(
            motor_params,
            self.profile,
            time_s,
            columns["voltage_v"],  # type: ignore[arg-type]
            columns["omega_rad_s"],  # type: ignore[arg-type]
            columns["current_a"],  # type: ignore[arg-type]
            columns.get("bus_voltage_v"),
            [self.carries.get(m) for m in motors],
            counts,
            command=columns.get("command"),
            sensor_current_a=columns.get("sensor_current_a"),
            extra_flags=columns.get("extra_flags"),
            pairing_s=pairing if pairing is not None else pairing_s,
            input_excursion_v=columns.get("input_excursion_v"),
            noise=self._noise_of(list(motors)) if self.profile.noise_bands > 0 else None,
            command_age_s=columns.get("command_age_s"),
        )

    def announced(self, motor: int) -> MotorState:
        carry = self.carries.get(motor)
        return carry.announced if carry else MotorState.NORMAL
