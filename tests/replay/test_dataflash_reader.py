"""The DataFlash .bin reader against pymavlink's DFReader on the same real ArduPilot SITL log."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink import DFReader

from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.dataflash import USED_RECORDS, read_dataflash, read_records

RPM_TO_RAD_S = 2 * math.pi / 60


PREFIX_BYTES = 4_000_000  # ~48 s of the flight, take-off included; DFReader needs ~1 s per MB here


@pytest.fixture(scope="module")
def bin_prefix(sitl_bin: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The log's first 4 MB: a log cut mid-record, as a logger that lost power leaves it."""
    path = tmp_path_factory.mktemp("bin") / "prefix.bin"
    path.write_bytes(sitl_bin.read_bytes()[:PREFIX_BYTES])
    return path


@pytest.fixture(scope="module")
def dfreader_records(bin_prefix: Path) -> dict[str, list[dict[str, Any]]]:
    reader = DFReader.DFReader_binary(str(bin_prefix))
    found: dict[str, list[dict[str, Any]]] = defaultdict(list)
    while (msg := reader.recv_match(type=list(USED_RECORDS))) is not None:
        found[msg.get_type()].append(msg.to_dict())
    reader.filehandle.close()  # DFReader leaves its file open
    return found


@pytest.mark.parametrize("name", USED_RECORDS)
def test_every_field_of_every_record_equals_dfreader(
    bin_prefix: Path, dfreader_records: dict[str, list[dict[str, Any]]], name: str
) -> None:
    log = read_records(bin_prefix, warn=False)
    theirs = dfreader_records[name]
    assert len(theirs) > 0
    ours = log[name]
    assert len(ours["TimeUS"]) == len(theirs)
    for column, values in ours.items():
        if values.dtype.kind == "S":
            got: list[Any] = [v.split(b"\0", 1)[0].decode("ascii", "replace") for v in values.tolist()]
            want = [str(m[column]) for m in theirs]
            assert got == want, f"{name}.{column}"
        else:
            want_arr = np.array([m[column] for m in theirs], dtype=float)
            np.testing.assert_array_equal(values.astype(float), want_arr, err_msg=f"{name}.{column}")


def test_table_maps_esc_instances_to_motors_and_scales(
    bin_prefix: Path, dfreader_records: dict[str, list[dict[str, Any]]]
) -> None:
    with pytest.warns(
        UserWarning, match=r"prefix\.bin: damaged log at byte offset \d+ \(truncated at byte \d+\)"
    ):
        table = sources.read(bin_prefix)
    esc = dfreader_records["ESC"]
    assert table.motors() == [1, 2, 3, 4, 5, 6]
    assert table.meta["motors"] == [1, 2, 3, 4, 5, 6]
    assert table.meta["params"]["SERVO1_FUNCTION"] == 33
    origin = min(m["TimeUS"] for m in esc) / 1e6
    assert table.meta["time_origin_boot_s"] <= origin
    for motor in (1, 6):
        rows = table.for_motor(motor)
        mine = [m for m in esc if m["Instance"] == motor - 1]
        assert len(rows) == len(mine)
        np.testing.assert_allclose(rows["omega_rad_s"], [m["RPM"] * RPM_TO_RAD_S for m in mine])
        np.testing.assert_allclose(rows["esc_current_a"], [m["Curr"] for m in mine])
        np.testing.assert_allclose(rows["bus_voltage_v"], [m["Volt"] for m in mine])
        np.testing.assert_allclose(
            rows["time_s"], np.array([m["TimeUS"] for m in mine]) / 1e6 - table.meta["time_origin_boot_s"]
        )


def test_throttle_from_rcou_and_the_motor1_fault_is_visible(sitl_bin: Path) -> None:
    table = read_dataflash(sitl_bin)
    rcou = read_records(sitl_bin, ["RCOU"])["RCOU"]  # RCOU itself is checked against DFReader above
    origin = table.meta["time_origin_boot_s"]
    t_rcou = rcou["TimeUS"] / 1e6 - origin
    rows = table.for_motor(1)
    pwm = rcou["C1"].astype(float)
    idx = np.searchsorted(t_rcou, rows["time_s"] + 1e-9, side="right") - 1
    ok = idx >= 0
    np.testing.assert_allclose(rows["throttle"][ok], np.clip((pwm[idx[ok]] - 1000) / 1000, 0, 1))
    # MANIFEST: motor 1 thrust halved 110.1-130.2 s; its command rises while its speed falls.
    m1, m3 = table.for_motor(1), table.for_motor(3)
    w1 = (m1["time_s"] > 112) & (m1["time_s"] < 128)
    w3 = (m3["time_s"] > 112) & (m3["time_s"] < 128)
    assert np.mean(m1["throttle"][w1]) > np.mean(m3["throttle"][w3]) + 0.1
    assert np.mean(m1["omega_rad_s"][w1]) < 0.7 * np.mean(m3["omega_rad_s"][w3])
    # SITL's ESC current is a constant (MANIFEST): the reader passes it through untouched; the motor
    # current derived from it (ESC current / throttle) is what the live agent would compute.
    assert np.unique(np.round(table["esc_current_a"], 3)).tolist() == [0.8]
    moving = table["throttle"] >= 0.05
    np.testing.assert_allclose(
        table["current_a"][moving], table["esc_current_a"][moving] / table["throttle"][moving]
    )


def test_dataflash_and_tlog_of_the_same_flight_agree(sitl_bin: Path, sitl_tlog: Path) -> None:
    """Both logs record the same SITL flight: hover speeds per motor agree within a few rad/s."""
    binary, telemetry = read_dataflash(sitl_bin), sources.read(sitl_tlog)
    for motor in range(1, 7):
        b, t = binary.for_motor(motor), telemetry.for_motor(motor)
        # times differ in origin (boot vs first tlog record); compare the hover plateau levels
        level_b = np.nanpercentile(b["omega_rad_s"], 75)
        level_t = np.nanpercentile(t["omega_rad_s"], 75)
        assert level_b == pytest.approx(level_t, rel=0.03)
