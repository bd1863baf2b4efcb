"""The PX4 ULog reader against pyulog on the same real PX4 logs."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pyulog import ULog as PyULog

from mav_motor_health.errors import DataError
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.ulog import read_ulog, read_ulog_topics

RPM_TO_RAD_S = 2 * math.pi / 60


def _flatten(arr: np.ndarray, prefix: str = "") -> dict[str, np.ndarray]:
    """Our nested structured array → pyulog's flat names (``esc[0].esc_rpm``)."""
    out: dict[str, np.ndarray] = {}
    for name in arr.dtype.names or ():
        values = arr[name]
        if values.dtype.names:
            if values.ndim == 2:
                for k in range(values.shape[1]):
                    out.update(_flatten(values[:, k], f"{prefix}{name}[{k}]."))
            else:
                out.update(_flatten(values, f"{prefix}{name}."))
        elif values.ndim == 2:
            for k in range(values.shape[1]):
                out[f"{prefix}{name}[{k}]"] = values[:, k]
        else:
            out[f"{prefix}{name}"] = values
    return out


@pytest.mark.parametrize(
    ("log_name", "topics"),
    [
        (
            "esc_status_log.ulg",
            [
                "esc_status",
                "actuator_outputs",
                "battery_status",
                "vehicle_local_position",
                "vehicle_air_data",
            ],
        ),
        (
            "quadrotor_local.ulg",
            ["actuator_motors", "actuator_outputs", "battery_status", "vehicle_air_data"],
        ),
    ],
)
def test_every_field_equals_pyulog(real_logs: Path, log_name: str, topics: list[str]) -> None:
    path = real_logs / "px4" / log_name
    theirs = PyULog(str(path), topics)
    ours = read_ulog_topics(path, topics)
    assert not ours.damage
    compared = 0
    for data in theirs.data_list:
        arr = ours.get(data.name, data.multi_id)
        assert arr is not None, (data.name, data.multi_id)
        flat = _flatten(arr)
        for field, values in data.data.items():
            if field.startswith("_padding"):
                continue
            np.testing.assert_array_equal(flat[field], values, err_msg=f"{data.name}.{field}")
            compared += 1
    assert compared > 50
    assert ours.params == {k: float(v) for k, v in theirs.initial_parameters.items()} | {
        k: float(v) for _, k, v in theirs.changed_parameters
    }
    assert ours.start_timestamp_us == theirs.start_timestamp


def test_esc_table_kelvin_to_celsius_and_esc_slots(px4_esc_ulg: Path) -> None:
    table = sources.read(px4_esc_ulg)
    esc = PyULog(str(px4_esc_ulg), ["esc_status"]).get_dataset("esc_status").data
    assert table.motors() == [1, 2, 3, 4]  # esc_count 4: slots 4-7 are empty
    assert table.meta["esc_temperature_kelvin"] is True
    for motor in range(1, 5):
        rows = table.for_motor(motor)
        assert len(rows) == len(esc["timestamp"])
        np.testing.assert_allclose(rows["omega_rad_s"], esc[f"esc[{motor - 1}].esc_rpm"] * RPM_TO_RAD_S)
        np.testing.assert_allclose(rows["esc_current_a"], esc[f"esc[{motor - 1}].esc_current"])
        np.testing.assert_allclose(
            rows["esc_temp_c"], esc[f"esc[{motor - 1}].esc_temperature"] - 273.15, rtol=1e-6
        )
    assert 15 < np.nanmedian(table["esc_temp_c"]) < 30  # a plausible air temperature, not 295
    assert 0.1 < np.nanmedian(table["throttle"]) < 0.9  # UAVCAN raw setpoint over 8191
    assert np.nanmedian(table["battery_voltage_v"]) == pytest.approx(22, abs=1.5)  # 6S
    assert np.isfinite(table["alt_m"]).mean() > 0.9


def test_a_log_without_esc_telemetry_says_what_it_has_and_what_is_needed(px4_no_esc_ulg: Path) -> None:
    with pytest.raises(DataError) as info:
        read_ulog(px4_no_esc_ulg)
    text = str(info.value)
    assert str(px4_no_esc_ulg) in text
    assert "no ESC telemetry" in text
    assert "actuator_motors" in text and "battery_status" not in text.split("It holds:")[0]
    assert "esc_status" in text
