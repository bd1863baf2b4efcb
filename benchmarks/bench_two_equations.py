"""The current deviation's two sources apart (issue 17): how much of a healthy motor's noise, and of a
fault's signal, lies in the mechanical balance and how much in the electrical one.

    PYTHONPATH=src python benchmarks/bench_two_equations.py --first 0 --count 20 --jobs 2     # development
    PYTHONPATH=src python benchmarks/bench_two_equations.py --first 1000 --count 20 --jobs 2  # held out

The balance rule judges the current deviation ``Δi = (k_e·r_T − G·r_V)/D`` (model/balance.py): the
torque the model cannot account for, ``r_T``, and the voltage, ``r_V``, both low-passed, in one number.
A fault moves one of them (friction F1.1 and a lighter propeller F3.1 the torque, an open transistor F4.1
the voltage), while the band around Δi holds the noise of both. This measures by how much a fault would
stand out of the noise in its own balance instead: ``i_T = k_e·r_T/D`` and ``i_V = −G·r_V/D``, each in
amperes as Δi is (the result's ``torque_residual_nm`` and ``voltage_residual_v``; ``G`` and ``D`` at the
model speed). Nothing here changes the diagnosis.

Each world (``sim.worlds.draw_world``) is identified from its own healthy 150-s flight as ``fit LOG --out
vehicle.toml`` does; its F1.1, F3.1 and F4.1 flights at each turbulence level (``evaluation.worlds.
world_flights``, 60 s, written as .tlog and read back) are diagnosed with the ``flight_vehicle`` profile.
Over each flight's judged samples: the *noise* of Δi, ``i_T`` and ``i_V`` is the median over the healthy
motors (all but the faulty one) of each motor's robust σ (half the distance between its 16th and 84th
percentiles); the *signal* is the faulty motor's median from 1 s after onset, less its median before
onset (where it has 20 judged samples there), along the fault's sign. Printed per world the signal over
the noise (``Δi`` → its own balance) per level and fault; then per level and fault over the worlds the
median and the worst decile (10th percentile) of each, and of their ratio. Worlds whose current
identification found unusable have no current to split and are left out (counted).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.config import load_profile  # noqa: E402
from mav_motor_health.evaluation.campaign import TURBULENCE_LEVELS  # noqa: E402
from mav_motor_health.evaluation.worlds import (  # noqa: E402
    describe_world,
    diagnose_flight,
    identify_world,
    percentile,
    world_flights,
)
from mav_motor_health.model.balance import linearised_slopes  # noqa: E402
from mav_motor_health.sim.worlds import draw_world  # noqa: E402

PROFILE = "flight_vehicle"
#: each fault: the balance it lives in (index into (Δi, i_T, i_V)) and the sign it moves Δi and that one
FAULTS = {"F1.1": (1, +1.0), "F3.1": (1, -1.0), "F4.1": (2, -1.0)}
#: a motor needs this many judged samples before onset for its own offset to be taken off
MIN_BEFORE = 20


def robust_sigma(x: np.ndarray) -> float:
    """Half the distance between the 16th and 84th percentiles (σ for a normal, robust to tails)."""
    x = x[np.isfinite(x)]
    if x.size < MIN_BEFORE:
        return float("nan")
    low, high = np.percentile(x, [16.0, 84.0])
    return float(high - low) / 2.0


def split(result, params, motor: int) -> tuple[np.ndarray, np.ndarray]:
    """One motor's judged samples: their times and (Δi, i_T, i_V) [A] as rows."""
    sel = (result["motor"] == motor) & result["steady"].astype(bool)
    p = params[motor] if isinstance(params, dict) else params
    omega = result["omega_model_rad_s"][sel]
    g, d = linearised_slopes(p, omega)
    di = result["current_judged_a"][sel] - result["current_model_a"][sel]
    i_t = p.k_e * result["torque_residual_nm"][sel] / d
    i_v = -g * result["voltage_residual_v"][sel] / d
    ok = np.isfinite(di) & np.isfinite(i_t) & np.isfinite(i_v)
    return result["time_s"][sel][ok], np.array([di[ok], i_t[ok], i_v[ok]])


def one_world(world: int) -> dict:
    started = time.monotonic()
    profile = load_profile(PROFILE)
    rows: list[tuple[str, str, list[float], list[float]]] = []  # level, fault, signal, noise (Δi, i_T, i_V)
    with tempfile.TemporaryDirectory(prefix=f"mmh-two{world}-") as tmp:
        folder = Path(tmp)
        try:
            _, _, vehicle = identify_world(world, folder)
        except Exception as exc:  # a benchmark reports every world, a refusal too
            return {"world": world, "error": f"{type(exc).__name__}: {exc}"}
        if vehicle.current is not None and vehicle.current.side == "unusable":
            return {"world": world, "error": "no usable current (identification)"}
        params = vehicle.models(range(1, 7))
        for flight in world_flights(world, duration_s=60.0, healthy_flights=0, faults=tuple(FAULTS)):
            result = diagnose_flight(flight, folder, vehicle, profile)
            assert flight.fault is not None and flight.onset_s is not None
            sigmas = []
            signal = [float("nan")] * 3
            for m in (int(m) for m in np.unique(result["motor"])):
                t, values = split(result, params, m)
                if m != flight.motor:
                    sigmas.append([robust_sigma(v) for v in values])
                    continue
                after = t >= flight.onset_s + 1.0
                before = t < flight.onset_s
                if after.sum() < MIN_BEFORE:
                    continue
                _, sign = FAULTS[flight.fault]
                for j, v in enumerate(values):
                    offset = float(np.median(v[before])) if before.sum() >= MIN_BEFORE else 0.0
                    signal[j] = sign * (float(np.median(v[after])) - offset)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                sigma = [float(x) for x in np.nanmedian(np.array(sigmas), axis=0)] if sigmas else [np.nan] * 3
            rows.append((flight.turbulence, flight.fault, signal, sigma))
    return {
        "world": world,
        "description": describe_world(draw_world(world)),
        "rows": rows,
        "seconds": time.monotonic() - started,
    }


def _ratio(signal: float, sigma: float) -> float:
    return signal / sigma if sigma > 0 else float("nan")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=0, help="first world seed (default 0: development)")
    parser.add_argument("--count", type=int, default=10, help="how many worlds (default 10)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes, one world each")
    args = parser.parse_args(argv)
    started = time.monotonic()
    worlds = range(args.first, args.first + args.count)
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(pool.map(one_world, worlds))
    # per (level, fault): signal over noise via Δi, via its own balance; and the noise of each
    combined: dict[tuple[str, str], list[float]] = {}
    own: dict[tuple[str, str], list[float]] = {}
    noise_share: dict[str, list[float]] = {level: [] for level in TURBULENCE_LEVELS}
    left_out = 0
    for r in results:
        if "error" in r:
            left_out += 1
            print(f"world {r['world']}: left out ({r['error']})")
            continue
        cells = []
        for level, fault, signal, sigma in r["rows"]:
            j, _ = FAULTS[fault]
            via_di, via_own = _ratio(signal[0], sigma[0]), _ratio(signal[j], sigma[j])
            combined.setdefault((level, fault), []).append(via_di)
            own.setdefault((level, fault), []).append(via_own)
            if fault == "F1.1" and sigma[0] > 0:  # each flight's healthy noise once per level and world
                noise_share[level].append(sigma[1] / sigma[0])
            cells.append(f"{level[0]}{fault} {via_di:5.1f}->{via_own:5.1f}")
        print(f"world {r['world']} ({r['description']}): {'  '.join(cells)}; {r['seconds']:.0f} s")
    print(
        "\nsignal over noise [robust sigma of the healthy motors], the faulty motor from 1 s after onset: "
        "via the current deviation -> via its own balance (F1.1, F3.1: torque; F4.1: voltage)"
    )
    print("                 median world           worst decile           ratio own/combined")
    for level in TURBULENCE_LEVELS:
        for fault in FAULTS:
            a = [x for x in combined.get((level, fault), []) if np.isfinite(x)]
            b = [x for x in own.get((level, fault), []) if np.isfinite(x)]
            pairs = [
                y / x
                for x, y in zip(combined.get((level, fault), []), own.get((level, fault), []))
                if np.isfinite(x) and np.isfinite(y) and x > 0
            ]
            if not a or not b:
                print(f"  {level:8s} {fault}: no flight judged after onset")
                continue
            print(
                f"  {level:8s} {fault}  {statistics.median(a):6.1f} -> {statistics.median(b):6.1f}"
                f"        {percentile(a, 10):6.1f} -> {percentile(b, 10):6.1f}"
                f"        median {statistics.median(pairs) if pairs else float('nan'):.2f} ({len(pairs)} flights)"
            )
    for level in TURBULENCE_LEVELS:
        share = [x for x in noise_share[level] if np.isfinite(x)]
        if share:
            print(
                f"healthy noise of i_T over that of the current deviation, {level}: median "
                f"{statistics.median(share):.2f} (range {min(share):.2f}-{max(share):.2f}, {len(share)} worlds)"
            )
    print(f"{left_out} world(s) left out; (benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
