"""The project's exceptions.

Every error the package raises on purpose derives from :class:`MotorHealthError`::

    MotorHealthError
    ├── ConfigError        a params/profile/scenario/agent TOML file is wrong (file, key, expected)
    ├── DataError          a telemetry table or data file is unusable (file, row or column, expected)
    │   └── LogFormatError a flight log cannot be decoded (file, byte offset)
    ├── FitError           an estimation cannot be carried out (too few points, singular problem)
    └── LinkError          a MAVLink or MQTT connection failed

Errors from third-party libraries are converted at the boundary with ``raise ... from exc``.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["ConfigError", "DataError", "FitError", "LinkError", "LogFormatError", "MotorHealthError"]


class MotorHealthError(Exception):
    """Base of every error mav-motor-health raises on purpose."""


class ConfigError(MotorHealthError):
    """A configuration file or value is invalid.

    ``path`` is the file (or None for values built in code), ``key`` the dotted key, ``expected`` what
    would have been accepted.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        key: str | None = None,
        expected: str | None = None,
    ) -> None:
        self.path = None if path is None else Path(path)
        self.key = key
        self.expected = expected
        self.reason = message
        where = []
        if path is not None:
            where.append(str(path))
        if key is not None:
            where.append(f"key '{key}'")
        prefix = ": ".join(where)
        text = f"{prefix}: {message}" if prefix else message
        if expected is not None:
            text += f" (expected {expected})"
        super().__init__(text)


class DataError(MotorHealthError):
    """Telemetry data is unusable: names the file and the place (row, column or byte offset)."""

    def __init__(self, message: str, *, path: str | Path | None = None, where: str | None = None) -> None:
        self.path = None if path is None else Path(path)
        self.where = where
        parts = [p for p in (None if path is None else str(path), where) if p]
        super().__init__(f"{', '.join(parts)}: {message}" if parts else message)


class LogFormatError(DataError):
    """A flight log cannot be decoded at all (damage that resynchronising cannot get past)."""

    def __init__(self, message: str, *, path: str | Path | None = None, offset: int | None = None) -> None:
        self.offset = offset
        super().__init__(message, path=path, where=None if offset is None else f"byte {offset}")


class FitError(MotorHealthError):
    """An estimation could not be carried out."""


class LinkError(MotorHealthError):
    """A MAVLink or MQTT link could not be opened or was lost beyond recovery."""
