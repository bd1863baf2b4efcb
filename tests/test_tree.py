"""Every branch of the decision tree (Fig. 7) and the transitions the paper reports in section IV.A."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health.diagnosis import MotorState, ThresholdProfile, classify
from mav_motor_health.model import MotorParams, steady_state

V = 9.2  # volts: current band there is 0.25 + (9.2-4)/(11-4)·2.25 = 1.921 A


def model_at(params: MotorParams, v: float = V) -> tuple[float, float]:
    s = steady_state(params, v)
    return float(s.omega_rad_s), float(s.current_a)


def one(
    profile: ThresholdProfile,
    params: MotorParams,
    d_omega: float,
    d_current: float,
    *,
    omega: float | None = None,
    current: float | None = None,
    v: float = V,
) -> MotorState:
    w_m, i_m = model_at(params, v)
    w = w_m + d_omega if omega is None else omega
    i = i_m + d_current if current is None else current
    code = classify(
        profile, omega_rad_s=[w], omega_model_rad_s=[w_m], current_a=[i], current_model_a=[i_m], voltage_v=[v]
    )
    return MotorState(int(code[0]))


@pytest.mark.parametrize(
    ("d_omega", "d_current", "expected"),
    [
        (0, 0, MotorState.NORMAL),
        (19, 1.9, MotorState.NORMAL),
        (-19, -1.9, MotorState.NORMAL),
        (40, -2.5, MotorState.F3_1),  # faster, less current: lighter propeller
        (-40, 2.5, MotorState.F1_1),  # slower, more current: friction
        (0, 2.5, MotorState.F1_1),  # speed inside, current above
        (-40, 0, MotorState.F4_1),  # slower, current inside
        (-40, -2.5, MotorState.F4_1),  # slower, less current
        (0, -2.5, MotorState.F4_1),  # speed inside, current below
        (40, 0, MotorState.UNKNOWN),  # faster with current inside: not named
        (40, 2.5, MotorState.UNKNOWN),  # faster with more current: not named
    ],
)
def test_band_branches(testbed_profile, paper_motor, d_omega, d_current, expected) -> None:
    assert one(testbed_profile, paper_motor, d_omega, d_current) == expected


def test_stall_branches_split_at_six_amps(testbed_profile, paper_motor) -> None:
    assert one(testbed_profile, paper_motor, 0, 0, omega=0.0, current=3.0) == MotorState.F2_1
    assert one(testbed_profile, paper_motor, 0, 0, omega=99.0, current=5.99) == MotorState.F2_1
    assert one(testbed_profile, paper_motor, 0, 0, omega=50.0, current=6.0) == MotorState.F4_2
    assert one(testbed_profile, paper_motor, 0, 0, omega=0.0, current=8.0) == MotorState.F4_2
    assert one(testbed_profile, paper_motor, 0, 0, omega=101.0, current=3.0) == MotorState.F4_1


def test_idle_motor_is_not_a_stalled_motor(testbed_profile, paper_motor) -> None:
    # At 0.5 V the model itself expects ~50 rad/s: slow is not a fault there.
    assert one(testbed_profile, paper_motor, 0, 0, v=0.5) == MotorState.NORMAL


def test_current_band_interpolation_and_hold(testbed_profile) -> None:
    widths = testbed_profile.current_halfwidth_a([2.0, 4.0, 7.5, 11.0, 22.0])
    np.testing.assert_allclose(widths, [0.25, 0.25, 1.375, 2.5, 2.5])


def test_missing_values_are_no_data(testbed_profile, paper_motor) -> None:
    w_m, i_m = model_at(paper_motor)
    code = classify(
        testbed_profile,
        omega_rad_s=[np.nan],
        omega_model_rad_s=[w_m],
        current_a=[i_m],
        current_model_a=[i_m],
        voltage_v=[V],
    )
    assert code[0] == MotorState.NO_DATA


def trajectory(testbed_profile, paper_motor, omegas, currents, v=V, omega_free_rad_s=None):
    """State labels of samples at the model point of voltage v (free speed given, or None)."""
    w_m, i_m = model_at(paper_motor, v)
    n = len(omegas)
    codes = classify(
        testbed_profile,
        omega_rad_s=omegas,
        omega_model_rad_s=np.full(n, w_m),
        current_a=currents,
        current_model_a=np.full(n, i_m),
        voltage_v=np.full(n, v),
        omega_free_rad_s=None if omega_free_rad_s is None else np.full(n, omega_free_rad_s),
    )
    return [MotorState(int(c)).label for c in codes]


def test_transition_f11_shows_f41_while_current_settles(testbed_profile, paper_motor) -> None:
    # IV.A, Fig. 9: speed converges in ~0.5 s, current later; F4.1 appears while current is still in band.
    w_m, i_m = model_at(paper_motor)
    omegas = [w_m, w_m - 30, w_m - 45, w_m - 50, w_m - 50]
    currents = [i_m, i_m + 0.5, i_m + 1.5, i_m + 2.5, i_m + 3.0]
    assert trajectory(testbed_profile, paper_motor, omegas, currents) == [
        "NORMAL",
        "F4.1",
        "F4.1",
        "F1.1",
        "F1.1",
    ]


def test_transition_f21_shows_f41_until_below_stop_speed(testbed_profile, paper_motor) -> None:
    # IV.A, Fig. 10: F4.1 while the speed falls through the band, then F2.1 below 100 rad/s.
    w_m, i_m = model_at(paper_motor)
    omegas = [w_m, 500.0, 200.0, 90.0, 0.0]
    currents = [i_m, 4.0, 3.0, 3.0, 2.5]
    assert trajectory(testbed_profile, paper_motor, omegas, currents) == [
        "NORMAL",
        "F4.1",
        "F4.1",
        "F2.1",
        "F2.1",
    ]


def test_transition_f21_at_high_current_shows_f42_until_below_six_amps(testbed_profile, paper_motor) -> None:
    # IV.A, Fig. 10 cases 4-5: F4.2 is shown while the stalled current is still above 6 A.
    omegas = [50.0, 20.0, 0.0, 0.0]
    currents = [9.0, 7.0, 5.0, 3.0]
    assert trajectory(testbed_profile, paper_motor, omegas, currents, v=11.0) == [
        "F4.2",
        "F4.2",
        "F2.1",
        "F2.1",
    ]


def test_transition_f42_shows_f21_while_current_rises_through_six_amps(testbed_profile, paper_motor) -> None:
    # IV.A, Fig. 13 cases 1-2: at low voltage the stall current rises from below 6 A to 7-8 A.
    omegas = [80.0, 40.0, 0.0, 0.0]
    currents = [2.0, 5.0, 7.0, 8.0]
    assert trajectory(testbed_profile, paper_motor, omegas, currents, v=4.2) == [
        "F2.1",
        "F2.1",
        "F4.2",
        "F4.2",
    ]


def test_transition_f42_shows_f11_while_slowing_above_stop_speed(testbed_profile, paper_motor) -> None:
    # IV.A, Fig. 13 cases 3-5: "F1.1 was diagnosed ... until below 100 rad/s".
    w_m, i_m = model_at(paper_motor, 7.6)
    omegas = [w_m - 300, 150.0, 60.0]
    currents = [i_m + 4.0, 8.0, 7.5]
    assert trajectory(testbed_profile, paper_motor, omegas, currents, v=7.6) == ["F1.1", "F1.1", "F4.2"]


def test_transition_f31_start_up_shows_f21_then_f41(testbed_profile, paper_motor) -> None:
    # IV.A, Fig. 11: started with a broken propeller: F2.1 below 100 rad/s, F4.1 while the speed passes
    # through the band with a low current, then F3.1.
    w_m, i_m = model_at(paper_motor)
    omegas = [50.0, w_m, w_m + 60]
    currents = [0.5, i_m - 3.0, i_m - 3.0]
    assert trajectory(testbed_profile, paper_motor, omegas, currents) == ["F2.1", "F4.1", "F3.1"]


def test_free_speed_headroom_narrows_only_the_upper_side(testbed_profile, paper_motor) -> None:
    # Rule 2 near the free speed: at 4.2 V the model is 410.4 rad/s and V/k_e 430.8 rad/s, a headroom of
    # 20.4 rad/s; half of it (free_speed_headroom_fraction 0.5) is the band above the model.
    v = 4.2
    w_m, i_m = model_at(paper_motor, v)
    free = v / paper_motor.k_e
    half = testbed_profile.free_speed_headroom_fraction * (free - w_m)
    assert testbed_profile.free_speed_headroom_fraction == 0.5 and half == pytest.approx(10.19, abs=0.01)
    low_i = i_m - 1.0  # well below the 0.31 A current band at 4.2 V
    omegas = [w_m + 15.0, w_m + 15.0, w_m + 9.0, w_m - 15.0, w_m - 25.0]
    currents = [low_i, i_m, i_m, i_m, low_i]

    def states(omega_free: float | None) -> list[str]:
        return trajectory(testbed_profile, paper_motor, omegas, currents, v=v, omega_free_rad_s=omega_free)

    # inside the full ±20 rad/s band, beyond half the headroom: F3.1 with a low current, UNKNOWN without;
    # inside half the headroom: NORMAL; below the model the full band still applies (-15 NORMAL, -25 F4.1)
    assert states(free) == ["F3.1", "UNKNOWN", "NORMAL", "NORMAL", "F4.1"]
    assert states(None) == ["F4.1", "NORMAL", "NORMAL", "NORMAL", "F4.1"]  # no free speed: the paper's band
    # where the headroom is large (9.2 V: 148 rad/s) the band is the profile's ±20 rad/s as before
    w9, i9 = model_at(paper_motor, 9.2)
    code = classify(
        testbed_profile,
        omega_rad_s=[w9 + 19.0, w9 + 21.0],
        omega_model_rad_s=[w9, w9],
        current_a=[i9 - 3.0, i9 - 3.0],
        current_model_a=[i9, i9],
        voltage_v=[9.2, 9.2],
        omega_free_rad_s=[9.2 / paper_motor.k_e] * 2,
    )
    assert [MotorState(int(c)).label for c in code] == ["F4.1", "F3.1"]


def test_free_speed_headroom_never_narrows_below_the_speed_noise(testbed_profile, paper_motor) -> None:
    # Near idle the headroom vanishes (2 V: 2.5 rad/s) but the ±10 rad/s noise does not: the band above the
    # model stays at least half the band (10 rad/s), else noise alone would be "faster".
    v = 2.0
    w_m, i_m = model_at(paper_motor, v)
    assert v / paper_motor.k_e - w_m < 3.0
    code = classify(
        testbed_profile,
        omega_rad_s=[w_m + 9.9, w_m + 10.5, w_m + 10.5],
        omega_model_rad_s=[w_m] * 3,
        current_a=[i_m, i_m, i_m - 1.0],
        current_model_a=[i_m] * 3,
        voltage_v=[v] * 3,
        omega_free_rad_s=[v / paper_motor.k_e] * 3,
    )
    assert [MotorState(int(c)).label for c in code] == ["NORMAL", "UNKNOWN", "F3.1"]
    # and a free speed below the model (a motor spinning down in flight) is no headroom, not a negative one
    code = classify(
        testbed_profile,
        omega_rad_s=[w_m + 9.9],
        omega_model_rad_s=[w_m],
        current_a=[i_m],
        current_model_a=[i_m],
        voltage_v=[v],
        omega_free_rad_s=[w_m - 50.0],
    )
    assert MotorState(int(code[0])) == MotorState.NORMAL


def test_free_speed_headroom_leaves_the_speed_only_branch_alone(testbed_profile, paper_motor) -> None:
    # Without a current, FAST keeps the wide band: speed noise near the free speed is not a fault.
    v = 4.2
    w_m, _ = model_at(paper_motor, v)
    code = classify(
        testbed_profile,
        omega_rad_s=[w_m + 15.0],
        omega_model_rad_s=[w_m],
        current_a=[np.nan],
        current_model_a=[np.nan],
        voltage_v=[v],
        omega_free_rad_s=[v / paper_motor.k_e],
    )
    assert MotorState(int(code[0])) == MotorState.NORMAL


def test_departures_that_agree_name_the_fault(testbed_profile, paper_motor) -> None:
    """joint_band_sum: speed and current both part-way out, the way one fault moves them, name it."""
    from dataclasses import replace

    joint = replace(testbed_profile, joint_band_sum=1.5)
    bw, bi = 20.0, 1.921  # the bands at V (speed, current)
    cases = [
        # (speed, current) in shares of their bands: paper's tree, with the joint rule
        ((-0.8, -0.8), MotorState.NORMAL, MotorState.F4_1),  # slower and less: open transistor
        ((-0.8, 0.8), MotorState.NORMAL, MotorState.F1_1),  # slower and more: friction
        ((0.8, -0.8), MotorState.NORMAL, MotorState.F3_1),  # faster and less: lighter propeller
        ((0.6, -1.2), MotorState.F4_1, MotorState.F3_1),  # "current low, speed inside" but rising
        ((-0.6, -0.6), MotorState.NORMAL, MotorState.NORMAL),  # 1.2 < 1.5: still noise
        ((0.8, 0.8), MotorState.NORMAL, MotorState.NORMAL),  # faster with more: no fault does that
        ((-0.8, -0.0), MotorState.NORMAL, MotorState.NORMAL),  # one departure alone: the full band
    ]
    for (dw, di), paper, with_joint in cases:
        assert one(testbed_profile, paper_motor, dw * bw, di * bi) == paper, (dw, di)
        assert one(joint, paper_motor, dw * bw, di * bi) == with_joint, (dw, di)


def test_joint_band_sum_is_validated() -> None:
    from mav_motor_health.errors import ConfigError

    for bad in (0.5, 2.5, -1.0):
        with pytest.raises(ConfigError, match="joint_band_sum"):
            ThresholdProfile(name="x", joint_band_sum=bad)


def test_stop_speed_fraction_names_a_stall_while_the_rotor_runs_down(testbed_profile, paper_motor) -> None:
    from dataclasses import replace

    w_m, _ = model_at(paper_motor)
    running_down = 0.2 * w_m  # well above 100 rad/s, a fifth of what the input gives
    assert running_down > 150
    assert one(testbed_profile, paper_motor, 0, 0, omega=running_down, current=3.0) == MotorState.F4_1
    early = replace(testbed_profile, stop_speed_fraction=0.25)
    assert one(early, paper_motor, 0, 0, omega=running_down, current=3.0) == MotorState.F2_1
    assert one(early, paper_motor, 0, 0, omega=running_down, current=8.0) == MotorState.F4_2
    assert (
        one(early, paper_motor, 0, 0, omega=0.3 * w_m, current=3.0) == MotorState.F4_1
    )  # not below a quarter


def test_depth_counts_the_bands_past_the_boundary(testbed_profile, paper_motor) -> None:
    """classify_depth: 1 on a state's boundary (and for NORMAL), the shares of the bands beyond it."""
    from dataclasses import replace

    from mav_motor_health.diagnosis.tree import classify_depth

    joint = replace(testbed_profile, joint_band_sum=1.5)
    w_m, i_m = model_at(paper_motor)
    bw, bi = 20.0, 1.921
    cases = [
        # (speed, current) in band shares, profile, expected state, expected depth
        ((0.0, 0.0), testbed_profile, MotorState.NORMAL, 1.0),
        ((-0.5, 2.0), testbed_profile, MotorState.F1_1, 2.0),  # the current, two bands above the model
        ((-3.0, 0.5), testbed_profile, MotorState.F4_1, 3.0),  # the speed, three bands below
        ((2.0, -3.0), testbed_profile, MotorState.F3_1, 2.0),  # both must be out: the lesser counts
        ((2.0, -3.0), joint, MotorState.F3_1, 5.0 / 1.5),  # ... or their sum over the joint sum
        ((-0.8, -0.8), joint, MotorState.F4_1, 1.6 / 1.5),  # departures that agree, just past 1.5
        ((2.5, 0.0), testbed_profile, MotorState.UNKNOWN, 2.5),
    ]
    for (dw, di), profile, state, depth in cases:
        codes, depths = classify_depth(
            profile,
            omega_rad_s=[w_m + dw * bw],
            omega_model_rad_s=[w_m],
            current_a=[i_m + di * bi],
            current_model_a=[i_m],
            voltage_v=[V],
        )
        assert MotorState(int(codes[0])) == state, (dw, di)
        assert depths[0] == pytest.approx(depth, rel=1e-3), (dw, di)


def test_agreeing_departures_name_a_fault_only_where_both_depart_its_way() -> None:
    """The slow look's rule (tree.agreeing_departures): one quantity alone names nothing."""
    from mav_motor_health.diagnosis.tree import agreeing_departures

    bw, bi = 10.0, 0.5  # the (narrowed) bands
    cases = [
        # (speed, current) in shares of the bands -> state, depth
        ((0.0, -3.0), MotorState.NORMAL, 1.0),  # the current alone, far below: a model error?
        ((0.0, 3.0), MotorState.NORMAL, 1.0),
        ((-3.0, 0.0), MotorState.NORMAL, 1.0),
        ((-0.4, -1.2), MotorState.F4_1, 1.6 / 1.5),  # slower and less, adding up to 1.6
        ((-0.9, 0.9), MotorState.F1_1, 1.8 / 1.5),  # slower and more
        ((0.5, -1.2), MotorState.F3_1, 1.7 / 1.5),  # faster and less
        ((-1.2, 0.5), MotorState.NORMAL, 1.0),  # below the speed band, current inside: not friction
        ((-1.2, 1.1), MotorState.F1_1, 2.3 / 1.5),
        ((0.9, 0.9), MotorState.NORMAL, 1.0),  # faster with more: no fault does that
        ((-0.6, -0.6), MotorState.NORMAL, 1.0),  # 1.2 < 1.5
        ((np.nan, -2.0), MotorState.NORMAL, 1.0),
    ]
    dw = np.array([c[0][0] * bw for c in cases])
    di = np.array([c[0][1] * bi for c in cases])
    states, depths = agreeing_departures(dw, di, bw, np.full(dw.size, bi), 1.5)
    for (shares, state, depth), got, got_depth in zip(cases, states, depths):
        assert MotorState(int(got)) == state, shares
        assert got_depth == pytest.approx(depth), shares


def test_current_band_may_differ_above_and_below_the_model(paper_motor) -> None:
    """With a fourth column in ``activity_band`` the current band widens apart on its two sides: a dip
    that the wider side below takes in is NORMAL, the same rise above the model is F1.1; without
    activity both sides are the base band."""
    profile = ThresholdProfile(
        name="sided",
        speed_band_rad_s=20.0,
        current_band_a=((4.0, 0.5), (11.0, 0.5)),
        activity_band=((0.0, 0.0, 0.0, 0.0), (2.0, 0.0, 0.2, 1.0)),
    )
    assert profile.current_halfwidth_a(8.0, 2.0) == pytest.approx(0.7)
    assert profile.current_halfwidth_a(8.0, 2.0, below=True) == pytest.approx(1.5)
    assert profile.current_halfwidth_a(8.0, 1.0, below=True) == pytest.approx(1.0)
    assert profile.current_halfwidth_a(8.0, None, below=True) == pytest.approx(0.5)
    w, i = model_at(paper_motor, 8.0)
    state = classify(
        profile,
        omega_rad_s=[w, w, w, w],
        omega_model_rad_s=w,
        current_a=[i - 1.2, i + 1.2, i - 1.2, i - 1.6],
        current_model_a=i,
        voltage_v=8.0,
        activity_v=[2.0, 2.0, 0.0, 2.0],
    )
    assert list(state) == [MotorState.NORMAL, MotorState.F1_1, MotorState.F4_1, MotorState.F4_1]
    # three columns: the one widening on both sides, as before
    even = ThresholdProfile(
        name="even", current_band_a=((4.0, 0.5),), activity_band=((0.0, 0.0, 0.0), (2.0, 0.0, 0.2))
    )
    assert (
        even.current_halfwidth_a(8.0, 2.0, below=True)
        == even.current_halfwidth_a(8.0, 2.0)
        == pytest.approx(0.7)
    )
