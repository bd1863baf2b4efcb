"""The ``mav-motor-health`` command: one subcommand per module in :mod:`.commands`.

Each subcommand module has ``add_parser(subparsers)`` and ``run(args) -> int``; the parsing lives there,
the work in a library function that tests call directly.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from collections.abc import Sequence

from .errors import MotorHealthError

__all__ = ["COMMANDS", "build_parser", "main"]

#: Subcommand modules, in the order ``--help`` lists them.
COMMANDS = (
    "demo",
    "fit",
    "predict",
    "diagnose",
    "replay",
    "compare",
    "explain",
    "agent",
    "display",
    "simulate",
    "score",
    "sim",
    "tune",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mav-motor-health",
        description="Which hexacopter motor is failing, and how: steady-state motor model and fault diagnosis.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f".commands.{name}", __package__)
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    warnings.simplefilter("default")
    warnings.formatwarning = lambda msg, cat, *a, **k: f"warning: {msg}\n"
    try:
        return int(args.run(args) or 0)
    except MotorHealthError as exc:
        print(f"mav-motor-health {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
