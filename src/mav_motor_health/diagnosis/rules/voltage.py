"""An open transistor read in the voltage balance, against how its siblings run (``voltage_slow_siblings``).

An open transistor (F4.1) leaves two of the six commutation steps without drive: like a winding of
higher resistance, the motor uses more of its input voltage than the model says at its speed and current
(``r_V = V − R·i − k_e·ω`` above 0), while the torque it makes still turns its propeller (``r_T`` near 0).
Friction and a lighter propeller move the torque balance and leave the voltage balance as it was; a stall
is the stall rule's. So among the faults read from the speed and the current, a voltage balance departing
up is the open transistor's alone (:mod:`...model.balance`, "The two equations apart").

The tree reads it from the speed and current deviations, which mix both balances, in bands of the noise
identification measured on its flight. Where that flight ran busier than the one judged, or was mostly
the wait after input steps, those bands are several times wider than the healthy deviations of a calm
flight: on held-out world 1009 (24 kg; one sample in a hundred of its identification flight settled) and
world 1000 (identified in gusty air) an open transistor of the paper's strength read NORMAL on 96 and 100 %
of its samples in calm air, though its voltage balance rose by 3.8 and 1.9 V from before the fault
(medians), three and four times the healthy motors' own 10th-to-90th percentile width (docs/flight.md, "An
open transistor in the voltage balance, as its siblings run").

So, as the torque's slow look does (:mod:`.equations`, "The torque's slow look as its siblings run"), each
motor's voltage residual less the median of its siblings' (the vehicle stage, :mod:`..siblings`: what the
six share, the battery, the one model's error at this operating point, drops out) is averaged as the slow
look averages the deviations (``voltage_slow_v``, :class:`~.equations.Equations`), and identification
measures that average's healthy noise (``[noise.N] slow_voltage_v ...``, :mod:`..noise`). How far it runs
in the air of the moment the siblings show, as for the deviations' slow look (:mod:`.tree`, "The slow look
as its siblings run"): :class:`~.bands.LiveNoise` averages each motor's own voltage residual alike and
that average's squared departure from the motor's voltage offset over ``conditions_siblings_s``, and the
vehicle stage gives the median of the other motors' latest. A mean square, not the spread of the
siblings' values around their median: in gusty air the yaw control drives the motors of one turning
direction harder than the other's, and the voltage balance, averaged, parts by direction (on development
world 11, healthy, the three clockwise motors stood about +0.5 V from their siblings' median, the three
others −0.5 V, while the median absolute deviation of five siblings, three of one group, saw mostly that
group's 0.2 V: a band of it lowered that flight's healthy NORMAL share from 100 to 96.3 %); each motor's
own departure in the mean square holds the split whichever group holds the median.

A sample still NORMAL after the deviations' slow look is named F4.1 where its slow voltage average
departs up from its offset by more than ``equation_bands · slow_band_fraction · m`` times the larger of
the root of the siblings' median mean square and the motor's own slow σ at the sample's conditions held
within those identification measured (m = ``voltage_slow_siblings``; the floor is what was measured, the
siblings take the place of the extrapolation beyond it, as for the torque), with a trusted current, and
its slow speed and current averages not above its model: the paper's directions (an open transistor
slows its motor and draws less current; friction slows it and draws more, and where the model's R is off
the voltage balance moves with the current: on held-out world 1013 friction in moderate air was named
F4.1 here on 6 % of its samples before the current was asked to agree). Judged wherever the slow look
may judge, in the wait after an input step too, as the torque's slow look is. Only in the motor's
identified speeds (by its model speed or the speed it turns) and where three siblings give a mean square;
no band of the motor's own beyond its conditions: where the siblings give none, the deviations alone read
it. Below its offset the voltage balance names nothing: no fault of the five gives a motor more voltage
than its model uses. The sequential test counts the departure as it counts the other slow looks' (the
slow evidence, in σ of the band: :mod:`..detection`, "The slow look's evidence"). The fast voltage
balance is read elsewhere only to tell friction from an open transistor where the tree named the latter
(:mod:`.equations`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..states import Code
from .base import Frame, Rule

if TYPE_CHECKING:
    from ..profile import ThresholdProfile

__all__ = ["VoltageSlowLook"]


@dataclass(frozen=True)
class VoltageSlowLook(Rule):
    """Where a sample still reads NORMAL after the deviations' slow look, F4.1 where the voltage balance's
    slow average against its siblings departs up beyond the band its siblings give (module doc), with that
    depth and its slow evidence."""

    name = "voltage_slow_look"
    profile: ThresholdProfile

    def judge(self, frame: Frame, carries: list[Any]) -> list[Any]:
        slow, averaged, siblings = frame.slow, frame.voltage_slow_v, frame.siblings_slow_ms_voltage
        if slow is None or averaged is None or siblings is None or frame.noise is None:
            return carries
        state = frame.state
        candidates = slow.ready & (state == Code.NORMAL) & frame.current_trusted() & np.isfinite(averaged)
        if not candidates.any():
            return carries
        with np.errstate(invalid="ignore"):
            share = self.share(frame, averaged, np.sqrt(siblings))
        # the paper's directions in the slow averages too: an open transistor turns its motor no faster and
        # draws no more current than its model (friction draws more: a model whose R is off by some share
        # moves the voltage balance with the current, and friction's raised it on held-out world 1013)
        z_speed, z_current = frame.slow_deviation_z()
        with np.errstate(invalid="ignore"):
            named = candidates & (share > 1.0) & (z_speed <= 0) & (z_current <= 0)
        if not named.any():
            return carries
        state[named] = Code.F4_1
        frame.depth[named] = share[named]
        # in σ of the band, as the test counts the other slow looks' departures
        frame.note_slow_evidence(named, share * self.profile.equation_bands)
        return carries

    def share(
        self, frame: Frame, averaged: NDArray[np.float64], siblings_rms: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Each sample's slow voltage departure from its offset as a share of the band its siblings give:
        ``equation_bands · slow_band_fraction · m`` times the root of their median mean square
        (``siblings_rms``), never below the motor's own slow σ at the sample's conditions held within those
        identification measured (module doc); NaN where the siblings give none, the noise has no slow
        voltage's, or beyond the motor's identified speeds; below the offset, negative."""
        profile = self.profile
        rows = frame.noise_as_rows()
        a = np.zeros(frame.shape) if frame.activity_v is None else frame.activity_v
        offset, measured = rows.slow_within(
            "slow_voltage", a, frame.pairing_error_rad_s, profile.range_margin
        )
        reach = profile.equation_bands * profile.slow_band_fraction * profile.voltage_slow_siblings
        # in the identified speeds by the model speed or the speed it turns (rules/tree.py, the same rule)
        turning = frame.omega_mean_rad_s if frame.omega_mean_rad_s is not None else frame.omega_rad_s
        within = rows.in_speed_range(frame.omega_model_rad_s, 0.0) | rows.in_speed_range(turning, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            # (np.maximum, not fmax: NaN where the siblings give none or the noise no slow voltage's)
            share = (averaged - offset) / (reach * np.maximum(siblings_rms, measured))
        return np.where(within, share, np.nan)
