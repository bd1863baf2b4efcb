"""TOML loading: bundled files load, bad files get one clear error naming file, key and expectation."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from mav_motor_health.config import dump_motor_params, load_motor_params, load_profile
from mav_motor_health.diagnosis.profile import ThresholdProfile
from mav_motor_health.errors import ConfigError


def test_bundled_files_load() -> None:
    motor = load_motor_params("paper_x2212")
    assert (motor.R_ohm, motor.k_e, motor.C_p, motor.B, motor.T_f, motor.k) == (
        0.165,
        0.00975,
        1.692e-10,
        1.275e-7,
        4.606e-10,
        3.0,
    )
    testbed = load_profile("testbed")
    flight = load_profile("flight")
    assert testbed.speed_band_rad_s == 20.0 and testbed.stop_speed_rad_s == 100.0
    assert testbed.stall_split_a == 6.0 and testbed.current_band_a == ((4.0, 0.25), (11.0, 2.5))
    assert flight.name == "flight"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "x.toml"
    path.write_text(text)
    return path


MOTOR = "[motor]\nR_ohm = 0.1\nk_e = 0.01\nC_p = 1e-10\n"


@pytest.mark.parametrize(
    ("text", "key", "expected"),
    [
        ("[motor]\nk_e = 0.01\nC_p = 1e-10\n", "motor.R_ohm", "a number ohm"),
        (MOTOR.replace("0.1", '"fast"'), "motor.R_ohm", "a number ohm"),
        (MOTOR.replace("R_ohm = 0.1", "R_ohm = -1"), "motor.R_ohm", ">= 1e-06 ohm"),
        (MOTOR + "colour = 3\n", "motor", "only"),
        (MOTOR + "k = 8\n", "motor.k", "between 0.5 and 6.0"),
        (MOTOR + "[extra]\n", None, "only"),
    ],
)
def test_bad_motor_files(tmp_path: Path, text: str, key: str | None, expected: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_motor_params(path)
    err = info.value
    assert err.path == path and err.key == key
    assert expected in str(err) and str(path) in str(err)


def test_not_toml_and_missing(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_motor_params(write(tmp_path, "[motor\n"))
    with pytest.raises(ConfigError, match="file not found"):
        load_motor_params(tmp_path / "nope.toml")
    with pytest.raises(ConfigError, match="no profile named 'windy'"):
        load_profile("windy")


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("[profile]\ncurrent_band_a = [[4, 0.25], [3, 2.5]]\n", "profile.current_band_a"),
        ("[profile]\ncurrent_band_a = [4, 0.25]\n", "profile.current_band_a"),
        ("[profile]\nspeed_band_rad_s = -2\n", "profile.speed_band_rad_s"),
        ('[persistence.announce_s]\n"F9.9" = 0.2\n', "persistence.announce_s.F9.9"),
        ("[steady]\nsettle = 0.2\n", "steady.settle"),  # named: not a setting of the step rule
        ('[steady]\nkind = "balance"\nlag_fraction = 1.0\n', "steady.lag_fraction"),  # the dynamic rule's
        ("[profile]\nfree_speed_headroom_fraction = -0.5\n", "profile.free_speed_headroom_fraction"),
        ("[profile]\nfree_speed_headroom_fraction = 1.5\n", "profile.free_speed_headroom_fraction"),
        ('[profile]\nfree_speed_headroom_fraction = "half"\n', "profile.free_speed_headroom_fraction"),
        ("[profile]\nactivity_band = [[0.5, 10]]\n", "profile.activity_band"),
        ("[profile]\nactivity_band = [[1.0, 10, 0.1], [0.5, 20, 0.2]]\n", "profile.activity_band"),
        ("[profile]\nactivity_band = [[0.5, -10, 0.1]]\n", "profile.activity_band"),
        ("[profile]\nactivity_band = [[0.5, 10, 0.1], [1.0, 20, 0.2, 0.3]]\n", "profile.activity_band"),
        ("[profile]\nactivity_band = [[0.5, 10, 0.1, 0.2, 0.3]]\n", "profile.activity_band"),
        ("[profile]\nactivity_band = [[0.5, 10, 0.1, -0.2]]\n", "profile.activity_band"),
        ('[steady]\nkind = "balance"\nresidual_tau_s = 0\n', "steady.residual_tau_s"),
        ("[persistence]\nmax_depth = 0.5\n", "persistence.max_depth"),
        ("[steady]\nslow_factor = 0.5\n", "steady.slow_factor"),
        ('[steady]\nkind = "balance"\nstep_sigmas = -1\n', "steady.step_sigmas"),
        ('[steady]\nkind = "balance"\nstep_over_changes = 2\n', "steady.step_over_changes"),
        ("[profile]\nslow_band_fraction = 1.5\n", "profile.slow_band_fraction"),
        ("[profile]\nconditions_reach = 0.5\n", "profile.conditions_reach"),
        ("[profile]\nconditions_growth = -1\n", "profile.conditions_growth"),
        ("[profile]\nrange_growth = 5\n", "profile.range_growth"),
        ("[profile]\nrange_growth = 1\n", "profile.range_growth"),  # without range_margin: nothing to grow in
        ("[profile]\ntorque_siblings_spread = -1\n", "profile.torque_siblings_spread"),
        ("[profile]\ntorque_siblings_spread = 101\n", "profile.torque_siblings_spread"),
        ("[profile]\nslow_siblings = -0.5\n", "profile.slow_siblings"),
        ("[profile]\nslow_siblings = 101\n", "profile.slow_siblings"),
    ],
)
def test_bad_profiles(tmp_path: Path, text: str, key: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_profile(path)
    assert info.value.key == key and info.value.path == path


@pytest.mark.parametrize(
    ("line", "fraction"),
    [("", 0.5), ("free_speed_headroom_fraction = 0", 0.5), ("free_speed_headroom_fraction = 1", 1.0)],
)
def test_free_speed_headroom_fraction_defaults_and_range(tmp_path: Path, line: str, fraction: float) -> None:
    # 0 or absent: the default (0.5); the bundled profiles use the default (the balance rule of the flight
    # profile does not narrow its band, see diagnosis/pipeline.py)
    assert load_profile(write(tmp_path, f"[profile]\n{line}\n")).free_speed_headroom_fraction == fraction
    assert load_profile("testbed").free_speed_headroom_fraction == 0.5
    assert load_profile("flight_dynamic").free_speed_headroom_fraction == 0.5
    assert load_profile("flight").free_speed_headroom_fraction == 0.5
    with pytest.raises(ConfigError, match="0 < f <= 1"):
        ThresholdProfile(name="x", free_speed_headroom_fraction=0.0)


def test_dump_round_trip(tmp_path: Path, paper_motor) -> None:
    with_effects = paper_motor.replace(
        name='a "quoted" name', effects=(("winding_temp", (("alpha", 0.0039),)),)
    )
    path = write(tmp_path, dump_motor_params(with_effects, {"fitted_from": "bench.csv"}))
    assert load_motor_params(path) == with_effects


def test_profile_dump_round_trip(tmp_path: Path) -> None:
    from mav_motor_health.config import dump_profile
    from mav_motor_health.diagnosis.profile import PersistenceRule

    profile = load_profile("flight")
    tuned = ThresholdProfile(
        name="tuned",
        description="tuned on x",
        speed_band_rad_s=31.5,
        current_band_a=((5.0, 0.4), (9.0, 1.1), (16.0, 2.0)),
        stall_split_a=5.5,
        stall_split_per_v=0.3,
        stall_split_ref_v=15.0,
        free_speed_headroom_fraction=0.7,
        activity_band=((0.1, 0.0, 0.0), (0.8, 30.5, 0.25), (2.5, 60.0, 1.25)),
        steady=profile.steady,
        persistence=PersistenceRule(0.2, (("F4.1", 0.35), ("F2.1", 0.05)), 0.6),
        plausibility=profile.plausibility,
    )
    path = write(tmp_path, dump_profile(tuned, {"tuned_on": "3 flights"}))
    assert load_profile(path) == tuned
    # the current widened apart above and below the model (a fourth column)
    sided = replace(tuned, activity_band=((0.1, 0.0, 0.0, 0.0), (0.8, 30.5, 0.2, 0.3), (2.5, 60.0, 0.9, 1.4)))
    assert load_profile(write(tmp_path, dump_profile(sided))) == sided
    # the shipped vehicle profile, with the slow look's bands bounded by its siblings
    vehicle = replace(load_profile("flight_vehicle"), slow_siblings=1.5)
    assert load_profile(write(tmp_path, dump_profile(vehicle))) == vehicle
