"""Leave-worlds-out evaluation (issue 17, item 3): the diagnosis scored on a randomised world it was never
tuned on, through the path a new user takes.

For one world seed (:func:`~mav_motor_health.sim.worlds.draw_world`), :func:`evaluate_world`

1. flies one healthy identification flight (the world's own 150-s manoeuvre plan and turbulence, noise
   seeded by the world's seed: :func:`write_identification_log`), writes it as a log (.tlog by default)
   with the simulator's writer and identifies the vehicle from it as ``fit LOG --out vehicle.toml`` does
   (:func:`~mav_motor_health.identification.identify_logs`, no prior; the vehicle file written and read
   back). Where identification refuses the world (a :class:`~mav_motor_health.errors.MotorHealthError`:
   a vehicle the project does not know), the evaluation says so (:attr:`WorldEvaluation.refused`) and
   flies nothing else: it is counted apart, never skipped in silence;
2. flies test flights of the same world with other noise seeds (:func:`world_flights`): at each
   turbulence level (calm, moderate, gusty: the world's own level replaced) one flight per fault (F1.1,
   F2.1, F3.1, F4.1, F4.2 at the paper's strength scaled to the world's motor, on a drawn motor at a drawn
   onset between 40 % and 70 % of the flight) and ``healthy_flights`` healthy ones; each is written in
   the same format and replayed as ``replay LOG --params vehicle.toml --profile flight`` does
   (:func:`~mav_motor_health.replay.replay_log` with the vehicle file), its ``diagnosis.csv`` read back and
   scored against the log's truth sidecar as ``score`` does (:func:`~.score.score`).

Per world it returns the accuracy after onset per turbulence level × fault (the faulty motor's judged
samples after onset diagnosed as the true fault), the detection delay (onset to the first announcement of
the true fault; None: never announced), the healthy motors' judged samples NORMAL (healthy motors of all
flights and the faulty motor before onset), the judged share of the healthy samples, and the false fault
events and flight hours of the healthy flights. :func:`summarise` takes many worlds to the median world
and the worst decile. Everything is seeded: the same seeds give the same numbers.

A world's turbulence is part of the world (:meth:`~mav_motor_health.sim.worlds.World.apply`); flying it
at another level, :func:`fly_world` sets the scenario's ``world_turbulence``, which the simulator applies
to the world it draws (``tests/test_flight_worlds.py`` checks that it flies the world's own level exactly
as :func:`~mav_motor_health.sim.engine.run_scenario` does).
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
import time
import warnings
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..config import dump_vehicle_params, load_profile, load_vehicle_params
from ..diagnosis.noise import band_noise_of
from ..diagnosis.pipeline import diagnose
from ..diagnosis.profile import ThresholdProfile
from ..diagnosis.states import MotorState
from ..errors import MotorHealthError
from ..identification import IdentifiedVehicle, identify_logs
from ..model.vehicle import VehicleParams
from ..replay import replay_log
from ..sim.engine import SimRecord, run_scenario
from ..sim.faults import FaultSpec
from ..sim.scenario import TURBULENCE, world_scenario
from ..sim.worlds import World, draw_world
from ..sim.writers import truth_path, write_record
from ..telemetry import sources
from ..telemetry.table import TelemetryTable
from .campaign import FAULTS, TURBULENCE_LEVELS
from .score import Score, read_diagnosis, read_truth, score

__all__ = [
    "FORMATS",
    "VEHICLE_SOURCES",
    "FlightResult",
    "WorldEvaluation",
    "WorldFlight",
    "WorldsSummary",
    "describe_world",
    "diagnose_flight",
    "evaluate_world",
    "fly_flight",
    "fly_world",
    "identify_world",
    "percentile",
    "summarise",
    "world_flights",
    "write_identification_log",
]

#: log formats a world's flights are written in (the simulator's writers)
FORMATS = ("tlog", "bin", "csv")
#: where the replay's vehicle comes from: identified from a healthy flight (``fit``), or the world's truth
VEHICLE_SOURCES = ("fit", "truth")
#: the fault's onset is drawn in this share of the flight
ONSET_SHARE = (0.4, 0.7)
#: the speed-only state that covers each fault where the current is not trusted (``SLOW``: F1.1 or F4.1...)
SPEED_ONLY_STATE = {
    "F1.1": MotorState.SLOW,
    "F4.1": MotorState.SLOW,
    "F2.1": MotorState.STALLED,
    "F4.2": MotorState.STALLED,
    "F3.1": MotorState.FAST,
}
#: test flights per world at most (their seeds are (world + 1) · 1000 + index: never the world's own)
MAX_FLIGHTS_PER_WORLD = 1000


@dataclass(frozen=True)
class WorldFlight:
    """One test flight of a world: its turbulence, noise seed, length and at most one fault."""

    world: int
    turbulence: str
    seed: int
    duration_s: float
    fault: str | None = None
    motor: int | None = None
    onset_s: float | None = None

    @property
    def name(self) -> str:
        what = "healthy" if self.fault is None else f"{self.fault}_m{self.motor}_at{self.onset_s:g}s"
        return f"world{self.world}_{self.turbulence}_{what}_seed{self.seed}"

    def faults(self) -> tuple[FaultSpec, ...]:
        if self.fault is None:
            return ()
        assert self.motor is not None and self.onset_s is not None
        return (FaultSpec(kind=self.fault, motor=self.motor, onset_s=self.onset_s),)


def world_flights(
    world: int,
    *,
    duration_s: float = 150.0,
    healthy_flights: int = 1,
    levels: Sequence[str] = TURBULENCE_LEVELS,
    faults: Sequence[str] = FAULTS,
) -> list[WorldFlight]:
    """The test flights of ``world``: per turbulence level one flight per fault, then ``healthy_flights``
    healthy ones. Motors, onsets and seeds come from the world's seed (the same world, the same flights);
    a fault's flight keeps its motor and onset when other levels or faults are asked for."""
    for level in levels:
        if level not in TURBULENCE:
            raise ValueError(f"turbulence {level!r}: expected one of {sorted(TURBULENCE)}")
    if healthy_flights < 0:
        raise ValueError(f"healthy_flights must be >= 0, got {healthy_flights}")
    per_level = len(FAULTS) + healthy_flights
    if len(TURBULENCE_LEVELS) * per_level > MAX_FLIGHTS_PER_WORLD:
        raise ValueError(f"at most {MAX_FLIGHTS_PER_WORLD} test flights per world")
    rng = np.random.default_rng([int(world), 0x17])
    # every draw is made for every level and fault, so a subset keeps the full set's motors and onsets
    drawn = {
        (level, fault): (
            int(rng.integers(1, 7)),
            round(float(rng.uniform(*ONSET_SHARE)) * duration_s, 2),
        )
        for level in TURBULENCE_LEVELS
        for fault in FAULTS
    }
    flights = []
    for i, level in enumerate(TURBULENCE_LEVELS):
        if level not in levels:
            continue
        base = (world + 1) * MAX_FLIGHTS_PER_WORLD + i * per_level
        for j, fault in enumerate(FAULTS):
            if fault in faults:
                motor, onset = drawn[level, fault]
                flights.append(WorldFlight(world, level, base + j, duration_s, fault, motor, onset))
        for k in range(healthy_flights):
            flights.append(WorldFlight(world, level, base + len(FAULTS) + k, duration_s))
    return flights


def fly_world(
    world: int,
    *,
    seed: int | None = None,
    duration_s: float = 150.0,
    turbulence: str | None = None,
    faults: Iterable[FaultSpec] = (),
    name: str | None = None,
    collect_esc: bool = True,
) -> SimRecord:
    """A flight of ``world``'s own manoeuvre plan (:func:`~mav_motor_health.sim.scenario.world_scenario`)
    with noise ``seed`` (default the world's), ``faults``, and at ``turbulence`` (default the world's
    own level). At the world's own level and seed this is ``run_scenario(world_scenario(world))``.
    ``collect_esc`` False: the vehicle's record only, without the ESC reports."""
    scenario = world_scenario(world, duration_s=duration_s)
    scenario = dataclasses.replace(
        scenario,
        name=name or scenario.name,
        seed=world if seed is None else int(seed),
        faults=tuple(faults),
        world_turbulence=turbulence,
    )
    return run_scenario(scenario, collect_esc=collect_esc)


def fly_flight(flight: WorldFlight, *, collect_esc: bool = True) -> SimRecord:
    """One test flight of :func:`world_flights` flown (its world, seed, length, air and fault);
    ``collect_esc`` as :func:`fly_world`."""
    return fly_world(
        flight.world,
        seed=flight.seed,
        duration_s=flight.duration_s,
        turbulence=flight.turbulence,
        faults=flight.faults(),
        name=flight.name,
        collect_esc=collect_esc,
    )


def diagnose_flight(
    flight: WorldFlight, folder: Path, vehicle: VehicleParams, profile: ThresholdProfile
) -> TelemetryTable:
    """One test flight flown, written to ``folder`` as a .tlog, read back and diagnosed with the vehicle
    file and the profile as replay does, with every column the core gives (:func:`~..diagnosis.pipeline.
    diagnose`; replay's ``diagnosis.csv`` keeps fewer); the log and its truth sidecar are removed. The
    simulator's and the reader's warnings are silenced."""
    log = folder / f"{flight.name}.tlog"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_record(fly_flight(flight), log)
        table = vehicle.calibrate(sources.read(log))
        result = diagnose(table, vehicle.models(range(1, 7)), profile, band_noise_of(vehicle.noise))
    for path in (log, truth_path(log)):
        path.unlink(missing_ok=True)
    return result


def write_identification_log(world: int, path: str | Path, duration_s: float = 150.0) -> Path:
    """The world's healthy identification flight (its own plan, turbulence and seed) written to ``path``
    (the format by its extension) with its truth sidecar; the simulator's warnings silenced."""
    path = Path(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_record(run_scenario(world_scenario(world, duration_s=duration_s)), path)
    return path


def identify_world(
    world: int, folder: Path, fmt: str = "tlog", identification_s: float = 150.0
) -> tuple[Path, IdentifiedVehicle, VehicleParams]:
    """``world`` identified from its healthy identification flight written into ``folder`` as
    ``fit LOG --out vehicle.toml`` does: the log, what identification found, and the vehicle read back
    from the file it wrote (as ``replay --params vehicle.toml`` reads it). A world identification refuses
    raises its :class:`~mav_motor_health.errors.MotorHealthError`."""
    log = write_identification_log(world, folder / f"identification.{fmt}", identification_s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        identified = identify_logs([log])
    vehicle_file = folder / "vehicle.toml"
    vehicle_file.write_text(dump_vehicle_params(identified.vehicle), encoding="utf-8")
    return log, identified, load_vehicle_params(vehicle_file)


@dataclass(frozen=True)
class FlightResult:
    """One test flight replayed and scored."""

    flight: WorldFlight
    score: Score
    #: the fault the log's truth sidecar says was injected (kind, motor, onset_s), None when healthy
    truth_fault: Mapping[str, Any] | None
    #: healthy samples (healthy motors, the faulty motor before onset), of them judged, of those NORMAL
    healthy_samples: int
    healthy_judged: int
    healthy_normal: int
    #: the faulty motor's judged samples after onset that are the true fault or the speed-only state
    #: covering it (``SLOW`` for F1.1...): noticed, if not named [%]; None when healthy or none judged
    noticed_pct: float | None = None
    warnings: tuple[str, ...] = ()

    @property
    def judged_share(self) -> float | None:
        return self.healthy_judged / self.healthy_samples if self.healthy_samples else None


@dataclass(frozen=True)
class WorldEvaluation:
    """One world: how identification went, and the test flights scored (none where it was refused)."""

    world: int
    description: str
    #: identification's reason for refusing the world ("" when identified)
    refused: str = ""
    #: an unexpected failure (a bug met on this world; "" when none): set by a caller that catches it
    error: str = ""
    #: what identification found against the world's truth (relative k_e error, idle offset error,
    #: current side true/found)
    identified: Mapping[str, Any] = field(default_factory=dict)
    flights: tuple[FlightResult, ...] = ()
    seconds: float = 0.0

    @property
    def evaluated(self) -> bool:
        return not self.refused and not self.error

    def _fault(self, turbulence: str, fault: str) -> FlightResult | None:
        found = [r for r in self.flights if r.flight.turbulence == turbulence and r.flight.fault == fault]
        return found[0] if found else None

    def accuracy(self, turbulence: str, fault: str) -> float | None:
        """Accuracy after onset [%] of the fault's flight at that level (None: no judged sample after
        onset, or no such flight)."""
        r = self._fault(turbulence, fault)
        return None if r is None else r.score.fault_accuracy_pct

    def noticed(self, turbulence: str, fault: str) -> float | None:
        """Share of the faulty motor's judged samples after onset that are the fault or its speed-only
        state [%] (:attr:`FlightResult.noticed_pct`)."""
        r = self._fault(turbulence, fault)
        return None if r is None else r.noticed_pct

    def detection(self, turbulence: str, fault: str) -> float | None:
        """Onset to the first announcement of the true fault [s]; inf: never announced; None: no flight."""
        r = self._fault(turbulence, fault)
        if r is None:
            return None
        return math.inf if r.score.detection_s is None else r.score.detection_s

    def _healthy(self, turbulence: str | None) -> list[FlightResult]:
        return [r for r in self.flights if turbulence is None or r.flight.turbulence == turbulence]

    def normal_share(self, turbulence: str | None = None) -> float | None:
        """Share of the healthy samples judged that are NORMAL [%], pooled over the level's flights."""
        rows = self._healthy(turbulence)
        judged = sum(r.healthy_judged for r in rows)
        return 100.0 * sum(r.healthy_normal for r in rows) / judged if judged else None

    def judged_share(self, turbulence: str | None = None) -> float | None:
        """Share of the healthy samples judged at all [%], pooled over the level's flights."""
        rows = self._healthy(turbulence)
        samples = sum(r.healthy_samples for r in rows)
        return 100.0 * sum(r.healthy_judged for r in rows) / samples if samples else None

    def healthy_flights(self, turbulence: str | None = None) -> list[FlightResult]:
        return [r for r in self._healthy(turbulence) if r.flight.fault is None]

    def false_events(self, turbulence: str | None = None) -> int:
        """Fault announcements in the healthy flights (any fault state, UNKNOWN, SLOW/STALLED/FAST)."""
        return sum(r.score.false_events for r in self.healthy_flights(turbulence))

    def false_events_by_state(self, turbulence: str | None = None) -> dict[str, int]:
        """:meth:`false_events` by the state announced (label: count)."""
        return _add_counts(r.score.false_events_by_state for r in self.healthy_flights(turbulence))

    def healthy_hours(self, turbulence: str | None = None) -> float:
        return sum(r.score.hours for r in self.healthy_flights(turbulence))

    def fault_flight_false_events(self) -> int:
        """Fault announcements on the healthy motors of the fault flights (and before onset)."""
        return sum(r.score.false_events for r in self.flights if r.flight.fault is not None)

    def fault_flight_false_events_by_state(self) -> dict[str, int]:
        """:meth:`fault_flight_false_events` by the state announced (label: count)."""
        return _add_counts(r.score.false_events_by_state for r in self.flights if r.flight.fault is not None)


def evaluate_world(
    world: int,
    *,
    duration_s: float = 150.0,
    healthy_flights: int = 1,
    profile: str | Path | ThresholdProfile = "flight",
    fmt: str = "tlog",
    identification_s: float = 150.0,
    levels: Sequence[str] = TURBULENCE_LEVELS,
    faults: Sequence[str] = FAULTS,
    vehicle_from: str = "fit",
) -> WorldEvaluation:
    """Identify ``world`` from one healthy flight, then replay and score its test flights (module
    docstring). ``levels`` and ``faults`` choose a subset of the test flights (the same motors, onsets
    and seeds as in the full set). ``vehicle_from="truth"`` replays with the world's true vehicle
    (:meth:`~mav_motor_health.sim.worlds.World.vehicle_params`) instead of the identified one, no
    identification flown: what the diagnosis does when identification is perfect."""
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: expected one of {FORMATS}")
    if vehicle_from not in VEHICLE_SOURCES:
        raise ValueError(f"vehicle_from {vehicle_from!r}: expected one of {VEHICLE_SOURCES}")
    started = time.monotonic()
    the_world = draw_world(world)
    chosen = profile if isinstance(profile, ThresholdProfile) else load_profile(profile)
    flights = world_flights(
        world, duration_s=duration_s, healthy_flights=healthy_flights, levels=levels, faults=faults
    )
    with tempfile.TemporaryDirectory(prefix=f"mmh-world{world}-") as tmp:
        folder = Path(tmp)
        if vehicle_from == "truth":
            truth = the_world.vehicle_params()
            results = tuple(_replay_flight(f, folder, fmt, truth, chosen) for f in flights)
            return WorldEvaluation(
                world,
                describe_world(the_world),
                identified={"vehicle": "truth"},
                flights=results,
                seconds=time.monotonic() - started,
            )
        try:
            _, identified, vehicle = identify_world(world, folder, fmt, identification_s)
        except MotorHealthError as exc:
            return WorldEvaluation(
                world, describe_world(the_world), refused=str(exc), seconds=time.monotonic() - started
            )
        results = tuple(_replay_flight(f, folder, fmt, vehicle, chosen) for f in flights)
    found = identified.found
    return WorldEvaluation(
        world,
        describe_world(the_world),
        identified={
            "k_e_error": found.params.k_e / the_world.motor.k_e - 1.0,
            "idle_offset_error": found.esc.idle_offset - the_world.esc.idle_offset,
            "current_side": f"{the_world.current.side}/{found.current.side}",
        },
        flights=results,
        seconds=time.monotonic() - started,
    )


def describe_world(world: World) -> str:
    """The world in one line: mass, KV, ESC rate, current side, own air."""
    return (
        f"{world.mass_kg:.1f} kg, KV {world.kv_rpm_per_v:.0f}, ESC {world.rate_hz:.0f} Hz, "
        f"current {world.current.side}, own air {world.turbulence}"
    )


def _replay_flight(
    flight: WorldFlight, folder: Path, fmt: str, vehicle: VehicleParams, profile: ThresholdProfile
) -> FlightResult:
    log = folder / f"{flight.name}.{fmt}"
    out = folder / f"{flight.name}.replay"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_record(fly_flight(flight), log)
        replayed = replay_log(log, out, vehicle, profile, reissue_warnings=False)
    diagnosis = read_diagnosis(out / "diagnosis.csv")
    truth = read_truth(truth_path(log))
    scored = score(diagnosis, truth)
    injected = truth.get("faults") or []
    healthy = _healthy_mask(diagnosis, truth)
    judged = healthy & diagnosis["steady"]
    noticed = None
    if flight.fault is not None:
        after = ~healthy & diagnosis["steady"]
        covering = (int(MotorState.from_label(flight.fault)), int(SPEED_ONLY_STATE[flight.fault]))
        noticed = (
            100.0 * float(np.mean(np.isin(diagnosis["state"][after], covering))) if after.any() else None
        )
    for path in (log, truth_path(log), *out.iterdir()):
        path.unlink()
    out.rmdir()
    return FlightResult(
        flight=flight,
        score=scored,
        truth_fault=(
            {k: injected[0][k] for k in ("fault", "motor", "onset_s") if k in injected[0]}
            if injected
            else None
        ),
        healthy_samples=int(healthy.sum()),
        healthy_judged=int(judged.sum()),
        healthy_normal=int(np.sum(judged & (diagnosis["state"] == MotorState.NORMAL))),
        noticed_pct=noticed,
        warnings=replayed.warnings,
    )


def _healthy_mask(diagnosis: Mapping[str, NDArray[Any]], truth: Mapping[str, Any]) -> NDArray[np.bool_]:
    """The samples :func:`~.score.score` counts as healthy: all but the faulty motor's from its onset."""
    healthy = np.ones(diagnosis["time_s"].size, dtype=bool)
    for f in truth.get("faults") or ():
        healthy &= ~((diagnosis["motor"] == int(f["motor"])) & (diagnosis["time_s"] >= float(f["onset_s"])))
    return healthy


# -- many worlds ----------------------------------------------------------------------------------------


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q``-th percentile (linear between ranks, as numpy's default) of values that may hold inf
    (a fault never announced); nan for no values."""
    finite = [v for v in values if not math.isnan(v)]
    if not finite:
        return math.nan
    ranked = sorted(finite)
    pos = (len(ranked) - 1) * q / 100.0
    lo, hi = math.floor(pos), math.ceil(pos)
    if math.isinf(ranked[lo]) or math.isinf(ranked[hi]):
        return ranked[hi] if pos - lo > 0 else ranked[lo]
    return ranked[lo] + (ranked[hi] - ranked[lo]) * (pos - lo)


@dataclass(frozen=True)
class WorldsSummary:
    """The median world and the worst decile over the evaluated worlds.

    ``accuracy[level, fault]``, ``noticed[level, fault]`` (the fault or its speed-only state) and
    ``normal[level]``, ``judged[level]``: (median, 10th percentile);
    ``detection[level, fault]``: (median, 90th percentile) [s], a fault never announced counted as inf;
    ``unjudged[level, fault]``: worlds whose fault flight had no judged sample after onset (counted as
    0 % in ``accuracy``: not judging is not being right); ``false_events``/``healthy_hours`` per level over
    all healthy flights of all worlds; ``refused`` and ``failed`` the worlds not evaluated."""

    worlds: int
    evaluated: int
    refused: tuple[int, ...]
    failed: tuple[int, ...]
    accuracy: Mapping[tuple[str, str], tuple[float, float]]
    noticed: Mapping[tuple[str, str], tuple[float, float]]
    unjudged: Mapping[tuple[str, str], int]
    detection: Mapping[tuple[str, str], tuple[float, float]]
    detection_all: tuple[float, float]
    normal: Mapping[str, tuple[float, float]]
    judged: Mapping[str, tuple[float, float]]
    false_events: Mapping[str, int]
    healthy_hours: Mapping[str, float]
    fault_flight_false_events: int
    #: the healthy flights' false events by the state announced (label: count), all levels
    false_events_by_state: Mapping[str, int] = field(default_factory=dict)
    #: the fault flights' false events (healthy motors, or before onset) by the state announced
    fault_flight_false_events_by_state: Mapping[str, int] = field(default_factory=dict)

    @property
    def false_events_per_hour(self) -> float:
        hours = sum(self.healthy_hours.values())
        return sum(self.false_events.values()) / hours if hours > 0 else math.nan


def _add_counts(counts: Iterable[Mapping[str, int]]) -> dict[str, int]:
    """Counts by label added up, the labels in order."""
    total: Counter[str] = Counter()
    for each in counts:
        total.update(each)
    return dict(sorted(total.items()))


def summarise(
    evaluations: Sequence[WorldEvaluation],
    levels: Sequence[str] = TURBULENCE_LEVELS,
    faults: Sequence[str] = FAULTS,
) -> WorldsSummary:
    done = [e for e in evaluations if e.evaluated]

    def spread(values: list[float], worst_q: float) -> tuple[float, float]:
        return percentile(values, 50.0), percentile(values, worst_q)

    accuracy, noticed, unjudged, detection = {}, {}, {}, {}
    for level in levels:
        for fault in faults:
            acc = [e.accuracy(level, fault) for e in done]
            unjudged[level, fault] = sum(a is None for a in acc)
            accuracy[level, fault] = spread([0.0 if a is None else a for a in acc], 10.0)
            seen = [e.noticed(level, fault) for e in done]
            noticed[level, fault] = spread([0.0 if a is None else a for a in seen], 10.0)
            det = [e.detection(level, fault) for e in done]
            detection[level, fault] = spread([d for d in det if d is not None], 90.0)
    every = [
        d
        for e in done
        for level in levels
        for fault in faults
        if (d := e.detection(level, fault)) is not None
    ]

    def shares(name: str, level: str) -> list[float]:
        out = [getattr(e, name)(level) for e in done]
        return [v for v in out if v is not None]

    return WorldsSummary(
        worlds=len(evaluations),
        evaluated=len(done),
        refused=tuple(e.world for e in evaluations if e.refused),
        failed=tuple(e.world for e in evaluations if e.error),
        accuracy=accuracy,
        noticed=noticed,
        unjudged=unjudged,
        detection=detection,
        detection_all=spread(every, 90.0),
        normal={level: spread(shares("normal_share", level), 10.0) for level in levels},
        judged={level: spread(shares("judged_share", level), 10.0) for level in levels},
        false_events={level: sum(e.false_events(level) for e in done) for level in levels},
        healthy_hours={level: sum(e.healthy_hours(level) for e in done) for level in levels},
        fault_flight_false_events=sum(e.fault_flight_false_events() for e in done),
        false_events_by_state=_add_counts(e.false_events_by_state() for e in done),
        fault_flight_false_events_by_state=_add_counts(e.fault_flight_false_events_by_state() for e in done),
    )
