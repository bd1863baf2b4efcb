"""The bands around the model the tree judges against: the profile's absolute ones, or each motor's own
noise times ``noise_bands`` (:mod:`..noise`).

**Grown as the siblings run** (``conditions_siblings``). Beyond the input activity and the pairing error
the identification flight reached, σ(a, e) is an extrapolation, and ``excess ** conditions_growth`` grows
it so that the worst healthy flight of the development worlds stayed inside; on most flights that made
the bands 5 to 20 times wider than their healthy deviations ran (``benchmarks/bench_noise_beyond.py``,
the tail at growth 2 as low as 0.05 σ), and a fault as deep as an open transistor in moderate air read
NORMAL. How wide healthy deviations run in the air of the moment is something the vehicle itself shows:
the six motors share the air, the battery and the model's error away from the identification flight.
So :class:`LiveNoise` low-passes each motor's squared deviations in its identified σ, ``z²``, over the
judged samples in its identified speed range (time constant ``conditions_siblings_s``), the vehicle
stage (:mod:`..siblings`) takes the median of the other motors' latest, and :class:`SiblingBands` grows
the bands beyond the conditions by ``m·√(median)`` (m = ``conditions_siblings``), never by less than 1
and never by more than ``excess ** conditions_growth``: a motor is judged against how its siblings run,
not against itself (a fault's own departure never widens its band), and where fewer than three of its
siblings (all but one on a smaller vehicle, :mod:`..siblings`) have a value the growth is the excess's
alone. Within the conditions nothing changes.

**The torque's own growth** (``torque_siblings_spread``). The torque balance against its siblings
(:mod:`..rules.equations`) has a band of its own σ, grown beyond the conditions as the larger of the
deviations' bands; in gusty air that was about twice what the median healthy flight's torque needed,
and up to 25 times on some (``benchmarks/bench_noise_beyond.py``: the torque's tail there 0.44-0.47 σ),
while with no growth it was too narrow on half the gusty flights. What the torque needs the siblings show
directly: the vehicle stage gives how far the other motors' torque residuals lie from their median (a
robust standard deviation, :mod:`..siblings`, "The siblings' spread"), :class:`SiblingBands` low-passes it
per motor over its judged samples in its identified speed range (``conditions_siblings_s``, as the live
noise), and the torque's growth beyond the conditions is at most m times that spread over the torque's
identified σ(a, e) (m = ``torque_siblings_spread``), never less than 1 and never more than the
deviations' growth. Where the profile bounds the torque's slow look by its siblings
(``torque_slow_siblings``), :class:`LiveNoise` also averages each motor's torque residual slowly for the
stage, and :class:`SiblingBands` low-passes the spread of the siblings' slow averages alike
(:mod:`..rules.equations`, "The torque's slow look as its siblings run"); where an open transistor is read
in the voltage balance's slow average (``voltage_slow_siblings``), the voltage residual too, and that slow
average's mean squared departure from the motor's voltage offset, whose median over the siblings the
vehicle stage gives (:mod:`..rules.voltage`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ..._arrays import broadcast_to
from ...model.dynamics import affine_recurrence, last_of, marked_before, previous
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..noise import BandNoise
    from ..profile import ThresholdProfile

__all__ = ["Bands", "LiveNoise", "SiblingBands"]

#: a sample's z² counts at most this much in the live noise (one wild sample moves it by a bounded step)
Z2_MAX = 100.0


def _noise_of(frame: Frame, profile: ThresholdProfile) -> list[BandNoise]:
    noise = frame.noise
    if noise is None or len(noise) != frame.shape[0]:
        raise ValueError(f"profile {profile.name!r} needs each motor's noise (noise_bands); none given")
    return list(noise)


def _live_samples(frame: Frame) -> NDArray[np.bool_]:
    """The samples a live low-pass counts: each row's own (not its padding), judged, and in its identified
    speed range (module doc: the deviations' live noise and the torque's spread alike)."""
    counted = frame.steady & (np.arange(frame.shape[1])[None, :] < np.asarray(frame.counts)[:, None])
    return np.asarray(counted & frame.within_identified_speeds)


def _against_siblings(noise: Sequence[BandNoise]) -> NDArray[np.bool_]:
    """Whether each row's motor is judged in the torque against its siblings' (its noise was measured
    so), a column (rows × 1)."""
    return np.array([n.torque_vs_siblings is not None for n in noise])[:, None]


def _sigmas(frame: Frame) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each row's identified σ(a, e) of the speed and the current at its samples."""
    a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
    return frame.noise_as_rows().sigmas(a, frame.pairing_error_rad_s)


@dataclass(frozen=True)
class LiveNoise(Rule):
    """Writes ``sigma_speed_rad_s``, ``sigma_current_a`` and the low-passed ``live_z2_speed``,
    ``live_z2_current`` of each motor (module doc, "Grown as the siblings run"), and where the profile
    bounds the slow look by its siblings (``slow_siblings``) ``slow_ms_speed``, ``slow_ms_current``
    (:meth:`_slow_squares`); carries each low-pass's last counted time and value (speed, then current),
    then the slow ones' counted means (:data:`SLOW_CARRY`)."""

    name = "live_noise"
    profile: ThresholdProfile

    def new_carry(self) -> Any:
        # (time, value) of the speed's and the current's low-pass, then (slow_siblings) the slow averages'
        # counted means' (time, sum, weight) of the speed and the current and the row's last sample time,
        # then (torque_slow_siblings) the slow torque average's (time, value), then (voltage_slow_siblings)
        # the slow voltage average's
        return (math.nan,) * self._widths()[-1]

    def _widths(self) -> tuple[int, int, int, int]:
        """Where each part of a row's carry ends: the fast low-passes, the slow squares, the slow torque,
        the slow voltage."""
        slow = 4 + (SLOW_CARRY if self.profile.slow_as_siblings else 0)
        torque = slow + (2 if self.profile.torque_slow_as_siblings else 0)
        return 4, slow, torque, torque + (VOLTAGE_CARRY if self.profile.voltage_slow_as_siblings else 0)

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        profile = self.profile
        _noise_of(frame, profile)  # each motor has its noise (else a clear error)
        fast_end, slow_end, torque_end, voltage_end = self._widths()
        parts = [self._fast(frame, [c[:fast_end] for c in carries])]
        if profile.slow_as_siblings:
            parts.append(self._slow_squares(frame, [c[fast_end:slow_end] for c in carries]))
        if profile.torque_slow_as_siblings:
            frame.torque_slow_raw_nm, torque = self._slow_raw(
                frame, frame.torque_residual_nm, [c[slow_end:torque_end] for c in carries]
            )
            parts.append(torque)
        if profile.voltage_slow_as_siblings:
            parts.append(self._slow_voltage_square(frame, [c[torque_end:voltage_end] for c in carries]))
        return [sum(row, ()) for row in zip(*parts)]

    def _slow_voltage_square(self, frame: Frame, carries: list[Any]) -> list[tuple[float, ...]]:
        """``voltage_slow_raw_v`` (:meth:`_slow_raw`) and ``slow_ms_voltage``: that slow average's squared
        departure from the motor's voltage offset, averaged over ``conditions_siblings_s`` of its counted
        samples (NaN until it holds one time constant's worth, :func:`counted_mean`), which the vehicle
        stage takes the median of (rules/voltage.py); each row's carry advanced (:data:`VOLTAGE_CARRY`)."""
        # as the voltage look reads it: with a trusted current (rules/voltage.py)
        averaged, raw = self._slow_raw(
            frame, frame.voltage_residual_v, [c[:2] for c in carries], trusted=True
        )
        frame.voltage_slow_raw_v = averaged
        c = np.array([tuple(x[2:]) for x in carries], dtype=float).reshape(frame.shape[0], 4)
        if averaged is None:
            frame.slow_ms_voltage = None
            return [r + tuple(x) for r, x in zip(raw, c.tolist())]
        x2 = (averaged - frame.noise_as_rows().voltage_offset) ** 2
        counted = np.isfinite(x2)
        mean, last_t, last_sum, last_weight = counted_mean(
            frame.time_s,
            np.where(counted, x2, 0.0),
            counted,
            self.profile.conditions_siblings_s,
            c[:, 0],
            c[:, 1],
            c[:, 2],
            c[:, 3],
        )
        frame.slow_ms_voltage = mean
        ends = last_of(frame.time_s, frame.counts)
        seen = [c[r, 3] if end is None else end for r, end in enumerate(ends)]
        return [raw[r] + (last_t[r], last_sum[r], last_weight[r], seen[r]) for r in range(frame.shape[0])]

    def _slow_raw(
        self, frame: Frame, residual: NDArray[np.float64] | None, carries: list[Any], trusted: bool = False
    ) -> tuple[NDArray[np.float64] | None, list[tuple[float, ...]]]:
        """A balance's ``residual`` averaged over each motor's judged samples in its identified speeds
        (``trusted``: with a trusted current only) with ``slow_factor`` times the deviations' low-pass time,
        as the slow looks average the balance against its siblings (rules/equations.py), NaN where not
        counted: the vehicle stage gives the spread of the siblings' torque (rules/equations.py, "The
        torque's slow look as its siblings run") and the voltage's mean square (rules/voltage.py); None
        without a residual; each row's carry advanced."""
        if residual is None:
            return None, [tuple(c) for c in carries]
        counted = _live_samples(frame) & np.isfinite(residual)
        if trusted:
            counted &= frame.current_trusted()
        return slow_average(frame, residual, counted, carries)

    def _slow_squares(self, frame: Frame, carries: list[Any]) -> list[tuple[float, ...]]:
        """``slow_ms_speed`` and ``slow_ms_current``: each motor's slow averages' squared deviation from its
        slow offset, averaged over ``conditions_siblings_s`` of its counted samples where the slow look is
        ready, and NaN (no reference for its siblings) until that average holds one time constant's worth
        of them (:func:`counted_mean`; rules/tree.py, "The slow look as its siblings run"); each row's carry
        advanced."""
        slow = frame.slow
        if slow is None:
            frame.slow_ms_speed = frame.slow_ms_current = None
            return [tuple(c) for c in carries]
        offset_speed, offset_current, _, _ = frame.noise_as_rows().slow_quiet()
        x2 = np.concatenate(
            [(slow.delta_omega_rad_s - offset_speed) ** 2, (slow.delta_current_a - offset_current) ** 2]
        )
        counted = np.concatenate([_live_samples(frame) & slow.ready] * 2) & np.isfinite(x2)
        rows = frame.shape[0]
        c = np.array(carries, dtype=float).reshape(rows, SLOW_CARRY)
        time2 = np.concatenate([frame.time_s, frame.time_s])
        seen = np.concatenate([c[:, 6], c[:, 6]])
        mean, last_t, last_sum, last_weight = counted_mean(
            time2,
            np.where(counted, x2, 0.0),
            counted,
            self.profile.conditions_siblings_s,
            np.concatenate([c[:, 0], c[:, 3]]),
            np.concatenate([c[:, 1], c[:, 4]]),
            np.concatenate([c[:, 2], c[:, 5]]),
            seen,
        )
        frame.slow_ms_speed, frame.slow_ms_current = mean[:rows], mean[rows:]
        ends = last_of(frame.time_s, frame.counts)  # each row's last sample time (None: no sample)
        last_seen = [c[r, 6] if end is None else end for r, end in enumerate(ends)]
        return [
            (
                last_t[r],
                last_sum[r],
                last_weight[r],
                last_t[rows + r],
                last_sum[rows + r],
                last_weight[rows + r],
                last_seen[r],
            )
            for r in range(rows)
        ]

    def _fast(self, frame: Frame, carries: list[Any]) -> list[Any]:
        """The fast deviations' σ and low-passed z² (class doc); each row's carry advanced."""
        speed, current = _sigmas(frame)
        frame.sigma_speed_rad_s, frame.sigma_current_a = speed, current
        counted = _live_samples(frame)
        with np.errstate(divide="ignore", invalid="ignore"):
            z2 = np.concatenate(
                [
                    ((frame.omega_judged_rad_s - frame.omega_model_rad_s) / speed) ** 2,
                    ((frame.current_judged_a - frame.current_model_a) / current) ** 2,
                ]
            )
        counted2 = np.concatenate([counted, counted]) & np.isfinite(z2)
        frame.live_z2_speed, frame.live_z2_current, carried = self._low_passes(
            frame, np.minimum(z2, Z2_MAX), counted2, carries
        )
        return carried

    def _low_passes(
        self, frame: Frame, values: NDArray[np.float64], counted: NDArray[np.bool_], carries: list[Any]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[tuple[float, ...]]]:
        """The speed's and the current's ``values`` (stacked: every row's speed, then every row's current)
        averaged over their ``counted`` samples for ``conditions_siblings_s`` (:func:`held_average`), from
        each row's carry of (time, value) for the speed then the current: the two averages and the carries
        advanced."""
        rows = frame.shape[0]
        carried = np.array(carries, dtype=float).reshape(rows, 2, 2)  # (speed, current) × (time, value)
        low, last_t, last_y = held_average(
            np.concatenate([frame.time_s, frame.time_s]),
            values,
            counted,
            self.profile.conditions_siblings_s,
            np.concatenate([carried[:, 0, 0], carried[:, 1, 0]]),
            np.concatenate([carried[:, 0, 1], carried[:, 1, 1]]),
        )
        advanced: list[tuple[float, ...]] = [
            (last_t[r], last_y[r], last_t[rows + r], last_y[rows + r]) for r in range(rows)
        ]
        return low[:rows], low[rows:], advanced


#: what a row carries between calls for each of its slow averages' counted means (speed, then current):
#: (last counted time, sum, weight) each, then the row's last sample time
SLOW_CARRY = 7
#: what a row carries for its slow voltage average (last counted time, value) and that average's counted
#: mean square (last counted time, sum, weight, the row's last sample time): rules/voltage.py
VOLTAGE_CARRY = 6
#: a counted mean is a reference only once its weight is this: one time constant's worth of counted
#: samples, not the few of a moment nor what a long gap has faded
COUNTED_WEIGHT_MIN = 1.0 - math.exp(-1.0)


def counted_mean(
    time_s: NDArray[np.float64],
    values: NDArray[np.float64],
    counted: NDArray[np.bool_],
    tau_s: float,
    carry_t: NDArray[np.float64],
    carry_sum: NDArray[np.float64],
    carry_weight: NDArray[np.float64],
    carry_seen_s: NDArray[np.float64],
) -> tuple[NDArray[np.float64], list[float], list[float], list[float]]:
    """An exponentially weighted mean of each row's counted values (time constant ``tau_s``) that knows
    how much it holds: a counted sample adds its value and its weight ``1 − exp(−h/τ)``, h the time it
    stands for (since the row's previous sample, counted or not, and at most since its previous counted
    one), to a sum and a weight that both fade by ``exp(−Δt/τ)`` over the time Δt since the previous
    counted sample. The mean is sum/weight wherever the weight, faded to the sample's time, is at least
    :data:`COUNTED_WEIGHT_MIN` (one time constant's worth of counted samples), else NaN: unlike
    :func:`held_average`, a row counted for a moment, or after a gap one sample bridges, gives no value.
    ``carry_seen_s``: each row's last sample time in the calls before (the first sample ever stands for
    no time). Returns the means and each row's last counted time, sum and weight (the carried ones where
    none was counted); a split of the rows into calls gives the same values (to rounding)."""
    rows = values.shape[0]
    last, _, t_before = marked_before(time_s, counted, carry_t)
    with np.errstate(invalid="ignore", over="ignore"):
        fade = np.exp(-np.maximum(time_s - t_before, 0.0) / tau_s)
        stands = np.fmin(time_s - previous(time_s, carry_seen_s), time_s - t_before)
        weight = 1.0 - np.exp(-np.maximum(stands, 0.0) / tau_s)
    fade = np.where(counted & np.isfinite(fade), fade, 1.0)
    weight = np.where(counted & np.isfinite(weight), weight, 0.0)
    sums = affine_recurrence(
        np.concatenate([fade, fade]),
        np.concatenate([weight * np.where(counted, values, 0.0), weight]),
        np.concatenate([np.nan_to_num(carry_sum), np.nan_to_num(carry_weight)]),
    )
    total, held = sums[:rows], sums[rows:]
    t_last = np.where(
        last >= 0, np.take_along_axis(time_s, np.maximum(last, 0), axis=1), np.asarray(carry_t)[:, None]
    )
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        now = held * np.exp(-np.maximum(time_s - t_last, 0.0) / tau_s)
        mean = np.where(now >= COUNTED_WEIGHT_MIN, total / held, np.nan)
    ends = last[:, -1]
    at = np.maximum(ends, 0)
    r = np.arange(rows)
    last_t = np.where(ends >= 0, time_s[r, at], carry_t)
    last_sum = np.where(ends >= 0, total[r, at], carry_sum)
    last_weight = np.where(ends >= 0, held[r, at], carry_weight)
    return mean, last_t.tolist(), last_sum.tolist(), last_weight.tolist()


def held_average(
    time_s: NDArray[np.float64],
    values: NDArray[np.float64],
    counted: NDArray[np.bool_],
    tau_s: float | NDArray[np.float64],
    carry_t: NDArray[np.float64],
    carry_y: NDArray[np.float64],
) -> tuple[NDArray[np.float64], list[float], list[float]]:
    """An exponential average of each row's counted values over time (time constant ``tau_s``), held
    between them: at a counted sample ``y ← a·y + (1 − a)·x`` with ``a = exp(−Δt/τ)`` (τ one number, or
    each sample's), Δt the time since
    the row's previous counted sample (the carried one's at the start), the first counted sample ever
    starting it at its value; elsewhere y holds (NaN before the first). Only counted samples move it or
    its clock, so a split of the rows into calls gives the same values (to rounding). Returns the
    averages and each row's last counted time and average (the carried ones where none was counted)."""
    rows = values.shape[0]
    last, before, t_before = marked_before(time_s, counted, carry_t)
    with np.errstate(invalid="ignore"):
        a = np.exp(-np.maximum(time_s - t_before, 0.0) / tau_s)
    started = np.isfinite(carry_y)[:, None] | (before >= 0)  # a value before this sample
    a = np.where(counted, np.where(started & np.isfinite(a), a, 0.0), 1.0)
    b = (1.0 - a) * np.where(counted, values, 0.0)  # 0 where not counted (a = 1 there)
    out = affine_recurrence(a, b, np.where(np.isfinite(carry_y), carry_y, 0.0))
    out = np.where(started | counted, out, np.nan)
    ends = last[:, -1]
    last_t = np.where(ends >= 0, time_s[np.arange(rows), np.maximum(ends, 0)], carry_t)
    last_y = np.where(ends >= 0, out[:, -1], carry_y)
    return out, last_t.tolist(), last_y.tolist()


@dataclass(frozen=True)
class Bands(Rule):
    """Writes ``speed_band_rad_s``, ``current_band_a`` and ``current_band_below_a`` (half-widths), and with
    the profile's ``equation_bands`` the torque balance's, ``torque_band_nm``."""

    name = "bands"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        profile = self.profile
        if profile.noise_bands > 0:
            noise, shape = _noise_of(frame, profile), frame.shape
            a = np.zeros(shape) if frame.activity_v is None else frame.activity_v
            e = frame.pairing_error_rad_s
            if frame.sigma_speed_rad_s is not None and frame.sigma_current_a is not None:
                speed, current = frame.sigma_speed_rad_s.copy(), frame.sigma_current_a.copy()
            else:
                speed, current = _sigmas(frame)
            # the torque balance's band, where the profile judges in it: NaN for a motor without its noise
            # (no usable current: nothing to judge; said once where a motor with a current has none)
            torque = np.full(shape, np.nan) if profile.equation_bands > 0 else None
            if torque is not None and any(
                not n.has_torque_noise and math.isfinite(n.current_a) for n in noise
            ):
                _warn_without_torque_noise(profile.name)
            # beyond the conditions σ was measured in, where the profile judges there (noise.py)
            reaching = profile.judges_within_noise_conditions and profile.conditions_reach > 1
            exponent = profile.conditions_growth if reaching else 0.0
            # after an input step, wider by what identification measured there (rules/balance.py)
            after = frame.after_step_factor
            widen_speed: NDArray[np.float64] | float = 1.0  # beyond the conditions, after a step
            widen_current: NDArray[np.float64] | float = 1.0
            if exponent > 0:
                grown = frame.noise_as_rows().growth(
                    frame.omega_model_rad_s, profile.range_margin, a, e, exponent
                )
                widen_speed, widen_current = self.as_siblings_run(frame, grown)
            step = None if after is None else np.where(np.isfinite(after), after, 1.0)
            if torque is not None:
                sigma = frame.noise_as_rows().torque_sigmas(a, e)
                widest = self.torque_growth(frame, np.maximum(widen_speed, widen_current), sigma)
                torque = sigma * broadcast_to(widest if step is None else widest * step, shape)
            if step is not None:
                widen_speed, widen_current = widen_speed * step, widen_current * step
            if profile.range_growth > 0 and profile.judges_within_noise_conditions:
                # beyond the identified speeds (within range_margin) each motor's own model is
                # extrapolated (noise.py, beyond_range), as far as the motor also turns beyond them (one
                # that lost drive is commanded beyond and turns short); a torque judged against its
                # siblings' is not: they share that error at the same speed (siblings.py, "Beyond the
                # identified speeds")
                beyond = frame.noise_as_rows().beyond_range(
                    frame.omega_model_rad_s,
                    profile.range_margin,
                    profile.range_growth,
                    frame.omega_judged_rad_s,
                )
                widen_speed, widen_current = widen_speed * beyond, widen_current * beyond
                if torque is not None:
                    torque = torque * np.where(_against_siblings(noise), 1.0, beyond)
            speed *= widen_speed
            current *= widen_current
            frame.speed_band_rad_s = profile.noise_bands * speed
            frame.current_band_a = profile.noise_bands * current
            frame.current_band_below_a = frame.current_band_a.copy()
            if torque is not None:
                frame.torque_band_nm = profile.equation_bands * torque
        else:
            frame.speed_band_rad_s, frame.current_band_a, frame.current_band_below_a = profile.bands(
                frame.judged_voltage_v, frame.activity_v
            )
        return carries

    def as_siblings_run(
        self, frame: Frame, grown: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The growth beyond the conditions of the speed's band and the current's (rows × samples): the
        excess's, ``grown``, for both (:class:`SiblingBands` bounds it by the siblings')."""
        return grown, grown

    def torque_growth(
        self, frame: Frame, grown: NDArray[np.float64] | float, sigma_nm: NDArray[np.float64]
    ) -> NDArray[np.float64] | float:
        """The growth of the torque's band beyond the conditions (before a step's widening), given the
        larger of the deviations' growths there, ``grown``, and the torque's identified σ(a, e) at each
        sample: ``grown`` (:class:`SiblingBands` may bound it by the siblings' torque spread)."""
        return grown


def slow_average(
    frame: Frame, values: NDArray[np.float64], counted: NDArray[np.bool_], carries: Sequence[Any]
) -> tuple[NDArray[np.float64] | None, list[tuple[float, ...]]]:
    """``values`` averaged over each row's ``counted`` samples with the profile's ``slow_factor`` times
    the deviations' low-pass time at each sample (:func:`held_average`, from each row's carried (time,
    value)), NaN where not counted, and the carries advanced; None and the carries as given where the
    profile has no slow look or the frame no low-pass time."""
    slow_factor = float(getattr(frame.profile.steady, "slow_factor", 0.0))
    if frame.low_pass_s is None or not slow_factor > 0:
        return None, [tuple(c) for c in carries]
    carried = np.array(carries, dtype=float).reshape(frame.shape[0], 2)
    low, last_t, last_y = held_average(
        frame.time_s,
        np.where(counted, values, 0.0),
        counted,
        slow_factor * broadcast_to(frame.low_pass_s, frame.shape),
        carried[:, 0],
        carried[:, 1],
    )
    return np.where(counted, low, np.nan), list(zip(last_t, last_y))


@dataclass(frozen=True)
class SiblingBands(Bands):
    """:class:`Bands`, grown beyond the noise's conditions no more than the siblings' deviations run
    (module doc, "Grown as the siblings run"): the vehicle stage runs before it."""

    reads_siblings: ClassVar[bool] = True

    def new_carry(self) -> Any:
        # each low-passed spread's last counted time and value: the siblings' torque spread, then
        # (torque_slow_siblings) the spread of their slow torque averages
        return (math.nan,) * (2 * len(self._spreads()))

    def _spreads(self) -> list[tuple[str, str, bool]]:
        """The spreads low-passed, in the carry's order: the stage's field, the low-passed field, and
        whether the profile asks for it."""
        profile = self.profile
        spreads = [("torque_siblings_spread_nm", "torque_spread_low_nm", profile.torque_siblings_spread > 0)]
        if profile.torque_slow_as_siblings:
            spreads.append(("siblings_torque_slow_spread_nm", "torque_slow_spread_low_nm", True))
        return spreads

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        rows = frame.shape[0]
        carried = np.array([c if c is not None else self.new_carry() for c in carries], dtype=float)
        carried = carried.reshape(rows, -1)
        frame.torque_spread_low_nm = frame.torque_slow_spread_low_nm = None
        parts = []
        for k, (given, into, asked) in enumerate(self._spreads()):
            part = carried[:, 2 * k : 2 * k + 2]
            spread = getattr(frame, given)
            if spread is None or not asked:
                parts.append([tuple(c) for c in part.tolist()])
                continue
            low, advanced = self._held(frame, spread, part)
            setattr(frame, into, low)
            parts.append(advanced)
        super().judge(frame, carries)
        return [sum(row, ()) for row in zip(*parts)]

    def _held(
        self, frame: Frame, spread: NDArray[np.float64], carried: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], list[tuple[float, float]]]:
        """A siblings' spread low-passed over each motor's judged samples in its identified speeds
        (``conditions_siblings_s``, as the live noise), from each row's carried (time, value): the
        low-passed spread and the carries advanced."""
        counted = _live_samples(frame) & np.isfinite(spread)
        low, last_t, last_y = held_average(
            frame.time_s,
            np.where(counted, spread, 0.0),
            counted,
            self.profile.conditions_siblings_s,
            carried[:, 0],
            carried[:, 1],
        )
        return low, list(zip(last_t, last_y))

    def torque_growth(
        self, frame: Frame, grown: NDArray[np.float64] | float, sigma_nm: NDArray[np.float64]
    ) -> NDArray[np.float64] | float:
        """``grown`` bounded by the siblings' torque spread (module doc, "The torque's own growth") on the
        rows judged against their siblings, where the spread is known."""
        low = frame.torque_spread_low_nm
        if low is None or frame.noise is None:
            return grown
        against = _against_siblings(frame.noise)
        with np.errstate(divide="ignore", invalid="ignore"):
            live = self.profile.torque_siblings_spread * low / sigma_nm
        bounded = np.minimum(grown, np.maximum(live, 1.0))
        return np.where(against & np.isfinite(live), bounded, grown)

    def as_siblings_run(
        self, frame: Frame, grown: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        out = []
        for siblings in (frame.siblings_z2_speed, frame.siblings_z2_current):
            if siblings is None:
                out.append(grown)
                continue
            with np.errstate(invalid="ignore"):
                live = self.profile.conditions_siblings * np.sqrt(siblings)
            out.append(np.where(np.isfinite(live), np.minimum(grown, np.maximum(live, 1.0)), grown))
        return out[0], out[1]


def _warn_without_torque_noise(profile_name: str) -> None:
    """Say once (Python's warnings show each place once) that a vehicle file without the torque's noise
    is judged from the deviations alone, and how to get it."""
    warnings.warn(
        f"profile {profile_name!r} judges friction and a lighter propeller in the torque balance "
        "(equation_bands), and the vehicle's noise has no noise.N.torque_residual_nm (a file written "
        "before it was measured): they are judged from the speed and current deviations instead; "
        "`mav-motor-health fit FLIGHT_LOG --out vehicle.toml` measures it",
        UserWarning,
        stacklevel=2,
    )
