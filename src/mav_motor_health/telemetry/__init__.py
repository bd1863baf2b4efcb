"""The telemetry table and the sources that yield it."""

from .csv import read_csv, write_csv
from .table import REQUIRED_COLUMNS, TelemetryTable

__all__ = ["REQUIRED_COLUMNS", "TelemetryTable", "read_csv", "write_csv"]
