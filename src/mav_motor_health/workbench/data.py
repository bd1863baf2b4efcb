"""Arrays the workbench works on, taken once from a telemetry table, and the base-model fit."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import FitError
from ..model.estimation import FitResult, estimate
from ..model.params import MotorParams
from ..telemetry.table import TelemetryTable

__all__ = ["MODEL_COLUMNS", "WorkbenchData", "fit_base"]

FloatArray = NDArray[np.float64]
#: Columns the base model itself uses; every other numeric column is context.
MODEL_COLUMNS = ("omega_rad_s", "current_a", "voltage_v", "motor")


@dataclass(frozen=True)
class WorkbenchData:
    """Voltage, speed, current, time, motor and every numeric context column, sorted by motor and time.

    Context columns that merely copy a measured output (speed or current) are left out.
    """

    time_s: FloatArray
    motor: NDArray[np.int64]
    voltage_v: FloatArray
    omega_rad_s: FloatArray
    current_a: FloatArray
    context: dict[str, FloatArray]
    source: str
    #: the current as the sensor reported it (the ESC's input current where the source has it)
    reported_current_a: FloatArray | None = None

    @classmethod
    def from_table(cls, table: TelemetryTable) -> WorkbenchData:
        t = table.sorted_by_motor_time()
        outputs = [np.asarray(t[name], dtype=float) for name in ("omega_rad_s", "current_a")]
        context = {
            name: np.asarray(t[name], dtype=float)
            for name in t.names
            if name not in MODEL_COLUMNS
            and name not in _MEASURED_OUTPUTS
            and t[name].dtype.kind in "biuf"
            and not any(_same(np.asarray(t[name], dtype=float), out) for out in outputs)
        }
        return cls(
            time_s=np.asarray(t["time_s"], float),
            motor=np.asarray(t["motor"]),
            voltage_v=t.voltage_v(),
            omega_rad_s=np.asarray(t["omega_rad_s"], float),
            current_a=np.asarray(t["current_a"], float),
            context=context,
            source=table.source,
            reported_current_a=None
            if t.get("esc_current_a") is None
            else np.asarray(t["esc_current_a"], float),
        )

    def __len__(self) -> int:
        return len(self.time_s)

    def select(self, rows: NDArray) -> WorkbenchData:
        return WorkbenchData(
            self.time_s[rows],
            self.motor[rows],
            self.voltage_v[rows],
            self.omega_rad_s[rows],
            self.current_a[rows],
            {k: v[rows] for k, v in self.context.items()},
            self.source,
            None if self.reported_current_a is None else self.reported_current_a[rows],
        )

    def usable(self) -> WorkbenchData:
        """Rows with finite voltage, speed and current and a turning motor (speed > 0)."""
        ok = np.isfinite(self.voltage_v) & np.isfinite(self.omega_rad_s) & np.isfinite(self.current_a)
        ok &= self.omega_rad_s > 0
        if not ok.any():
            raise FitError(f"{self.source or 'the data'}: no sample has voltage, speed and current together")
        reported = self.current_a if self.reported_current_a is None else self.reported_current_a
        for name, values in (("current_a", reported[ok]), ("omega_rad_s", self.omega_rad_s[ok])):
            distinct = np.unique(values)
            if len(distinct) < 3:
                raise FitError(
                    f"{self.source or 'the data'}: {name} takes only the value(s) "
                    f"{', '.join(f'{x:g}' for x in distinct)} in {int(ok.sum())} samples: the source does not "
                    "really measure it (simulated ESC telemetry reports constants), so the model cannot be "
                    "compared or fitted"
                )
        return self.select(np.flatnonzero(ok))


#: The current as the ESC reports it (duty × motor current): the measured output in another form, never a
#: variable to explain the current's residual with.
_MEASURED_OUTPUTS = frozenset({"esc_current_a"})


def _same(a: FloatArray, b: FloatArray) -> bool:
    """A copy of a measured output (a reader's ``esc_current_a`` = ``current_a``) is not context."""
    ok = np.isfinite(a) & np.isfinite(b)
    return bool(ok.sum() > 0 and np.array_equal(a[ok], b[ok]))


def fit_base(data: WorkbenchData, name: str = "fitted motor") -> FitResult:
    """The foundation's two-step estimate; bench data with one sample per step is fitted ungrouped."""
    try:
        return estimate(data.voltage_v, data.current_a, data.omega_rad_s, name=name)
    except FitError:
        return estimate(data.voltage_v, data.current_a, data.omega_rad_s, name=name, min_samples=1)


def base_params(data: WorkbenchData) -> MotorParams:
    return fit_base(data).params
