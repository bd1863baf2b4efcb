"""The project's CSV telemetry format (see :mod:`mav_motor_health.telemetry.csv`) from a simulation."""

from __future__ import annotations

from pathlib import Path

from ...telemetry.csv import write_csv
from ...telemetry.table import TelemetryTable
from ..engine import SimRecord

__all__ = ["COLUMNS", "write_sim_csv"]

COLUMNS = (
    "time_s",
    "motor",
    "omega_rad_s",
    "current_a",
    "voltage_v",
    "bus_voltage_v",
    "throttle",
    "esc_current_a",
    "esc_temp_c",
    "motor_temp_c",
)


def sim_table(record: SimRecord) -> TelemetryTable:
    cols = record.esc_columns()
    return TelemetryTable(
        {c: cols[c] for c in COLUMNS}, source=record.scenario.name, meta=record.scenario.truth()
    )


def write_sim_csv(record: SimRecord, path: Path) -> None:
    write_csv(sim_table(record), path, COLUMNS)
