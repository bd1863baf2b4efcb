"""Each motor against the best linear prediction from its siblings, learned on the identification flight
(issue 17): how much of the healthy residuals' spread in manoeuvres and gusts the attitude controller's
pattern across the motors explains, measured before any rule is built on it.

    PYTHONPATH=src python benchmarks/bench_sibling_covariance.py --first 1000 --count 20 --jobs 2
    PYTHONPATH=src python benchmarks/bench_sibling_covariance.py --first 0 --count 10 --jobs 2   # development

Why. In gusty air a motor's torque, voltage and speed residuals spread several times wider than in calm
air, and friction, a lighter propeller and an open transistor sit inside that spread (docs/flight.md,
"The two equations apart"). Much of the spread is not each motor's own: the attitude controller drives
the six motors in a pattern (collective, roll, pitch, yaw: four directions of six), and whatever the model
gets wrong in fast changes (the inertia's torque, a reading averaged over its report, a command paired
with another instant) follows that pattern. "What the siblings share" (docs/flight.md) measured the
siblings' *median* and found it cancels only a common mode, since "the attitude controller drives opposite
motors opposite ways, which no median cancels". A linear prediction does cancel it: with Σ the covariance
of the six motors' residuals, motor m's conditional residual ``r_m − E[r_m | siblings]`` in its own
conditional σ is ``g_m = e_mᵀ Σ⁻¹ r / √(e_mᵀ Σ⁻¹ e_m)``, the generalised likelihood ratio statistic for a
bias on motor m alone. Σ needs no frame geometry and no constant: it is measured on the vehicle's own
healthy identification flight.

How. Each world (``sim.worlds.draw_world``) is identified from its own healthy 150-s flight as ``fit LOG
--out vehicle.toml`` does, and that flight is diagnosed with the vehicle file (``flight_vehicle``); Σ and
each motor's median are estimated there, per quantity, on the judged samples where every motor has a
value at most ``--max-age-s`` old (each motor's latest at the times of the others' samples). Then the
world's test flights (one per fault and one healthy, per turbulence level, 60 s) are diagnosed as replay
does, and at each judged sample of each motor:

* *as judged*: ``z_m = (r_m − median_m)/√Σ_mm`` (the motor on its own, in its identified spread);
* *less its siblings' median* (the median of the others' aligned values, where all but one have one);
* *against its siblings*: ``g_m`` above;
* *against its siblings at the activity*: ``g_m`` with ``Σ(a) = S0 + a²·S1`` at the motor's input activity
  (each element of Σ fitted on [1, a²] over the identification flight; measured, not kept: docs/flight.md).

The quantities: the torque balance's residual (``torque_residual_nm``: friction above, a lighter propeller
below), the voltage balance's (``voltage_residual_v``: an open transistor above) and the speed deviation
(judged speed − model: an open transistor and friction below). The two statistics are calibrated alike on
the test flights' healthy motors of the same turbulence level (their 99.9th percentile of |statistic|,
``q``), and the figure is the faulty motor's median departure along its fault's direction from 1 s after
onset over that ``q``: above 1, the fault stands beyond all but a thousandth of the healthy samples.
Printed per world, then per turbulence level the median and the worst decile of worlds for each
fault × quantity, both ways. Nothing here changes the diagnosis.
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
from mav_motor_health.diagnosis.noise import band_noise_of  # noqa: E402
from mav_motor_health.diagnosis.pipeline import diagnose  # noqa: E402
from mav_motor_health.evaluation.worlds import (  # noqa: E402
    TURBULENCE_LEVELS,
    describe_world,
    diagnose_flight,
    identify_world,
    percentile,
    world_flights,
)
from mav_motor_health.sim.worlds import draw_world  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402
from mav_motor_health.telemetry.assemble import held  # noqa: E402

PROFILE = "flight_vehicle"
#: the faults measured, each with the quantities it departs in and its direction there
SIGNATURES = {
    "F1.1": {"torque": 1.0, "speed": -1.0},
    "F3.1": {"torque": -1.0},
    "F4.1": {"voltage": 1.0, "speed": -1.0},
}
QUANTITIES = ("torque", "voltage", "speed")
#: the statistics compared: the motor alone, less its siblings' median, against their linear prediction
STATISTICS = ("alone", "median off", "against", "against at the activity")
#: the healthy samples' quantile each statistic is calibrated on
HEALTHY_Q = 99.9
#: at least this many aligned samples to estimate Σ, and this many after onset to take a median
MIN_SAMPLES = 50


def quantity(result, name: str) -> np.ndarray:
    """One residual column of a diagnosis result, NaN where the sample was not judged."""
    steady = result["steady"].astype(bool)
    if name == "torque":
        values = result["torque_residual_nm"]
    elif name == "voltage":
        values = result["voltage_residual_v"]
    else:
        values = result["omega_judged_rad_s"] - result["omega_model_rad_s"]
    return np.where(steady, np.asarray(values, dtype=float), np.nan)


def aligned(
    result, name: str, motors: list[int], max_age_s: float
) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """For each motor, at its own samples' times: the times, the matrix of every motor's latest finite value
    at most ``max_age_s`` old (columns in ``motors``' order; the motor's own column its own value), and the
    motor's own input activity there."""
    values = quantity(result, name)
    series = {}
    activity = {}
    for m in motors:
        sel = result["motor"] == m
        t, v = result["time_s"][sel], values[sel]
        ok = np.isfinite(v)
        series[m] = (t, v, t[ok], v[ok])
        activity[m] = np.asarray(result["input_activity_v"][sel], dtype=float)
    out = {}
    for m in motors:
        t = series[m][0]
        columns = []
        for o in motors:
            if o == m:
                columns.append(series[m][1])
                continue
            columns.append(held((series[o][2], series[o][3]), t, max_age_s)[0])
        out[m] = (t, np.column_stack(columns), activity[m])
    return out


def covariance(
    rows: list[np.ndarray], activity: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """Each motor's median, the covariance of the rows where every motor has a value, and that covariance
    as it grows with the input activity, ``Σ(a) = S0 + a²·S1`` (each element's product fitted on [1, a²],
    both parts made positive semi-definite); None: too few rows."""
    stack, a = np.vstack(rows), np.concatenate(activity)
    full = np.isfinite(stack).all(axis=1) & np.isfinite(a)
    if full.sum() < MIN_SAMPLES:
        return None
    center = np.median(stack[full], axis=0)
    x = stack[full] - center
    products = (x[:, :, None] * x[:, None, :]).reshape(x.shape[0], -1)
    design = np.column_stack([np.ones(x.shape[0]), a[full] ** 2])
    coefficients = np.linalg.lstsq(design, products, rcond=None)[0]
    s0, s1 = (_psd(c.reshape(x.shape[1], x.shape[1])) for c in coefficients)
    return center, np.cov(x, rowvar=False), s0, s1


def _psd(matrix: np.ndarray) -> np.ndarray:
    """The nearest positive semi-definite matrix (negative eigenvalues set to 0)."""
    sym = 0.5 * (matrix + matrix.T)
    values, vectors = np.linalg.eigh(sym)
    return (vectors * np.maximum(values, 0.0)) @ vectors.T


def statistics_of(
    matrix: np.ndarray, activity: np.ndarray, column: int, fitted: tuple[np.ndarray, ...]
) -> tuple[np.ndarray, ...]:
    """The motor in ``column`` in each of :data:`STATISTICS` (NaN where its inputs are missing)."""
    center, cov, s0, s1 = fitted
    x = matrix - center
    own = x[:, column]
    alone = own / np.sqrt(cov[column, column])
    others = np.delete(x, column, axis=1)
    enough = np.sum(np.isfinite(others), axis=1) >= others.shape[1] - 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        median_off = np.where(enough, own - np.nanmedian(others, axis=1), np.nan)
    precision = np.linalg.pinv(cov)
    against = x @ (precision[column] / np.sqrt(precision[column, column]))
    full = np.isfinite(x).all(axis=1) & np.isfinite(activity)
    # Σ at each sample's activity: the controller's pattern as strong as the air makes it there
    a2 = np.where(np.isfinite(activity), activity, 0.0) ** 2
    n = x.shape[1]
    ridge = 1e-9 * np.trace(cov) / n * np.eye(n)
    at = np.linalg.inv(s0[None] + a2[:, None, None] * s1[None] + ridge)
    row = at[:, column, :]
    with np.errstate(invalid="ignore"):
        at_activity = np.einsum("ij,ij->i", np.nan_to_num(x), row) / np.sqrt(row[:, column])
    return alone, median_off, np.where(full, against, np.nan), np.where(full, at_activity, np.nan)


def _quantile(pool: list[np.ndarray]) -> float:
    """The healthy samples' :data:`HEALTHY_Q` percentile (NaN: fewer than :data:`MIN_SAMPLES`)."""
    values = np.concatenate(pool) if pool else np.zeros(0)
    return float(np.percentile(values, HEALTHY_Q)) if values.size >= MIN_SAMPLES else float("nan")


def one_world(world: int, max_age_s: float) -> dict:
    started = time.monotonic()
    profile = load_profile(PROFILE)
    with tempfile.TemporaryDirectory(prefix=f"mmh-cov{world}-") as tmp:
        folder = Path(tmp)
        try:
            log, _, vehicle = identify_world(world, folder)
        except Exception as exc:  # a benchmark reports every world, a refusal too
            return {"world": world, "error": f"{type(exc).__name__}: {exc}"}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            table = vehicle.calibrate(sources.read(log))
            ident = diagnose(table, vehicle.models(range(1, 7)), profile, band_noise_of(vehicle.noise))
        motors = sorted(int(m) for m in np.unique(ident["motor"]))
        fitted = {}
        for name in QUANTITIES:
            columns = aligned(ident, name, motors, max_age_s).values()
            found = covariance([matrix for _, matrix, _ in columns], [a for _, _, a in columns])
            if found is not None:
                fitted[name] = found
        # per level and quantity: healthy |statistics|, and each fault's departures, per statistic
        healthy: dict[tuple[str, str], list[list[np.ndarray]]] = {}
        departures: dict[tuple[str, str, str], list[float]] = {}
        for flight in world_flights(world, duration_s=60.0, healthy_flights=1, faults=tuple(SIGNATURES)):
            result = diagnose_flight(flight, folder, vehicle, profile)
            for name, fit in fitted.items():
                pools = healthy.setdefault((flight.turbulence, name), [[] for _ in STATISTICS])
                for column, (m, (t, matrix, activity)) in enumerate(
                    aligned(result, name, motors, max_age_s).items()
                ):
                    values = statistics_of(matrix, activity, column, fit)
                    every = np.all([np.isfinite(v) for v in values], axis=0)
                    faulty = flight.fault is not None and m == flight.motor
                    well = (t < flight.onset_s if faulty else np.ones(t.size, dtype=bool)) & every
                    for pool, v in zip(pools, values):
                        pool.append(np.abs(v[well]))
                    sign = SIGNATURES.get(flight.fault or "", {}).get(name)
                    if not faulty or sign is None:
                        continue
                    after = (t >= flight.onset_s + 1.0) & every
                    if after.sum() >= MIN_SAMPLES:
                        departures[flight.turbulence, flight.fault, name] = [
                            float(np.median(sign * v[after])) for v in values
                        ]
        scale = {key: tuple(_quantile(pool) for pool in pools) for key, pools in healthy.items()}
        figures = {
            key: tuple(d / q for d, q in zip(found, scale[key[0], key[2]]))
            for key, found in departures.items()
            if np.isfinite(scale[key[0], key[2]]).all()
        }
    return {
        "world": world,
        "description": describe_world(draw_world(world)),
        "figures": figures,
        "scale": scale,
        "seconds": time.monotonic() - started,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000, help="first world seed (default 1000: held out)")
    parser.add_argument("--count", type=int, default=20, help="how many worlds (default 20)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes, one world each")
    parser.add_argument("--max-age-s", type=float, default=0.15, help="a sibling's value at most this old")
    args = parser.parse_args(argv)
    started = time.monotonic()
    worlds = range(args.first, args.first + args.count)
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(pool.map(one_world, worlds, [args.max_age_s] * len(worlds)))
    collected: dict[tuple[str, str, str], list[list[float]]] = {}
    for r in results:
        if "error" in r:
            print(f"world {r['world']}: not identified ({r['error']})")
            continue
        parts = []
        for (level, fault, name), found in sorted(r["figures"].items()):
            parts.append(f"{level[0]}{fault}/{name} " + "/".join(f"{f:.2f}" for f in found))
            for pool, f in zip(collected.setdefault((level, fault, name), [[] for _ in STATISTICS]), found):
                pool.append(f)
        spread = " ".join(
            f"{level[0]}/{name} " + "/".join(f"{q:.3g}" for q in qs)
            for (level, name), qs in sorted(r["scale"].items())
        )
        print(f"world {r['world']} ({r['description']}), {r['seconds']:.0f} s")
        print(
            f"   fault departure over the healthy q{HEALTHY_Q:g} ({' / '.join(STATISTICS)}): {' '.join(parts)}"
        )
        print(f"   healthy q{HEALTHY_Q:g}: {spread}")
    print(
        f"\nthe faulty motor's median departure from 1 s after onset, over the healthy motors' q{HEALTHY_Q:g} of"
        " the same statistic and level (> 1: beyond all but a thousandth of the healthy samples); median world"
        f" [worst decile], {' -> '.join(STATISTICS)}"
    )
    for level in TURBULENCE_LEVELS:
        for fault, signature in SIGNATURES.items():
            for name in signature:
                pools = collected.get((level, fault, name))
                if not pools or not pools[0]:
                    continue
                shown = " -> ".join(f"{statistics.median(p):5.2f} [{percentile(p, 10):4.2f}]" for p in pools)
                print(f"   {level:8s} {fault} {name:7s} ({len(pools[0]):2d} worlds): {shown}")
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
