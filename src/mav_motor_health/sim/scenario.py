"""Scenarios: what to simulate, as TOML files in ``params/scenarios/`` (validated on load).

::

    [scenario]
    name = "testbed F1.1 at 4.2 V"
    mode = "testbed"          # "testbed": one motor on a stand at constant voltage; "flight": hexacopter
    duration_s = 20.0
    seed = 1
    dt_s = 0.001              # physics step [s]
    motor = "paper_x2212"     # params/motors name or TOML path
    world = 7                 # optional: fly a randomised world (sim/worlds.py) instead of motor/[flight]

    [testbed]                 # mode = "testbed"
    voltage_v = 4.2           # voltage applied to the motor (duty × supply)
    supply_v = 12.0           # lab supply (stiff)

    [flight]                  # mode = "flight"
    turbulence = "moderate"   # calm | moderate | gusty
    start_alt_m = 10.0
    mass_kg = 2.0
    battery_cells = 3
    battery_capacity_mah = 5000.0
    battery_resistance_ohm = 0.02
    [[flight.segment]]        # hover | climb | descend | translate | yaw, in order; then hover to the end
    kind = "climb"
    duration_s = 5.0
    speed_m_s = 1.0
    heading_deg = 0.0         # translate: direction of travel; yaw: the heading to turn to

    [[fault]]                 # any number
    kind = "F4.1"
    motor = 1
    onset_s = 30.0
    severity = 1.0            # optional (paper's strength when left out)
    stall_current_a = 2.26    # optional, F2.1/F4.2

    [sensors]
    rate_hz = [10.0, 50.0]    # each ESC draws its rate from this range
    dropout = 0.01
    burst_per_hour = 2.0
    speed_noise_rad_s = 10.0
    current_noise_a = [0.15, 1.0]

    [output]
    esc_stream_hz = 10.0      # ESC_TELEMETRY message rate in .tlog files
    log_hz = 10.0             # vehicle records (RCOU, BAT, positions) per second

With ``world`` set, the world supplies the vehicle, its motors, ESCs, battery, turbulence and telemetry
(``[flight]`` keeps only ``start_alt_m`` and the segments, ``[sensors]`` only the dropouts, clock error and
jitter); a world scenario without segments flies the world's own manoeuvre plan. The scenario name
``world`` (or ``flight/world``) is that flight, built in: 150 s of the world's plan.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import PARAMS_DIR, _Section, read_toml
from ..errors import ConfigError
from .faults import FaultSpec
from .sensors import SensorSpec

__all__ = [
    "TURBULENCE",
    "WORLD_SCENARIO_NAMES",
    "FlightSpec",
    "Scenario",
    "Segment",
    "load_scenario",
    "scenario_from_dict",
    "world_scenario",
]

#: turbulence presets: wind standard deviation [m/s], torque disturbance standard deviation [N·m],
#: gyro noise the rate controller sees [rad/s] (vibration grows with rough air and hard manoeuvring)
TURBULENCE: dict[str, tuple[float, float, float]] = {
    "calm": (0.3, 0.004, 0.015),
    "moderate": (1.5, 0.03, 0.12),
    "gusty": (3.5, 0.08, 0.35),
}
SEGMENT_KINDS = ("hover", "climb", "descend", "translate", "yaw")
#: names of the built-in scenario that flies a randomised world's own plan (:func:`world_scenario`)
WORLD_SCENARIO_NAMES = ("world", "flight/world")


@dataclass(frozen=True)
class Segment:
    kind: str
    duration_s: float
    speed_m_s: float = 0.0
    heading_deg: float = 0.0


@dataclass(frozen=True)
class FlightSpec:
    turbulence: str = "calm"
    start_alt_m: float = 10.0
    mass_kg: float = 2.0
    battery_cells: int = 3
    battery_capacity_mah: float = 5000.0
    battery_resistance_ohm: float = 0.02
    segments: tuple[Segment, ...] = ()

    @property
    def turbulence_levels(self) -> tuple[float, float, float]:
        return TURBULENCE[self.turbulence]


@dataclass(frozen=True)
class Scenario:
    name: str
    mode: str = "testbed"
    duration_s: float = 20.0
    seed: int = 1
    dt_s: float = 0.001
    motor: str = "paper_x2212"
    voltage_v: float = 7.6
    supply_v: float = 12.0
    flight: FlightSpec = field(default_factory=FlightSpec)
    faults: tuple[FaultSpec, ...] = ()
    sensors: SensorSpec = field(default_factory=SensorSpec)
    esc_stream_hz: float = 10.0
    log_hz: float = 10.0
    source: str = ""
    #: seed of a randomised world (:func:`.worlds.draw_world`); None: ``motor`` and ``flight`` as given
    world: int | None = None
    #: fly the world at this turbulence level instead of its own (None: the world's)
    world_turbulence: str | None = None

    def __post_init__(self) -> None:
        if self.world_turbulence is not None and self.world_turbulence not in TURBULENCE:
            raise ConfigError(
                f"{self.world_turbulence!r}",
                key="scenario.world_turbulence",
                expected=f"one of {sorted(TURBULENCE)}",
            )

    @property
    def n_motors(self) -> int:
        return 1 if self.mode == "testbed" else 6

    def truth(self) -> dict[str, Any]:
        """The ground truth a scorer needs (written as the sidecar JSON)."""
        return {
            "scenario": self.name,
            "mode": self.mode,
            "seed": self.seed,
            "duration_s": self.duration_s,
            "voltage_v": self.voltage_v if self.mode == "testbed" else None,
            "turbulence": self.flight.turbulence if self.mode == "flight" else None,
            "motors": self.n_motors,
            "faults": [f.to_dict() for f in self.faults],
        } | ({} if self.world is None else {"world": self.world})


def world_scenario(world: int | None = None, *, duration_s: float = 150.0) -> Scenario:
    """The built-in flight of a randomised world: its own manoeuvre plan (no segments here), the noise
    seeded by the world's seed, the ESC reports losing a sample now and then."""
    return Scenario(
        name="world" if world is None else f"world {world}",
        mode="flight",
        duration_s=duration_s,
        seed=world if world is not None else 1,
        dt_s=0.01,
        sensors=SensorSpec(rate_hz=(10.0, 50.0), dropout=0.01, burst_per_hour=2.0),
        world=world,
        source="built-in",
    )


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A scenario from a TOML file, or by name from ``params/scenarios/`` (``testbed/F1.1_4.2V``); the
    names in :data:`WORLD_SCENARIO_NAMES` give :func:`world_scenario` (its world still to be chosen)."""
    path = Path(name_or_path)
    if not path.exists() and str(name_or_path) in WORLD_SCENARIO_NAMES:
        return world_scenario()
    if not path.exists() and path.suffix != ".toml":
        bundled = PARAMS_DIR / "scenarios" / f"{name_or_path}.toml"
        if bundled.exists():
            path = bundled
    if not path.exists():
        known = sorted(
            str(p.relative_to(PARAMS_DIR / "scenarios"))[:-5]
            for p in (PARAMS_DIR / "scenarios").rglob("*.toml")
        )
        raise ConfigError(
            "no such scenario file", path=path, expected=f"a TOML path or one of {known[:12]}..."
        )
    return scenario_from_dict(read_toml(path), path)


def scenario_from_dict(data: dict[str, Any], path: Path | str = "<scenario>") -> Scenario:
    path = Path(path)
    top = _Section(data, path, "")
    sc = top.table("scenario")
    mode = sc.text("mode", "testbed")
    if mode not in ("testbed", "flight"):
        raise ConfigError(f"{mode!r}", path=path, key="scenario.mode", expected="'testbed' or 'flight'")
    name = sc.text("name", path.stem)
    duration = sc.number("duration_s", 20.0, minimum=0.01, maximum=86400.0, unit="s")
    seed = int(sc.number("seed", 1.0, minimum=0.0))
    dt = sc.number("dt_s", 0.001 if mode == "testbed" else 0.005, minimum=1e-5, maximum=0.02, unit="s")
    motor = sc.text("motor", "paper_x2212")
    world_raw = sc.raw("world")
    sc.done()
    world: int | None = None
    if world_raw is not None:
        if isinstance(world_raw, bool) or not isinstance(world_raw, int) or world_raw < 0:
            raise ConfigError(
                f"{world_raw!r}", path=path, key="scenario.world", expected="a seed, an integer >= 0"
            )
        if mode != "flight":
            raise ConfigError(
                "a world is a flying vehicle", path=path, key="scenario.world", expected="mode = 'flight'"
            )
        world = int(world_raw)

    tb = top.table("testbed")
    voltage = tb.number("voltage_v", 7.6, minimum=0.0, maximum=60.0, unit="V")
    supply = tb.number("supply_v", 12.0, minimum=1.0, maximum=60.0, unit="V")
    tb.done()
    if voltage > supply:
        raise ConfigError(
            f"{voltage} V > supply {supply} V", path=path, key="testbed.voltage_v", expected="<= supply_v"
        )

    fl = top.table("flight")
    turbulence = fl.text("turbulence", "calm")
    if turbulence not in TURBULENCE:
        raise ConfigError(
            f"{turbulence!r}", path=path, key="flight.turbulence", expected=f"one of {sorted(TURBULENCE)}"
        )
    segments = []
    raw_segments = fl.raw("segment") or []
    if not isinstance(raw_segments, list):
        raise ConfigError("not a list", path=path, key="flight.segment", expected="[[flight.segment]] tables")
    for k, raw in enumerate(raw_segments):
        s = _Section(raw, path, f"flight.segment[{k}]")
        kind = s.text("kind", "hover")
        if kind not in SEGMENT_KINDS:
            raise ConfigError(
                f"{kind!r}", path=path, key=f"flight.segment[{k}].kind", expected=f"one of {SEGMENT_KINDS}"
            )
        segments.append(
            Segment(
                kind=kind,
                duration_s=s.number("duration_s", minimum=0.0, unit="s"),
                speed_m_s=s.number("speed_m_s", 0.0, minimum=0.0, maximum=15.0, unit="m/s"),
                heading_deg=s.number("heading_deg", 0.0, minimum=-360.0, maximum=360.0, unit="deg"),
            )
        )
        s.done()
    flight = FlightSpec(
        turbulence=turbulence,
        start_alt_m=fl.number("start_alt_m", 10.0, minimum=1.0, maximum=500.0, unit="m"),
        mass_kg=fl.number("mass_kg", 2.0, minimum=0.5, maximum=4.0, unit="kg"),
        battery_cells=int(fl.number("battery_cells", 3.0, minimum=2.0, maximum=4.0)),
        battery_capacity_mah=fl.number("battery_capacity_mah", 5000.0, minimum=100.0, unit="mAh"),
        battery_resistance_ohm=fl.number(
            "battery_resistance_ohm", 0.02, minimum=0.0, maximum=1.0, unit="ohm"
        ),
        segments=tuple(segments),
    )
    fl.done()

    faults = []
    raw_faults = top.raw("fault") or []
    if not isinstance(raw_faults, list):
        raise ConfigError("not a list", path=path, key="fault", expected="[[fault]] tables")
    n_motors = 1 if mode == "testbed" else 6
    for k, raw in enumerate(raw_faults):
        s = _Section(raw, path, f"fault[{k}]")
        kind = s.text("kind", "")
        motor_no = int(s.number("motor", 1.0, minimum=1.0, maximum=float(n_motors)))
        onset = s.number("onset_s", minimum=0.0, unit="s")
        severity = s.raw("severity")
        stall = s.raw("stall_current_a")
        end = s.number("end_s", minimum=0.0, unit="s") if "end_s" in s.data else float("inf")
        s.done()
        for key, value in (("severity", severity), ("stall_current_a", stall)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
                raise ConfigError(f"{value!r}", path=path, key=f"fault[{k}].{key}", expected="a number")
        try:
            faults.append(
                FaultSpec(
                    kind=kind,
                    motor=motor_no,
                    onset_s=onset,
                    severity=None if severity is None else float(severity),
                    stall_current_a=None if stall is None else float(stall),
                    end_s=end,
                )
            )
        except ConfigError as exc:
            raise ConfigError(
                exc.reason,
                path=path,
                key=f"fault[{k}]." + (exc.key or "").split(".")[-1],
                expected=exc.expected,
            ) from None

    se = top.table("sensors")
    rate = se.raw("rate_hz")
    if rate is None:
        rate_pair = (40.0, 40.0) if mode == "testbed" else (10.0, 50.0)
    elif isinstance(rate, (int, float)) and not isinstance(rate, bool):
        rate_pair = (float(rate), float(rate))
    elif (
        isinstance(rate, list)
        and len(rate) == 2
        and all(isinstance(x, (int, float)) for x in rate)
        and 0 < rate[0] <= rate[1] <= 1000
    ):
        rate_pair = (float(rate[0]), float(rate[1]))
    else:
        raise ConfigError(
            f"{rate!r}",
            path=path,
            key="sensors.rate_hz",
            expected="a rate in Hz or [low, high] with 0 < low <= high",
        )
    cur = se.raw("current_noise_a")
    if cur is None:
        cur_pair = (0.15, 1.0)
    elif isinstance(cur, list) and len(cur) == 2 and all(isinstance(x, (int, float)) and x >= 0 for x in cur):
        cur_pair = (float(cur[0]), float(cur[1]))
    else:
        raise ConfigError(
            f"{cur!r}", path=path, key="sensors.current_noise_a", expected="[half-width at 4 V, at 11 V] in A"
        )
    sensors = SensorSpec(
        rate_hz=rate_pair,
        clock_error=se.number("clock_error", 0.02, minimum=0.0, maximum=0.2),
        jitter=se.number("jitter", 0.05, minimum=0.0, maximum=0.5),
        speed_noise_rad_s=se.number("speed_noise_rad_s", 10.0, minimum=0.0, unit="rad/s"),
        current_noise_low_a=cur_pair[0],
        current_noise_high_a=cur_pair[1],
        dropout=se.number("dropout", 0.0, minimum=0.0, maximum=0.9),
        burst_per_hour=se.number("burst_per_hour", 0.0, minimum=0.0),
        burst_s=se.number("burst_s", 1.0, minimum=0.0, unit="s"),
        current_filter_s=se.number("current_filter_s", 0.02, minimum=0.0, maximum=1.0, unit="s"),
    )
    se.done()
    out = top.table("output")
    esc_stream = out.number(
        "esc_stream_hz", 40.0 if mode == "testbed" else 10.0, minimum=0.1, maximum=400.0, unit="Hz"
    )
    log_hz = out.number("log_hz", 10.0, minimum=0.1, maximum=400.0, unit="Hz")
    out.done()
    top.done()
    return Scenario(
        name=name,
        mode=mode,
        duration_s=duration,
        seed=seed,
        dt_s=dt,
        motor=motor,
        voltage_v=voltage,
        supply_v=supply,
        flight=flight,
        faults=tuple(faults),
        sensors=sensors,
        esc_stream_hz=esc_stream,
        log_hz=log_hz,
        source=str(path),
        world=world,
    )
