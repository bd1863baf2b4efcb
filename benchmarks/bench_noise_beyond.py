"""How a vehicle's healthy deviations grow beyond the conditions its identification flight measured them
in (issue 17; diagnosis/noise.py, "Beyond the measured conditions").

    PYTHONPATH=src python benchmarks/bench_noise_beyond.py --first 0 --count 20 --jobs 2   # development
    PYTHONPATH=src python benchmarks/bench_noise_beyond.py                                  # held out

Each world (``sim.worlds.draw_world``) is identified from its own healthy 150-s flight as ``fit LOG --out
vehicle.toml`` does; then one healthy flight per turbulence level (the benchmark's seeds,
``evaluation.worlds.world_flights``), written as .tlog and read back, is diagnosed with the
``flight_vehicle`` profile judging every input activity and pairing error (``conditions_reach`` at its
maximum, no growth). Each judged sample's deviations are divided by the σ(a, e) identification measured
(:meth:`~mav_motor_health.diagnosis.noise.BandNoise.sigmas`), and the samples beyond the flight's limits
(``excess`` > 1, :meth:`~mav_motor_health.diagnosis.noise.BandNoise.beyond_conditions`) up to the
profile's reach are divided again by ``excess ** g`` for a few exponents g. Printed per world and level:
the share of healthy samples in that region, and the tail of the normalised deviations there (the 99th
percentile of |z| / 2.576: 1 where σ is right, above 1 where the bands would be too narrow) for speed and
current; then over all flights with enough such samples, the median and the worst tail per exponent and
how many flights' tails exceed 1. ``conditions_growth`` is the exponent whose worst tail stays near 1.

``--siblings M ...`` adds the growth bounded by the siblings' (rules/bands.py, "Grown as the siblings
run"): the flight diagnosed again with the shipped profile and ``conditions_siblings`` = M, the growth
each sample's bands got read back from them (its band over the one the diagnosis without growth gave),
and the same tails divided by it (``M/TAU``: with ``conditions_siblings_s`` = TAU seconds too). The
shipped M is the largest narrowing whose worst tail and count of tails above 1 on the development worlds
are those of the growth by the excess alone.

Last, the torque balance against its siblings (rules/equations.py), where identification measured its
noise so: ``r_T`` less the siblings' median, less its offset, over its own σ(a, e), with no growth. Its
tail within the limits, beyond them, and beyond them divided by the growth the shipped profile gives the
torque's band there as the deviations' (the larger of the speed's and the current's growth as the
siblings run, rules/bands.py, the columns ``m=...``): whether that is as wide as the torque needs.
``--torque-spread T ...`` adds the torque's own growth (rules/bands.py, "The torque's own growth"): the
flight diagnosed with ``torque_siblings_spread`` = T, the growth of each sample's torque band read back as
the deviations' is, and the torque's tail beyond the limits divided by it (columns ``T=...``; the
shipped profile's is 3, chosen on the development worlds as the smallest whole multiple whose worst tail
stays below 1.5).

The default worlds 1000-1019 are held out: the exponent was chosen on the development worlds 0-19.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from mav_motor_health.config import dump_vehicle_params, load_profile, load_vehicle_params  # noqa: E402
from mav_motor_health.diagnosis.noise import band_noise_of  # noqa: E402
from mav_motor_health.diagnosis.pipeline import diagnose  # noqa: E402
from mav_motor_health.errors import MotorHealthError  # noqa: E402
from mav_motor_health.evaluation.worlds import fly_world, world_flights, write_identification_log  # noqa: E402
from mav_motor_health.identification import identify_logs  # noqa: E402
from mav_motor_health.replay import motor_numbers  # noqa: E402
from mav_motor_health.sim.worlds import draw_world  # noqa: E402
from mav_motor_health.sim.writers import write_record  # noqa: E402
from mav_motor_health.telemetry import sources  # noqa: E402

EXPONENTS = (0.0, 1.0, 1.5, 2.0)
#: the siblings' bounds evaluated by default (``--siblings``): the shipped multiplier, at the shipped time
#: constant (None)
SIBLINGS: tuple[tuple[float, float | None], ...] = ((4.0, None),)
MIN_SAMPLES = 100  # a tail on fewer samples than this is not reported


def _tail(z: np.ndarray) -> float:
    z = z[np.isfinite(z)]
    return float(np.quantile(np.abs(z), 0.99) / 2.576) if z.size >= MIN_SAMPLES else float("nan")


def _bound(text: str) -> tuple[float, float | None]:
    """``--siblings``' M or M/TAU."""
    m, _, tau = text.partition("/")
    try:
        return float(m), float(tau) if tau else None
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected M or M/TAU (numbers)") from None


def _label(bound: tuple[float, float | None], name: str = "m") -> str:
    m, tau = bound
    return f"{name}={m:g}" if tau is None else f"{name}={m:g}/{tau:g}s"


def _diagnosed(
    table: Any, params: Any, noise: Any, profile: Any, tau_s: float | None, **changes: float
) -> Any:
    """``table`` diagnosed with ``profile`` changed so (and ``conditions_siblings_s`` = ``tau_s`` where
    given)."""
    if tau_s is not None:
        changes["conditions_siblings_s"] = tau_s
    return diagnose(table, params, dataclasses.replace(profile, **changes), noise)


def one_world(
    world: int,
    duration_s: float,
    siblings: tuple[tuple[float, float | None], ...] = SIBLINGS,
    torque_spreads: tuple[tuple[float, float | None], ...] = (),
) -> list[tuple[str, str, float, dict[str, tuple[float, float]], dict[str, float]]]:
    """Per healthy flight: (world label, level, share of samples beyond the limits within the reach,
    {growth: (speed tail, current tail)}, growth ``g=...`` by the excess's exponent, ``m=...`` bounded by
    the siblings'; the torque against its siblings' tails {``within`` the limits, ``beyond`` them with no
    growth, ``m=...`` beyond them grown as the deviations' bands are}, empty where no motor is judged
    so); empty where identification refuses the world."""
    shipped = load_profile("flight_vehicle")
    everywhere = dataclasses.replace(
        shipped,
        conditions_reach=100.0,
        conditions_growth=0.0,
        conditions_siblings=0.0,
        torque_siblings_spread=0.0,
    )
    reach = shipped.conditions_reach
    out = []
    with tempfile.TemporaryDirectory(prefix=f"mmh-beyond{world}-") as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        folder = Path(tmp)
        log = write_identification_log(world, folder / "identification.tlog")
        try:
            identified = identify_logs([log])
        except MotorHealthError:
            return []
        path = folder / "vehicle.toml"
        path.write_text(dump_vehicle_params(identified.vehicle), encoding="utf-8")
        vehicle = load_vehicle_params(path)
        noise = band_noise_of(vehicle.noise)
        label = f"{world} (own air {draw_world(world).turbulence})"
        for flight in world_flights(world, duration_s=duration_s, healthy_flights=1, faults=()):
            record = fly_world(world, seed=flight.seed, duration_s=duration_s, turbulence=flight.turbulence)
            flight_log = folder / f"{flight.name}.tlog"
            write_record(record, flight_log)
            table = vehicle.calibrate(sources.read(flight_log))
            params = vehicle.models(range(1, max(motor_numbers(table["motor"])) + 1))
            d = diagnose(table, params, everywhere, noise)

            # the bands with the siblings' bound, over the bands without growth: the growth each sample got
            grown_by = {}
            for m in siblings:
                g = _diagnosed(table, params, noise, shipped, m[1], conditions_siblings=m[0])
                with np.errstate(divide="ignore", invalid="ignore"):
                    grown_by[m] = (
                        g["speed_band_rad_s"] / d["speed_band_rad_s"],
                        g["current_band_a"] / d["current_band_a"],
                    )
            # the torque's band grown by its siblings' spread (rules/bands.py, "The torque's own growth"),
            # over the band without growth: the growth each sample's torque band got
            torque_by = {}
            for m in torque_spreads:
                g = _diagnosed(table, params, noise, shipped, m[1], torque_siblings_spread=m[0])
                with np.errstate(divide="ignore", invalid="ignore"):
                    torque_by[m] = g["torque_band_nm"] / d["torque_band_nm"]
            z_speed, z_current, excess, total = [], [], [], 0
            by_sibling: dict[tuple[float, float | None], tuple[list, list]] = {m: ([], []) for m in siblings}
            # the torque against its siblings in its own σ(a, e) (rules/equations.py), where measured so
            z_torque: list[np.ndarray] = []
            torque_excess: list[np.ndarray] = []
            torque_grown: dict[tuple[float, float | None], list[np.ndarray]] = {m: [] for m in siblings}
            torque_spread: dict[tuple[float, float | None], list[np.ndarray]] = {
                m: [] for m in torque_spreads
            }
            for motor in np.unique(d["motor"]):
                rows = (d["motor"] == motor) & d["steady"] & (d["throttle"] >= shipped.min_command)
                n = noise[int(motor)]
                a = d["input_activity_v"][rows]
                e = d["pairing_error_rad_s"][rows] if "pairing_error_rad_s" in d.names else None
                speed, current = n.sigmas(a, e)
                z_speed.append((d["omega_judged_rad_s"][rows] - d["omega_model_rad_s"][rows]) / speed)
                z_current.append((d["current_judged_a"][rows] - d["current_model_a"][rows]) / current)
                excess.append(n.beyond_conditions(shipped.range_margin, a, e))
                total += int(np.count_nonzero(d["motor"] == motor))
                for m in siblings:
                    by_sibling[m][0].append(grown_by[m][0][rows])
                    by_sibling[m][1].append(grown_by[m][1][rows])
                if n.torque_vs_siblings is not None:
                    against = d["torque_residual_nm"][rows] - d["torque_siblings_nm"][rows]
                    sigma = n.torque_vs_siblings.sigmas(a, e)
                    z_torque.append((against - n.torque_vs_siblings.offset) / sigma)
                    torque_excess.append(excess[-1])
                    for m in siblings:  # the torque's band grows as the larger of the deviations' (bands.py)
                        torque_grown[m].append(np.maximum(grown_by[m][0][rows], grown_by[m][1][rows]))
                    for t in torque_spreads:
                        torque_spread[t].append(torque_by[t][rows])
            zs, zc, x = (np.concatenate(v) for v in (z_speed, z_current, excess))
            region = (x > 1.0) & (x <= reach)
            tails = {
                f"g={g:g}": (_tail(zs[region] / x[region] ** g), _tail(zc[region] / x[region] ** g))
                for g in EXPONENTS
            }
            for m in siblings:
                fs, fc = (np.concatenate(v) for v in by_sibling[m])
                tails[_label(m)] = (_tail(zs[region] / fs[region]), _tail(zc[region] / fc[region]))
            torque = {}
            if z_torque:
                zt, xt = np.concatenate(z_torque), np.concatenate(torque_excess)
                beyond = (xt > 1.0) & (xt <= reach)
                torque = {"within": _tail(zt[xt <= 1.0]), "beyond": _tail(zt[beyond])}
                for m in siblings:
                    torque[_label(m)] = _tail(zt[beyond] / np.concatenate(torque_grown[m])[beyond])
                for t in torque_spreads:
                    torque[_label(t, "T")] = _tail(zt[beyond] / np.concatenate(torque_spread[t])[beyond])
            out.append(
                (label, flight.turbulence, float(np.count_nonzero(region)) / max(total, 1), tails, torque)
            )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=1000, help="first world seed (default 1000: held out)")
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--duration-s", type=float, default=60.0, help="each healthy flight's length")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument(
        "--siblings",
        type=_bound,
        nargs="*",
        default=list(SIBLINGS),
        help="conditions_siblings multipliers to evaluate, each M or M/TAU (TAU: conditions_siblings_s in "
        "seconds; default: the shipped 4 at the shipped time constant)",
    )
    parser.add_argument(
        "--torque-spread",
        type=_bound,
        nargs="*",
        default=[],
        help="torque_siblings_spread multipliers to evaluate, each T or T/TAU (the torque's band grown by its "
        "siblings' spread, columns T=...; TAU: conditions_siblings_s, the deviations' too; default: none)",
    )
    args = parser.parse_args(argv)
    started = time.monotonic()
    worlds = list(range(args.first, args.first + args.count))
    siblings = tuple(args.siblings)
    growths = [f"g={g:g}" for g in EXPONENTS] + [_label(m) for m in siblings]
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        results = list(
            pool.map(
                one_world,
                worlds,
                [args.duration_s] * len(worlds),
                [siblings] * len(worlds),
                [tuple(args.torque_spread)] * len(worlds),
            )
        )
    refused = [w for w, r in zip(worlds, results) if not r]
    reach = load_profile("flight_vehicle").conditions_reach
    print(f"beyond the identification flight's limits, up to {reach:g} x them; tail of |z| (1: sigma right)")
    print("world                   level     share  " + "  ".join(f"{g:<5s} speed/current" for g in growths))
    rows = [row for r in results for row in r]
    for label, level, share, tails, _ in rows:
        cells = "  ".join(f"{s:5.2f} / {c:5.2f}      " for s, c in (tails[g] for g in growths))
        print(f"{label:23s} {level:9s} {100 * share:5.1f} %  {cells}")
    print()
    for g in growths:
        worst = [max((t for t in tails[g] if np.isfinite(t)), default=float("nan")) for *_, tails, _ in rows]
        worst = [w for w in worst if np.isfinite(w)]
        if not worst:
            continue
        print(
            f"growth {g}: over {len(worst)} flights with >= {MIN_SAMPLES} samples beyond, the larger tail "
            f"median {statistics.median(worst):.2f}, worst {max(worst):.2f}; above 1 on {sum(w > 1 for w in worst)}"
        )
    torque_columns = ["within", "beyond"] + [_label(m) for m in siblings]
    torque_columns += [_label(t, "T") for t in args.torque_spread]
    print(
        "\nthe torque against its siblings in its own sigma(a, e) (rules/equations.py), tail of |z|: within the"
        "\nlimits; beyond them (up to the reach) with no growth; beyond them grown as the deviations' bands (m=...)"
    )
    print("world                   level     " + "  ".join(f"{c:>7s}" for c in torque_columns))
    for label, level, _, _, torque in rows:
        if torque:
            print(f"{label:23s} {level:9s} " + "  ".join(f"{torque[c]:7.2f}" for c in torque_columns))
    for c in torque_columns:
        for air in ("calm", "moderate", "gusty", None):
            found = [t[c] for _, lv, _, _, t in rows if t and (air is None or lv == air)]
            found = [x for x in found if np.isfinite(x)]
            if found:
                print(
                    f"torque {c:7s} {air or 'all':9s}: over {len(found)} flights, tail median "
                    f"{statistics.median(found):.2f}, worst {max(found):.2f}; above 1 on {sum(x > 1 for x in found)}"
                )
    if refused:
        print(f"(refused by identification: {', '.join(map(str, refused))})")
    print(f"\n(benchmark took {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
