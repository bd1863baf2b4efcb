"""An input current's ripple (issue 17; diagnosis/rules/equations.py, "An input current's ripple"):
what an ESC that reports its input current says about its motor's current when the duty jitters.

    PYTHONPATH=src python benchmarks/bench_input_ripple.py --world 5

A world of the simulator (``sim.worlds``) is flown step by step at each turbulence level (its own plan,
one seed) and, per step, motor 1's own current ``i``, speed ``ω`` and duty ``d`` are read from the
simulated motor itself, with the reports its ESC sends. Printed per level: the duty's σ; the mean motor
current; the mean of the motor current as a log gives it (each report's current over its command, as
the readers compute it, ``esc_current_ca / command``); the true mean input current ``mean(d·i)`` and
``d̄·ī``; and how well the torque balance closes with the world's true motor, ``k_t·mean(i)`` against
``mean(C_p·ω^k + B·ω + T_f)`` [mN·m] (the propeller's manufacturing spread included). Nothing is
identified; nothing is diagnosed. The point it shows: the motor's own current and its torque balance do
not move with the air, while the current an input-side ESC reports does, by ``V·σ_d²/R`` (the ripple's
copper loss), so a torque balance read from it carries the air's jitter.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.evaluation.campaign import TURBULENCE_LEVELS  # noqa: E402
from mav_motor_health.sim.engine import Simulation  # noqa: E402
from mav_motor_health.sim.scenario import world_scenario  # noqa: E402


def fly(world: int, level: str, seconds: float, seed: int, skip_s: float) -> dict[str, float]:
    scenario = dataclasses.replace(
        world_scenario(world, duration_s=seconds), seed=seed, world_turbulence=level
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = Simulation(scenario)
        dt = sim.scenario.dt_s
        p = sim.bank.dyn.params
        spread = float(sim.bank.load_factor[0])
        current, omega, duty, reported = [], [], [], []
        for k in range(round(seconds / dt)):
            reports = sim.step()
            if k * dt < skip_s:
                continue
            current.append(sim.bank.current_a[0])
            omega.append(sim.bank.omega_rad_s[0])
            duty.append(sim.duty[0])
            reported += [r.motor_current_ca / 100.0 for r in reports if r.motor == 1]
    i, w, d = np.array(current), np.array(omega), np.array(duty)
    load = p.C_p * spread * w**p.k + p.B * w + p.T_f
    return {
        "duty_sigma": float(d.std()),
        "motor_a": float(i.mean()),
        "reported_a": float(np.mean(reported)),
        "input_a": float(np.mean(d * i)),
        "duty_times_current_a": float(d.mean() * i.mean()),
        "torque_mnm": 1e3 * p.k_t * float(i.mean()),
        "load_mnm": 1e3 * float(load.mean()),
        "side": str(sim.world.truth()["current"]["side"]) if sim.world is not None else "?",
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", type=int, default=5, help="world seed (default 5: a development world)")
    parser.add_argument("--seconds", type=float, default=30.0, help="flight length [s] (30)")
    parser.add_argument("--seed", type=int, default=77, help="the flights' noise seed (77)")
    args = parser.parse_args(argv)
    started = time.monotonic()
    print(
        f"world {args.world}, {args.seconds:g}-s flights (the first 8 s left out), motor 1, step by step; "
        "currents in A, torques in mN·m"
    )
    print(
        f"{'air':9s} {'σ_d':>6s} {'mean i':>7s} {'log i':>7s} {'mean d·i':>9s} {'d̄·ī':>7s}"
        f" {'k_t·ī':>9s} {'load':>9s}  ESC current"
    )
    for level in TURBULENCE_LEVELS:
        r = fly(args.world, level, args.seconds, args.seed, skip_s=8.0)
        print(
            f"{level:9s} {r['duty_sigma']:6.3f} {r['motor_a']:7.2f} {r['reported_a']:7.2f} {r['input_a']:9.2f}"
            f" {r['duty_times_current_a']:7.2f} {r['torque_mnm']:9.2f} {r['load_mnm']:9.2f}  {r['side']}"
        )
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
