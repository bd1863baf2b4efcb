"""Sinks: what the diagnosis is published to (MQTT, MAVLink, reports, the web display)."""
