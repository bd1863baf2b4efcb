"""Pick the reader for a telemetry file by its extension; every reader yields a TelemetryTable."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..errors import DataError
from .table import TelemetryTable

__all__ = ["READERS", "read"]


def _read_csv(path: Path) -> TelemetryTable:
    from .csv import read_csv

    return read_csv(path)


#: Reader per lower-case file extension. Log readers register here as they are added.
READERS: dict[str, Callable[[Path], TelemetryTable]] = {
    ".csv": _read_csv,
}


def read(path: str | Path) -> TelemetryTable:
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise DataError(
            f"unknown telemetry format '{path.suffix}'",
            path=path,
            where=f"expected one of {', '.join(sorted(READERS))}",
        )
    if not path.exists():
        raise DataError("file not found", path=path)
    return reader(path)
