"""The live agent's path against replay's on a world's flight (shared by the tests of every folder)."""

from __future__ import annotations

import warnings

import numpy as np

from mav_motor_health.diagnosis.noise import band_noise_of
from mav_motor_health.diagnosis.pipeline import MotorBatch, StreamingDiagnoser
from mav_motor_health.evaluation.worlds import fly_flight
from mav_motor_health.sim.writers import write_record
from mav_motor_health.telemetry import sources


def streams_as_replay(flight, tmp_path, vehicle, profile, whole) -> None:
    """The live agent's way: ``flight`` flown and written as a .tlog, read, and fed to a
    :class:`StreamingDiagnoser` in batches cut in arrival order (time, then motor; 1 to 39 samples, every
    motor's samples of a batch in one call) gives the states ``whole`` (replay's diagnosis of it) has."""
    log = tmp_path / "streamed.tlog"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        write_record(fly_flight(flight), log)
        table = vehicle.calibrate(sources.read(log))
    cols = {name: table[name] for name in table.names}
    motor = np.asarray(table["motor"]).astype(int)
    np.testing.assert_array_equal(motor, whole["motor"])
    np.testing.assert_array_equal(cols["time_s"], whole["time_s"])
    motors = sorted(set(motor.tolist()))
    stream = StreamingDiagnoser(vehicle.models(range(1, 7)), profile, motors, band_noise_of(vehicle.noise))
    measured = np.isfinite(cols["omega_rad_s"]) | np.isfinite(cols["current_a"])
    arrival = np.lexsort((motor, cols["time_s"]))
    arrival = arrival[measured[arrival]]
    got = np.full(motor.size, -1)
    rng = np.random.default_rng(30)
    k = 0
    while k < arrival.size:
        part = arrival[k : k + int(rng.integers(1, 40))]
        k += part.size
        batches = {}
        for m in np.unique(motor[part]).tolist():
            rows = part[motor[part] == m]
            batches[m] = (MotorBatch.of_columns(cols, rows), rows)
        results = stream.update_motors({m: b for m, (b, _) in batches.items()})
        for m, (_, rows) in batches.items():
            got[rows] = results[m]["state"]
    np.testing.assert_array_equal(got[measured], whole["state"][measured])
