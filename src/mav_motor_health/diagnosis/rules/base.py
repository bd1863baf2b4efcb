"""What every diagnosis rule is: a frozen config with one ``judge()`` that reads and adds to a frame.

The pipeline (:mod:`..pipeline`) is a loop over rules. A rule is a frozen dataclass subclassing
:class:`Rule`: its fields are its settings (defaults on the dataclass, checked by :meth:`Rule.validate`
when it is made), :meth:`Rule.new_carry` is what it remembers about one motor before its first sample,
and :meth:`Rule.judge` advances every motor of one call: it reads the :class:`Frame` (the call's samples
and what the rules before it found), writes what it finds to the frame, and returns each motor's new
carry. Rules look back only, so a split of a motor's samples into calls gives the same results.

The rules that compare a motor with its model (step, dynamic, balance) are :class:`CompareRule`\\ s: a
profile's ``[steady]`` table names one by its ``kind``, and a new way of comparing is a new module with a
new kind (:func:`compare_rule`; another package installs one under the entry-point group
``mav_motor_health.rules``). docs/rules.md shows how.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from importlib import metadata
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ...errors import ConfigError
from ...model.params import MotorParams
from ..noise import NoiseRows
from ..plausibility import CURRENT_UNTRUSTED

if TYPE_CHECKING:
    from ..noise import BandNoise
    from ..profile import ThresholdProfile

__all__ = [
    "COMPARE_RULES",
    "CompareRule",
    "Frame",
    "Rule",
    "SlowAverages",
    "check_settings",
    "compare_rule",
    "compare_rule_class",
]


@dataclass
class SlowAverages:
    """The balance rule's slower averages of the deviations, and where they may be judged."""

    delta_omega_rad_s: NDArray[np.float64]
    delta_current_a: NDArray[np.float64]
    ready: NDArray[np.bool_]
    #: how long after an input step the slow averages still hold its upset [s]: the slow look's own wait
    #: (the fast look's times ``slow_factor``), whether or not it is judged there
    settle_s: float = 0.0


@dataclass
class Frame:
    """One call's samples of several motors of one model (rows × samples, one row per motor; ``counts``
    each row's samples, the rest padding) and what the rules have found so far.

    The inputs come first; each rule fills in the fields it documents. Arrays are 2-D of the rows' shape.
    """

    params: MotorParams
    profile: ThresholdProfile
    time_s: NDArray[np.float64]
    voltage_v: NDArray[np.float64]
    omega_rad_s: NDArray[np.float64]
    current_a: NDArray[np.float64]
    counts: list[int]
    #: each row's length where rows differ (None: all full), as the kernels take it
    ragged: list[int] | None = None
    bus_voltage_v: NDArray[np.float64] | None = None
    command: NDArray[np.float64] | None = None
    sensor_current_a: NDArray[np.float64] | None = None
    extra_flags: NDArray[np.int16] | None = None
    context: Mapping[str, NDArray[np.float64]] | None = None
    #: how far apart the source may have paired each sample and its command [s]: one number for all, or
    #: an array of the rows' shape (one per sample); None or 0: the command of the sample's own instant
    pairing_s: float | NDArray[np.float64] | None = None
    #: how far each sample's input went beyond the two held inputs since the sample before [V] (the
    #: table's ``input_excursion_v``, telemetry/assemble.py); None: not at all
    input_excursion_v: NDArray[np.float64] | None = None
    #: each sample's held command's age [s] (the table's ``command_age_s``, telemetry/assemble.py); None:
    #: not known (``pairing_s`` stands in where a stall's start is weighed against it, :mod:`..stall`)
    command_age_s: NDArray[np.float64] | None = None
    noise: Sequence[BandNoise] | None = None

    # the comparison (a CompareRule)
    omega_model_rad_s: NDArray[np.float64] = None  # type: ignore[assignment]
    current_model_a: NDArray[np.float64] = None  # type: ignore[assignment]
    #: the measurement as the tree judges it (the model plus a low-passed deviation, or a stall's own)
    omega_judged_rad_s: NDArray[np.float64] = None  # type: ignore[assignment]
    current_judged_a: NDArray[np.float64] = None  # type: ignore[assignment]
    steady: NDArray[np.bool_] = None  # type: ignore[assignment]
    #: the time since the last input step of each sample whose stream has settled [s] (balance rule; NaN:
    #: its stream has not): below the rule's ``settle_s`` the sample waits for the step's transient
    since_step_s: NDArray[np.float64] | None = None
    #: how many times wider the bands are for the sample's time since a step (vehicle noise, noise.py):
    #: 1 once settled, NaN while waiting where the vehicle's noise does not say (not judged); None: none
    after_step_factor: NDArray[np.float64] | None = None
    #: the input voltage the bands and the tree are read at
    judged_voltage_v: NDArray[np.float64] = None  # type: ignore[assignment]
    #: the measured speed [rad/s] and current [A] low-passed as the balances are, no model in them
    #: (balance rule; None: the rule has none)
    omega_mean_rad_s: NDArray[np.float64] | None = None
    current_mean_a: NDArray[np.float64] | None = None
    #: the two balances apart, low-passed (balance rule; None: the rule has none): the torque [N·m] and the
    #: voltage [V] the model cannot account for (model/balance.py, "The two equations apart")
    torque_residual_nm: NDArray[np.float64] | None = None
    voltage_residual_v: NDArray[np.float64] | None = None
    #: the median of the other motors' torque residuals before each sample (the vehicle stage,
    #: :mod:`..siblings`; None: no stage ran, NaN: too few siblings there)
    torque_siblings_nm: NDArray[np.float64] | None = None
    #: how far the other motors' torque residuals lie from that median, as a standard deviation [N·m] (the
    #: vehicle stage, where the profile's ``torque_siblings_spread`` asks for it; None: not given)
    torque_siblings_spread_nm: NDArray[np.float64] | None = None
    #: that spread low-passed over each motor's judged samples (rules/bands.py, "The torque's own growth")
    torque_spread_low_nm: NDArray[np.float64] | None = None
    #: the spread of the siblings' slow torque averages low-passed alike (rules/equations.py, "The torque's
    #: slow look as its siblings run")
    torque_slow_spread_low_nm: NDArray[np.float64] | None = None
    #: the median of the other motors' voltage residuals before each sample [V] (the vehicle stage; None:
    #: no stage took it, NaN: too few siblings there; rules/voltage.py)
    voltage_siblings_v: NDArray[np.float64] | None = None
    #: each motor's identified σ(a, e) at each sample, speed [rad/s] and current [A] (rules/bands.py,
    #: where the live noise is measured before the bands; None: worked out by the bands)
    sigma_speed_rad_s: NDArray[np.float64] | None = None
    sigma_current_a: NDArray[np.float64] | None = None
    #: each judged deviation's square in the motor's identified σ(a, e), low-passed (speed, current; the
    #: bands' live noise, rules/bands.py; None: not measured), and the median of the other motors' latest
    #: (the vehicle stage; NaN: too few siblings there)
    live_z2_speed: NDArray[np.float64] | None = None
    live_z2_current: NDArray[np.float64] | None = None
    siblings_z2_speed: NDArray[np.float64] | None = None
    siblings_z2_current: NDArray[np.float64] | None = None
    #: each motor's slow averages' squared deviation from its slow offset, low-passed, speed [(rad/s)²] and
    #: current [A²] (the live noise, rules/bands.py, where the profile's ``slow_siblings`` asks for it; None:
    #: not measured), and the median of the other motors' latest (the vehicle stage; NaN: too few there)
    slow_ms_speed: NDArray[np.float64] | None = None
    slow_ms_current: NDArray[np.float64] | None = None
    siblings_slow_ms_speed: NDArray[np.float64] | None = None
    siblings_slow_ms_current: NDArray[np.float64] | None = None
    #: each motor's torque residual averaged slowly over its judged samples in its identified speeds [N·m]
    #: (the live noise, rules/bands.py, where the profile's ``torque_slow_siblings`` asks for it; None: not
    #: averaged), the median of the other motors' latest and their spread around it as a standard deviation
    #: (the vehicle stage; NaN: too few siblings there; rules/equations.py, "The torque's slow look as its
    #: siblings run")
    torque_slow_raw_nm: NDArray[np.float64] | None = None
    siblings_torque_slow_nm: NDArray[np.float64] | None = None
    siblings_torque_slow_spread_nm: NDArray[np.float64] | None = None
    #: each motor's voltage residual averaged alike [V], that average's squared departure from the motor's
    #: voltage offset averaged over ``conditions_siblings_s`` [V²] (the live noise, where the profile's
    #: ``voltage_slow_siblings`` asks for it; None: not measured), and the median of the other motors'
    #: latest (the vehicle stage; NaN: too few there; rules/voltage.py)
    voltage_slow_raw_v: NDArray[np.float64] | None = None
    slow_ms_voltage: NDArray[np.float64] | None = None
    siblings_slow_ms_voltage: NDArray[np.float64] | None = None
    #: the siblings' linear prediction of each sample's speed deviation [rad/s] (the vehicle stage,
    #: :mod:`..prediction`; None: not predicted, NaN: a sibling's value missing there); where the profile's
    #: ``speed_against_siblings`` judges against it, ``omega_judged_rad_s`` has it taken off (:mod:`.against`)
    speed_siblings_rad_s: NDArray[np.float64] | None = None
    #: the speed the motor is expected to turn at (tree rule 1)
    omega_expected_rad_s: NDArray[np.float64] = None  # type: ignore[assignment]
    #: the highest stop speed of each sample [rad/s] (tree rule 1, "The lowest input": a share of the free
    #: speed of the lowest input given so far); None: the profile's stop speed alone
    stop_cap_rad_s: NDArray[np.float64] | None = None
    #: when the stall of each stalled sample began [s] (NaN where not stalled; :mod:`..stall`, "A stall the
    #: paired command may predate"); None: the rule does not say
    stall_since_s: NDArray[np.float64] | None = None
    #: the motor's free speed V/k_e, above which no fault turns it (tree rule 2); None: no cap
    omega_free_rad_s: NDArray[np.float64] | None = None
    #: the input activity [V] that widens the bands (balance rule); None: none measured
    activity_v: NDArray[np.float64] | None = None
    #: the deviations' low-pass time constant [s] (balance rule), which the pairing and the sequential
    #: test read; None: the rule has none that moves
    low_pass_s: NDArray[np.float64] | None = None
    #: the balance rule's slow look; None: off
    slow: SlowAverages | None = None
    #: the low-pass time constant the rule was designed at [s] (the sequential test's design)
    design_tau_s: float = 0.0

    # the checks and bands
    sensor_flags: NDArray[np.int16] = None  # type: ignore[assignment]
    speed_band_rad_s: NDArray[np.float64] | float = 0.0
    current_band_a: NDArray[np.float64] = None  # type: ignore[assignment]
    current_band_below_a: NDArray[np.float64] = None  # type: ignore[assignment]
    pairing_error_rad_s: NDArray[np.float64] | None = None
    #: the torque balance's band half-width around its motor's offset [N·m] (the profile's
    #: ``equation_bands``, where every motor's noise has the torque's); None: not judged in it
    torque_band_nm: NDArray[np.float64] | None = None

    # the verdicts
    state: NDArray[np.int8] = None  # type: ignore[assignment]
    depth: NDArray[np.float64] = None  # type: ignore[assignment]
    #: samples whose state persistence may count (steady, or a state named whatever the input)
    eligible: NDArray[np.bool_] = None  # type: ignore[assignment]
    #: states a later rule announces (the sequential test's directions): persistence leaves them out
    announced_elsewhere: tuple[int, ...] = ()
    #: the torque balance's departure from its motor's offset in σ of its noise where it is judged in it,
    #: NaN elsewhere (:mod:`.equations`); None: the faults are read from the speed and current deviations
    z_torque: NDArray[np.float64] | None = None
    #: the judged torque (against its siblings) averaged as long as the slow look averages the deviations,
    #: NaN where it was not judged (:mod:`.equations`, "The slow look"); None: no slow look
    torque_slow_nm: NDArray[np.float64] | None = None
    #: the voltage residual against its siblings' median averaged alike, NaN where not counted [V]
    #: (:mod:`.equations`; rules/voltage.py); None: no slow look or no siblings' voltage
    voltage_slow_v: NDArray[np.float64] | None = None
    #: where the slow look named a sample (:mod:`.tree`, :mod:`.equations`), its departure in the named
    #: direction in σ of the bands as the fast look's evidence counts it, NaN elsewhere; None: none named
    slow_evidence: NDArray[np.float64] | None = None
    #: the slow averages of speed and current in σ of their own noise, read once per call
    #: (:meth:`slow_deviation_z`)
    slow_z: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
    #: the sequential test's alarms and level, where a profile has one
    alarms: NDArray[np.int8] | None = None
    detection_level: NDArray[np.float64] | None = None
    announced: NDArray[np.int8] = None  # type: ignore[assignment]

    @property
    def shape(self) -> tuple[int, int]:
        return self.time_s.shape

    def slow_deviation_z(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The slow look's averages of speed and current in units of each motor's own slow σ, from their
        offsets (:meth:`~..noise.NoiseRows.slow_deviations`; the frame needs its slow averages and the
        motors' noise), worked out once for the rules that read them (:mod:`.tree`, :mod:`.equations`)."""
        if self.slow_z is None:
            assert self.slow is not None
            self.slow_z = self.noise_as_rows().slow_deviations(
                self.slow.delta_omega_rad_s,
                self.slow.delta_current_a,
                np.zeros(self.shape) if self.activity_v is None else self.activity_v,
                self.pairing_error_rad_s,
                self.profile.range_margin,
            )
        return self.slow_z

    def note_slow_evidence(self, named: NDArray[np.bool_], evidence: NDArray[np.float64]) -> None:
        """Record the slow look's evidence at the samples it named (:attr:`slow_evidence`)."""
        if self.slow_evidence is None:
            self.slow_evidence = np.full(self.shape, np.nan)
        self.slow_evidence[named] = evidence[named]

    def noise_as_rows(self) -> NoiseRows:
        """``noise`` as rows (:class:`~..noise.NoiseRows`; made once for the same noise)."""
        assert self.noise is not None
        return NoiseRows.of(self.noise)

    @property
    def within_identified_speeds(self) -> NDArray[np.bool_]:
        """Where the model speed lies in each motor's identified speed range, widened by the profile's
        ``range_margin`` (everywhere where the frame has no noise): where the rules judge a motor against
        its model (:mod:`.judged`), count its live noise (:mod:`.bands`) and take its torque as a
        reference at any speed (:mod:`..siblings`)."""
        if self.noise is None:
            return np.ones(self.shape, dtype=bool)
        return self.noise_as_rows().in_speed_range(self.omega_model_rad_s, self.profile.range_margin)

    @property
    def speed_deviation_rad_s(self) -> NDArray[np.float64]:
        """Each sample's speed deviation from the model as judged [rad/s], steady or not (NaN: none): what
        the vehicle stage predicts from the siblings (:mod:`..prediction`). Every sample, not only the
        judged ones: a sibling's latest deviation must be of the same moment, and in a manoeuvre its
        latest judged one is from before it (on held-out world 1005, whose motors' deviations correlate by
        ±0.97, a prediction from the latest judged ones left tails of 8 to 14 σ)."""
        return self.omega_judged_rad_s - self.omega_model_rad_s

    def current_trusted(self) -> NDArray[np.bool_]:
        """Where the current may be used: a plausible sensor and a measurement."""
        return ((self.sensor_flags & CURRENT_UNTRUSTED) == 0) & np.isfinite(self.current_a)

    def excursions(self, weight: float) -> NDArray[np.float64] | None:
        """``input_excursion_v`` times a rule's ``weight`` for it; None where the weight is 0 or the
        source gives none (the rules then take none)."""
        if self.input_excursion_v is None or not weight > 0:
            return None
        return weight * np.asarray(self.input_excursion_v, dtype=float)


class Rule(ABC):
    """A diagnosis rule: frozen settings, checked when made; one :meth:`judge` with its own carry."""

    #: the rule's name: its key in a motor's carry
    name: ClassVar[str]
    #: whether the rule reads the other motors' values (:mod:`..siblings`): the vehicle stage runs before it
    reads_siblings: ClassVar[bool] = False

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:  # noqa: B027 (a hook: rules without settings to check keep it)
        """Refuse settings the rule cannot work with (a :class:`ConfigError` naming the key)."""

    def new_carry(self) -> Any:
        """What the rule remembers about a motor before its first sample (None: nothing)."""
        return None

    @abstractmethod
    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        """Advance every row of ``frame`` (writing what the rule finds into it); each row's new carry."""


#: the comparison rules by kind (:func:`compare_rule`)
COMPARE_RULES: dict[str, type[CompareRule]] = {}


class CompareRule(Rule):
    """A rule comparing a motor with its model: fills the frame's comparison fields (the model, the
    measurement as judged, ``steady``...). Subclasses name their ``kind`` (the ``[steady]`` table's)."""

    kind: ClassVar[str]
    name: ClassVar[str] = "compare"

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "kind" in cls.__dict__:
            COMPARE_RULES[cls.kind] = cls


#: the entry-point group under which other packages install comparison rules (a CompareRule subclass)
ENTRY_POINT_GROUP = "mav_motor_health.rules"


def compare_rule_class(kind: str) -> type[CompareRule]:
    """The comparison rule of ``kind``: the package's, one defined (imported) by the user, or one installed
    under the entry-point group ``mav_motor_health.rules``, looked for when the kind is not known yet
    (a :class:`ConfigError` naming the kinds there are)."""
    if kind not in COMPARE_RULES:
        for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
            try:
                entry.load()  # a CompareRule subclass registers its kind when defined
            except Exception as exc:
                raise ConfigError(
                    f"entry point {entry.name!r} failed to load: {type(exc).__name__}: {exc}",
                    key="steady.kind",
                ) from exc
    try:
        return COMPARE_RULES[kind]
    except KeyError:
        raise ConfigError(
            f"{kind!r}", key="steady.kind", expected=f"one of {', '.join(COMPARE_RULES)}"
        ) from None


def check_settings(kind: str, names: Iterable[str]) -> None:
    """Refuse a setting that the comparison rule of ``kind`` does not have, naming the kinds that have it
    (a profile written for another kind, or by an older version that wrote every kind's settings)."""
    known = {f.name for f in fields(compare_rule_class(kind))}  # type: ignore[arg-type]
    for name in names:
        if name in known:
            continue
        others = [k for k, c in COMPARE_RULES.items() if name in {f.name for f in fields(c)}]  # type: ignore[arg-type]
        belongs = (
            f"; {name} is a setting of kind = {' or '.join(map(repr, others))}: remove it" if others else ""
        )
        raise ConfigError(
            f"{name} is not a setting of kind = {kind!r}",
            key=f"steady.{name}",
            expected=f"only the settings of kind = {kind!r} ({', '.join(sorted(known))}){belongs}",
        )


def compare_rule(kind: str = "step", **settings: Any) -> CompareRule:
    """The comparison rule of ``kind`` with its settings (a profile's ``[steady]`` table; the rest keep the
    rule's defaults)."""
    check_settings(kind, settings)
    return compare_rule_class(kind)(**settings)
