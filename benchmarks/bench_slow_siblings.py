"""The slow look's speed deviation judged against what its siblings show at the moment, measured (issue 17;
no change to the diagnosis): would it name an open transistor (F4.1) in moderate and gusty air, where the
shipped bands swallow it, without naming healthy motors? (The profile's ``slow_siblings`` is built on
``--scale rms``: rules/tree.py, docs/flight.md "The slow look as its siblings run".)

    PYTHONPATH=src python benchmarks/bench_slow_siblings.py --first 1000 --count 20 --jobs 2

Per world (:mod:`mav_motor_health.evaluation.worlds`): identified by ``fit`` from its own healthy 150-s
flight; at each ``--levels`` turbulence one ``--fault`` flight and ``--healthy-flights`` healthy ones (60 s,
.tlog, the fault run's flights of ``bench_flight_worlds.py``), diagnosed with the shipped
``flight_vehicle``. From the diagnosis, each motor's slow speed deviation ``x`` (the balance rule's slow
look, ``omega_slow_judged_rad_s - omega_model_rad_s``, less the motor's identified slow offset) against its
siblings at the same moment: each sibling's latest ``x`` at most ``--recent-s`` old, with at least three,
their median ``m`` and spread ``s`` (median absolute deviation × 1.4826), and

    z = (x - m) / max(lowpass_tau(s), floor · σ_slow)

``lowpass_tau`` a first-order low-pass over the motor's samples (``--tau-s``, as the torque's spread is
low-passed, rules/bands.py), σ_slow the motor's identified quiet slow σ (``[noise.N] slow_speed_rad_s``).
With ``--scale rms`` instead ``z = x / max(√median_j(lowpass_tau(x_j²)), floor · σ_slow)``: the motor's own
value in the root of its siblings' mean squares, each low-passed over that sibling's own samples.
``--quantity slow_current`` compares the slow current deviation instead (an open transistor lowers it
too); ``--quantity voltage`` the voltage balance's residual (``voltage_residual_v`` less its
identified offset, its quiet σ the floor's unit; an open transistor raises it: z above ``+band``).

Printed: for each fault flight the faulty motor's median z from 1 s after onset and the share of its
samples beyond the shipped bands' 4.5 the fault's way, its median value and the healthy
motors' 10th and 90th percentiles over the same time; for the healthy motors (every
motor of the healthy flights and of the fault flights, the faulty one before onset only) each motor-flight's 99th and 99.9th
percentile of |z| and the count of motor-flights whose 99.9th lies beyond the band. A test that names the
fault at z beyond the band needs the faulty medians beyond it and the healthy tails within it.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.config import load_profile  # noqa: E402
from mav_motor_health.diagnosis.rules.bands import held_average  # noqa: E402
from mav_motor_health.errors import MotorHealthError  # noqa: E402
from mav_motor_health.evaluation.campaign import TURBULENCE_LEVELS  # noqa: E402
from mav_motor_health.evaluation.worlds import diagnose_flight, identify_world, world_flights  # noqa: E402

BAND = 4.5  # the shipped flight_vehicle's noise_bands
MAD_TO_SIGMA = 1.4826


def low_pass(t: NDArray[np.float64], x: NDArray[np.float64], tau_s: float) -> NDArray[np.float64]:
    """First-order low-pass of ``x`` over its finite samples at times ``t``, started on the first; held
    (the last value) on the others: the live noise's
    :func:`~mav_motor_health.diagnosis.rules.bands.held_average` on one row."""
    finite = np.isfinite(x)
    start = np.full(1, np.nan)
    out, _, _ = held_average(
        t[None, :], np.where(finite, x, 0.0)[None, :], finite[None, :], tau_s, start, start
    )
    return np.asarray(out[0])


#: what is compared: its value from the diagnosis' columns, the noise keys of its quiet σ and offset, and
#: the way an open transistor moves it
QUANTITIES = {
    "slow_speed": (
        lambda c: c["omega_slow_judged_rad_s"] - c["omega_model_rad_s"],
        "slow_speed_rad_s",
        "slow_speed_offset_rad_s",
        -1.0,
    ),
    "slow_current": (
        lambda c: c["current_slow_judged_a"] - c["current_model_a"],
        "slow_current_a",
        "slow_current_offset_a",
        -1.0,
    ),
    "voltage": (lambda c: c["voltage_residual_v"], "voltage_residual_v", "voltage_residual_offset_v", 1.0),
}


def sibling_z(
    columns: dict[str, NDArray[Any]], noise: Any, args: argparse.Namespace
) -> dict[int, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]:
    """Each motor's samples' times, values less their offset, and z (module doc)."""
    recent_s, tau_s, floor = args.recent_s, args.tau_s, args.floor
    read, sigma_key, offset_key, _ = QUANTITIES[args.quantity]
    motor, t = columns["motor"], columns["time_s"].astype(float)
    x = np.asarray(read(columns), dtype=float)
    motors = sorted(int(m) for m in np.unique(motor))
    series = {}
    for m in motors:
        rows = motor == m
        own = noise.get(m, {})
        series[m] = (t[rows], x[rows] - own.get(offset_key, 0.0), own.get(sigma_key, math.nan))
    if args.scale == "rms":
        # each motor's own mean square over its recent samples: what the siblings' median is taken of
        given = {m: low_pass(tm, xm**2, tau_s) for m, (tm, xm, _) in series.items()}
    else:
        given = {m: xm for m, (_, xm, _) in series.items()}
    out = {}
    for m in motors:
        tm, xm, sigma = series[m]
        latest = []
        for j in motors:
            if j == m:
                continue
            tj, xj = series[j][0], given[j]
            ok = np.isfinite(xj)
            tj, xj = tj[ok], xj[ok]
            if not len(xj):  # this sibling never gave the value (no usable current, say)
                latest.append(np.full(len(tm), np.nan))
                continue
            k = np.searchsorted(tj, tm, side="right") - 1
            value = np.where(k >= 0, xj[np.clip(k, 0, None)], np.nan)
            value[(k < 0) | (tm - tj[np.clip(k, 0, None)] > recent_s)] = np.nan
            latest.append(value)
        siblings = np.array(latest)
        enough = np.isfinite(siblings).sum(axis=0) >= 3
        with warnings.catch_warnings(), np.errstate(invalid="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            median = np.nanmedian(siblings, axis=0)
            spread = MAD_TO_SIGMA * np.nanmedian(np.abs(siblings - median), axis=0)
        if args.scale == "rms":
            usable = enough & np.isfinite(xm) & np.isfinite(median)
            scale = np.fmax(np.sqrt(median), floor * sigma)
            z = np.where(usable, xm / scale, np.nan)
        else:
            usable = enough & np.isfinite(xm) & np.isfinite(spread)
            scale = np.fmax(low_pass(tm, np.where(usable, spread, np.nan), tau_s), floor * sigma)
            z = np.where(usable, (xm - median) / scale, np.nan)
        out[m] = (tm, xm, z)
    return out


def evaluate(world: int, args: argparse.Namespace) -> dict[str, Any]:
    profile = load_profile("flight_vehicle")
    sign = QUANTITIES[args.quantity][3]
    faults, healthy = [], []
    with tempfile.TemporaryDirectory() as folder:
        try:
            _, _, vehicle = identify_world(world, Path(folder))
        except MotorHealthError as error:
            return {"world": world, "refused": str(error)}
        noise = vehicle.noise or {}
        for flight in world_flights(
            world,
            duration_s=args.duration_s,
            healthy_flights=args.healthy_flights,
            levels=args.levels,
            faults=[args.fault],
        ):
            columns = dict(diagnose_flight(flight, Path(folder), vehicle, profile).columns)
            found = sibling_z(columns, noise, args)
            for m, (t, x, z) in found.items():
                healthy_part = np.ones(len(t), bool)
                if flight.fault is not None and m == flight.motor:
                    assert flight.onset_s is not None
                    late = t > flight.onset_s + 1.0
                    after = z[late & np.isfinite(z)]
                    own = x[late & np.isfinite(x)]
                    # the healthy motors' values over the same time, pooled: 10th and 90th percentiles
                    others = np.concatenate(
                        [
                            v[(u > flight.onset_s + 1.0) & np.isfinite(v)]
                            for j, (u, v, _) in found.items()
                            if j != m
                        ]
                    )
                    faults.append(
                        (
                            flight.turbulence,
                            float(np.median(after)) if len(after) else math.nan,
                            float(np.mean(sign * after > BAND)) if len(after) else 0.0,
                            float(np.median(own)) if len(own) else math.nan,
                            *(
                                np.percentile(others, [10.0, 90.0]).tolist()
                                if len(others)
                                else [math.nan] * 2
                            ),
                        )
                    )
                    healthy_part = t < flight.onset_s
                values = np.abs(z[healthy_part & np.isfinite(z)])
                if len(values) >= 50:
                    healthy.append(
                        (
                            flight.turbulence,
                            m,
                            *np.percentile(values, [99.0, 99.9]).tolist(),
                            f"world {world} {flight.fault or 'healthy'} motor {m}",
                        )
                    )
    return {"world": world, "faults": faults, "healthy": healthy}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000)
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--levels", nargs="+", default=list(TURBULENCE_LEVELS))
    parser.add_argument("--fault", default="F4.1")
    parser.add_argument("--healthy-flights", type=int, default=1)
    parser.add_argument("--duration-s", type=float, default=60.0)
    parser.add_argument(
        "--recent-s", type=float, default=0.3, help="a sibling's latest value at most this old"
    )
    parser.add_argument("--tau-s", type=float, default=10.0, help="the spread's low-pass time constant")
    parser.add_argument("--floor", type=float, default=1.0, help="the scale at least this many quiet slow σ")
    parser.add_argument(
        "--quantity",
        choices=sorted(QUANTITIES),
        default="slow_speed",
        help="the slow speed deviation [rad/s] (default), the slow current deviation [A] or the voltage "
        "balance's residual [V]",
    )
    parser.add_argument(
        "--scale",
        choices=("spread", "rms"),
        default="spread",
        help="z against the siblings' median in their low-passed spread (default), or each motor's own value "
        "in the median of its siblings' root mean squares over --tau-s",
    )
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args(argv)
    worlds = range(args.first, args.first + args.count)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if args.jobs > 1:
            with ProcessPoolExecutor(args.jobs) as pool:
                results = list(pool.map(evaluate, worlds, [args] * len(worlds)))
        else:
            results = [evaluate(w, args) for w in worlds]
    print(
        f"worlds {args.first}-{args.first + args.count - 1}, {args.fault}, {args.quantity} against the siblings' "
        f"{args.scale} (over {args.tau_s:g} s), at least {args.floor:g} quiet sigma, band {BAND}"
    )
    sign = QUANTITIES[args.quantity][3]
    for level in args.levels:
        rows = [(r["world"], f) for r in results if "faults" in r for f in r["faults"] if f[0] == level]
        medians = [f[1] for _, f in rows if math.isfinite(f[1])]
        shares = [f[2] for _, f in rows]
        tails = [h for r in results if "healthy" in r for h in r["healthy"] if h[0] == level]
        t999 = np.array([h[3] for h in tails])
        t99 = np.array([h[2] for h in tails])
        print(f"\n{level}: {len(rows)} fault flights, {len(tails)} healthy motor-flights")
        if medians:
            print(
                f"  faulty motor, median z after onset: median flight {np.median(medians):.1f}, "
                f"the flight nearest 0 {sign * min(sign * v for v in medians):.1f}; share beyond {BAND} the fault's way: median {np.median(shares):.2f}"
            )
            print("  per world: z " + ", ".join(f"{w} {f[1]:.1f}" for w, f in rows))
            print(
                "  per world: the faulty motor's median value after onset [the healthy motors' 10th, 90th "
                "percentile]: " + ", ".join(f"{w} {f[3]:.3g} [{f[4]:.3g}, {f[5]:.3g}]" for w, f in rows)
            )
        if len(tails):
            print(
                f"  healthy |z|, 99th percentile: median {np.median(t99):.2f}, worst {t99.max():.2f}; "
                f"99.9th: median {np.median(t999):.2f}, worst {t999.max():.2f}; "
                f"motor-flights with the 99.9th beyond {BAND}: {int(np.sum(t999 > BAND))}"
            )
            worst = sorted(tails, key=lambda h: -h[3])[:5]
            print("  the five widest: " + ", ".join(f"{h[4]} {h[3]:.1f}" for h in worst))
    refused = [r["world"] for r in results if "refused" in r]
    if refused:
        print(f"\nrefused by identification: {refused}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
