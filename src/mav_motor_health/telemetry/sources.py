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


def _read_tlog(path: Path) -> TelemetryTable:
    from .tlog import read_tlog

    return read_tlog(path)


def _read_dataflash(path: Path) -> TelemetryTable:
    from .dataflash import read_dataflash

    return read_dataflash(path)


def _read_dataflash_text(path: Path) -> TelemetryTable:
    from .dataflash import read_dataflash_text

    return read_dataflash_text(path)


def _read_ulog(path: Path) -> TelemetryTable:
    from .ulog import read_ulog

    return read_ulog(path)


#: Reader per lower-case file extension. Log readers register here as they are added.
READERS: dict[str, Callable[[Path], TelemetryTable]] = {
    ".csv": _read_csv,
    ".tlog": _read_tlog,
    ".bin": _read_dataflash,
    ".ulg": _read_ulog,
    ".log": _read_dataflash_text,
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
