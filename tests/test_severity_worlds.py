"""The severity floor on randomised worlds (evaluation/severity.py): the ladder's rule, and one
development world flown through it (the figures on held-out worlds are benchmarks/bench_severity_worlds.py's)."""

from __future__ import annotations

import math

import pytest

from mav_motor_health.evaluation.severity import SeverityTrial, WorldSeverity, severity_world


def trial(severity: float, ours_s: float | None, ours_false: int = 0) -> SeverityTrial:
    return SeverityTrial("F4.1", severity, 1, ours_s, ours_false, None, 0)


def test_the_floor_is_the_weakest_severity_from_which_every_stronger_flight_is_named() -> None:
    world = WorldSeverity(
        0,
        "",
        (
            trial(0.1, 0.5),  # named, but a stronger flight is not: not the floor
            trial(0.2, None),
            trial(0.35, 2.0),
            trial(0.5, 1.0),
            trial(1.0, 0.3),
        ),
    )
    assert world.floor("F4.1", "ours") == 0.35
    assert math.isinf(world.floor("F4.1", "baseline"))  # the baseline named none
    late = WorldSeverity(0, "", (trial(0.5, 3.5), trial(1.0, 0.2)))  # named after more than 3 s: not named
    assert late.floor("F4.1", "ours") == 1.0
    noisy = WorldSeverity(0, "", (trial(0.5, 0.4, ours_false=1), trial(1.0, 0.2)))  # a false event
    assert noisy.floor("F4.1", "ours") == 1.0
    assert math.isinf(WorldSeverity(0, "", (trial(0.5, 0.4), trial(1.0, None))).floor("F4.1", "ours"))


def test_beyond_the_paper_s_strength_the_floor_is_the_weakest_rung_named() -> None:
    # not named at 1: the rungs beyond it give the floor, each on its own (friction five times the paper's
    # may stall the motor, named a stall)
    beyond = WorldSeverity(
        0,
        "",
        (
            trial(0.5, None),
            trial(1.0, None),
            trial(1.5, None),
            trial(2.0, 1.0),
            trial(3.0, 0.5),
            trial(5.0, None),
        ),
    )
    assert beyond.floor("F4.1", "ours") == 2.0
    # named from 0.5 up to 1: the rungs beyond do not move the floor, named or not
    within = WorldSeverity(0, "", (trial(0.2, None), trial(0.5, 0.4), trial(1.0, 0.3), trial(2.0, None)))
    assert within.floor("F4.1", "ours") == 0.5
    assert math.isinf(WorldSeverity(0, "", (trial(1.0, None), trial(2.0, 4.0))).floor("F4.1", "ours"))


def test_a_ladder_outside_its_ranges_is_refused_before_anything_is_flown() -> None:
    with pytest.raises(ValueError, match="must lie in"):
        severity_world(4, severities=(0.5, 1.5))
    with pytest.raises(ValueError, match="must lie in"):
        severity_world(4, beyond=(1.0,))


def test_a_development_world_names_an_open_transistor_at_its_full_strength_and_the_baseline_is_fitted() -> (
    None
):
    # development world 4 (1.8 kg, its ESCs report the motor current): identified from its own healthy
    # flight, the PX4-style line fitted on the same flight
    result = severity_world(
        4, severities=(0.05, 1.0), faults=("F4.1",), beyond=(), duration_s=20.0, onset_s=10.0
    )
    assert result.refused is None and result.baseline is None, (result.refused, result.baseline)
    strongest = next(t for t in result.trials if t.severity == 1.0)
    assert strongest.named("ours") and strongest.ours_s is not None and strongest.ours_s < 1.0
    assert all(t.ours_false == 0 and t.baseline_false == 0 for t in result.trials), result.trials
    assert result.floor("F4.1", "ours") <= 1.0
