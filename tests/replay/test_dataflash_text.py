"""DataFlash *text* logs (.log): against pymavlink's DFReader_text on the real ArduCopter 3.1 log, and the
ESC path on a text rendering of the SITL .bin's first records."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pymavlink import DFReader

from mav_motor_health.errors import DataError
from mav_motor_health.evaluation.damage import dataflash_text
from mav_motor_health.telemetry import sources
from mav_motor_health.telemetry.dataflash import read_text_records


@pytest.fixture(scope="module")
def text_log(real_logs: Path) -> Path:
    return real_logs / "ardupilot" / "mechanical_fail.log"


def test_text_records_equal_dfreader_text(text_log: Path) -> None:
    types = ["MOT", "CTUN", "CURR", "PARM", "ATT"]
    reader = DFReader.DFReader_text(str(text_log))
    theirs: dict[str, list[Any]] = defaultdict(list)
    while (msg := reader.recv_match(type=types)) is not None:
        theirs[msg.get_type()].append(msg)
    reader.close()
    ours = read_text_records(text_log, types)
    for name in types:
        assert len(theirs[name]) == ours.counts[name] > 0, name
        for column, values in ours[name].items():
            want = [getattr(m, column) for m in theirs[name]]
            if values.dtype == object:
                assert values.tolist() == want, f"{name}.{column}"
            else:
                np.testing.assert_allclose(values, np.array(want, dtype=float), err_msg=f"{name}.{column}")


def test_text_log_without_esc_names_what_it_holds(text_log: Path) -> None:
    with pytest.raises(DataError) as info:
        sources.read(text_log)
    text = str(info.value)
    assert "no ESC telemetry" in text and "MOT ×1100" in text and "ESC records" in text


def test_esc_records_in_a_text_log_give_the_binary_logs_table(sitl_bin: Path, tmp_path: Path) -> None:
    head = tmp_path / "head.bin"
    head.write_bytes(sitl_bin.read_bytes()[:1_500_000])
    text = tmp_path / "head.log"
    text.write_text(dataflash_text(head, ("PARM", "ESC", "RCOU")))
    from_text = sources.read(text)
    with pytest.warns(UserWarning, match="damaged log"):  # the binary head is cut mid-record
        from_binary = sources.read(head)
    assert from_text.motors() == from_binary.motors() == [1, 2, 3, 4, 5, 6]
    for column in ("time_s", "omega_rad_s", "esc_current_a", "throttle", "voltage_v"):
        np.testing.assert_allclose(from_text[column], from_binary[column], err_msg=column)
