"""Arguments and helpers shared by several subcommands."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..config import DEFAULT_MOTOR, DEFAULT_PROFILE, load_motor_params, load_profile
from ..diagnosis.profile import ThresholdProfile
from ..errors import DataError
from ..model.params import MotorParams
from ..telemetry.table import TelemetryTable

__all__ = ["add_model_arguments", "models_from_args", "read_telemetry", "write_new_file"]


def add_model_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--params",
        default=DEFAULT_MOTOR,
        metavar="FILE",
        help=f"motor parameters TOML, or a name in params/motors (default {DEFAULT_MOTOR})",
    )
    parser.add_argument(
        "--profile",
        default=DEFAULT_PROFILE,
        metavar="P",
        help=f"threshold profile: testbed, flight or a TOML file (default {DEFAULT_PROFILE})",
    )


def models_from_args(args: argparse.Namespace) -> tuple[MotorParams, ThresholdProfile]:
    return load_motor_params(args.params), load_profile(args.profile)


def read_telemetry(path: str | Path) -> TelemetryTable:
    """Any telemetry source the project reads, chosen by file extension."""
    path = Path(path)
    from ..telemetry import sources

    return sources.read(path)


def write_new_file(path: str | Path, text: str, *, force: bool = False) -> Path:
    """Write text to a file that must not exist yet (unless ``force``): user files are never overwritten."""
    path = Path(path)
    if path.exists() and not force:
        raise DataError("exists already; not overwritten (use --force to replace it)", path=path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path
