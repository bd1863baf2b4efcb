"""Sinks for motor health: MAVLink (STATUSTEXT, NAMED_VALUE_*, the MOTOR_HEALTH dialect) and MQTT."""

from .mavlink_health import StatustextGate, TokenBucket, severity_for, statustext_for
from .mqtt import MqttPublisher, MqttSettings, Outbox, parse_mqtt_url

__all__ = [
    "MqttPublisher",
    "MqttSettings",
    "Outbox",
    "StatustextGate",
    "TokenBucket",
    "parse_mqtt_url",
    "severity_for",
    "statustext_for",
]
