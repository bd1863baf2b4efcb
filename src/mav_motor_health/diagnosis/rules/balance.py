"""The balance rule (flight): no steady state needed.

The model's electrical and mechanical equations are checked as balances at every sample, low-passed with
``residual_tau_s``, and turned into the speed and current deviations they imply in steady state
(:mod:`...model.balance`, the equations); a sample is judged once the low-passes have had ``settle_s`` of
samples without a gap longer than the persistence rule's ``max_gap_s``; while it waits after a step,
a sample is judged all the same where the vehicle's noise says how much wider the deviations are then
(identification measured it: :mod:`..noise`, "After an input step"), in bands that much wider.
``activity_tau_s`` is the window of the input activity that widens the bands (the profile's
``activity_band``) and, with ``activity_ref_v`` > 0, lengthens the low-pass to
``residual_tau_s·activity/activity_ref_v`` (at most ``residual_tau_max_s``). ``slow_factor`` > 0 (≥ 1)
adds a slow look: the deviations low-passed again with ``slow_factor`` times that time constant, judged
``slow_factor`` × ``settle_s`` after a step, in calm air, against the bands narrowed to the profile's
``slow_band_fraction`` (:class:`..tree.SlowLook`); with bands from the vehicle's noise, judged wherever
the fast look is, against its own measured noise (:mod:`..noise`, "The slow look's own noise").

``bus_ref_v`` > 0: ``step_v`` and ``activity_ref_v`` are volts at this bus voltage and scale with the
vehicle's (a step of 0.8 V at 11.1 V is one of 2.4 V at 33.3 V: the same command change); 0: volts as
they are.

``excursion_weight`` > 0 (an option, off in every shipped profile): the input activity also takes how far
each sample's command went beyond the two held commands since the sample before (the sources' column
``input_excursion_v``, a command that dipped and came back between two ESC reports), weighted by it;
``excursion_pairing_weight`` > 0 (also off) gives them to the pairing guard instead, as the command's
movement between two samples (:mod:`..pairing`). Whatever those weights, an excursion larger than a step
is a step: the wait starts again at the sample after it (the samples never saw the input it was; docs/
flight.md, "Speed only, in the vehicle's own noise; a command dip between two reports as a step").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..._arrays import broadcast_to, nan_to_zero
from ...errors import ConfigError
from ...model.balance import BalanceCarry, balance_deviations_rows
from ...model.dynamics import ResponseCarry, first_order_responses, last_of, previous
from ..stall import StallCarry, stall_rows, stop_speeds
from ..steady import SteadyCarry, settling_rows
from .base import CompareRule, Frame, SlowAverages
from .step import check_settling

__all__ = ["BalanceCarry", "BalanceRule", "BalanceRuleCarry"]


@dataclass(frozen=True)
class BalanceRuleCarry:
    """What the balance rule remembers about one motor."""

    balance: BalanceCarry = field(default_factory=BalanceCarry)
    steady: SteadyCarry = field(default_factory=SteadyCarry)
    stall: StallCarry = field(default_factory=StallCarry)
    slow_omega: ResponseCarry = field(default_factory=ResponseCarry)
    slow_current: ResponseCarry = field(default_factory=ResponseCarry)
    #: the lowest positive input the motor has been given in the stream [V] (inf: none yet)
    lowest_input_v: float = math.inf
    #: the model speed at the motor's last sample [rad/s] (``step_sigmas``; NaN: none yet)
    last_model_rad_s: float = math.nan
    #: when the slow look's averages started (the motor's first sample) [s]; NaN: not yet
    slow_since_s: float = math.nan


@dataclass(frozen=True)
class BalanceRule(CompareRule):
    """The balances low-passed with ``residual_tau_s`` [s], judged ``settle_s`` after a step of ``step_v``
    [V]; see the module."""

    kind = "balance"

    step_v: float = 0.2
    settle_s: float = 0.3
    residual_tau_s: float = 0.15
    activity_tau_s: float = 0.5
    activity_ref_v: float = 0.0
    residual_tau_max_s: float = 2.0
    slow_factor: float = 0.0
    bus_ref_v: float = 0.0
    #: how much of each sample's command excursion between two ESC reports (``input_excursion_v``) the input
    #: activity takes, as a zigzag of ``(w·e)²`` (model/balance.py); 0: none (the default: measured on the
    #: held-out worlds, docs/flight.md "A command dip between two ESC reports, measured")
    excursion_weight: float = 0.0
    #: the same excursions as the pairing guard's command movement between two samples, ``|ΔV| + 2·w·e``
    #: (diagnosis/pairing.py); 0: none (the default, measured in the same place)
    excursion_pairing_weight: float = 0.0
    #: a step also where the model speed moves by more than this many times the motor's identified quiet
    #: σ of the speed (``[noise.N] speed_rad_s``) from one sample to the next, whatever the volts did (the
    #: wait restarts there, as for a motor at idle); 0: off (the default, as a profile without a vehicle's
    #: noise has no σ to count in); ``flight_vehicle`` ships 5 (docs/flight.md "A step in the motor's own
    #: noise", measured over twenty healthy hours)
    step_sigmas: float = 0.0
    #: 1: a step's allowance beyond ``step_v`` is three times the zigzag over the command's changes, however
    #: many ESC reports repeat one command (model/balance.py, ``change_zigzag_rows``); 0: over the samples
    #: (the default, and the shipped profiles': measured on the held-out worlds with it on, it settled world
    #: 1009's identification flight and named most of its misses, but a ramp of the command by steps each
    #: within the allowance went unwaited, and on development world 3 the motors taking over a damaged
    #: propeller's load were named F3.1: docs/flight.md, "The step's allowance over the command's changes")
    step_over_changes: float = 0.0

    def validate(self) -> None:
        check_settling(self.step_v, self.settle_s)
        if not self.residual_tau_s > 0:
            raise ConfigError(
                f"{self.residual_tau_s!r}",
                key="steady.residual_tau_s",
                expected='a time constant > 0 s for kind = "balance"',
            )
        if not (self.slow_factor == 0 or self.slow_factor >= 1):
            raise ConfigError(
                f"{self.slow_factor!r}", key="steady.slow_factor", expected="a factor >= 1, or 0 (off)"
            )
        if not self.bus_ref_v >= 0:
            raise ConfigError(f"{self.bus_ref_v!r}", key="steady.bus_ref_v", expected="a voltage >= 0 V")
        if not self.activity_tau_s > 0:
            raise ConfigError(
                f"{self.activity_tau_s!r}", key="steady.activity_tau_s", expected="a time constant > 0 s"
            )
        if not self.step_sigmas >= 0:
            raise ConfigError(
                f"{self.step_sigmas!r}", key="steady.step_sigmas", expected="a number of sigmas >= 0 (0: off)"
            )
        for name in ("excursion_weight", "excursion_pairing_weight", "step_over_changes"):
            if not 0 <= getattr(self, name) <= 1:
                raise ConfigError(
                    f"{getattr(self, name)!r}", key=f"steady.{name}", expected="a weight 0 <= w <= 1"
                )

    def new_carry(self) -> BalanceRuleCarry:
        return BalanceRuleCarry()

    def bus_scale(self, frame: Frame) -> NDArray[np.float64] | float:
        """What the rule's volts (``step_v``, ``activity_ref_v``) are multiplied by at each sample: the bus
        voltage over ``bus_ref_v`` where the rule scales with it and the sample has one, else 1."""
        if not self.bus_ref_v > 0 or frame.bus_voltage_v is None:
            return 1.0
        bus = broadcast_to(np.asarray(frame.bus_voltage_v, dtype=float), frame.shape)
        with np.errstate(invalid="ignore"):
            return np.where(np.isfinite(bus) & (bus > 0), bus / self.bus_ref_v, 1.0)

    def judge(self, frame: Frame, carries: list[BalanceRuleCarry]) -> list[BalanceRuleCarry]:
        t, v = frame.time_s, frame.voltage_v
        omega_in, current_in = frame.omega_rad_s, frame.current_a
        profile, counts, rows = frame.profile, frame.counts, frame.shape[0]
        command = frame.command
        # volts of the rule scaled with the vehicle's bus voltage (a 12S vehicle's input moves 3.3 times
        # the volts of a 3S one for the same command)
        volts = self.bus_scale(frame)
        bal, balance_carries = balance_deviations_rows(
            frame.params,
            t,
            v,
            omega_in,
            current_in,
            self.residual_tau_s,
            self.activity_tau_s,
            [c.balance for c in carries],
            counts,
            activity_ref_v=self.activity_ref_v * volts,
            tau_max_s=self.residual_tau_max_s,
            input_current_a=frame.sensor_current_a if command is not None else None,
            duty=command if frame.sensor_current_a is not None else None,
            input_excursion_v=frame.excursions(self.excursion_weight),
            # where the vehicle's noise says the ESC reads its input current (the motor current is that
            # over the duty): the torque reads it as mean(s)/mean(d) (model/balance.py)
            torque_through_duty=None
            if frame.noise is None
            else [n.torque is not None and n.torque.through_duty for n in frame.noise],
            command=command,
            zigzag_over_changes=self.step_over_changes > 0,
        )
        omega_pred, current_pred = bal.omega_model_rad_s, bal.current_model_a
        # A stalled motor: the speed itself (the lower of the sample and its low-pass, so that a
        # start-up kick does not break the run and the first slow sample counts), and the current
        # averaged since the stall began (diagnosis/stall.py: the low-pass still holds the flight's).
        stall_speed = np.fmin(omega_in, bal.omega_mean_rad_s)
        lowest = [c.lowest_input_v for c in carries]
        if profile.stop_speed_lowest_fraction > 0:
            # never stopped above a share of the free speed of the lowest input given so far (tree.py,
            # "The lowest input"): a healthy motor runs down towards that input's speed, not below it
            given = np.where(v > 0, v, np.inf)  # NaN and disarmed (<= 0) inputs are not given
            running = np.minimum.accumulate(
                np.concatenate([np.array(lowest)[:, None], given], axis=1), axis=1
            )
            low_v = running[:, 1:]
            frame.stop_cap_rad_s = profile.stop_speed_lowest_fraction * low_v / frame.params.k_e
            lowest = [old if last is None else last for old, last in zip(lowest, last_of(low_v, counts))]
        stop_speed, _ = stop_speeds(profile, omega_pred, frame.stop_cap_rad_s)  # the tree's rule 1
        stalled_like = stall_speed < stop_speed
        omega_seen = np.where(stalled_like, stall_speed, omega_pred + bal.delta_omega_rad_s)
        omega_seen = np.where(np.isfinite(omega_in), omega_seen, np.nan)
        # the stall's mean current, and when it began: one younger than its sample's command is not
        # counted (stall.py, "A stall the paired command may predate"; rules/judged.py)
        stall_current, frame.stall_since_s, stall_carries = stall_rows(
            current_in, stalled_like, [c.stall for c in carries], frame.ragged, t
        )
        current_seen = np.where(stalled_like, stall_current, current_pred + bal.delta_current_a)
        current_seen = np.where(np.isfinite(current_in), current_seen, np.nan)
        # An input step (larger than step_v plus a few times the input's zigzag, which in gusty air
        # is no step at all) puts two operating points into the low-passes: judge after settle_s. A new
        # stream (the first sample, or after a gap) waits until the activity is known too. Where asked
        # (step_over_changes), the zigzag over the command's changes, however many reports repeat one
        # command (model/balance.py, change_zigzag_rows: an ESC reporting at 50 Hz, commands logged at 10 Hz)
        step_v = self.step_v * volts + 3.0 * nan_to_zero(bal.zigzag_v)  # the jumps as measured, not scaled
        # A motor whose low-passed input is at idle (below min_command: spin-down, braking with its current
        # unread) restarts the wait: when it comes back the low-passes still hold the idle. The low-passed
        # input, not the sample: in gusty air single commands dip to idle and back all the time.
        at_idle = None
        if command is not None and profile.min_command > 0:
            cmd = np.asarray(command, dtype=float)
            with np.errstate(divide="ignore", invalid="ignore"):
                bus_v = np.where(cmd > 0.05, v / cmd, np.nan)  # the input is command × bus voltage
            at_idle = bal.voltage_v < profile.min_command * bus_v
        restart = at_idle  # the samples whose wait starts again whatever the volts did
        excursion = frame.excursions(1.0)
        if excursion is not None:
            # the command went further than a step and came back between two of the motor's reports
            # (a dip the log's ESC samples never paired with, input_excursion_v): the low-passes did not
            # see it, the motor did, and its speed still lags it at the next samples (held-out world 1026,
            # 10 Hz ESC telemetry: a dip of 10 V between two reports left the next speed 50 rad/s short)
            with np.errstate(invalid="ignore"):
                dipped = excursion > step_v
            restart = dipped if restart is None else restart | dipped
        last_model = [c.last_model_rad_s for c in carries]
        if self.step_sigmas > 0 and frame.noise is not None and len(frame.noise) == rows:
            # the model speed jumped by more than a few σ of the motor's noise since the sample before: an
            # input the log's ESC reports have not caught up with, whatever the volts' step says
            before = previous(omega_pred, last_model)
            quiet = frame.noise_as_rows().speed_rad_s
            with np.errstate(invalid="ignore"):
                jump = np.abs(omega_pred - before) > self.step_sigmas * quiet
            restart = jump if restart is None else restart | jump
            last_model = [
                old if new is None else new for old, new in zip(last_model, last_of(omega_pred, counts))
            ]
        slow_on = self.slow_factor > 0
        # with bands from the vehicle's noise the slow look is judged where the fast one is: its own noise
        # was measured there, the waits after steps and the gusts included (noise.py); else it waits
        # slow_factor times longer after each step, in calm air only, against bands narrowed by a share
        own_noise = profile.noise_bands > 0
        slow_waits = slow_on and not own_noise
        # the activity's low-pass has to fill up first, and the deviations' (longer in gusts)
        start_settle_s = np.maximum(3.0 * self.activity_tau_s, 3.0 * bal.tau_s)
        warm, settled, since_step = settling_rows(
            t,
            v,
            self.settle_s,
            profile.persistence.max_gap_s,
            step_v,
            [c.steady for c in carries],
            counts,
            start_settle_s=start_settle_s,
            restart=restart,
            also_settle_s=self.slow_factor * self.settle_s if slow_waits else None,
        )
        slow_warm = None
        if slow_waits:
            warm, slow_warm = warm[0], warm[1]
        steady = warm & np.isfinite(v) & np.isfinite(omega_in)
        since_step = np.where(np.isfinite(v) & np.isfinite(omega_in), since_step, np.nan)
        if frame.noise is not None and len(frame.noise) == rows and profile.noise_bands > 0:
            # waiting after a step, judged where the vehicle's noise says how much wider it is there
            # (identification measured it: noise.py, "After an input step"); elsewhere the wait holds
            after = frame.noise_as_rows().after_step_factor(since_step, self.settle_s)
            with np.errstate(invalid="ignore"):
                steady = steady | (np.isfinite(after) & (since_step < self.settle_s))
            frame.after_step_factor = after
        slow_carries = [c.slow_omega for c in carries] + [c.slow_current for c in carries]
        since_start = np.array([c.slow_since_s for c in carries], dtype=float)
        if slow_on:
            # The slow look: the deviations averaged slow_factor times longer, judged as long after a step
            slow_both, slow_carries = first_order_responses(
                t,
                np.concatenate([bal.delta_omega_rad_s, bal.delta_current_a]),
                self.slow_factor * bal.tau_s,
                slow_carries,
                counts * 2,
            )
            if slow_warm is None:
                # judged where the fast look is, once the slow averages have filled as long as the fast
                # ones must at the start (slow_factor times): a slow average of a few samples is not slow,
                # and read in the slow look's narrower σ its start-up would look like a fault
                since_start = np.where(np.isfinite(since_start), since_start, t[:, 0])
                filled = (t - since_start[:, None]) >= self.slow_factor * start_settle_s
                ready = steady & ~stalled_like & filled
            else:
                # only where the low-pass is not already lengthened by the activity (calm air): in gusts
                # the fast look averages long already, and a slower one would hold every gust's upset
                # for seconds
                ready = slow_warm & steady & ~stalled_like & (bal.tau_s <= self.residual_tau_s)
            frame.slow = SlowAverages(
                slow_both[:rows], slow_both[rows:], ready, self.slow_factor * self.settle_s
            )
        frame.omega_model_rad_s, frame.current_model_a = omega_pred, current_pred
        frame.omega_judged_rad_s, frame.current_judged_a = omega_seen, current_seen
        frame.steady = steady
        frame.since_step_s = since_step
        frame.judged_voltage_v = bal.voltage_v
        frame.omega_mean_rad_s, frame.current_mean_a = bal.omega_mean_rad_s, bal.current_mean_a
        frame.torque_residual_nm, frame.voltage_residual_v = bal.torque_residual_nm, bal.voltage_residual_v
        frame.activity_v = bal.activity_v
        frame.omega_expected_rad_s = omega_pred
        # No fault turns the motor faster than V/k_e (tree rule 2), but the balance rule judges the model
        # plus a low-passed deviation, not a measured speed: its band is the deviation's noise, which the
        # physical cap does not bound, so it keeps the full band.
        frame.omega_free_rad_s = None
        frame.low_pass_s = bal.tau_s
        frame.design_tau_s = self.residual_tau_s
        return [
            BalanceRuleCarry(
                balance_carries[r],
                settled[r],
                stall_carries[r],
                slow_carries[r],
                slow_carries[rows + r],
                lowest[r],
                last_model[r],
                float(since_start[r]) if counts[r] > 0 else carries[r].slow_since_s,
            )
            for r in range(rows)
        ]
