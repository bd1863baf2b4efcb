"""The agent's TOML config is validated with clear errors; the MQTT outbox keeps what matters."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from mav_motor_health.agent.config import load_agent_config
from mav_motor_health.agent.link import parse_url
from mav_motor_health.errors import ConfigError, LinkError
from mav_motor_health.publish.mqtt import Outbox, dumps, parse_mqtt_url

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "params" / "agent.example.toml"


def test_the_shipped_example_config_loads():
    config = load_agent_config(EXAMPLE)
    assert config.connect == "/dev/serial0:921600"
    assert config.vehicle_id == "hexa1" and config.motors == 6 and config.component_id == 191
    assert config.profile.name == "flight" and config.mqtt is None


def test_command_line_overrides_the_file():
    config = load_agent_config(EXAMPLE, connect="udpin:0.0.0.0:14550", mqtt_url="mqtt://u:p%40ss@broker:1884")
    assert config.connect == "udpin:0.0.0.0:14550"
    assert config.mqtt is not None
    assert (config.mqtt.host, config.mqtt.port, config.mqtt.username, config.mqtt.password) == (
        "broker",
        1884,
        "u",
        "p@ss",
    )
    assert config.mqtt.topic("motor", 3, "state") == "mmh/hexa1/motor/3/state"


@pytest.mark.parametrize(
    ("text", "key", "expected"),
    [
        ("[link]\nconnect = 'udpin:0.0.0.0:14550'\n[agent]\nmotors = 20\n", "agent.motors", "between 1"),
        (
            "[link]\nconnect = 'udpin:0.0.0.0:14550'\n[agent]\nvehicle_id = 'a b'\n",
            "agent.vehicle_id",
            "letters",
        ),
        ("[link]\nconnect = 'udpin:0.0.0.0:14550'\nbaud = 5\n", "link", "only"),
        ("[link]\nconnect = 'bogus'\n", "link.connect", None),
        ("[agent]\nmotors = 6\n", "link.connect", "MAVLink URL"),
        ("[link]\nconnect = 'udpin:0.0.0.0:14550'\n[mqtt]\nurl = 'http://x'\n", "mqtt.url", "mqtt://"),
        (
            "[link]\nconnect = 'udpin:0.0.0.0:14550'\n[mqtt]\nurl = 'mqtt://x'\nca_file = 'nope.pem'\n",
            "mqtt.ca_file",
            "PEM",
        ),
        (
            "[link]\nconnect = 'udpin:0.0.0.0:14550'\n[publish]\nstatustext = 'yes'\n",
            "publish.statustext",
            "true or false",
        ),
        ("[link]\nconnect = 'udpin:0.0.0.0:14550'\n[model]\nprofile = 'nonesuch'\n", None, "testbed"),
    ],
)
def test_bad_config_names_file_key_and_what_was_expected(tmp_path, text, key, expected):
    path = tmp_path / "agent.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_agent_config(path)
    message = str(info.value)
    if key is not None:
        assert str(path) in message and f"'{key}'" in message, message
    if expected is not None:
        assert expected in message, message


def test_a_profile_in_amperes_is_refused_for_a_vehicle_identified_with_its_noise(tmp_path):
    from mav_motor_health.config import dump_vehicle_params, load_motor_params
    from mav_motor_health.diagnosis.noise import BandNoise
    from mav_motor_health.model.vehicle import VehicleParams

    noise = {m: BandNoise(6.0, 0.25, 20.0, 0.4, 900, 3.8, 300.0, 900.0).as_mapping() for m in range(1, 7)}
    vehicle = tmp_path / "vehicle.toml"
    vehicle.write_text(dump_vehicle_params(VehicleParams(motor=load_motor_params(), noise=noise)))
    path = tmp_path / "agent.toml"
    path.write_text(
        f"[link]\nconnect = 'udpin:0.0.0.0:14550'\n[model]\nparams = '{vehicle}'\nprofile = 'flight'\n"
    )
    with pytest.raises(ConfigError) as info:
        load_agent_config(path)
    message = str(info.value)
    assert str(path) in message and "'model.profile'" in message and "'flight_vehicle'" in message, message
    path.write_text(f"[link]\nconnect = 'udpin:0.0.0.0:14550'\n[model]\nparams = '{vehicle}'\n")
    assert load_agent_config(path).profile.name == "flight_vehicle"  # the default for such a file


def test_mavlink_urls():
    assert parse_url("/dev/serial0:921600").baud == 921600
    assert parse_url("/dev/ttyACM0").device == "/dev/ttyACM0"
    assert parse_url("udpin:0.0.0.0:14550").kind == "socket"
    assert parse_url("flight.tlog").kind == "tlog"
    for bad in ("udpin:14550", "tcp:host:99999", "serial0", "http://x"):
        with pytest.raises(LinkError):
            parse_url(bad)


def test_mqtt_urls():
    assert parse_mqtt_url("mqtts://broker").port == 8883
    assert parse_mqtt_url("mqtts://broker").tls
    assert parse_mqtt_url("broker:1999").port == 1999


def test_payloads_send_non_finite_numbers_as_null():
    assert dumps({"a": float("nan"), "b": [float("inf"), 1.5]}) == b'{"a":null,"b":[null,1.5]}'


def test_outbox_drops_oldest_telemetry_first_and_keeps_every_event():
    async def scenario():
        box = Outbox(limit=10, telemetry_limit=5)
        for k in range(8):
            box.put_telemetry("t", str(k).encode())
        assert [m.payload for m in box.telemetry] == [b"3", b"4", b"5", b"6", b"7"]
        for k in range(8):
            box.put_event("e", str(k).encode())
        # events took the room: the oldest telemetry went, every event is there in order
        assert [m.payload for m in box.events] == [str(k).encode() for k in range(8)]
        assert [m.payload for m in box.telemetry] == [b"6", b"7"]
        assert box.dropped_events == 0
        box.put_retained("s/1", b"a")
        box.put_retained("s/1", b"b")  # latest wins
        order = []
        while (m := box.peek()) is not None:
            order.append((m.topic, m.payload))
            box.done(m)
        assert order[0] == ("s/1", b"b")
        assert [p for t, p in order if t == "e"] == [str(k).encode() for k in range(8)]
        # after a reconnect every retained topic goes out again
        box.mark_all_retained_dirty()
        assert box.peek().payload == b"b"

    asyncio.run(scenario())
