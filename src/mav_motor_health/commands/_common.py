"""Arguments and helpers shared by several subcommands."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..config import DEFAULT_MOTOR, DEFAULT_PROFILE, load_motor_params, load_profile
from ..diagnosis.profile import ThresholdProfile
from ..errors import DataError
from ..model.params import MotorParams
from ..telemetry.table import TelemetryTable

__all__ = [
    "add_model_arguments",
    "finite_float",
    "models_from_args",
    "non_negative_float",
    "non_negative_int",
    "port_number",
    "port_or_zero",
    "positive_float",
    "positive_int",
    "read_telemetry",
    "socket_url",
    "write_new_file",
]


def _whole_number(text: str, minimum: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {text!r}") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"expected a whole number >= {minimum}, got {value}")
    return value


def positive_int(text: str) -> int:
    """argparse type: a whole number >= 1."""
    return _whole_number(text, 1)


def non_negative_int(text: str) -> int:
    """argparse type: a whole number >= 0 (a seed)."""
    return _whole_number(text, 0)


def finite_float(text: str) -> float:
    """argparse type: a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    value = finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text}")
    return value


def non_negative_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    value = finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text}")
    return value


def port_or_zero(text: str) -> int:
    """argparse type: a port 1..65535, or 0 for a free one."""
    if text.strip() == "0":
        return 0
    return port_number(text)


def socket_url(text: str) -> str:
    """argparse type: a MAVLink socket URL (udpin:, udpout:, tcp:, tcpin: HOST:PORT with a valid port)."""
    from ..agent.link import parse_url
    from ..errors import LinkError

    try:
        url = parse_url(text)
    except LinkError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if url.kind != "socket":
        raise argparse.ArgumentTypeError(f"expected udpin:, udpout:, tcp: or tcpin:HOST:PORT, got {text!r}")
    return text


def port_number(text: str) -> int:
    """argparse type: a TCP/UDP port, 1..65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a port number 1..65535, got {text!r}") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"expected a port number 1..65535, got {value}")
    return value


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
