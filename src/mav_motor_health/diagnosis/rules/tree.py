"""The paper's threshold tree (:mod:`..tree`) as pipeline rules: the tree on every sample, then the slow
look where the tree saw nothing.

**The stall split's scale.** A stalled motor's current tells an open phase (F2.1, little) from a lost
back-EMF signal (F4.2, more); with the profile's ``stall_split_typical`` the split is that multiple of the
motor's typical current in flight (the shipped profile: 1.27, halfway in ratio between the paper's two
stalls, about 3 A and 7.7 A, over its motor's 3.8 A at hover; docs/flight.md, "The stall split halfway
between the paper's stalls"). Identification
measures the typical current on its healthy flight; but where the ESC reports its *input* current, the
reading divided by the duty carries the duty ripple's copper loss, ``V·σ_d²/R``, which grows with the air
(``benchmarks/bench_input_ripple.py``), while a stalled motor's command sits at full duty, with no
ripple. On a vehicle identified in gusty air the typical current then came out 2–3 × what the motor
draws in calm air, the split above any F4.2 stall, and every F4.2 was named F2.1 (docs/flight.md, "The
stall split from the lower of two typical currents"). Ripple only ever adds, so of two typical currents
the lower is the nearer the motor's own: the split's scale is the lower of identification's and this
flight's so far: the geometric mean of the motor's measured current on its judged samples, counted once
:data:`MIN_FLIGHT_SAMPLES` are in. A sample whose model speed is below the speeds identification covered
(idle, the ground, a long descent) or that is stalled (below the tree's stop speed) does not count: its
current is not the motor's typical one and would set the split too low; samples above those speeds can
only raise this flight's figure, which the lower of the two then leaves aside. With a motor-side current
the two agree and the split moves little.

**The slow look as its siblings run** (``slow_siblings``). The slow look's σ is measured on the
identification flight and extrapolated in the input activity and the pairing error beyond it; where a
vehicle identified in calm air meets moderate air with ESCs reporting at 10 Hz, that extrapolation ran
two to three times wider than the healthy slow averages did, and the reach grew with the fast bands on
top (held-out world 1008: a slow band of about 90 rad/s around healthy slow deviations of about ±7 rad/s,
10th to 90th percentile, and an open transistor's 35 rad/s read NORMAL). How far healthy slow averages run
from their models in the air of the moment, the five siblings show: each motor's squared slow deviation
from its slow offset is averaged over ``conditions_siblings_s`` (:class:`~.bands.LiveNoise`), the
vehicle stage takes the median of the other motors' latest (:mod:`..siblings`), and the slow look's band
is at most ``noise_bands · slow_band_fraction · m`` times its square root (m = ``slow_siblings``), never
below as many of the motor's own quiet slow σ: the narrower of the two bands. A motor's own departure
never narrows or widens its own band (its own mean square is never its reference), and a single faulty
sibling moves a median of five little. Unlike the siblings' spread at an instant, which five motors
parting in a yaw turn make small, each sibling's own mean square over seconds holds its manoeuvres'
departures (``benchmarks/bench_slow_siblings.py``, docs/flight.md). Only where the motor lies in its
identified speeds (by its model speed or the speed it turns): the motors that take a failed one's share
run beyond them together. A sibling's mean square is a reference only once it holds one time constant's
worth of its counted samples (:func:`~.bands.counted_mean`): on a vehicle whose motors seldom reach their
identified speeds, a sibling counted for a moment held the mean square of a few quiet samples and
narrowed the others' bands; where fewer than three siblings give one, the band is the motor's own; and
not in the slow look's own wait after an input step (``slow_factor × settle_s``,
:class:`~.base.SlowAverages`): a transient of one motor stays in its slow average for seconds, in its
siblings' mean squares never (docs/flight.md, "The slow look as its siblings run, made safe and shipped").

**The speed alone.** Where a sample has no trusted current (ESCs that report none, a reading set aside)
and the profile judges the speed alone in its own noise (bands from the vehicle's noise,
``speed_only_band_frac = 0``, the slow look as its siblings run), the slow look reads the slow speed
average alone as the tree reads the fast one there: ``SLOW`` below its band, ``FAST`` above it (depth 1),
its evidence counted for those directions as the others' is. Its band is the siblings' alone (``noise_bands
· fraction · m`` times the root of their median slow mean square, at least as many of the motor's quiet
slow σ), never the motor's own, and where the siblings give none (fewer than three, beyond the identified
speeds, in the slow look's wait) the speed alone is not read slowly. Speed and current agreeing on a fault
is what keeps the slow look's own band safe; alone, the speed has only its siblings to agree with. In
busier air than identification's, the motor's own slow σ is an extrapolation: on held-out world 1025
(no usable current) in gusty air, with commands and reports paired four to eight times more loosely than
on its identification flight, healthy slow speed averages ran 26–47 rad/s from the model against an
extrapolated slow σ of about 5, and judged against the narrower of the two bands (as the slow look with a
current is) the speed alone raised four false events in 100 minutes; its siblings, paired as loosely, held
as much. In busier air the fast look's bands grow with the air and an open transistor's or friction's few
percent of speed stay inside them, while the siblings' slow averages stay near the model (docs/flight.md,
"The slow look reads the speed alone"). The 15 % band of the other profiles is not a noise band, and
there the slow look still judges only samples with a trusted current.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..._arrays import broadcast_to
from ...model.dynamics import last_of
from ..detection import direction_evidence, evidence_toward
from ..noise import MIN_MOTOR_SAMPLES
from ..stall import stop_speeds
from ..states import Code
from ..tree import agreeing_departures, classify_depth
from .base import Frame, Rule, SlowAverages

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["MIN_FLIGHT_SAMPLES", "SlowLook", "Tree", "TypicalCarry"]

#: samples counted (:func:`flight_typical`) before this flight's typical current counts (as many as
#: identification needs to measure a motor's noise)
MIN_FLIGHT_SAMPLES = MIN_MOTOR_SAMPLES


@dataclass(frozen=True)
class TypicalCarry:
    """This flight's typical current of one motor so far: the sum of the logs of its counted samples' current
    and how many (module doc)."""

    log_sum: float = 0.0
    count: int = 0


@dataclass(frozen=True)
class Tree(Rule):
    """Writes ``state`` and ``depth``: the tree's verdict on the judged measurement against the bands."""

    name = "tree"
    profile: ThresholdProfile

    def new_carry(self) -> TypicalCarry:
        return TypicalCarry()

    def judge(self, frame: Frame, carries: list[TypicalCarry]) -> list[TypicalCarry]:
        split, carries = self._stall_split(frame, carries)
        frame.state, frame.depth = classify_depth(
            self.profile,
            omega_rad_s=frame.omega_judged_rad_s,
            omega_model_rad_s=frame.omega_model_rad_s,
            current_a=frame.current_judged_a,
            current_model_a=frame.current_model_a,
            voltage_v=frame.judged_voltage_v,
            bus_voltage_v=frame.bus_voltage_v,
            current_trusted=frame.current_trusted(),
            omega_expected_rad_s=frame.omega_expected_rad_s,
            activity_v=frame.activity_v,
            omega_free_rad_s=frame.omega_free_rad_s,
            bands=(frame.speed_band_rad_s, frame.current_band_a, frame.current_band_below_a),
            stall_split_a=split,
            stop_cap_rad_s=frame.stop_cap_rad_s,
        )
        return carries

    def _stall_split(
        self, frame: Frame, carries: list[TypicalCarry]
    ) -> tuple[NDArray[np.float64] | None, list[TypicalCarry]]:
        """The F2.1/F4.2 split of each row where the profile scales it with the motor's typical current
        and the motor's noise has one (the lower of identification's and this flight's so far, module
        doc), and the carries advanced; None: the profile's split everywhere."""
        profile, noise = self.profile, frame.noise
        if not (profile.stall_split_typical > 0 and noise):
            return None, carries
        typical = np.array([n.current_typical_a for n in noise], dtype=float)
        if not np.isfinite(typical).any():
            return None, carries
        flight, carries = flight_typical(frame, carries)
        fallback = broadcast_to(
            np.asarray(profile.stall_split(frame.bus_voltage_v), dtype=float), frame.shape
        )
        # the lower of the two; identification's where the flight has none yet, none where it has none
        reference = np.where(np.isfinite(typical)[:, None], np.fmin(typical[:, None], flight), np.nan)
        own = profile.stall_split_typical * reference
        return np.where(np.isfinite(own), own, fallback), carries


def flight_typical(
    frame: Frame, carries: list[TypicalCarry]
) -> tuple[NDArray[np.float64], list[TypicalCarry]]:
    """Each row's typical current of this flight up to each sample [A], and the carries advanced: the
    geometric mean of its judged, trusted, positive currents where its model speed is not below the speeds
    identification covered and it turns above the tree's stop speed; NaN until :data:`MIN_FLIGHT_SAMPLES`
    are counted, and on a motor whose noise does not give that range."""
    noise = frame.noise or ()
    low = np.array([n.omega_low_rad_s for n in noise], dtype=float)[:, None]
    width = frame.shape[1]
    current, model = frame.current_a, frame.omega_model_rad_s
    expected = model if frame.omega_expected_rad_s is None else frame.omega_expected_rad_s
    stop, _ = stop_speeds(frame.profile, expected, frame.stop_cap_rad_s)
    counted = (
        (np.arange(width)[None, :] < np.asarray(frame.counts)[:, None])
        & frame.steady
        & frame.current_trusted()
        & (current > 0)
        & (model >= low)  # not below the speeds identification covered (NaN: not measured, none counts)
        & (np.abs(frame.omega_rad_s) >= stop)  # turning: a stall is not the motor's typical current
    )
    logs = np.log(np.where(counted, current, 1.0))
    total = np.cumsum(logs, axis=1) + np.array([[c.log_sum] for c in carries])
    count = np.cumsum(counted, axis=1) + np.array([[c.count] for c in carries])
    with np.errstate(invalid="ignore"):
        flight = np.where(count >= MIN_FLIGHT_SAMPLES, np.exp(total / np.maximum(count, 1)), np.nan)
    news = [
        carry if last_total is None else TypicalCarry(float(last_total), int(last_count))
        for carry, last_total, last_count in zip(
            carries, last_of(total, frame.counts), last_of(count, frame.counts)
        )
    ]
    return flight, news


@dataclass(frozen=True)
class SlowLook(Rule):
    """Where the tree sees nothing, a small lasting departure may still show in the comparison's longer
    averages (the balance rule's slow look): named where speed and current agree on a fault, against the
    bands narrowed to ``fraction``; ``joint_band_sum`` as the tree's (0: 2).

    With bands from the vehicle's noise (``noise_bands``) the slow averages are read in units of their own
    σ (:mod:`..noise`, "The slow look's own noise"), against as many of them as the fast look's bands hold
    of its σ at the sample (grown beyond the identified conditions alike), times ``fraction`` (the shipped
    profile: 1, no narrowing); a motor whose vehicle file has no slow noise is not read this way. Where the
    torque balance judges friction and a lighter propeller (:mod:`.equations`), the slow look names only an
    open transistor. Without a trusted current, where the profile judges the speed alone in its own noise,
    the slow speed alone names ``SLOW`` or ``FAST`` (module doc, "The speed alone")."""

    name = "slow_look"
    fraction: float
    joint_band_sum: float = 0.0

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        slow = frame.slow
        if slow is None or not self.fraction > 0:
            return carries
        state = frame.state
        trusted = frame.current_trusted()
        own_noise = frame.noise is not None and frame.profile.noise_bands > 0
        # the speed alone too where the profile judges it in its own noise (module doc, "The speed alone")
        speed_alone = own_noise and frame.profile.speed_only_band_frac == 0 and frame.profile.slow_as_siblings
        alone = ~trusted if speed_alone else None
        candidates = slow.ready & (state == Code.NORMAL) & (trusted if alone is None else True)
        if not np.any(candidates):
            return carries
        named_toward = None
        if own_noise:
            # bands from the vehicle's noise: the slow averages in units of their own measured σ, against
            # as many of them as the fast look's bands hold of its σ here (noise_bands, grown beyond the
            # identified conditions as those are); a motor whose slow noise was not measured: none
            z_speed, z_current = frame.slow_deviation_z()
            if frame.sigma_speed_rad_s is not None and frame.sigma_current_a is not None:
                sigma_speed, sigma_current = frame.sigma_speed_rad_s, frame.sigma_current_a
            else:
                a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
                sigma_speed, sigma_current = frame.noise_as_rows().sigmas(a, frame.pairing_error_rad_s)
            with np.errstate(divide="ignore", invalid="ignore"):
                band_speed = np.asarray(frame.speed_band_rad_s, dtype=float) / sigma_speed
                band_current = (
                    np.where(z_current < 0, frame.current_band_below_a, frame.current_band_a) / sigma_current
                )
            # each departure as a share of its band: the narrower of its own and its siblings' (module doc)
            with np.errstate(divide="ignore", invalid="ignore"):
                share_speed = z_speed / (self.fraction * band_speed)
                share_current = z_current / (self.fraction * band_current)
            narrowed, siblings_speed = None, None
            if frame.profile.slow_as_siblings:
                share_speed, share_current, narrowed, siblings_speed = self._as_siblings_run(
                    frame, slow, share_speed, share_current
                )
            slow_state, slow_depth = agreeing_departures(
                share_speed, share_current, 1.0, np.ones(frame.shape), self.joint_band_sum or 2.0
            )
            if alone is not None and siblings_speed is not None:
                # no trusted current: the slow speed alone against its siblings' band (module doc, "The
                # speed alone"), as the tree reads the speed alone (depth 1); none without their reference
                with np.errstate(invalid="ignore"):
                    only = np.where(
                        siblings_speed < -1.0,
                        Code.SLOW,
                        np.where(siblings_speed > 1.0, Code.FAST, Code.NORMAL),
                    )
                slow_state[alone] = only[alone]
                slow_depth[alone] = 1.0
            if frame.z_torque is not None:
                # friction and a lighter propeller are the torque balance's where it judges them
                # (rules/equations.py): there the slow look names an open transistor only
                torque = np.isfinite(frame.z_torque)
                slow_state[torque & (slow_state != Code.F4_1)] = Code.NORMAL
            # the departure in the named direction, in σ of the bands as the test counts the fast look's
            n = frame.profile.noise_bands
            with np.errstate(divide="ignore", invalid="ignore"):
                in_bands = [n * z_speed / band_speed, n * z_current / band_current]
                if narrowed is not None:  # where the siblings' band is the narrower, in σ of that band
                    in_bands = [
                        np.where(narrower, n * self.fraction * share, own)
                        for narrower, share, own in zip(narrowed, (share_speed, share_current), in_bands)
                    ]
                if alone is not None and siblings_speed is not None:  # the speed alone: in σ of its siblings'
                    in_bands[0] = np.where(alone, n * self.fraction * siblings_speed, in_bands[0])
                toward = direction_evidence(in_bands[0], in_bands[1], trusted, n)
            named_toward = evidence_toward(toward, slow_state)
        else:
            slow_state, slow_depth = agreeing_departures(
                slow.delta_omega_rad_s,
                slow.delta_current_a,
                self.fraction * np.asarray(frame.speed_band_rad_s, dtype=float),
                self.fraction
                * np.where(slow.delta_current_a < 0, frame.current_band_below_a, frame.current_band_a),
                self.joint_band_sum or 2.0,
            )
        use = candidates & (slow_state != Code.NORMAL)
        state[use] = slow_state[use]
        frame.depth[use] = slow_depth[use]
        if named_toward is not None:
            frame.note_slow_evidence(use, named_toward)
        return carries

    def _as_siblings_run(
        self,
        frame: Frame,
        slow: SlowAverages,
        share_speed: NDArray[np.float64],
        share_current: NDArray[np.float64],
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], list[NDArray[np.bool_]], NDArray[np.float64] | None]:
        """The slow departures' shares of the narrower of their own band and the band the siblings give
        (module doc, "The slow look as its siblings run"): ``noise_bands · fraction · m`` times the root of
        the siblings' median mean square, at least as many of the motor's quiet slow σ; each share as it
        was where the siblings give none. Also where the siblings' band was the narrower (speed, current),
        and the speed's share of the siblings' band itself where they give one (NaN elsewhere; None: the
        frame has no siblings' mean squares of the speed), which the speed alone is judged in."""
        rows = frame.noise_as_rows()
        offset_speed, offset_current, quiet_speed, quiet_current = rows.slow_quiet()
        reach = frame.profile.noise_bands * self.fraction * frame.profile.slow_siblings
        # the motor in its identified speeds as measured, by its model speed or by the speed it turns (a
        # motor that lost drive is commanded beyond them and turns short: rules/bands.py, "beyond_range")
        turning = frame.omega_mean_rad_s if frame.omega_mean_rad_s is not None else frame.omega_rad_s
        within = rows.in_speed_range(frame.omega_model_rad_s, 0.0) | rows.in_speed_range(turning, 0.0)
        # and not while the slow averages still hold an input step's upset, which the siblings' mean squares
        # over seconds do not follow (the slow look's own wait after a step, rules/balance.py)
        if frame.since_step_s is not None:
            with np.errstate(invalid="ignore"):
                within &= ~(frame.since_step_s < slow.settle_s)
        out: list[NDArray[np.float64]] = []
        narrower: list[NDArray[np.bool_]] = []
        siblings_speed = None  # the speed's share of the siblings' band itself
        for q, (share, deviation, offset, quiet, siblings) in enumerate(
            (
                (
                    share_speed,
                    slow.delta_omega_rad_s,
                    offset_speed,
                    quiet_speed,
                    frame.siblings_slow_ms_speed,
                ),
                (
                    share_current,
                    slow.delta_current_a,
                    offset_current,
                    quiet_current,
                    frame.siblings_slow_ms_current,
                ),
            )
        ):
            if siblings is None:
                out.append(share)
                narrower.append(np.zeros(share.shape, dtype=bool))
                continue
            with np.errstate(divide="ignore", invalid="ignore"):
                # (np.maximum, not fmax: where the siblings give no reference, NaN, the motor's own band)
                theirs = (deviation - offset) / (reach * np.maximum(np.sqrt(siblings), quiet))
                # a larger share of the siblings' band: it is the narrower (NaN: the motor's own); only in
                # the motor's identified speeds (beyond, its own model is extrapolated and its bands grow,
                # rules/bands.py; the motors that take a failed one's share run there together)
                deeper = within & np.isfinite(theirs) & ~(np.abs(theirs) <= np.abs(share))
            out.append(np.where(deeper, theirs, share))
            narrower.append(deeper)
            if q == 0:
                siblings_speed = np.where(within & np.isfinite(theirs), theirs, np.nan)
        return out[0], out[1], narrower, siblings_speed
