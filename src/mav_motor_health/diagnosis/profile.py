"""Threshold profiles: the decision tree's limits as data (paper section III.B).

A profile holds the bands around the model, the stop speed and the stall-current split, the
comparison rule (``[steady]``, :mod:`.rules`) and the persistence times, and lists the pipeline's rules
(:attr:`ThresholdProfile.rules`). ``testbed`` is the paper's; ``flight`` is tuned
for fluctuating input. Profiles load from TOML in ``params/profiles/`` (see :mod:`..config`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import nan_to_zero
from ..errors import ConfigError
from .detection import SequentialRule
from .plausibility import PlausibilityRule
from .rules import BalanceRule, CompareRule, StepRule
from .states import MotorState
from .vehicle_check import VehicleCheckRule

if TYPE_CHECKING:
    from .rules.base import Rule

__all__ = ["PersistenceRule", "ThresholdProfile"]


@dataclass(frozen=True)
class PersistenceRule:
    """How long a state must hold before it is announced (``announce_s``), per state label.

    ``default_announce_s`` applies to states not listed. Returning to NORMAL uses ``clear_s``. A run
    ends where eligible samples are more than ``max_gap_s`` apart (sparse quasi-steady samples in gusts).

    ``max_depth`` (≥ 1): a sample whose departure measures d bands (the tree's depth, 1 on its state's
    boundary) counts its interval d times, up to ``max_depth`` times: a deep departure is announced
    sooner than one on the edge of its band, as a CUSUM detector does. 1 (the default): time alone.
    """

    default_announce_s: float = 0.1
    announce_s: tuple[tuple[str, float], ...] = ()
    clear_s: float = 0.5
    max_gap_s: float = float("inf")
    #: per state label: seconds of hold added per volt of input activity (balance rule)
    announce_per_activity_s: tuple[tuple[str, float], ...] = ()
    max_depth: float = 1.0

    def __post_init__(self) -> None:
        if not self.max_depth >= 1:
            raise ConfigError(
                f"{self.max_depth!r}", key="persistence.max_depth", expected="a depth >= 1 (1: time alone)"
            )
        values = [
            self.default_announce_s,
            self.clear_s,
            *(v for _, v in self.announce_s),
            *(v for _, v in self.announce_per_activity_s),
        ]
        if any(not (v >= 0) for v in values):
            raise ConfigError("persistence times must be >= 0 s", key="persistence", expected="seconds >= 0")
        for label, _ in (*self.announce_s, *self.announce_per_activity_s):
            try:
                MotorState.from_label(label)
            except ValueError as exc:
                raise ConfigError(str(exc), key=f"persistence.announce_s.{label}") from None

    def hold_per_activity_s(self) -> NDArray[np.float64] | None:
        """Hold added per volt of input activity, per state code; None when no state has one."""
        if not self.announce_per_activity_s:
            return None
        slopes = np.zeros(len(MotorState))
        for label, value in self.announce_per_activity_s:
            slopes[MotorState.from_label(label)] = value
        return slopes

    def hold_s(self) -> NDArray[np.float64]:
        """Hold time per state code (index = :class:`MotorState` value)."""
        holds = np.full(len(MotorState), self.default_announce_s)
        holds[MotorState.NORMAL] = self.clear_s
        for label, value in self.announce_s:
            holds[MotorState.from_label(label)] = value
        return holds


#: the profile's multiples of what the siblings show (0..100, 0: not used), and what each multiplies
SIBLING_MULTIPLES = {
    "conditions_siblings": "the siblings' deviations in their noise",
    "torque_siblings_spread": "the siblings' torque spread",
    "slow_siblings": "the siblings' slow deviations",
    "torque_slow_siblings": "the siblings' slow torque spread",
    "voltage_slow_siblings": "the siblings' slow voltage spread",
}


@dataclass(frozen=True)
class ThresholdProfile:
    """The limits of the decision tree (Fig. 7) and the rules around it.

    The current band's half-width is interpolated linearly in input voltage between the anchor points
    ``current_band_a`` (pairs of voltage [V], half-width [A]) and held at the end values outside them
    (``np.interp``): the paper gives ±0.25 A at the low end and ±2.5 A at the high end of 4–11 V.

    ``free_speed_headroom_fraction`` (0 < f ≤ 1) narrows the upper side of the speed band where the model
    speed is near the free speed ``V/k_e``: "speed above the band" is ω > ω_model + clip(f·(V/k_e −
    ω_model), band/2, band) (see :mod:`.tree`, rule 2). 0 or absent in TOML: the default, 0.5.

    ``stop_speed_fraction`` (0 ≤ f < 1): a motor below f × its expected speed counts as stopped too (tree
    rule 1; 0, the default: the paper's stop speed alone).

    ``stop_speed_lowest_fraction`` (0 ≤ g < 1): the stop speed is at most g × the free speed ``V/k_e`` of
    the lowest input the motor has been given in the stream (tree rule 1, "The lowest input"): a healthy
    motor never turns slower than its lowest input drives it, whatever the log paired it with. 0, the
    default: no such cap.

    ``joint_band_sum`` (1 ≤ c ≤ 2, or 0): where speed and current both leave the model in the directions a
    fault moves them, by shares of their bands that add up to at least c, that fault is named even if
    neither leaves its band (two departures that agree need less of each; see :mod:`.tree`). 0, the
    default: off, the paper's tree.

    ``slow_band_fraction`` (0 < f ≤ 1, or 0): the share of the bands that the slow look of the balance
    rule (``steady.slow_factor``) judges its longer averages against; set by tuning. 0: no slow look.
    With ``noise_bands`` the slow look's bands are its own measured noise times as many σ as the fast
    look's (rules/tree.py), and this share narrows them further (``flight_vehicle``: 1, none).

    ``activity_band`` rows widen the bands with the input's activity (balance rule): ``[activity_v,
    speed_widening_rad_s, current_widening_a]`` widens the current band alike on both sides; a fourth
    number, ``[..., current_above_a, current_below_a]``, widens it above and below the model apart (in
    gusty air the healthy current deviation is skewed, see docs/flight.md). Linear in activity, held at
    the end rows.

    ``noise_bands`` (n > 0, or 0): the bands are n times each motor's own noise σ(a), measured by
    identification on the vehicle's healthy flight (:mod:`.noise`); ``speed_band_rad_s``,
    ``current_band_a`` and ``activity_band`` are then not used. 0, the default: the absolute bands.
    ``stall_split_typical`` (> 0, with ``noise_bands``): the F2.1/F4.2 split of a stalled motor's current
    is this multiple of the motor's typical current in flight (measured with the noise, or this flight's
    own where lower: rules/tree.py), instead of ``stall_split_a``: a stalled motor's current scales with
    the motor's size, not with the paper's.
    ``range_margin`` (> 0, with ``noise_bands``): samples whose model speed lies beyond the speeds the
    identification flight covered, by more than this share of the range's ends, or whose input activity
    exceeds the flight's busiest by more than this share, are not judged (the model, or its noise, was
    never checked there; stalls are still named). 0: judged everywhere.
    ``range_growth`` (g ≥ 0, with ``range_margin``): within that margin, beyond the identified speeds, the
    bands are multiplied by ``(1 + d/span)**g``, d how far both the model speed and the speed the motor
    turns lie beyond the range (the lesser distance: a motor that lost drive is commanded beyond it and
    turns short) and span the range's width: the model there is an extrapolation of a curve fitted over
    the span, and its error grows with the distance in units of the span the fit saw
    (:meth:`~.noise.NoiseRows.beyond_range`). 0, the default: the bands as measured up to the margin
    (``flight_vehicle`` ships with 1).
    ``conditions_reach`` (≥ 1, with ``noise_bands`` and ``range_margin``): the input activity and the
    pairing error are judged up to this multiple of those limits, where σ is an extrapolation, multiplied
    by ``excess ** conditions_growth`` (≥ 0; excess: how many times the limit the sample lies beyond it),
    so that the bands grow faster there than the noise was measured to grow (:mod:`.noise`, "Beyond the
    measured conditions"). 1, the default: nothing beyond the limits.
    ``conditions_siblings`` (m > 0, with ``conditions_growth``): beyond the limits the bands grow by no more
    than m times how wide the other motors' deviations run right now, in units of their identified σ
    (the square root of the median over the siblings of each one's ``z²`` low-passed over
    ``conditions_siblings_s`` seconds), and never by less than 1: the air the six motors share, measured on
    them, instead of a growth that only the worst flight needed (:mod:`.rules.bands`, "Grown as the siblings
    run"). 0, the default: ``excess ** conditions_growth`` alone.
    ``torque_siblings_spread`` (m > 0, with ``conditions_siblings`` and ``equation_bands``): beyond the
    limits the torque's band grows by no more than m times the spread of the other motors' torque residuals
    around their median, low-passed over ``conditions_siblings_s``, in units of the torque's identified σ,
    and never by less than 1 nor by more than the deviations' growth (:mod:`.rules.bands`, "The torque's
    own growth"; nothing to bound without them). 0, the default: the torque's band grows as the larger of
    the deviations' bands.
    ``slow_siblings`` (m > 0, with ``conditions_siblings`` and ``slow_band_fraction``): the slow look's
    bands are at most as wide as m times how far the other motors' slow averages run from their models
    right now (the square root of the median over the siblings of each one's squared slow deviation,
    averaged over ``conditions_siblings_s``, a sibling's only once it holds that long of its counted
    samples, in the deviation's own unit; never below the motor's own quiet slow σ), times the fast bands'
    ``noise_bands`` and ``slow_band_fraction``, not in the slow look's wait after an input step
    (:mod:`.rules.tree`, "The slow look as its siblings run"; nothing to bound without them). 0, the
    default: the slow look's bands from its own measured noise alone.
    ``torque_slow_siblings`` (m > 0, with ``conditions_siblings``, ``equation_bands`` and
    ``slow_band_fraction``): the torque's slow look (:class:`~.rules.equations.TorqueSlowLook`) is at most
    as wide as m times the spread of the other motors' slow torque averages around their median (in N·m,
    low-passed over ``conditions_siblings_s``; never below the motor's own quiet slow σ of the torque),
    times ``equation_bands`` and ``slow_band_fraction``, within the motor's identified speeds, the slow
    look's wait after an input step included (:mod:`.rules.equations`, "The torque's slow look as its
    siblings run"). 0, the default: the
    torque's slow look as wide as the fast torque's band holds of its σ, its growth included.
    ``voltage_slow_siblings`` (m > 0, with ``conditions_siblings``, ``equation_bands`` and
    ``slow_band_fraction``): an open transistor (F4.1) is also read in the voltage balance against its
    siblings, averaged slowly (:class:`~.rules.voltage.VoltageSlowLook`), against m times the spread of the
    other motors' slow voltage averages around their median (low-passed over ``conditions_siblings_s``;
    never below the motor's own slow σ of it at the sample's conditions held within those identification
    measured), times ``equation_bands`` and ``slow_band_fraction`` (:mod:`.rules.voltage`). 0, the default:
    the open transistor read from the speed and current deviations alone.
    ``equation_bands`` (n > 0, with ``noise_bands``): friction (F1.1) and a lighter propeller (F3.1),
    which move the model's torque balance alone, are judged in it, against n times its own noise, which
    identification measured (:mod:`.rules.equations`; not where the ESC reports its input current, whose
    ripple moves the torque with the air). 0, the default: the tree on the speed and current deviations,
    which mix both balances' noise.
    ``speed_against_siblings`` (s > 0, with ``noise_bands``): the speed deviation is judged less its
    siblings' linear prediction (:mod:`.prediction`) where the vehicle file measured that difference's
    noise and its σ is below s times the deviation's own (:mod:`.rules.against`; the shipped
    ``flight_vehicle``: 1, "where the narrower"). 0, the default: each motor's speed on its own.
    """

    name: str
    speed_band_rad_s: float = 20.0
    current_band_a: tuple[tuple[float, float], ...] = ((4.0, 0.25), (11.0, 2.5))
    stop_speed_rad_s: float = 100.0
    stop_speed_fraction: float = 0.0
    stop_speed_lowest_fraction: float = 0.0
    stall_split_a: float = 6.0
    stall_split_per_v: float = 0.0
    stall_split_ref_v: float = 11.1
    speed_only_band_frac: float = 0.15
    free_speed_headroom_fraction: float = 0.5
    joint_band_sum: float = 0.0
    slow_band_fraction: float = 0.0
    min_command: float = 0.0
    activity_band: tuple[tuple[float, ...], ...] = ()
    noise_bands: float = 0.0
    stall_split_typical: float = 0.0
    range_margin: float = 0.0
    range_growth: float = 0.0
    conditions_reach: float = 1.0
    conditions_growth: float = 0.0
    conditions_siblings: float = 0.0
    conditions_siblings_s: float = 10.0
    torque_siblings_spread: float = 0.0
    slow_siblings: float = 0.0
    torque_slow_siblings: float = 0.0
    voltage_slow_siblings: float = 0.0
    equation_bands: float = 0.0
    speed_against_siblings: float = 0.0
    steady: CompareRule = field(default_factory=StepRule)
    persistence: PersistenceRule = field(default_factory=PersistenceRule)
    plausibility: PlausibilityRule = field(default_factory=PlausibilityRule)
    vehicle_check: VehicleCheckRule = field(default_factory=VehicleCheckRule)
    detection: SequentialRule = field(default_factory=SequentialRule)
    description: str = ""

    def __post_init__(self) -> None:
        if not self.speed_band_rad_s > 0:
            raise ConfigError(
                f"{self.speed_band_rad_s!r}", key="speed_band_rad_s", expected="a band > 0 rad/s"
            )
        if not self.stop_speed_rad_s >= 0:
            raise ConfigError(f"{self.stop_speed_rad_s!r}", key="stop_speed_rad_s", expected=">= 0 rad/s")
        if not 0 <= self.stop_speed_fraction < 1:
            raise ConfigError(
                f"{self.stop_speed_fraction!r}",
                key="stop_speed_fraction",
                expected="a fraction 0 <= f < 1 of the expected speed (0: 100 rad/s alone, the paper)",
            )
        if not 0 <= self.stop_speed_lowest_fraction < 1:
            raise ConfigError(
                f"{self.stop_speed_lowest_fraction!r}",
                key="stop_speed_lowest_fraction",
                expected="a fraction 0 <= g < 1 of the lowest input's free speed (0: no cap)",
            )
        if not self.stall_split_a > 0:
            raise ConfigError(f"{self.stall_split_a!r}", key="stall_split_a", expected="a current > 0 A")
        widen = self.activity_band
        if widen and (len(widen[0]) not in (3, 4) or any(len(row) != len(widen[0]) for row in widen)):
            raise ConfigError(
                f"{widen!r}",
                key="activity_band",
                expected="rows of [activity_v, speed_widening_rad_s, current_widening_a] (a fourth number: "
                "the current's widening below the model, the third then above it), all of one length",
            )
        if any(b[0] <= a[0] for a, b in zip(widen, widen[1:])):
            raise ConfigError(
                "activities must increase", key="activity_band", expected="increasing activities"
            )
        if any(not all(x >= 0 for x in row) for row in widen):
            raise ConfigError(
                "values must be >= 0", key="activity_band", expected="activities and widenings >= 0"
            )
        if not 0 < self.free_speed_headroom_fraction <= 1:
            raise ConfigError(
                f"{self.free_speed_headroom_fraction!r}",
                key="free_speed_headroom_fraction",
                expected="a fraction 0 < f <= 1 of the free-speed headroom (0 or absent: the default 0.5)",
            )
        if not (self.joint_band_sum == 0 or 1 <= self.joint_band_sum <= 2):
            raise ConfigError(
                f"{self.joint_band_sum!r}",
                key="joint_band_sum",
                expected="a sum of band shares between 1 and 2, or 0 (off)",
            )
        if not (self.noise_bands == 0 or 1 <= self.noise_bands <= 50):
            raise ConfigError(
                f"{self.noise_bands!r}",
                key="noise_bands",
                expected="a number of the vehicle's noise units between 1 and 50, or 0 (absolute bands)",
            )
        if self.detection.on and not (self.noise_bands > 0 and isinstance(self.steady, BalanceRule)):
            raise ConfigError(
                f"false_alarms_per_100h = {self.detection.false_alarms_per_100h!r}",
                key="detection",
                expected='the sequential test needs bands in noise units (noise_bands > 0) and kind = "balance"',
            )
        if not (self.equation_bands == 0 or (1 <= self.equation_bands <= 50 and self.noise_bands > 0)):
            raise ConfigError(
                f"{self.equation_bands!r}",
                key="equation_bands",
                expected="a number of each balance's noise units between 1 and 50 (with noise_bands > 0), "
                "or 0 (the tree on the speed and current deviations alone)",
            )
        if not (
            self.speed_against_siblings == 0
            or (0 < self.speed_against_siblings <= 10 and self.noise_bands > 0)
        ):
            raise ConfigError(
                f"{self.speed_against_siblings!r}",
                key="speed_against_siblings",
                expected="a share 0 < s <= 10 of each motor's own speed sigma below which the speed is judged "
                "against its siblings' prediction (with noise_bands > 0), or 0 (each motor on its own)",
            )
        if not 0 <= self.range_margin <= 10:
            raise ConfigError(
                f"{self.range_margin!r}",
                key="range_margin",
                expected="a share 0..10 of the identified speed range's ends (0: judged everywhere)",
            )
        if not (self.range_growth == 0 or (0 < self.range_growth <= 4 and self.range_margin > 0)):
            raise ConfigError(
                f"{self.range_growth!r}",
                key="range_growth",
                expected="an exponent 0 < g <= 4 of the bands' growth beyond the identified speeds (with"
                " range_margin > 0), or 0 (the bands as measured)",
            )
        if not 1 <= self.conditions_reach <= 100:
            raise ConfigError(
                f"{self.conditions_reach!r}",
                key="conditions_reach",
                expected="a multiple 1..100 of the identified flight's busiest input and loosest pairing "
                "(1: not beyond)",
            )
        if not 0 <= self.conditions_growth <= 4:
            raise ConfigError(
                f"{self.conditions_growth!r}",
                key="conditions_growth",
                expected="an exponent 0..4 of the bands' growth beyond the identified flight's conditions",
            )
        for key, of in SIBLING_MULTIPLES.items():
            if not 0 <= getattr(self, key) <= 100:
                raise ConfigError(
                    f"{getattr(self, key)!r}", key=key, expected=f"a multiple 0..100 of {of} (0: not used)"
                )
        if not 0 < self.conditions_siblings_s <= 600:
            raise ConfigError(
                f"{self.conditions_siblings_s!r}",
                key="conditions_siblings_s",
                expected="a time constant > 0 and <= 600 s",
            )
        if not self.stall_split_typical >= 0:
            raise ConfigError(
                f"{self.stall_split_typical!r}",
                key="stall_split_typical",
                expected="a multiple >= 0 of the motor's typical current (0: stall_split_a)",
            )
        if not 0 <= self.slow_band_fraction <= 1:
            raise ConfigError(
                f"{self.slow_band_fraction!r}",
                key="slow_band_fraction",
                expected="a share 0 < f <= 1 of the bands, or 0 (no slow look)",
            )
        band = self.current_band_a
        if len(band) < 1 or any(len(p) != 2 for p in band):
            raise ConfigError(
                "needs at least one [voltage_v, halfwidth_a] pair",
                key="current_band_a",
                expected="a list of [voltage_v, halfwidth_a] pairs",
            )
        volts = [p[0] for p in band]
        if any(b <= a for a, b in zip(volts, volts[1:])):
            raise ConfigError("voltages must increase", key="current_band_a", expected="increasing voltages")
        if any(not p[1] > 0 for p in band):
            raise ConfigError("half-widths must be > 0 A", key="current_band_a", expected="half-widths > 0 A")

    @cached_property
    def rules(self) -> tuple[Rule, ...]:
        """The pipeline's rules in order (:mod:`.rules`): the comparison (``steady``), each motor's healthy
        offset (bands from the vehicle's noise), the sensors, the pairing error, the bands (which may grow
        with it), the pairing's limits, the tree and its slow look, which samples count, the sequential test where
        the profile has one, persistence. Made once per profile (frozen)."""
        from .rules.against import AgainstSiblings
        from .rules.announce import Persistence, Sequential
        from .rules.bands import Bands, LiveNoise, SiblingBands
        from .rules.equations import Equations, TorqueSlowLook
        from .rules.judged import Judged
        from .rules.offsets import HealthyOffsets
        from .rules.pairing import PairingGuard, PairingLimits
        from .rules.sensors import SensorCheck
        from .rules.tree import SlowLook, Tree
        from .rules.voltage import VoltageSlowLook

        return (
            self.steady,
            *([HealthyOffsets()] if self.noise_bands > 0 else []),
            SensorCheck(self.plausibility),
            PairingGuard(self),
            *([LiveNoise(self), SiblingBands(self)] if self.grows_as_siblings else [Bands(self)]),
            PairingLimits(self),
            *([AgainstSiblings(self)] if self.speed_against_siblings > 0 and self.noise_bands > 0 else []),
            Tree(self),
            *([Equations(self)] if self.equation_bands > 0 else []),
            SlowLook(self.slow_band_fraction, self.joint_band_sum),
            *([VoltageSlowLook(self)] if self.voltage_slow_as_siblings else []),
            *([TorqueSlowLook(self)] if self.equation_bands > 0 and self.slow_band_fraction > 0 else []),
            Judged(self),
            *([Sequential(self)] if self.detection.on else []),
            Persistence(self),
        )

    def current_halfwidth_a(
        self, voltage_v: ArrayLike, activity_v: ArrayLike | None = None, *, below: bool = False
    ) -> NDArray[np.float64]:
        """Half-width of the current band at each input voltage (linear, held constant outside), widened
        by the input activity when given: the side above the model, or with ``below`` the side below it
        (the same unless ``activity_band`` has its fourth column)."""
        v = np.asarray(voltage_v, dtype=float)
        xs = [p[0] for p in self.current_band_a]
        ys = [p[1] for p in self.current_band_a]
        band = np.interp(v, xs, ys)
        if activity_v is not None and self.activity_band:
            band = band + self._widening(activity_v, 3 if below and len(self.activity_band[0]) == 4 else 2)
        return band

    def bands(
        self, voltage_v: ArrayLike, activity_v: ArrayLike | None = None
    ) -> tuple[NDArray[np.float64] | float, NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`speed_band`, :meth:`current_halfwidth_a` and its side below the model, in one call (the
        activity read once)."""
        if activity_v is None or not self.activity_band:
            current = self.current_halfwidth_a(voltage_v)
            return self.speed_band_rad_s, current, current.copy()
        activity = nan_to_zero(np.asarray(activity_v, dtype=float))
        xs = [row[0] for row in self.activity_band]
        base = self.current_halfwidth_a(voltage_v)
        above = base + np.interp(activity, xs, [row[2] for row in self.activity_band])
        below = (
            base + np.interp(activity, xs, [row[3] for row in self.activity_band])
            if len(self.activity_band[0]) == 4
            else above.copy()
        )
        speed = self.speed_band_rad_s + np.interp(activity, xs, [row[1] for row in self.activity_band])
        return speed, above, below

    def speed_band(self, activity_v: ArrayLike | None = None) -> NDArray[np.float64] | float:
        """Half-width of the speed band [rad/s], widened by the input activity when given."""
        if activity_v is None or not self.activity_band:
            return self.speed_band_rad_s
        return self.speed_band_rad_s + self._widening(activity_v, 1)

    @property
    def judges_within_noise_conditions(self) -> bool:
        """Whether samples are judged only within the speeds, input activity and pairing the vehicle's noise
        was measured at (``range_margin`` > 0 with bands in noise units): :class:`~.rules.judged.Judged`
        sets the rest aside, and :class:`~.rules.pairing.PairingLimits` then leaves the pairing to it."""
        return self.noise_bands > 0 and self.range_margin > 0

    @property
    def slow_as_siblings(self) -> bool:
        """Whether the slow look's bands are bounded by how its siblings' slow averages run
        (``slow_siblings``, :mod:`.rules.tree`): the live noise measures them before the vehicle stage."""
        return self.slow_siblings > 0 and self.slow_band_fraction > 0 and self.grows_as_siblings

    @property
    def torque_slow_as_siblings(self) -> bool:
        """Whether the torque's slow look is bounded by the spread of its siblings' slow torque averages
        (``torque_slow_siblings``, :mod:`.rules.equations`): the live noise averages each motor's torque
        slowly before the vehicle stage, which gives the spread."""
        return (
            self.torque_slow_siblings > 0
            and self.slow_band_fraction > 0
            and self.equation_bands > 0
            and self.grows_as_siblings
        )

    @property
    def voltage_slow_as_siblings(self) -> bool:
        """Whether an open transistor is also read in the voltage balance's slow average against its
        siblings (``voltage_slow_siblings``, :mod:`.rules.voltage`): the live noise averages each motor's
        voltage residual slowly before the vehicle stage, which gives the spread."""
        return (
            self.voltage_slow_siblings > 0
            and self.slow_band_fraction > 0
            and self.equation_bands > 0
            and self.grows_as_siblings
        )

    @property
    def grows_as_siblings(self) -> bool:
        """Whether the bands beyond the noise's conditions grow as the siblings' deviations run
        (``conditions_siblings``, :mod:`.rules.bands`): the vehicle stage then runs before the bands."""
        return (
            self.judges_within_noise_conditions
            and self.conditions_reach > 1
            and self.conditions_growth > 0
            and self.conditions_siblings > 0
        )

    def speed_only_band(
        self, speed_band_rad_s: ArrayLike, omega_model_rad_s: ArrayLike
    ) -> NDArray[np.float64]:
        """Half-width of the speed band without a trusted current [rad/s]: the wider of the speed band and
        ``speed_only_band_frac`` of the model speed (a model error cannot be told from a fault)."""
        return np.maximum(speed_band_rad_s, self.speed_only_band_frac * np.abs(omega_model_rad_s))

    def _widening(self, activity_v: ArrayLike, column: int) -> NDArray[np.float64]:
        """Column 1 (speed), 2 (current; above the model with four columns) or 3 (current below the model)
        of ``activity_band`` at each activity (linear, held outside)."""
        a = nan_to_zero(np.asarray(activity_v, dtype=float))
        return np.interp(
            a, [row[0] for row in self.activity_band], [row[column] for row in self.activity_band]
        )

    def stall_split(self, bus_voltage_v: ArrayLike | None = None) -> NDArray[np.float64] | float:
        """The F2.1/F4.2 current split [A], scaled with bus voltage when ``stall_split_per_v`` is set."""
        if bus_voltage_v is None or self.stall_split_per_v == 0:
            return self.stall_split_a
        bus = np.asarray(bus_voltage_v, dtype=float)
        scaled = self.stall_split_a + self.stall_split_per_v * (bus - self.stall_split_ref_v)
        return np.where(np.isfinite(bus), scaled, self.stall_split_a)
