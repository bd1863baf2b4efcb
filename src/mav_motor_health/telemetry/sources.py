"""Pick the reader for a telemetry file by its extension; every reader yields a TelemetryTable."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..errors import DataError
from .table import TelemetryTable

__all__ = ["READERS", "read"]


def _read_csv(path: Path) -> TelemetryTable:
    from .bench import bench_format, read_bench
    from .csv import read_csv

    return read_bench(path) if bench_format(path) else read_csv(path)


def _read_bench(path: Path) -> TelemetryTable:
    from .bench import read_bench

    return read_bench(path)


#: Reader per lower-case file extension. Log readers register here as they are added.
READERS: dict[str, Callable[[Path], TelemetryTable]] = {
    ".csv": _read_csv,
    ".txt": _read_bench,
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
