"""Motor parameters as a value: the steady-state model of a UAV motor (BLDC motor + propeller + ESC).

Symbols follow the paper (Lee et al., section II): eq. 2 ``V = R·i + k_e·ω`` and eq. 7
``k_t·i = C_p·ω^k + B·ω + T_f`` with ``k_t = k_e`` in SI units.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from ..errors import ConfigError

__all__ = ["PARAMETER_UNITS", "MotorParams", "MotorRows", "same_type"]

#: Unit of every motor parameter, by the name it has everywhere (TOML, JSON, reports).
PARAMETER_UNITS: dict[str, str] = {
    "R_ohm": "ohm",
    "k_e": "V*s/rad (= N*m/A, k_t = k_e)",
    "C_p": "N*m/(rad/s)^k",
    "B": "N*m/(rad/s)",
    "T_f": "N*m",
    "k": "1",
    "J_kg_m2": "kg*m^2",
}


@dataclass(frozen=True)
class MotorParams:
    """Steady-state parameters of one motor + propeller.

    ``R_ohm`` phase resistance [Ω]; ``k_e`` back-EMF constant [V·s/rad], equal to the torque constant
    k_t [N·m/A]; ``C_p`` propeller load factor [N·m/(rad/s)^k]; ``B`` viscous damping [N·m/(rad/s)];
    ``T_f`` dynamic friction torque [N·m]; ``k`` exponent of the propeller load (3 in the paper);
    ``J_kg_m2`` rotor + propeller inertia [kg·m²], needed only for the motor's time constant in flight.

    ``effects`` holds extra physical effects by name with their fitted parameters (see
    :mod:`mav_motor_health.model.effects` where present); the base model ignores it.
    """

    R_ohm: float
    k_e: float
    C_p: float
    B: float
    T_f: float
    k: float = 3.0
    name: str = "motor"
    J_kg_m2: float | None = None
    effects: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = field(default=())

    def __post_init__(self) -> None:
        checks = (
            ("R_ohm", self.R_ohm > 0, "a resistance > 0 ohm"),
            ("k_e", self.k_e > 0, "a back-EMF constant > 0 V*s/rad"),
            ("C_p", self.C_p >= 0, "a propeller factor >= 0"),
            ("k", 0.5 <= self.k <= 6, "an exponent between 0.5 and 6"),
        )
        for key in ("R_ohm", "k_e", "C_p", "B", "T_f", "k"):
            value = getattr(self, key)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ConfigError(f"{value!r} is not a finite number", key=key, expected="a finite number")
        for key, ok, expected in checks:
            if not ok:
                raise ConfigError(f"{getattr(self, key)!r} is out of range", key=key, expected=expected)
        if self.J_kg_m2 is not None and not (math.isfinite(self.J_kg_m2) and self.J_kg_m2 > 0):
            raise ConfigError(
                f"{self.J_kg_m2!r} is out of range", key="J_kg_m2", expected="an inertia > 0 kg*m^2"
            )
        if self.B + self.k_e**2 / self.R_ohm <= 0:
            raise ConfigError(
                "B is so negative that speed no longer rises with voltage",
                key="B",
                expected=f"B > {-(self.k_e**2) / self.R_ohm:.3g}",
            )

    @property
    def k_t(self) -> float:
        """Torque constant [N·m/A]; equal to k_e in SI units."""
        return self.k_e

    @property
    def start_voltage_v(self) -> float:
        """Input voltage below which the friction torque T_f holds the motor still (eq. 2 with eq. 7 at ω=0)."""
        return max(self.T_f, 0.0) * self.R_ohm / self.k_e

    def effect_params(self, name: str) -> dict[str, float] | None:
        for effect_name, values in self.effects:
            if effect_name == name:
                return dict(values)
        return None

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data["effects"] = {name: dict(values) for name, values in self.effects}
        return data

    def replace(self, **changes: Any) -> MotorParams:
        from dataclasses import replace

        return replace(self, **changes)


#: the parameters that may differ between the motors of one type in one core call (:class:`MotorRows`)
_PER_ROW = ("R_ohm", "k_e")


def same_type(a: MotorParams, b: MotorParams) -> bool:
    """Whether two motors' models differ at most in R and k_e (and name), as the per-motor models of one
    identification do: the core can then diagnose them in one call (:class:`MotorRows`)."""
    if a is b:
        return True
    if type(a) is not MotorParams or type(b) is not MotorParams or a.effects or b.effects:
        return False
    return all(getattr(a, f) == getattr(b, f) for f in ("C_p", "B", "T_f", "k", "J_kg_m2"))


class MotorRows(MotorParams):
    """Several motors of one type in one core call (the rows of its 2-D arrays, one per motor): R and k_e
    as column arrays, one row per motor, every other parameter the type's. The model's equations are
    elementwise, so each row gets what its own motor's :class:`MotorParams` gives. Made by :meth:`of`
    only; not a value to compare, hash or write."""

    @classmethod
    def of(cls, motors: list[MotorParams]) -> MotorParams:
        """The motors' models as rows (the first model itself where all are one); each must be
        :func:`same_type` as the first."""
        first = motors[0]
        if all(m is first for m in motors):
            return first
        if not all(same_type(first, m) for m in motors):
            raise ValueError("the motors' models differ beyond R and k_e: not one type")
        rows = cls(**{f.name: getattr(first, f.name) for f in fields(first)})
        for name in _PER_ROW:
            object.__setattr__(rows, name, np.array([[getattr(m, name)] for m in motors], dtype=float))
        return rows
