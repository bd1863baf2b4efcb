"""The agent's one TOML file (``params/agent.example.toml``), validated at start into frozen settings.

Every section and key is checked with :class:`mav_motor_health.config._Section`: a wrong type, a value
out of range or an unknown key stops the agent with one :class:`~mav_motor_health.errors.ConfigError`
naming the file, the key and what was expected. Command-line options override the file.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..config import (
    DEFAULT_MOTOR,
    _Section,
    check_profile_for_vehicle,
    default_profile,
    load_motor_params,
    load_profile,
    load_vehicle_params,
    read_toml,
)
from ..diagnosis.noise import BandNoise, band_noise_of
from ..diagnosis.profile import ThresholdProfile
from ..errors import ConfigError, LinkError
from ..model.identify import CurrentReading, EscMap
from ..model.params import MotorParams
from ..publish.mqtt import MqttSettings, parse_mqtt_url
from .link import parse_url

__all__ = ["AgentConfig", "PublishSettings", "load_agent_config"]

_VEHICLE_ID = re.compile(r"^[A-Za-z0-9_-]+$")


@dataclass(frozen=True)
class PublishSettings:
    """MAVLink publishing: STATUSTEXT rate limit and the steady rates of the per-motor messages."""

    statustext: bool = True
    statustext_burst: int = 3
    statustext_interval_s: float = 5.0
    named_value_hz: float = 1.0
    motor_health_hz: float = 1.0
    telemetry_hz: float = 5.0  # MQTT telemetry per motor


@dataclass(frozen=True)
class AgentConfig:
    """Everything the agent needs; ``source`` is the file it came from (or None)."""

    connect: str
    vehicle_id: str = "vehicle1"
    frame: str = "hexa-x"
    motors: int = 6
    params: MotorParams | dict[int, MotorParams] = field(default_factory=lambda: load_motor_params())
    params_name: str = DEFAULT_MOTOR
    #: the vehicle's ESC map and current reading, where the params file was written by identification
    esc: EscMap | None = None
    current: CurrentReading | None = None
    #: each motor's noise from identification (a profile with noise_bands sets its bands from it)
    noise: Mapping[int, BandNoise] = field(default_factory=dict)
    profile: ThresholdProfile = field(default_factory=lambda: load_profile("flight"))
    system_id: int = 0  # 0: take the autopilot's once it is found
    component_id: int = 191  # MAV_COMP_ID_ONBOARD_COMPUTER
    # ESC_TELEMETRY and SERVO_OUTPUT_RAW: each packet beside a command at most 5 ms newer (docs/agent.md)
    esc_rate_hz: float = 200.0
    heartbeat_timeout_s: float = 3.0
    stale_s: float = 1.0
    batch_s: float = 0.1  # samples wait at most this long to be diagnosed together (0: one by one)
    publish: PublishSettings = field(default_factory=PublishSettings)
    mqtt: MqttSettings | None = None
    source: Path | None = None

    def with_overrides(self, **kw: Any) -> AgentConfig:
        return replace(self, **{k: v for k, v in kw.items() if v is not None})


def load_agent_config(
    path: str | Path | None = None,
    *,
    connect: str | None = None,
    mqtt_url: str | None = None,
    params: str | None = None,
    profile: str | None = None,
    vehicle_id: str | None = None,
) -> AgentConfig:
    """Read and check the agent's TOML (``path`` may be None: defaults), then apply the overrides."""
    data: dict[str, Any] = {} if path is None else read_toml(path)
    where = Path(path) if path is not None else Path("<command line>")
    base = where.parent if path is not None else Path.cwd()
    top = _Section(data, where, "")
    agent = top.table("agent")
    link = top.table("link")
    model = top.table("model")
    pub = top.table("publish")
    mq = top.table("mqtt")
    top.done()

    file_vid = agent.text("vehicle_id", "vehicle1")
    vid = vehicle_id or file_vid
    if not _VEHICLE_ID.match(vid):
        raise ConfigError(f"{vid!r}", path=where, key="agent.vehicle_id", expected="letters, digits, _ or -")
    motors = int(agent.number("motors", 6, minimum=1, maximum=12))
    frame = agent.text("frame", "hexa-x")
    stale_s = agent.number("stale_s", 1.0, minimum=0.05, maximum=60, unit="s")
    batch_s = agent.number("batch_s", 0.1, minimum=0.0, maximum=1.0, unit="s")
    agent.done()

    file_url = link.text("connect", "")
    url = connect or file_url
    if not url:
        raise ConfigError(
            "missing", path=where, key="link.connect", expected="a MAVLink URL such as /dev/serial0:921600"
        )
    try:
        parse_url(url)
    except LinkError as exc:
        raise ConfigError(str(exc), path=where, key="link.connect") from None
    system_id = int(link.number("system_id", 0, minimum=0, maximum=255))
    component_id = int(link.number("component_id", 191, minimum=1, maximum=255))
    esc_rate_hz = link.number("esc_rate_hz", 200.0, minimum=1.0, maximum=400.0, unit="Hz")
    hb_timeout = link.number("heartbeat_timeout_s", 3.0, minimum=0.5, maximum=60.0, unit="s")
    link.done()

    file_params, file_profile = model.text("params", DEFAULT_MOTOR), model.text("profile", "")
    params_name = params or file_params
    per_motor = model.table("motor")
    vehicle = load_vehicle_params(_resolve(params_name, base))
    # unnamed: the vehicle's own noise bands where its file carries them (fit), else the flight profile
    profile_name = profile or file_profile or default_profile(vehicle)
    motor_params: MotorParams | dict[int, MotorParams] = vehicle.models(range(1, motors + 1))
    overrides = {}
    for key in list(per_motor.data):
        if not key.isdigit() or not 1 <= int(key) <= motors:
            raise ConfigError("unknown motor", path=where, key=f"model.motor.{key}", expected=f"1..{motors}")
        overrides[int(key)] = load_motor_params(_resolve(per_motor.text(key, ""), base))
    per_motor.done()
    if overrides:
        default = motor_params
        motor_params = {
            n: overrides.get(n, default if isinstance(default, MotorParams) else default[n])
            for n in range(1, motors + 1)
        }
    the_profile = load_profile(_resolve(profile_name, base))
    try:
        check_profile_for_vehicle(the_profile, vehicle)
    except ConfigError as exc:
        raise ConfigError(exc.reason, path=where, key="model.profile", expected=exc.expected) from None
    model.done()

    statustext = pub.raw("statustext")
    if statustext is None:
        statustext = True
    if not isinstance(statustext, bool):
        raise ConfigError(f"{statustext!r}", path=where, key="publish.statustext", expected="true or false")
    publish = PublishSettings(
        statustext=statustext,
        statustext_burst=int(pub.number("statustext_burst", 3, minimum=1, maximum=100)),
        statustext_interval_s=pub.number("statustext_interval_s", 5.0, minimum=0.1, maximum=3600, unit="s"),
        named_value_hz=pub.number("named_value_hz", 1.0, minimum=0.0, maximum=50.0, unit="Hz"),
        motor_health_hz=pub.number("motor_health_hz", 1.0, minimum=0.0, maximum=50.0, unit="Hz"),
        telemetry_hz=pub.number("telemetry_hz", 5.0, minimum=0.0, maximum=100.0, unit="Hz"),
    )
    pub.done()

    mqtt_settings = _mqtt(mq, where, base, mqtt_url, vid)
    mq.done()
    return AgentConfig(
        connect=url,
        vehicle_id=vid,
        frame=frame,
        motors=motors,
        params=motor_params,
        params_name=Path(params_name).stem,
        esc=vehicle.esc,
        current=vehicle.current,
        noise=band_noise_of(vehicle.noise),
        profile=the_profile,
        system_id=system_id,
        component_id=component_id,
        esc_rate_hz=esc_rate_hz,
        heartbeat_timeout_s=hb_timeout,
        stale_s=stale_s,
        batch_s=batch_s,
        publish=publish,
        mqtt=mqtt_settings,
        source=Path(path) if path is not None else None,
    )


def _resolve(name: str, base: Path) -> str:
    """A relative path in the config file is relative to the file; a bare name is a bundled one."""
    candidate = Path(name)
    if (candidate.suffix == ".toml" or len(candidate.parts) > 1) and not candidate.is_absolute():
        return str(base / candidate)
    return name


def _mqtt(
    mq: _Section, where: Path, base: Path, url_override: str | None, vehicle_id: str
) -> MqttSettings | None:
    file_url = mq.text("url", "")
    url = url_override if url_override is not None else file_url
    prefix = mq.text("prefix", "mmh")
    username = mq.text("username", "") or None
    password = mq.text("password", "") or None
    password_file = mq.text("password_file", "")
    ca_file = mq.text("ca_file", "") or None
    cert_file = mq.text("cert_file", "") or None
    key_file = mq.text("key_file", "") or None
    insecure = mq.raw("tls_insecure")
    client_id = mq.text("client_id", "") or None
    reconnect_min = mq.number("reconnect_min_s", 0.5, minimum=0.05, maximum=60, unit="s")
    reconnect_max = mq.number("reconnect_max_s", 10.0, minimum=0.05, maximum=600, unit="s")
    queue_limit = int(mq.number("queue_limit", 100_000, minimum=100, maximum=10_000_000))
    keepalive = int(mq.number("keepalive_s", 10, minimum=2, maximum=3600, unit="s"))
    if insecure is not None and not isinstance(insecure, bool):
        raise ConfigError(f"{insecure!r}", path=where, key="mqtt.tls_insecure", expected="true or false")
    if not url:
        return None
    if not re.match(r"^[A-Za-z0-9_/-]+$", prefix):
        raise ConfigError(f"{prefix!r}", path=where, key="mqtt.prefix", expected="letters, digits, _, - or /")
    if password_file:
        pf = Path(password_file) if Path(password_file).is_absolute() else base / password_file
        try:
            password = pf.read_text(encoding="utf-8").strip()
        except OSError as exc:
            raise ConfigError(f"cannot read: {exc}", path=where, key="mqtt.password_file") from None
    for key, value in (("ca_file", ca_file), ("cert_file", cert_file), ("key_file", key_file)):
        if value and not (Path(value) if Path(value).is_absolute() else base / value).is_file():
            raise ConfigError(f"no such file {value!r}", path=where, key=f"mqtt.{key}", expected="a PEM file")

    def absolute(value: str | None) -> str | None:
        return None if value is None else str(Path(value) if Path(value).is_absolute() else base / value)

    try:
        return parse_mqtt_url(
            url,
            prefix=prefix,
            vehicle_id=vehicle_id,
            username=username,
            password=password,
            ca_file=absolute(ca_file),
            cert_file=absolute(cert_file),
            key_file=absolute(key_file),
            tls_insecure=insecure,
            client_id=client_id,
            reconnect_min_s=reconnect_min,
            reconnect_max_s=reconnect_max,
            queue_limit=queue_limit,
            keepalive_s=keepalive,
        )
    except ConfigError as exc:
        raise ConfigError(exc.reason, path=where, key=exc.key, expected=exc.expected) from None
