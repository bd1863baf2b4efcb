"""Motor faults as the paper injected them (section III.A, Figs. 3–4), as effects on the motor dynamics.

Each fault acts on one motor from ``onset_s`` on, scaled by ``severity`` (1.0: as on the paper's testbed):

==========  =================================================================================
``F1.1``    a rubbing bar: extra friction torque ``severity·(T_rub0 + B_rub·ω)`` (Coulomb + viscous).
            Speed slightly lower, current higher (Fig. 9).
``F2.1``    one phase open: the ESC loses synchronisation. The two healthy phases hold the rotor (a drag
            torque ``k_hold·ω``), the ESC retries start-ups (short kicks, the motor "starts to rotate and
            stop repeatedly"), and a current of about ``stall_current_a`` = 3 A flows (2–4 A, Fig. 10;
            2.26 A on average in flight). ``severity`` scales that current.
``F3.1``    blades trimmed: ``severity`` is the share of the blade length cut off; the propeller load
            factor falls as the length to the 5th power and the thrust as the 4th, ``(1 − s)^5`` and
            ``(1 − s)^4``. Speed higher, current lower (Fig. 11). The paper trimmed the blades "to about
            30 % of their original length": severity 0.7. At low voltage the speed can rise at most to
            the free speed ``V/k_e`` (at 4.2 V only ≈ 20 rad/s above the model, the speed band's width;
            the tree narrows its band above the model there, :mod:`..diagnosis.tree` rule 2).
``F4.1``    one transistor open: two of the six commutation steps do not conduct and the current of the
            others has a longer path; the drive (torque and current at a given speed) falls to
            ``1/(1 + 2·severity)``, like a resistance ``R·(1 + 2·severity)``: both speed and current lower,
            little difference at low speed where the current is small (Fig. 12).
``F4.2``    back-EMF signal grounded: the ESC cannot find the rotor position and drives blindly; the
            motor stalls like F2.1 but the healthy phases carry about ``stall_current_a`` = 7.7 A, with a
            slow random wander that in flight dips below 6 A (Fig. 13, Fig. 16). ``severity`` scales it.
==========  =================================================================================

F2.1 and F4.2 have no partial form in the paper (a phase is open or it is not); their severity scales
the stall current only. Severities lie in 0..1, but F1.1 and F4.1 have stronger forms than the paper's
(more friction, less drive): up to ``STRONGER_MAX`` = 10 (the severity floor's rungs beyond the paper's
strength, :mod:`..evaluation.severity`).

The absolute constants (the rubbing bar's torque, the stall currents) are the paper's X2212's. On another
motor (a randomised world, :mod:`.worlds`) a :class:`FaultScale` carries them over in proportion to the
motor's hover torque, speed and current, so a fault is as strong relative to its motor as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..errors import ConfigError

__all__ = ["FAULT_KINDS", "STRONGER_FORMS", "FaultEffects", "FaultScale", "FaultSpec", "effects_at"]

FAULT_KINDS = ("F1.1", "F2.1", "F3.1", "F4.1", "F4.2")
#: the faults with a stronger form than the paper's (severity above 1): more friction than its rubbing bar,
#: less drive than its open transistor left (a blade cannot lose more than its length; a stall's severity
#: scales a current the paper measured); up to :data:`STRONGER_MAX` times the paper's
STRONGER_FORMS = ("F1.1", "F4.1")
STRONGER_MAX = 10.0

#: F1.1: friction torque of the rubbing bar at severity 1 [N·m] and its speed-proportional part [N·m·s/rad].
RUB_TORQUE_NM = 0.012
RUB_VISCOUS_NM_S = 6.0e-5
#: F3.1: exponents of the blade length in the propeller's load torque and thrust (P ∝ D^5, T ∝ D^4).
LOAD_LENGTH_EXPONENT = 5.0
THRUST_LENGTH_EXPONENT = 4.0
#: F3.1: the paper trimmed the blades "to about 30 % of their original length".
PAPER_TRIM_SEVERITY = 0.7
#: Default stall currents [A] (paper: about 3 A for F2.1, 7–8 A for F4.2 on the testbed).
STALL_CURRENT_A = {"F2.1": 3.0, "F4.2": 7.7}


@dataclass(frozen=True)
class FaultScale:
    """A motor's size relative to the paper's X2212 at its hover (0.037 N·m, 604 rad/s, 3.8 A): the
    factors that carry the faults' absolute constants over to it (1: the paper's motor)."""

    torque: float = 1.0
    speed: float = 1.0
    current: float = 1.0

    def resolve(self, fault: FaultSpec) -> FaultSpec:
        """``fault`` with its stall current in this motor's amperes (explicit ones are kept)."""
        if fault.stall_current_a is not None or fault.kind not in STALL_CURRENT_A:
            return fault
        return replace(fault, stall_current_a=fault.stall_current * self.current)


@dataclass(frozen=True)
class FaultSpec:
    """One injected fault: which, on which motor (1-based), from when, how strong."""

    kind: str
    motor: int
    onset_s: float
    #: None: the paper's strength (1.0; F3.1: 0.7, blades trimmed to 30 % of their length)
    severity: float | None = None
    #: F2.1/F4.2: mean current while stalled [A]; None: the paper's testbed value times severity.
    stall_current_a: float | None = None
    end_s: float = float("inf")

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ConfigError(
                f"unknown fault {self.kind!r}", key="fault.kind", expected=f"one of {FAULT_KINDS}"
            )
        if self.severity is None:
            object.__setattr__(self, "severity", PAPER_TRIM_SEVERITY if self.kind == "F3.1" else 1.0)
        if not 1 <= self.motor <= 12:
            raise ConfigError(f"{self.motor!r}", key="fault.motor", expected="a motor number 1..12")
        top = STRONGER_MAX if self.kind in STRONGER_FORMS else 1.0
        if not 0.0 <= self.strength <= top:
            raise ConfigError(
                f"{self.severity!r} for {self.kind}",
                key="fault.severity",
                expected=f"a severity between 0 and {top:g}"
                + (
                    f" (above 1 only {' and '.join(STRONGER_FORMS)}, which have stronger forms)"
                    if top == 1.0
                    else ""
                ),
            )
        if not self.onset_s >= 0:
            raise ConfigError(f"{self.onset_s!r}", key="fault.onset_s", expected="a time >= 0 s")

    @property
    def strength(self) -> float:
        """The severity as a number (set from the paper's default when not given)."""
        return float(self.severity if self.severity is not None else 1.0)

    @property
    def stall_current(self) -> float:
        if self.stall_current_a is not None:
            return self.stall_current_a
        return STALL_CURRENT_A.get(self.kind, 0.0) * self.strength

    def active(self, time_s: float) -> bool:
        return self.onset_s <= time_s < self.end_s

    def to_dict(self) -> dict[str, object]:
        return {
            "fault": self.kind,
            "motor": self.motor,
            "onset_s": self.onset_s,
            "severity": self.strength,
            "stall_current_a": self.stall_current,
            "end_s": None if self.end_s == float("inf") else self.end_s,
        }


@dataclass
class FaultEffects:
    """Per-motor modifiers of the motor dynamics at one instant (arrays over motors)."""

    rub_torque_nm: NDArray[np.float64]
    rub_viscous_nm_s: NDArray[np.float64]
    load_factor: NDArray[np.float64]
    thrust_factor: NDArray[np.float64]
    drive_factor: NDArray[np.float64]
    stalled: NDArray[np.bool_]
    stall_current_a: NDArray[np.float64]
    back_emf_lost: NDArray[np.bool_]
    any_stalled: bool = False

    @classmethod
    def healthy(cls, n: int) -> FaultEffects:
        return cls(
            rub_torque_nm=np.zeros(n),
            rub_viscous_nm_s=np.zeros(n),
            load_factor=np.ones(n),
            thrust_factor=np.ones(n),
            drive_factor=np.ones(n),
            stalled=np.zeros(n, dtype=bool),
            stall_current_a=np.zeros(n),
            back_emf_lost=np.zeros(n, dtype=bool),
        )


def effects_at(
    faults: tuple[FaultSpec, ...] | list[FaultSpec],
    time_s: float,
    n_motors: int,
    scale: FaultScale | None = None,
) -> FaultEffects:
    """The combined effect of every fault active at ``time_s`` (motors beyond ``n_motors`` ignored), on a
    motor of ``scale`` (None: the paper's)."""
    fx = FaultEffects.healthy(n_motors)
    if scale is not None:
        faults = [scale.resolve(f) for f in faults]
    rub_torque, rub_viscous = RUB_TORQUE_NM, RUB_VISCOUS_NM_S
    if scale is not None:
        rub_torque, rub_viscous = rub_torque * scale.torque, rub_viscous * scale.torque / scale.speed
    for f in faults:
        j = f.motor - 1
        if j >= n_motors or not f.active(time_s):
            continue
        s = f.strength
        if f.kind == "F1.1":
            fx.rub_torque_nm[j] += s * rub_torque
            fx.rub_viscous_nm_s[j] += s * rub_viscous
        elif f.kind == "F3.1":
            fx.load_factor[j] *= (1.0 - s) ** LOAD_LENGTH_EXPONENT
            fx.thrust_factor[j] *= (1.0 - s) ** THRUST_LENGTH_EXPONENT
        elif f.kind == "F4.1":
            fx.drive_factor[j] /= 1.0 + 2.0 * s
        else:  # F2.1, F4.2: the motor loses synchronisation
            fx.stalled[j] = True
            fx.stall_current_a[j] = f.stall_current
            fx.back_emf_lost[j] = f.kind == "F4.2"
    fx.any_stalled = bool(fx.stalled.any())
    return fx
