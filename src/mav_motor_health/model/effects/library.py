"""The built-in effects: physics the paper's steady-state model leaves out.

Each effect is a pure function ``(terms, parameters, data) -> terms`` whose docstring states the physics,
when it matters, and why its parameters have the bounds they have. Every effect has *neutral* parameter
values (mostly zero) at which it returns the base model unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .base import Effect, EffectParameter, FloatArray, ModelTerms

__all__ = ["BUILTIN_EFFECTS", "REFERENCE_SPEED_RAD_S", "REFERENCE_TEMP_C", "SEA_LEVEL_DENSITY_KG_M3"]

#: Temperature at which the base model's R and k_e hold [°C].
REFERENCE_TEMP_C = 25.0
#: ISA sea-level air density [kg/m³]; the base model's C_p is read as C_p at this density.
SEA_LEVEL_DENSITY_KG_M3 = 1.225
#: Speed at which a change of the propeller exponent leaves the load unchanged [rad/s] (conditioning).
REFERENCE_SPEED_RAD_S = 1000.0


def winding_resistance_temperature(
    terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]
) -> ModelTerms:
    """Winding resistance rises with temperature: ``R(T) = R·(1 + alpha·(T − 25 °C))``.

    Copper's resistance grows by 0.393 %/K, so a winding at 85 °C has 24 % more resistance than at
    25 °C: at a given voltage the motor draws less current and turns slower, most at high load (the R·i
    drop grows with current). Matters in long flights, hot climates and after heavy manoeuvres. Uses the
    motor temperature, or the ESC temperature when the motor's is not measured (a weaker proxy).
    ``alpha`` [1/K] is bounded by 0..1 %/K (copper 0.393 %/K; the ESC's MOSFETs add a similar rise).
    """
    temperature = data["motor_temp_c"]
    return terms.replace(R_ohm=terms.R_ohm * (1.0 + p["alpha_per_k"] * (temperature - REFERENCE_TEMP_C)))


def magnet_flux_temperature(
    terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]
) -> ModelTerms:
    """Magnet flux falls as the magnets warm: ``k_e(T) = k_e·(1 − beta·(T − 25 °C))``.

    The remanence of NdFeB magnets drops by about 0.11–0.12 %/K (ferrite 0.2 %/K), and with it the
    back-EMF and torque constants (k_t = k_e). A warm motor spins faster at a given voltage but needs
    more current for the same torque. ``beta`` [1/K] is bounded by 0..0.5 %/K.
    """
    temperature = data["motor_temp_c"]
    return terms.replace(k_e=terms.k_e * (1.0 - p["beta_per_k"] * (temperature - REFERENCE_TEMP_C)))


def esc_pwm(terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]) -> ModelTerms:
    """The ESC as a PWM stage: effective voltage and current from the duty cycle.

    The ESC chops the bus voltage: the windings see on average ``V_eff = duty·V_bus``, with
    ``duty = clip((throttle − throttle_offset)/(1 − throttle_offset), 0, 1)`` (ESCs map their command
    range with an offset; ``throttle_offset`` [1] in −0.2..0.4). Energy is conserved across the stage,
    so the current on the battery side is ``duty`` times the motor current: many ESCs (and every bench
    that measures at the battery) report that bus current. ``bus_current_fraction`` [1] blends the two:
    0 = the reported current is the motor's, 1 = it is the bus current. Needs ``throttle`` and
    ``bus_voltage_v``; matters whenever the model is fed from throttle and battery voltage.
    """
    u0 = p["throttle_offset"]
    duty = np.clip((data["throttle"] - u0) / (1.0 - u0), 0.0, 1.0)
    fraction = p["bus_current_fraction"]
    return terms.replace(
        voltage_v=duty * data["bus_voltage_v"],
        current_scale=terms.current_scale * (1.0 - fraction + fraction * duty),
    )


def air_density(terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]) -> ModelTerms:
    """Air density scales the propeller load: ``C_p(ρ) = C_p·(ρ/1.225 kg/m³)^n``.

    Propeller torque is ``C_Q·ρ·n²·D⁵``: proportional to air density (``n`` = 1 in theory).
    Density from the ISA barometric formula at altitude ``alt_m`` and the ideal gas law at the air
    temperature (``air_temp_c`` when measured, else the ISA temperature at that altitude):
    ``p = 101325·(1 − 2.25577e-5·h)^5.25588`` Pa, ``ρ = p / (287.05·T)``. At 2,000 m the load is 18 %
    lighter, so the motor turns faster on less current. ``density_exponent`` [1] is bounded 0..1.5.
    """
    h = data["alt_m"]
    pressure = 101325.0 * np.clip(1.0 - 2.25577e-5 * h, 0.05, None) ** 5.25588
    temperature_k = data.get("air_temp_c", 15.0 - 6.5e-3 * h) + 273.15
    rho = pressure / (287.05 * temperature_k)
    return terms.replace(C_p=terms.C_p * (rho / SEA_LEVEL_DENSITY_KG_M3) ** p["density_exponent"])


def propeller_exponent(
    terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]
) -> ModelTerms:
    """A non-integer propeller exponent: load ``C_p·ω_ref^(−Δk)·ω^(k+Δk)``.

    The paper takes the load torque as C_p·ω³ (k chosen among integers); real propellers depart from
    the square law of thrust (Reynolds number, blade flex, tip losses) and fit better with k ≈ 2.6–3.3.
    The load is left unchanged at ω_ref = 1000 rad/s so C_p and Δk stay separable. ``delta_k`` [1] in
    −1..1. Needs no extra variable.
    """
    dk = p["delta_k"]
    return terms.replace(C_p=terms.C_p * REFERENCE_SPEED_RAD_S ** (-dk), k=terms.k + dk)


def thrust_bearing_friction(
    terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]
) -> ModelTerms:
    """Bearing friction loaded by thrust: an extra torque ``B2·ω²``.

    The paper's argument for T_f: the bearings carry the propeller's thrust, and rolling friction grows
    with the load. Thrust grows with ω², so the friction torque gains a term in ω² between the viscous
    B·ω and the propeller's ω³. Matters for worn or dry bearings (fault F1.1 grows it). ``B2``
    [N·m/(rad/s)²] in 0..1e-5 (1e-5 is 10 N·m at 1000 rad/s: far beyond any small motor).
    """
    return terms.replace(B2=terms.B2 + p["B2"])


def esc_voltage_drop(terms: ModelTerms, p: Mapping[str, float], data: Mapping[str, FloatArray]) -> ModelTerms:
    """ESC and wiring voltage drop: ``V_windings = V − drop_v − wiring_ohm·duty²·i``.

    The ESC's MOSFETs and the battery leads eat voltage: a near-constant part (switch forward drop,
    dead-time losses: ``drop_v`` [V] in 0..2) and a part in the bus current ``duty·i`` through the lead
    resistance ``wiring_ohm`` [Ω] in 0..0.5, which the windings see scaled by the duty once more. With
    no ``throttle`` column duty is 1 and the wiring resistance cannot be told apart from R (it adds to it).
    """
    duty = np.clip(data["throttle"], 0.0, 1.0) if "throttle" in data else 1.0
    return terms.replace(
        voltage_v=terms.voltage_v - p["drop_v"], R_ohm=terms.R_ohm + p["wiring_ohm"] * duty * duty
    )


#: Built-in effects by name, in the order reports list them.
BUILTIN_EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "resistance_temperature",
            winding_resistance_temperature,
            (
                EffectParameter(
                    "alpha_per_k", "1/K", 0.0, 0.01, 0.0039, 0.0, "resistance temperature coefficient"
                ),
            ),
            needs=("motor_temp_c|esc_temp_c",),
            summary="winding resistance rising with temperature",
        ),
        Effect(
            "flux_temperature",
            magnet_flux_temperature,
            (EffectParameter("beta_per_k", "1/K", 0.0, 0.005, 0.0012, 0.0, "flux temperature coefficient"),),
            needs=("motor_temp_c|esc_temp_c",),
            summary="magnet flux (k_e) falling with temperature",
        ),
        Effect(
            "esc_pwm",
            esc_pwm,
            (
                EffectParameter("throttle_offset", "1", -0.2, 0.4, 0.0, 0.0, "throttle at zero duty"),
                EffectParameter("bus_current_fraction", "1", 0.0, 1.0, 0.5, 0.0, "0 motor current, 1 bus"),
            ),
            needs=("throttle", "bus_voltage_v"),
            summary="ESC PWM: effective voltage and current from the duty",
        ),
        Effect(
            "air_density",
            air_density,
            (EffectParameter("density_exponent", "1", 0.0, 1.5, 1.0, 0.0, "load ∝ ρ^n"),),
            needs=("alt_m",),
            optional=("air_temp_c",),
            summary="air density (altitude, temperature) scaling the propeller load",
        ),
        Effect(
            "propeller_exponent",
            propeller_exponent,
            (EffectParameter("delta_k", "1", -1.0, 1.0, 0.0, 0.0, "k_effective − k"),),
            summary="non-integer propeller exponent",
        ),
        Effect(
            "bearing_friction",
            thrust_bearing_friction,
            (EffectParameter("B2", "N*m/(rad/s)^2", 0.0, 1e-5, 0.0, 0.0, "thrust-loaded friction"),),
            summary="bearing friction loaded by thrust (a term in ω²)",
        ),
        Effect(
            "esc_voltage_drop",
            esc_voltage_drop,
            (
                EffectParameter("drop_v", "V", 0.0, 2.0, 0.1, 0.0, "constant ESC drop"),
                EffectParameter("wiring_ohm", "ohm", 0.0, 0.5, 0.0, 0.0, "lead resistance"),
            ),
            optional=("throttle",),
            summary="ESC and wiring voltage drop",
        ),
    )
}
