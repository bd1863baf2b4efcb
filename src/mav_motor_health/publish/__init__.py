"""Sinks: what the diagnosis is published to (MAVLink STATUSTEXT, NAMED_VALUE_* and the MOTOR_HEALTH
dialect; MQTT; the web display)."""

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
