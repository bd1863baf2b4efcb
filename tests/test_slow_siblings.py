"""The slow look's bands bounded by how its siblings' slow averages run (``slow_siblings``;
diagnosis/rules/tree.py, "The slow look as its siblings run")."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np


def test_an_open_transistor_in_moderate_air_is_named_against_the_siblings_and_friction_as_before(
    tmp_path,
) -> None:
    """Development world 4 (ESCs at 30 Hz reporting their input current), identified from its 150-s
    healthy flight, 30-s flights in moderate air: the slow look's own bands, extrapolated beyond the
    identification flight's activity, leave the open transistor NORMAL after onset; bounded by the
    siblings' slow averages it is named on most samples. Friction, named in the torque balance, is named
    as often either way, and no other motor is announced in any of the four diagnoses."""
    from mav_motor_health.config import load_profile
    from mav_motor_health.diagnosis.states import MotorState
    from mav_motor_health.evaluation.worlds import diagnose_flight, identify_world, world_flights

    _, _, vehicle = identify_world(4, tmp_path)
    shipped = load_profile("flight_vehicle")
    with_siblings = dataclasses.replace(shipped, slow_siblings=1.0)
    own_alone = dataclasses.replace(shipped, slow_siblings=0.0)
    accuracy = {}
    for fault in ("F4.1", "F1.1"):
        (flight,) = world_flights(
            4, duration_s=30.0, healthy_flights=0, levels=("moderate",), faults=(fault,)
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            results = [diagnose_flight(flight, tmp_path, vehicle, p) for p in (own_alone, with_siblings)]
        for r in results:
            assert (r["announced"][r["motor"] != flight.motor] == MotorState.NORMAL).all(), fault
        after = [
            (r["motor"] == flight.motor) & (r["time_s"] > flight.onset_s) & r["steady"].astype(bool)
            for r in results
        ]
        accuracy[fault] = [
            float(np.mean(r["state"][a] == MotorState.from_label(fault))) for r, a in zip(results, after)
        ]
    assert accuracy["F4.1"][0] < 0.1 and accuracy["F4.1"][1] > 0.6, accuracy
    assert accuracy["F1.1"][1] == accuracy["F1.1"][0] > 0.5, accuracy
