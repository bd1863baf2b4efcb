"""``mav-motor-health predict --voltage V...``: steady-state speed and current from the model."""

from __future__ import annotations

import argparse
import json
import math

from ..config import DEFAULT_MOTOR, load_motor_params
from ..model.equations import steady_state
from ._common import non_negative_float


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("predict", help="steady-state speed and current for input voltages")
    p.add_argument(
        "--voltage",
        type=non_negative_float,
        nargs="+",
        required=True,
        metavar="V",
        help="input voltage(s) [V]",
    )
    p.add_argument("--params", default=DEFAULT_MOTOR, metavar="FILE", help="motor parameters TOML or name")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    params = load_motor_params(args.params)
    result = steady_state(params, args.voltage)
    rows = [
        {"voltage_v": v, "omega_rad_s": float(w), "rpm": float(w) * 60 / (2 * math.pi), "current_a": float(i)}
        for v, w, i in zip(args.voltage, result.omega_rad_s, result.current_a)
    ]
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'voltage_v':>10} {'omega_rad_s':>12} {'rpm':>9} {'current_a':>10}")
    for r in rows:
        print(f"{r['voltage_v']:10.3f} {r['omega_rad_s']:12.2f} {r['rpm']:9.0f} {r['current_a']:10.3f}")
    return 0
