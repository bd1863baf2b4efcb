"""The severity floor on randomised worlds (issue 17, item 3 and its last goal): how weak a fault each
method still names, on a vehicle it knows only from one healthy flight.

For one world (:func:`~mav_motor_health.sim.worlds.draw_world`), :func:`severity_world`

1. identifies the vehicle from its healthy identification flight as ``fit LOG --out vehicle.toml`` does
   (:func:`~.worlds.identify_world`), and fits the PX4-style baseline (:mod:`.px4_baseline`: a straight
   line of ESC current against throttle, bands as narrow as that flight allows without a flag) on the same
   flight, as a PX4 user runs ``mfd_fit`` on a healthy flight of their own: both methods learn the vehicle
   from the same log;
2. flies calm test flights of the world with F1.1, F3.1 and F4.1 at each severity of a ladder (the
   simulator's ``severity``: 1 is the paper's strength scaled to the world's motor, F3.1's the share of
   blade cut off), one drawn motor per fault, onset at a fixed time; each written as a .tlog, replayed
   with the vehicle file (:func:`~mav_motor_health.replay.replay_log`) and read back by the baseline;
3. counts a flight as named by a method when it names the fault within :data:`WITHIN_S` of onset and
   raises no false event: ours, the true fault announced (:func:`~.score.score`'s detection) and no fault
   event on a healthy motor or before onset; the baseline, any under- or over-current flag on the faulty
   motor (it cannot tell faults apart, so any flag counts as its class) and none elsewhere.

A method's floor for a fault is the smallest severity from which every flight of the ladder up to the
paper's strength (1) is named. Where a method names no fault of the ladder at 1 (the baseline, whose
bands must hold a healthy flight's climbs and turns, on most worlds), a quarter of its floor would be no
number, so F1.1 and F4.1, whose faults have stronger forms, are also flown beyond it (:data:`BEYOND`:
1.5 to 5 times the paper's rubbing bar, a drive of 1/4 to 1/11), and the floor is then the weakest of
those rungs it names (``inf``: none). A rung beyond 1 stands on its own, not for every stronger one:
friction five times the paper's may stall a motor, which is then named a stall, not friction. F3.1 has
no stronger form (1 is the whole blade cut off). Where the ESCs report no usable current the baseline
cannot be fitted and its floors are ``inf`` (:attr:`WorldSeverity.baseline`: why). Seeded: the same
world gives the same flights, and the rungs beyond 1 their own seeds after the ladder's.
"""

from __future__ import annotations

import math
import tempfile
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..config import load_profile
from ..diagnosis.profile import ThresholdProfile
from ..errors import MotorHealthError
from ..replay import replay_log
from ..sim.faults import FaultSpec
from ..sim.worlds import draw_world
from ..sim.writers import truth_path, write_record
from ..telemetry import sources
from ..telemetry.table import TelemetryTable
from .px4_baseline import Px4Baseline, fit_baseline, motor_series, table_flags
from .score import read_diagnosis, read_truth, score
from .worlds import MAX_FLIGHTS_PER_WORLD, describe_world, fly_world, identify_world

__all__ = [
    "BEYOND",
    "BEYOND_FAULTS",
    "SEVERITIES",
    "SEVERITY_FAULTS",
    "WITHIN_S",
    "SeverityTrial",
    "WorldSeverity",
    "baseline_events",
    "severity_world",
]

#: the severity ladder (bench_flight.py's)
SEVERITIES = (0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)
#: the faults with a partial form (F2.1 and F4.2 are stalls: all or nothing)
SEVERITY_FAULTS = ("F1.1", "F3.1", "F4.1")
#: the rungs beyond the paper's strength (module doc), for the faults that have a stronger form
BEYOND = (1.5, 2.0, 3.0, 5.0)
BEYOND_FAULTS = ("F1.1", "F4.1")
#: a fault counts as named when named within this long after onset [s] (issue 17)
WITHIN_S = 3.0
#: the ladder's flights take the world's seeds from this index on (world_flights' flights come first)
_SEED_INDEX = 900


@dataclass(frozen=True)
class SeverityTrial:
    """One flight of the ladder: the fault, its severity, and what each method made of it (detection
    after onset [s], None: not named; false events)."""

    fault: str
    severity: float
    motor: int
    ours_s: float | None
    ours_false: int
    baseline_s: float | None
    baseline_false: int

    def named(self, method: str) -> bool:
        """Named within :data:`WITHIN_S` with no false event, by ``"ours"`` or ``"baseline"``."""
        detection, false = (
            (self.ours_s, self.ours_false) if method == "ours" else (self.baseline_s, self.baseline_false)
        )
        return detection is not None and detection <= WITHIN_S and false == 0


@dataclass(frozen=True)
class WorldSeverity:
    """One world's ladder: ``refused`` where identification refused the world (nothing flown),
    ``baseline`` why the baseline could not be fitted (None: it was)."""

    world: int
    description: str
    trials: tuple[SeverityTrial, ...] = ()
    refused: str | None = None
    baseline: str | None = None
    seconds: float = 0.0

    def floor(self, fault: str, method: str) -> float:
        """The smallest severity from which every stronger flight of ``fault`` up to the paper's strength
        (1) is named by ``method`` (``"ours"`` or ``"baseline"``); where the flight at 1 is not, the
        weakest rung beyond 1 that is (module doc); ``inf`` where none is."""
        trials = [t for t in self.trials if t.fault == fault]
        ladder = sorted((t for t in trials if t.severity <= 1.0), key=lambda t: t.severity)
        floor = math.inf
        for trial in reversed(ladder):
            if not trial.named(method):
                break
            floor = trial.severity
        if math.isinf(floor):
            named = [t.severity for t in trials if t.severity > 1.0 and t.named(method)]
            floor = min(named, default=math.inf)
        return floor


def baseline_events(
    detector: Px4Baseline, table: TelemetryTable, motor: int, onset_s: float
) -> tuple[float | None, int]:
    """The baseline on one flight's table: the time from ``onset_s`` to its first flag on ``motor`` (None:
    none), and its false events (flags rising on the other motors, or on ``motor`` before onset)."""
    flags = table_flags(detector, table) != 0
    motors, t = np.asarray(table["motor"]), np.asarray(table["time_s"], dtype=float)
    false = 0
    for m in table.motors():
        rows = motors == m
        on = flags[rows] & ((t[rows] < onset_s) if int(m) == motor else True)
        false += int(np.count_nonzero(on[1:] & ~on[:-1])) + int(on[:1].sum())
    hit = np.flatnonzero(flags & (motors == motor) & (t >= onset_s))
    return (float(t[hit[0]] - onset_s) if hit.size else None), false


def severity_world(
    world: int,
    *,
    severities: Sequence[float] = SEVERITIES,
    faults: Sequence[str] = SEVERITY_FAULTS,
    beyond: Sequence[float] = BEYOND,
    duration_s: float = 30.0,
    onset_s: float = 15.0,
    profile: str | Path | ThresholdProfile = "flight_vehicle",
    identification_s: float = 150.0,
) -> WorldSeverity:
    """Identify ``world`` and fit the baseline on its healthy flight, then fly the severity ladder and,
    for :data:`BEYOND_FAULTS`, the rungs ``beyond`` it (module docstring; ``()``: none)."""
    if not 0 < onset_s < duration_s:
        raise ValueError(f"onset_s must lie inside the flight (0 < {onset_s} < {duration_s})")
    unknown = [f for f in faults if f not in SEVERITY_FAULTS]
    if unknown:
        raise ValueError(f"faults {unknown}: expected some of {SEVERITY_FAULTS}")
    if any(not 0 < s <= 1 for s in severities) or any(not s > 1 for s in beyond):
        raise ValueError(
            f"severities {list(severities)} must lie in (0, 1] and beyond {list(beyond)} above 1 "
            "(1: the paper's strength)"
        )
    # the rungs beyond 1 take their seeds after the ladder's (the default ladder's at least: its flights keep
    # the seeds they had before there were rungs beyond 1)
    beyond_index = _SEED_INDEX + len(SEVERITY_FAULTS) * max(len(severities), len(SEVERITIES))
    if beyond_index + len(BEYOND_FAULTS) * len(beyond) > MAX_FLIGHTS_PER_WORLD:
        raise ValueError(f"at most {MAX_FLIGHTS_PER_WORLD - _SEED_INDEX} ladder flights per world")
    started = time.monotonic()
    the_world = draw_world(world)
    chosen = profile if isinstance(profile, ThresholdProfile) else load_profile(profile)
    rng = np.random.default_rng([int(world), 0x5E7])
    motors = {fault: int(rng.integers(1, 7)) for fault in SEVERITY_FAULTS}
    with tempfile.TemporaryDirectory(prefix=f"mmh-severity{world}-") as tmp:
        folder = Path(tmp)
        try:
            log, _, vehicle = identify_world(world, folder, "tlog", identification_s)
        except MotorHealthError as exc:
            return WorldSeverity(
                world, describe_world(the_world), refused=str(exc), seconds=time.monotonic() - started
            )
        detector, why = None, None
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                detector = fit_baseline(motor_series([sources.read(log)]))
        except ValueError as exc:
            why = f"no current line: {exc}"
        trials = []
        for fault in faults:
            # the full ladder's seed, whatever subset is asked for (as world_flights keeps its flights)
            j = SEVERITY_FAULTS.index(fault)
            rungs = [(_SEED_INDEX + j * len(severities) + k, s) for k, s in enumerate(severities)]
            if fault in BEYOND_FAULTS:
                b = BEYOND_FAULTS.index(fault)
                rungs += [(beyond_index + b * len(beyond) + k, s) for k, s in enumerate(beyond)]
            for index, severity in rungs:
                seed = (world + 1) * MAX_FLIGHTS_PER_WORLD + index
                spec = FaultSpec(kind=fault, motor=motors[fault], onset_s=onset_s, severity=float(severity))
                name = f"world{world}_calm_{fault}_s{severity:g}_seed{seed}"
                path, out = folder / f"{name}.tlog", folder / f"{name}.replay"
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    record = fly_world(
                        world, seed=seed, duration_s=duration_s, turbulence="calm", faults=(spec,), name=name
                    )
                    write_record(record, path)
                    replay_log(path, out, vehicle, chosen, reissue_warnings=False)
                    table = sources.read(path)
                ours = score(read_diagnosis(out / "diagnosis.csv"), read_truth(truth_path(path)))
                base_s, base_false = (
                    (None, 0) if detector is None else baseline_events(detector, table, spec.motor, onset_s)
                )
                trials.append(
                    SeverityTrial(
                        fault,
                        float(severity),
                        spec.motor,
                        ours.detection_s,
                        ours.false_events,
                        base_s,
                        base_false,
                    )
                )
                for p in (path, truth_path(path), *out.iterdir()):
                    p.unlink()
                out.rmdir()
    return WorldSeverity(
        world,
        describe_world(the_world),
        tuple(trials),
        baseline=why,
        seconds=time.monotonic() - started,
    )
