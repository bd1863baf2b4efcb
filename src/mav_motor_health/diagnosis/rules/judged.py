"""Which samples the announcements may count: never a motor fault from a bad sensor, nothing beyond the
speeds the model was checked at (a stall still, and a propeller that has lost its load), nothing at idle.

Beyond the speeds identification checked the model at, the model is an extrapolation and its noise
unknown, so a departure from it is not judged. One departure needs no extrapolation: a healthy propeller's
load rises with its speed, so a healthy motor turning faster than the fastest speed of the identification
flight draws at least the current the model needs at that speed, where the model *was* checked. A motor
turning faster than that and drawing less than that current by more than its band below has lost
propeller load (F3.1: a broken or thrown blade, which the autopilot answers with full command, beyond any
speed a healthy flight shows); it is judged however far beyond the range it turns
(:func:`_unloaded_beyond`).

The check reads the motor two ways, and a sample either way shows counts. *As judged*: the model plus
the low-passed deviations against the band below, where the rule holds the sample; the deviations imply
the steady state at once, so in quiet air a lost load is named before the motor has run up to its new
speed. *As measured*, under the balance rule: the measured speed and current low-passed as the balances
are, no model in them, against the floor with the motor's band in quiet input. The deviation's band
widens with the input's activity because the model's steady state, read at a jittering paired command,
is far off in busy air (its current by tens of amperes on a heavy vehicle); the floor is the load's and
needs none of it. What a healthy motor can do below the floor is coast down after its input falls, so
this view takes a motor driven: its input not below its low-pass. And it judges such a motor also while
the rule waits after an input step: the autopilot's answer to the lost thrust *is* a step up to full
command, and waiting it out delayed the alarm by the whole wait; a healthy motor driven up lags below
its speed and draws more than its load, never less.

**In the torque.** Both views compare currents, against the current's bands, and a current's band holds
the error of the model's current at the paired command, which on a heavy vehicle runs to tens of amperes
(held-out worlds 1009 and 1014: 30 and 59 A, where the motor hovers at 11 and 5 A). The torque balance
against its siblings (:mod:`.equations`) reads the measured speed instead of the command, and its band
there was a sixth to a seventh of the current's (in amperes, over k_t); a lost propeller load read 2.5 to
10 of its bands below it, while neither current view saw it (world 1009: the faulty motor at full command,
50 % beyond the identified top, 0.7 A drawn). So a sample the rules read as F3.1 whose low-passed speed lies beyond the top is judged where its
torque, with the load the model adds between the top and the speed taken back (the floor again: a
healthy propeller needs at least its load at the top), lies below its band against its siblings and also
on its own (against its own offset and noise, grown as the band is), where the rule holds the sample;
the sequential test counts that shortfall, not the one below the extrapolated load
(:func:`_torque_below_floor`). On its own too, because the motors beyond the top are mostly those flying
on a failed one, whose siblings are no common reference: on held-out world 1008 (10-Hz telemetry) two
motors at a third of the command turned 570-610 rad/s on 35 A after a sibling stalled, and a healthy
motor at its own model read F3.1 below their median on 12 flights' samples (docs/flight.md, "A lost load
read in the torque beyond the identified speeds")."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..._arrays import one_of
from ...model.equations import current_from_speed
from ..plausibility import SensorIssue
from ..states import Code, MotorState
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["TRANSIENT_OK", "Judged"]

#: States a stalled motor shows whatever its input: announced from transient samples too.
TRANSIENT_OK = (MotorState.F2_1, MotorState.F4_2, MotorState.STALLED)
_SPEED_BROKEN = int(SensorIssue.SPEED_STUCK | SensorIssue.SPEED_RANGE)


@dataclass(frozen=True)
class Judged(Rule):
    """Writes ``eligible`` and narrows ``steady``: a broken speed sensor makes SENSOR_FAULT; with
    ``range_margin`` and the motors' noise, samples beyond the identified speeds are not steady; below
    ``min_command`` nothing is."""

    name = "judged"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        profile, state, noise = self.profile, frame.state, frame.noise
        state[(frame.sensor_flags & _SPEED_BROKEN) != 0] = Code.SENSOR_FAULT
        steady = frame.steady
        if profile.judges_within_noise_conditions and noise is not None:
            # beyond the speeds identification checked the model at, in busier air than its flight's or
            # paired more loosely (the noise there is an extrapolation): not judged (a stall still is)
            omega, activity, pairing = frame.omega_model_rad_s, frame.activity_v, frame.pairing_error_rad_s
            known = frame.noise_as_rows().known(
                omega, profile.range_margin, activity, pairing, profile.conditions_reach
            )
            held = steady  # the rule's own verdict, before the range
            steady = steady & (known | one_of(state, TRANSIENT_OK))
            if not known.all():  # (the lost-load check only where some sample lies beyond)
                # judged beyond the range: as judged, where the rule holds the sample; as measured,
                # also while it waits after a step (a healthy motor driven up never shows it)
                judged_view, measured_view = _unloaded_beyond(frame)
                current_views = (judged_view & held) | (measured_view & (held | _waiting(frame)))
                steady = steady | current_views
                below_floor = _torque_below_floor(frame)
                if below_floor is not None:
                    # the torque's view, where neither current's sees it: its evidence the shortfall
                    # below the load at the top, not below the model extrapolated beyond it
                    torque_view, z_floor = below_floor
                    torque_only = torque_view & held & ~known & ~steady
                    assert frame.z_torque is not None  # (none without it)
                    frame.z_torque = np.where(torque_only, z_floor, frame.z_torque)
                    steady = steady | torque_only
        eligible = (steady | one_of(state, TRANSIENT_OK)) & (state != Code.NO_DATA)
        young = _stall_younger_than_its_command(frame)
        if young is not None:
            eligible &= ~young
        if frame.command is not None and profile.min_command > 0:
            idle = np.asarray(frame.command, dtype=float) < profile.min_command  # idle and spin-up
            eligible &= ~idle
            steady = steady & ~idle
        frame.depth[state == Code.SENSOR_FAULT] = 1.0
        frame.steady, frame.eligible = steady, eligible
        return carries


def _stall_younger_than_its_command(frame: Frame) -> NDArray[np.bool_] | None:
    """Stalled samples whose stall began less than their held command's age ago: that command was
    logged before the motor stopped, and the motor may have stopped on one the log did not show
    (:mod:`..stall`, "A stall the paired command may predate"). The age is the source's ``command_age_s``
    where it gives one, else its pairing (a bound on the age); None where the rule gives no stall's start
    or the source pairs each sample with its own instant's command."""
    if frame.stall_since_s is None:
        return None
    pairing = None if frame.pairing_s is None else np.asarray(frame.pairing_s, dtype=float)
    age = pairing
    if frame.command_age_s is not None:
        given = np.asarray(frame.command_age_s, dtype=float)
        age = given if pairing is None else np.where(np.isfinite(given), given, pairing)
    if age is None or not np.any(age > 0):
        return None
    with np.errstate(invalid="ignore"):
        young = frame.time_s - frame.stall_since_s < age
    return young & one_of(frame.state, TRANSIENT_OK)


def _waiting(frame: Frame) -> NDArray[np.bool_]:
    """Samples the balance rule holds back after an input step, their stream running."""
    since = frame.since_step_s
    if since is None:
        return np.zeros(frame.shape, dtype=bool)
    return np.isfinite(since) & ~frame.steady


def _torque_below_floor(frame: Frame) -> tuple[NDArray[np.bool_], NDArray[np.float64]] | None:
    """Samples the rules read as F3.1 whose motor turns faster than the top of its identified speed range
    (widened by ``range_margin``) while its torque balance, with the load taken at that top instead of the
    model's extrapolation beyond it, lies below its band, against its siblings and on its own (its own
    noise's offset and σ, grown as the band is; a motor without its own torque noise: never): a propeller
    that lost load (module doc, "In the torque"). And each sample's departure against its siblings so
    read, in σ of the torque (``z_torque`` plus the load the model adds beyond the top). None where the
    torque is not judged (no torque band, no ``z_torque``, no low-passed speed or torque).

    A healthy propeller needs at least its load at the top where it turns beyond it, so the torque it
    draws there less that load is not below the torque's noise; the model's load beyond the top, an
    extrapolation, is taken back. The current's views (:func:`_unloaded_beyond`) hold the same argument
    in amperes, against the current's band, which carries the command's jitter; the torque's does not
    (it reads the measured speed, not the command's model), and on heavy vehicles whose current band
    ran to 30-60 A it was a sixth to a seventh of it (module doc)."""
    z, band, omega = frame.z_torque, frame.torque_band_nm, frame.omega_mean_rad_s
    if z is None or band is None or omega is None or frame.noise is None or frame.torque_residual_nm is None:
        return None
    lighter = (frame.state == Code.F3_1) & frame.current_trusted()
    if not lighter.any():
        return None
    params, n = frame.params, frame.profile.equation_bands
    top = _identified_top(frame)
    with np.errstate(invalid="ignore", over="ignore"):
        beyond = omega > top
        # the load the model adds between the top and the speed (0 where within the top)
        added_nm = params.k_t * (
            current_from_speed(params, np.where(beyond, omega, 0.0))
            - current_from_speed(params, np.where(beyond, top, 0.0))
        )
        z_floor = z + added_nm / (band / n)
        view = lighter & beyond & (z_floor < -n)
    if view.any():
        # and below the floor on its own, against its own offset and noise, grown as the band is: siblings
        # that fly on a failed motor are no common reference (module doc, "In the torque")
        rows = frame.noise_as_rows()
        a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
        e = frame.pairing_error_rad_s
        torque = frame.torque_residual_nm
        with np.errstate(divide="ignore", invalid="ignore"):
            grown = band / (n * rows.torque_sigmas(a, e))
            own = rows.own_torque_z(torque + added_nm, a, e) / grown
            view &= own < -n
    return view, z_floor


def _identified_top(frame: Frame) -> NDArray[np.float64]:
    """Each row's top of its identified speed range widened by ``range_margin`` [rad/s], a column (inf
    where the motor's noise has no top)."""
    assert frame.noise is not None
    top = np.array([m.omega_high_rad_s for m in frame.noise], dtype=float)
    return np.where(np.isfinite(top), (1.0 + frame.profile.range_margin) * top, np.inf)[:, None]


def _unloaded_beyond(frame: Frame) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Samples the tree reads as F3.1 whose motor turns faster than the top of its identified speed range
    (widened by ``range_margin``) while drawing less than the model's current at that top, by more than
    the band below: a propeller that lost load, whatever the model says beyond the range (module doc).

    Two views, each a mask: *as judged*, the rule's speed and current (the model plus the low-passed
    deviations) against the band below; *as measured*, where the rule low-passes the measurements (the
    balance rule), those, with no model in them, against the motor's band in quiet input, the motor
    driven (its input not below its low-pass); all False where the rule has none, and then the judged view
    also only where the measured current is not at or above the floor. The judged view reads
    the steady state the deviations imply, and so names a lost load before the motor has run up to it
    (quiet air: the speed the model expects jumps at once, the measured mean follows the motor's run-up
    and the low-pass); the measured one needs no model, whose current at a jittering paired command is
    tens of amperes off in busy air and whose band grows with it."""
    assert frame.noise is not None
    profile = frame.profile
    top = _identified_top(frame)
    # the current a healthy motor needs at the top of its range (a lower bound beyond it), with each
    # motor's own offset from the shared model, as its model is judged (rules/offsets.py)
    offset = np.array([n.current_offset_a for n in frame.noise], dtype=float)[:, None]
    floor = current_from_speed(frame.params, np.where(np.isfinite(top), top, 0.0)) + offset
    lighter = (frame.state == Code.F3_1) & frame.current_trusted()
    with np.errstate(invalid="ignore"):
        judged = (
            lighter
            & (frame.omega_judged_rad_s > top)
            & (frame.current_judged_a + frame.current_band_below_a < floor)
        )
    measured = np.zeros(frame.shape, dtype=bool)
    if frame.omega_mean_rad_s is not None and frame.current_mean_a is not None and profile.noise_bands > 0:
        # the judged view only where the motor does not draw what a loaded one needs there (in busy air the
        # model's current can read low by more than its band while the motor draws its load)
        with np.errstate(invalid="ignore"):
            judged &= ~(frame.current_mean_a >= floor)
        quiet = frame.noise_as_rows().sigmas(0.0)[1]
        with np.errstate(invalid="ignore"):
            measured = (
                lighter
                & (frame.omega_mean_rad_s > top)
                & (frame.current_mean_a + profile.noise_bands * quiet < floor)
                & (frame.voltage_v >= frame.judged_voltage_v)
            )
    return judged, measured
