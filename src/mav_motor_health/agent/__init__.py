"""The companion-computer agent: six motors live over MAVLink, health out over MAVLink and MQTT.

Modules: :mod:`.link` (MAVLink transport, threads → asyncio), :mod:`.samples` (messages → motor samples),
:mod:`.monitor` (the diagnosis core per sample, plus silence), :mod:`.vehicle` (autopilot discovery,
loss and reboot), :mod:`.config` (the TOML file), :mod:`.view` (terminal), :mod:`.app` (the agent).
"""

from .app import Agent, run_agent
from .config import AgentConfig, PublishSettings, load_agent_config
from .link import LinkUrl, MavlinkLink, Received, parse_url
from .monitor import HealthMonitor, MotorStatus, StateChange
from .samples import MotorSample, SampleAssembler
from .vehicle import AutopilotTracker

__all__ = [
    "Agent",
    "AgentConfig",
    "AutopilotTracker",
    "HealthMonitor",
    "LinkUrl",
    "MavlinkLink",
    "MotorSample",
    "MotorStatus",
    "PublishSettings",
    "Received",
    "SampleAssembler",
    "StateChange",
    "load_agent_config",
    "parse_url",
    "run_agent",
]
