"""Sinks: what the diagnosis is published to (MAVLink STATUSTEXT, NAMED_VALUE_* and the MOTOR_HEALTH
dialect; MQTT; the web display).

The names below are imported when first used: a replay's report needs only the web view, and the MQTT
client (aiomqtt, paho, asyncio, ssl) takes longer to import than the report takes to write.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .mavlink_health import StatustextGate, TokenBucket, severity_for, statustext_for
    from .mqtt import EventDedupe, MqttPublisher, MqttSettings, Outbox, parse_mqtt_url

__all__ = [
    "EventDedupe",
    "MqttPublisher",
    "MqttSettings",
    "Outbox",
    "StatustextGate",
    "TokenBucket",
    "parse_mqtt_url",
    "severity_for",
    "statustext_for",
]

_MODULE_OF = {
    "StatustextGate": ".mavlink_health",
    "TokenBucket": ".mavlink_health",
    "severity_for": ".mavlink_health",
    "statustext_for": ".mavlink_health",
    "EventDedupe": ".mqtt",
    "MqttPublisher": ".mqtt",
    "MqttSettings": ".mqtt",
    "Outbox": ".mqtt",
    "parse_mqtt_url": ".mqtt",
}


def __getattr__(name: str) -> Any:
    """The exported names, imported from their module on first use."""
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value
    return value
