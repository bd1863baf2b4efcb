"""The one telemetry table every source yields: column arrays named with their units.

One row per motor sample (long format). Required columns:

=================  ==========================================================
``time_s``         seconds, increasing within each motor
``motor``          1-based motor number (int)
``omega_rad_s``    mechanical speed [rad/s] (NaN when the ESC does not report it)
``current_a``      motor current [A] (NaN when the ESC does not report it)
=================  ==========================================================

Optional, with fixed meaning: ``voltage_v`` (voltage applied to the motor), ``bus_voltage_v`` (ESC
input voltage), ``throttle`` (command 0..1), ``esc_current_a`` (ESC input current), ``motor_temp_c``,
``esc_temp_c``, ``alt_m``, ``climb_m_s``, ``air_temp_c``... Any other numeric column is carried along as
context.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._arrays import distinct
from ..errors import DataError

__all__ = ["REQUIRED_COLUMNS", "TelemetryTable"]

REQUIRED_COLUMNS = ("time_s", "motor", "omega_rad_s", "current_a")


@dataclass(frozen=True)
class TelemetryTable:
    """Columnar telemetry: a mapping of equally long numpy arrays, plus where it came from."""

    columns: Mapping[str, NDArray[Any]]
    source: str = ""
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        cols: dict[str, NDArray[Any]] = {}
        for name, values in self.columns.items():
            arr = np.asarray(values)
            if arr.ndim != 1:
                raise DataError(
                    f"column '{name}' must be one-dimensional, has shape {arr.shape}",
                    path=self.source or None,
                )
            if name == "motor":
                arr = arr.astype(np.int64)
            elif arr.dtype.kind == "f" and arr.dtype != np.float64:
                arr = arr.astype(np.float64)
            cols[name] = arr
        missing = [c for c in REQUIRED_COLUMNS if c not in cols]
        if missing:
            raise DataError(
                f"telemetry lacks column(s) {', '.join(missing)}; has {', '.join(cols) or 'none'}",
                path=self.source or None,
            )
        lengths = {len(a) for a in cols.values()}
        if len(lengths) > 1:
            raise DataError(
                "columns differ in length: " + ", ".join(f"{n}={len(a)}" for n, a in cols.items()),
                path=self.source or None,
            )
        object.__setattr__(self, "columns", cols)

    @classmethod
    def from_columns(
        cls, source: str = "", meta: Mapping[str, Any] | None = None, **columns: ArrayLike
    ) -> TelemetryTable:
        return cls({k: np.asarray(v) for k, v in columns.items()}, source=source, meta=dict(meta or {}))

    @classmethod
    def concat(cls, tables: Iterable[TelemetryTable]) -> TelemetryTable:
        """Stack tables row-wise; a column missing from some table is NaN there."""
        tables = list(tables)
        if not tables:
            raise DataError("nothing to concatenate")
        names: list[str] = []
        for t in tables:
            names += [n for n in t.names if n not in names]
        cols = {}
        for n in names:
            parts = [t[n] if n in t else np.full(len(t), np.nan) for t in tables]
            cols[n] = np.concatenate(parts)
        return cls(cols, source=tables[0].source, meta=dict(tables[0].meta))

    def __len__(self) -> int:
        return len(self.columns["time_s"])

    def __getitem__(self, name: str) -> NDArray[Any]:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"no column '{name}' (has {', '.join(self.columns)})") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    @property
    def names(self) -> list[str]:
        return list(self.columns)

    def get(self, name: str) -> NDArray[Any] | None:
        return self.columns.get(name)

    def with_columns(self, **columns: ArrayLike) -> TelemetryTable:
        return TelemetryTable(
            {**self.columns, **{k: np.asarray(v) for k, v in columns.items()}},
            source=self.source,
            meta=self.meta,
        )

    def select(self, rows: NDArray[Any]) -> TelemetryTable:
        """Rows by boolean mask or index array."""
        return TelemetryTable(
            {n: a[rows] for n, a in self.columns.items()}, source=self.source, meta=self.meta
        )

    def motors(self) -> list[int]:
        return distinct(self.columns["motor"])[0].tolist()  # motor numbers: counted, not sorted

    def for_motor(self, motor: int) -> TelemetryTable:
        return self.select(self.columns["motor"] == motor)

    def sorted_by_motor_time(self) -> TelemetryTable:
        motor, time_s = self.columns["motor"], self.columns["time_s"]
        step = np.diff(motor)
        if (step >= 0).all() and ((step > 0) | (np.diff(time_s) >= 0)).all():
            return self  # sorted already (a log's table): what the sort would leave as it is
        order = np.lexsort((time_s, motor))
        if np.all(order == np.arange(len(order))):
            return self
        return self.select(order)

    def sorted_by_time(self) -> TelemetryTable:
        order = np.argsort(self.columns["time_s"], kind="stable")
        return self.select(order)

    def voltage_v(self) -> NDArray[np.float64]:
        """Voltage applied to the motor: ``voltage_v`` where given, else ``throttle × bus_voltage_v``.

        The product is the ESC seen as an ideal PWM stage (effective voltage = duty × bus voltage); where
        neither is known the result is NaN.
        """
        n = len(self)
        direct = self.columns.get("voltage_v")
        derived = np.full(n, np.nan)
        if "throttle" in self.columns and "bus_voltage_v" in self.columns:
            derived = np.clip(self.columns["throttle"], 0.0, 1.0) * self.columns["bus_voltage_v"]
        if direct is None:
            return derived
        return np.where(np.isfinite(direct), direct, derived)
