"""How much of a healthy motor's departure from the model its siblings share (issue 17): the common mode
that a motor model fitted on one flight leaves at another operating point.

    PYTHONPATH=src python benchmarks/bench_sibling_common_mode.py --first 0 --count 10 --jobs 2  # development
    PYTHONPATH=src python benchmarks/bench_sibling_common_mode.py --first 1000 --count 20 --jobs 2

Each world (``sim.worlds.draw_world``) is identified from its own healthy 150-s flight as ``fit LOG --out
vehicle.toml`` does; then its test flights (``evaluation.worlds.world_flights``: one per fault and one
healthy, per turbulence level, 60 s, written as .tlog and read back) are diagnosed with the
``flight_vehicle`` profile. Each judged sample's deviations are put in units of the motor's σ (the judged
speed and current minus the model, over the band / ``noise_bands``; the current's band on its own side).
The *sibling median* of a sample is the median of the other motors' latest judged deviations, each at
most ``--max-age-s`` old, where at least all but one of the other motors have one (else none).

Printed per world, and as the median and the worst world: for healthy motors (every motor of the
healthy flights, the other motors of the fault flights, the faulty one before onset) the share of judged
samples outside the profile's bands (|z| > ``noise_bands``, speed or current) as diagnosed and with the
sibling median taken off; and for the faulty motor, from 1 s after onset, the median deviation along the
fault's direction in σ, as diagnosed and with the sibling median taken off (how much of the fault's
signal would remain). Nothing here changes the diagnosis: it measures what judging each motor against its
siblings would gain before the pipeline is built for it.
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
from mav_motor_health.evaluation.worlds import (  # noqa: E402
    describe_world,
    diagnose_flight,
    identify_world,
    world_flights,
)
from mav_motor_health.sim.worlds import draw_world  # noqa: E402

PROFILE = "flight_vehicle"
#: each fault's direction in (speed, current) σ: the sign its deviations take (0: not used)
DIRECTION = {"F1.1": (0, 1), "F2.1": (-1, -1), "F3.1": (1, -1), "F4.1": (-1, -1), "F4.2": (-1, 0)}


def deviations(result, motor: int, bands: float) -> tuple[np.ndarray, ...]:
    """One motor's judged samples: time, speed and current deviations in σ."""
    sel = (result["motor"] == motor) & result["steady"].astype(bool)
    t = result["time_s"][sel]
    dw = result["omega_judged_rad_s"][sel] - result["omega_model_rad_s"][sel]
    di = result["current_judged_a"][sel] - result["current_model_a"][sel]
    with np.errstate(divide="ignore", invalid="ignore"):
        zw = dw / (result["speed_band_rad_s"][sel] / bands)
        side = np.where(di >= 0, result["current_band_a"][sel], result["current_band_below_a"][sel])
        zi = di / (side / bands)
    return t, zw, zi


def sibling_median(
    times: dict[int, np.ndarray], values: dict[int, np.ndarray], motor: int, max_age_s: float
) -> np.ndarray:
    """At each of ``motor``'s times, the median of the other motors' latest finite values at most
    ``max_age_s`` old, where all but one of the others have one (NaN elsewhere)."""
    t = times[motor]
    latest = []
    for other in times:
        if other == motor:
            continue
        ok = np.isfinite(values[other])
        to, vo = times[other][ok], values[other][ok]
        j = np.searchsorted(to, t, side="right") - 1
        have = j >= 0
        v = np.where(have, vo[np.maximum(j, 0)] if vo.size else np.nan, np.nan)
        age = np.where(have, t - (to[np.maximum(j, 0)] if to.size else 0.0), np.inf)
        latest.append(np.where(age <= max_age_s, v, np.nan))
    if not latest:
        return np.full(t.size, np.nan)
    stack = np.array(latest)
    enough = np.sum(np.isfinite(stack), axis=0) >= max(1, len(latest) - 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(stack, axis=0)
    return np.where(enough, med, np.nan)


def one_world(world: int, max_age_s: float) -> dict:
    started = time.monotonic()
    profile = load_profile(PROFILE)
    bands = profile.noise_bands
    healthy_out = [0, 0, 0]  # judged samples, outside the bands as diagnosed, with the sibling median off
    fault_signal: list[tuple[str, str, float, float]] = []
    with tempfile.TemporaryDirectory(prefix=f"mmh-cm{world}-") as tmp:
        folder = Path(tmp)
        try:
            _, _, vehicle = identify_world(world, folder)
        except Exception as exc:  # a benchmark reports every world, a refusal too
            return {"world": world, "error": f"{type(exc).__name__}: {exc}"}
        for flight in world_flights(world, duration_s=60.0, healthy_flights=1):
            result = diagnose_flight(flight, folder, vehicle, profile)
            motors = [int(m) for m in np.unique(result["motor"])]
            per = {m: deviations(result, m, bands) for m in motors}
            times = {m: per[m][0] for m in motors}
            for m in motors:
                t, zw, zi = per[m]
                cw = sibling_median(times, {o: per[o][1] for o in motors}, m, max_age_s)
                ci = sibling_median(times, {o: per[o][2] for o in motors}, m, max_age_s)
                faulty = flight.fault is not None and m == flight.motor
                healthy = t < flight.onset_s if faulty else np.ones(t.size, dtype=bool)
                judged = healthy & np.isfinite(zw) & np.isfinite(zi) & np.isfinite(cw) & np.isfinite(ci)
                healthy_out[0] += int(judged.sum())
                healthy_out[1] += int(np.sum(judged & ((np.abs(zw) > bands) | (np.abs(zi) > bands))))
                off_w, off_i = zw - cw, zi - ci
                healthy_out[2] += int(np.sum(judged & ((np.abs(off_w) > bands) | (np.abs(off_i) > bands))))
                if faulty:
                    after = (t >= flight.onset_s + 1.0) & np.isfinite(cw) & np.isfinite(ci)
                    sw, si = DIRECTION[flight.fault]
                    along = sw * zw + si * zi
                    along_off = sw * off_w + si * off_i
                    if after.sum() >= 10:
                        fault_signal.append(
                            (
                                flight.turbulence,
                                flight.fault,
                                float(np.median(along[after])),
                                float(np.median(along_off[after])),
                            )
                        )
    return {
        "world": world,
        "description": describe_world(draw_world(world)),
        "healthy": healthy_out,
        "faults": fault_signal,
        "seconds": time.monotonic() - started,
    }


def _pct(part: int, whole: int) -> float:
    return 100.0 * part / whole if whole else float("nan")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=0, help="first world seed (default 0: development)")
    parser.add_argument("--count", type=int, default=10, help="how many worlds (default 10)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes, one world each")
    parser.add_argument("--max-age-s", type=float, default=0.3, help="a sibling's value at most this old")
    args = parser.parse_args(argv)
    started = time.monotonic()
    worlds = range(args.first, args.first + args.count)
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(pool.map(one_world, worlds, [args.max_age_s] * len(worlds)))
    before, after, ratio = [], [], []
    for r in results:
        if "error" in r:
            print(f"world {r['world']}: not identified ({r['error']})")
            continue
        n, out, out_off = r["healthy"]
        if n:  # a world whose current identification found unusable judges no current: left out
            before.append(_pct(out, n))
            after.append(_pct(out_off, n))
        kept = [off / on for _, _, on, off in r["faults"] if on > 1.0]
        ratio.extend(kept)
        signal = " ".join(f"{lv[0]}{f}:{on:.1f}->{off:.1f}" for lv, f, on, off in r["faults"])
        print(
            f"world {r['world']} ({r['description']}): healthy judged outside the bands "
            f"{_pct(out, n):.3f} -> {_pct(out_off, n):.3f} % of {n}; faulty motor along its fault [sigma] "
            f"{signal}; {r['seconds']:.0f} s"
        )
    if before:
        print(
            f"\nhealthy judged samples outside the bands ({len(before)} worlds with a usable current): "
            f"median world {statistics.median(before):.3f} % as diagnosed, {statistics.median(after):.3f} % "
            f"with the sibling median off; worst world {max(before):.3f} / {max(after):.3f} %; "
            f"fewer in {sum(a < b for b, a in zip(before, after))}, more in "
            f"{sum(a > b for b, a in zip(before, after))}"
        )
    if ratio:
        print(
            f"fault signal kept with the sibling median off (faults > 1 sigma deep, {len(ratio)} flights): "
            f"median {statistics.median(ratio):.2f}, lowest {min(ratio):.2f}"
        )
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
