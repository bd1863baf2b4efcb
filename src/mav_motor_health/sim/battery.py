"""A LiPo battery: open-circuit voltage by state of charge, internal resistance, coulomb counting; and its
current monitor, which averages (ArduPilot's analog monitor reads the ADC's mean since its last read, at
10 Hz: :data:`MONITOR_TAU_S`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["MONITOR_TAU_S", "Battery", "BatterySpec", "cell_open_circuit_v"]

#: time constant of the battery monitor's current average [s]
MONITOR_TAU_S = 0.1

#: open-circuit voltage of one LiPo cell [V] at state of charge 0, 0.1, ..., 1.0
_CELL_OCV_V = (3.27, 3.61, 3.69, 3.71, 3.73, 3.77, 3.79, 3.82, 3.87, 3.95, 4.20)


@dataclass(frozen=True)
class BatterySpec:
    cells: int = 3
    capacity_mah: float = 5000.0
    #: internal resistance of the pack [Ω]; 0 with ``stiff`` = a lab supply at ``supply_v``
    resistance_ohm: float = 0.02
    initial_soc: float = 1.0
    #: a stiff supply (the testbed's): constant voltage, no sag, no discharge
    supply_v: float | None = None
    #: the current monitor's scale (reading / true; 1: honest)
    monitor_gain: float = 1.0


def cell_open_circuit_v(soc: float) -> float:
    """Open-circuit voltage of one LiPo cell [V] at state of charge ``soc`` (clipped to 0..1)."""
    x = min(max(soc, 0.0), 1.0) * 10.0
    k = min(int(x), 9)
    return _CELL_OCV_V[k] + (x - k) * (_CELL_OCV_V[k + 1] - _CELL_OCV_V[k])


class Battery:
    def __init__(self, spec: BatterySpec) -> None:
        self.spec = spec
        self.soc = spec.initial_soc
        self.consumed_mah = 0.0
        self.energy_wh = 0.0
        self.current_a = 0.0
        #: the current as the battery monitor reports it (averaged over MONITOR_TAU_S)
        self.monitor_current_a = math.nan
        self.voltage_v = self.open_circuit_v()

    def open_circuit_v(self) -> float:
        if self.spec.supply_v is not None:
            return self.spec.supply_v
        return self.spec.cells * cell_open_circuit_v(self.soc)

    def step(self, current_a: float, dt: float) -> float:
        """Draw ``current_a`` for ``dt`` seconds; returns the terminal voltage."""
        self.current_a = current_a
        sensed_a = current_a * self.spec.monitor_gain
        if math.isnan(self.monitor_current_a):
            self.monitor_current_a = sensed_a
        else:
            self.monitor_current_a += (sensed_a - self.monitor_current_a) * (
                1.0 - math.exp(-dt / MONITOR_TAU_S)
            )
        if self.spec.supply_v is not None:
            self.voltage_v = self.spec.supply_v
        else:
            self.voltage_v = max(self.open_circuit_v() - self.spec.resistance_ohm * current_a, 0.0)
            used = current_a * dt / 3.6
            self.consumed_mah += used
            self.soc -= used / self.spec.capacity_mah
        self.energy_wh += self.voltage_v * current_a * dt / 3600.0
        return self.voltage_v

    @property
    def remaining_pct(self) -> int:
        return round(100 * min(max(self.soc, 0.0), 1.0))
