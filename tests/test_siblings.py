"""The vehicle stage (diagnosis/siblings.py): each motor's torque against the median of its siblings',
in the order the live agent receives samples, the same whether given whole or in pieces."""

from __future__ import annotations

import warnings

import numpy as np

from mav_motor_health.diagnosis.siblings import VehicleStage, median_of_finite


def rows(values: list[list[float]]) -> np.ndarray:
    return np.array(values, dtype=float)


class SiblingTorque(VehicleStage):
    """The stage with the torque alone (one quantity)."""

    def reference(self, motors, time_s, values, counts, max_age_s):  # type: ignore[no-untyped-def]
        return self.references(motors, time_s, {"torque_residual_nm": values}, counts, max_age_s)[
            "torque_residual_nm"
        ]


def test_a_sample_sees_the_siblings_that_arrived_before_it_time_then_motor_number() -> None:
    stage = SiblingTorque([1, 2, 3, 4])
    t = rows([[0.0, 1.0], [0.0, 1.0], [0.0, 1.0], [0.0, 1.0]])
    v = rows([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]])
    ref = stage.reference([1, 2, 3, 4], t, v, [2, 2, 2, 2], np.full(t.shape, 5.0))
    # at t = 1 motor 1 comes first: its siblings' latest are those of t = 0 (2, 3, 4)
    assert ref[0, 1] == 3.0
    # motor 3 at t = 1: motors 1 and 2 of t = 1 arrived before it, motor 4's latest is of t = 0
    assert ref[2, 1] == 10.0  # median of 10, 20, 4
    # motor 4 at t = 1: every sibling's of t = 1
    assert ref[3, 1] == 20.0
    # at t = 0 motor 1 has no sibling yet; motor 3 only two of three (1 and 2): enough (all but one)
    assert np.isnan(ref[0, 0]) and np.isnan(ref[1, 0])
    assert ref[2, 0] == 1.5 and ref[3, 0] == 2.0


def test_a_stale_sibling_does_not_count_and_two_missing_leave_no_reference() -> None:
    stage = SiblingTorque([1, 2, 3, 4])
    t = rows([[0.0, 2.0], [0.0, 0.0], [0.0, 0.0], [0.0, 1.95]])
    v = rows([[1.0, 1.0], [2.0, np.nan], [3.0, np.nan], [4.0, 5.0]])
    ref = stage.reference([1, 2, 3, 4], t, v, [2, 1, 1, 2], np.full(t.shape, 0.2))
    # motor 1 at t = 2: motors 2 and 3 last spoke at t = 0 (2 s > 0.2 s old): one fresh sibling only
    assert np.isnan(ref[0, 1])
    # padding beyond a row's count is NaN
    assert np.isnan(ref[1, 1]) and np.isnan(ref[2, 1])
    # with a longer age allowed, the same samples give one
    again = SiblingTorque([1, 2, 3, 4]).reference([1, 2, 3, 4], t, v, [2, 1, 1, 2], np.full(t.shape, 5.0))
    assert again[0, 1] == 3.0  # median of 2, 3, 5


def test_pieces_in_arrival_order_give_what_the_whole_gives() -> None:
    rng = np.random.default_rng(17)
    motors = [1, 2, 3, 4, 5, 6]
    n = 400
    # six ESCs at their own rates, some samples lost (NaN), a common drift and each its own noise
    times = [np.sort(rng.uniform(0, 20, n)) for _ in motors]
    values = [np.sin(0.3 * t) + 0.05 * rng.standard_normal(n) for t in times]
    for v in values:
        v[rng.random(n) < 0.05] = np.nan
    age = 0.15
    whole = SiblingTorque(list(motors)).reference(
        motors, np.array(times), np.array(values), [n] * 6, np.full((6, n), age)
    )
    assert np.isfinite(whole).mean() > 0.5
    # the siblings' median follows the common drift: each motor's own noise is what remains
    assert np.nanstd(np.array(values) - whole) < 0.1
    # pieces: every sample before a cut time in one call, the rest in later calls (as the agent gets them)
    stage = SiblingTorque(list(motors))
    pieces = [np.full(n, np.nan) for _ in motors]
    cuts = np.sort(rng.uniform(0, 20, 30))
    done = [0] * 6
    for cut in [*cuts, np.inf]:
        counts = [int(np.searchsorted(t, cut, side="right")) - d for t, d in zip(times, done)]
        width = max(max(counts), 1)
        t_rows, v_rows = np.zeros((6, width)), np.full((6, width), np.nan)
        for r, (d, k) in enumerate(zip(done, counts)):
            t_rows[r, :k], v_rows[r, :k] = times[r][d : d + k], values[r][d : d + k]
        got = stage.reference(motors, t_rows, v_rows, counts, np.full((6, width), age))
        for r, (d, k) in enumerate(zip(done, counts)):
            pieces[r][d : d + k] = got[r, :k]
        done = [d + k for d, k in zip(done, counts)]
    np.testing.assert_array_equal(np.array(pieces), whole)


def test_the_siblings_spread_is_their_median_absolute_deviation_as_a_sigma() -> None:
    """Where asked (``spreads``), the stage gives how far the other motors' values lie from their median:
    their median absolute deviation from it, as a standard deviation (diagnosis/siblings.py, "The
    siblings' spread"); one sibling far off moves it as little as it moves the median."""
    from mav_motor_health.diagnosis.siblings import MAD_TO_SIGMA, SPREAD

    motors = [1, 2, 3, 4, 5, 6]
    t = np.zeros((6, 1))
    v = rows([[1.0], [2.0], [3.0], [4.0], [10.0], [6.0]])
    age = np.full(t.shape, 1.0)
    plain = VehicleStage(list(motors)).references(motors, t, {"torque_residual_nm": v}, [1] * 6, age)
    assert set(plain) == {"torque_residual_nm"}  # not asked: no spread
    stage = VehicleStage(list(motors), spreads=("torque_residual_nm",))
    got = stage.references(motors, t, {"torque_residual_nm": v}, [1] * 6, age)
    spread = got["torque_residual_nm" + SPREAD]
    # motor 6 arrives last: its siblings 1, 2, 3, 4 and 10, median 3, deviations 2, 1, 0, 1, 7
    assert got["torque_residual_nm"][5, 0] == 3.0
    assert spread[5, 0] == MAD_TO_SIGMA * 1.0
    # motor 4 sees 1, 2 and 3 (three: enough): median 2, deviations 1, 0, 1
    assert spread[3, 0] == MAD_TO_SIGMA * 1.0
    # motors 1 to 3 have fewer than three siblings before them: no reference, no spread
    assert np.isnan(spread[:3, 0]).all()
    # the spread comes with the median from the carried values in a later call
    later = stage.references(motors, np.ones((6, 1)), {"torque_residual_nm": v + 100.0}, [1] * 6, age)
    # motor 1 at t = 1: its siblings' carried 2, 3, 4, 10 and 6, median 4, deviations 2, 1, 0, 6, 2
    assert later["torque_residual_nm" + SPREAD][0, 0] == MAD_TO_SIGMA * 2.0


def test_the_median_of_finite_values_needs_enough_of_them() -> None:
    values = rows([[1.0, 5.0, np.nan, 3.0], [np.nan, np.nan, 2.0, np.nan], [4.0, 1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(median_of_finite(values, 2), [3.0, np.nan, 2.5])


def test_the_median_of_a_long_stream_by_the_sorting_network_is_the_median() -> None:
    """A whole log's stream (motors along a short axis, more values than the sort path takes) goes through
    the sorting network: each place's median of its finite values, NaN where fewer than three are, as
    numpy's nanmedian gives, and the same values as sorting a short piece of it."""
    rng = np.random.default_rng(29)
    values = rng.normal(size=(3, 6, 2000))  # quantities × motors × stream places
    values[rng.random(values.shape) < 0.35] = np.nan
    values[0, :, 7] = [1.0, 1.0, np.nan, 1.0, 2.0, -0.0]  # ties and a signed zero
    count = np.isfinite(values).sum(axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # nanmedian of the all-NaN places
        expected = np.where(count >= 3, np.nanmedian(values, axis=1), np.nan)
    long = median_of_finite(values, 3, axis=1)
    assert values.size > 4096 and np.isfinite(long).mean() > 0.5 and set(count.ravel()) >= {0, 3, 6}
    np.testing.assert_array_equal(long, expected)
    np.testing.assert_array_equal(median_of_finite(values[:, :, :50], 3, axis=1), long[:, :50])
    # the rows' layout (motors along the last axis) gives the same
    np.testing.assert_array_equal(median_of_finite(np.moveaxis(values, 1, 2).reshape(-1, 6), 3), long.ravel())


def test_every_quantity_in_one_pass_gives_what_each_alone_gives() -> None:
    """The stage takes several quantities in one pass (the torque and the deviations' live noise): each
    one's references, whole and in pieces with the latest values carried, are those of a stage that
    takes it alone, though the quantities are lost at different samples and so carry different latest
    values and times."""
    rng = np.random.default_rng(23)
    motors = [1, 2, 3, 4, 5, 6]
    n = 300
    times = np.array([np.sort(rng.uniform(0, 15, n)) for _ in motors])
    names = ("torque_residual_nm", "live_z2_speed", "live_z2_current")
    values = {}
    for q, name in enumerate(names):
        v = np.cos((0.2 + 0.1 * q) * times) + 0.05 * rng.standard_normal(times.shape)
        v[rng.random(v.shape) < 0.05 + 0.1 * q] = np.nan
        values[name] = v
    age = np.full(times.shape, 0.2)
    cuts = [*np.sort(rng.uniform(0, 15, 25)), np.inf]

    def in_pieces(stage: VehicleStage, given: tuple[str, ...]) -> dict[str, np.ndarray]:
        got = {name: np.full(times.shape, np.nan) for name in given}
        done = [0] * 6
        for cut in cuts:
            counts = [int(np.searchsorted(t, cut, side="right")) - d for t, d in zip(times, done)]
            width = max(max(counts), 1)
            t_rows = np.zeros((6, width))
            v_rows = {name: np.full((6, width), np.nan) for name in given}
            for r, (d, k) in enumerate(zip(done, counts)):
                t_rows[r, :k] = times[r, d : d + k]
                for name in given:
                    v_rows[name][r, :k] = values[name][r, d : d + k]
            out = stage.references(motors, t_rows, v_rows, counts, np.full((6, width), 0.2))
            for r, (d, k) in enumerate(zip(done, counts)):
                for name in given:
                    got[name][r, d : d + k] = out[name][r, :k]
            done = [d + k for d, k in zip(done, counts)]
        return got

    together = VehicleStage(list(motors)).references(motors, times, values, [n] * 6, age)
    pieces = in_pieces(VehicleStage(list(motors)), names)
    for name in names:
        alone = VehicleStage(list(motors)).references(motors, times, {name: values[name]}, [n] * 6, age)
        assert np.isfinite(alone[name]).mean() > 0.3
        np.testing.assert_array_equal(together[name], alone[name], err_msg=name)
        np.testing.assert_array_equal(pieces[name], alone[name], err_msg=name)
        np.testing.assert_array_equal(in_pieces(VehicleStage(list(motors)), (name,))[name], alone[name])


def test_quantities_lost_at_the_same_samples_give_what_each_alone_gives() -> None:
    """Quantities lost at the same samples (the squared deviations of speed and current, low-passed
    together) share the stage's search for each motor's latest value and which siblings are recent
    enough, and the values they carry to the next call share a place of its stream (siblings.py, "One
    stream for the quantities"): each one's references, whole and in pieces, with a quantity lost
    elsewhere beside them, are those of a stage that takes it alone."""
    rng = np.random.default_rng(29)
    motors = [1, 2, 3, 4, 5, 6]
    n = 300
    times = np.array([np.sort(rng.uniform(0, 15, n)) for _ in motors])
    lost = rng.random(times.shape) < 0.1
    names = ("torque_residual_nm", "live_z2_speed", "live_z2_current")
    values = {}
    for q, name in enumerate(names):
        v = np.cos((0.2 + 0.1 * q) * times) + 0.05 * rng.standard_normal(times.shape)
        v[lost if q > 0 else rng.random(v.shape) < 0.05] = np.nan
        values[name] = v
    speeds = 400.0 + 60.0 * rng.standard_normal(times.shape)
    in_range = rng.random(times.shape) < 0.8
    cuts = [*np.sort(rng.uniform(0, 15, 25)), np.inf]

    def stage() -> VehicleStage:
        return VehicleStage(list(motors), alike={"torque_residual_nm": 0.1}, spreads=("torque_residual_nm",))

    def rows(x: np.ndarray, done: list[int], counts: list[int], fill: float | bool = np.nan) -> np.ndarray:
        """Samples ``done[r]`` on of each row r, ``counts[r]`` of them, as rows padded with ``fill``."""
        out = np.full((6, max(max(counts), 1)), fill, dtype=x.dtype)
        for r, (d, k) in enumerate(zip(done, counts)):
            out[r, :k] = x[r, d : d + k]
        return out

    def in_pieces(given: tuple[str, ...]) -> dict[str, np.ndarray]:
        vehicle = stage()
        got: dict[str, np.ndarray] = {}
        done = [0] * 6
        for cut in cuts:
            counts = [int(np.searchsorted(t, cut, side="right")) - d for t, d in zip(times, done)]
            found = vehicle.references(
                motors,
                rows(times, done, counts),
                {name: rows(values[name], done, counts) for name in given},
                counts,
                rows(np.full(times.shape, 0.2), done, counts),
                rows(speeds, done, counts),
                rows(in_range, done, counts, False),
            )
            for key, x in found.items():
                into = got.setdefault(key, np.full(times.shape, np.nan))
                for r, (d, k) in enumerate(zip(done, counts)):
                    into[r, d : d + k] = x[r, :k]
            done = [d + k for d, k in zip(done, counts)]
        return got

    age = np.full(times.shape, 0.2)
    together = stage().references(motors, times, values, [n] * 6, age, speeds, in_range)
    pieces = in_pieces(names)
    for name in names:
        alone = stage().references(motors, times, {name: values[name]}, [n] * 6, age, speeds, in_range)
        assert np.isfinite(alone[name]).mean() > 0.3
        for key in alone:
            np.testing.assert_array_equal(together[key], alone[key], err_msg=key)
            np.testing.assert_array_equal(pieces[key], alone[key], err_msg=key)


def test_three_siblings_make_a_reference_on_a_hexacopter() -> None:
    """A median of three holds against one sibling that departs: on a hexacopter two silent siblings
    leave a reference, three do not; a quadcopter still needs all but one (two)."""
    t = np.zeros((6, 1))
    v = rows([[1.0], [2.0], [np.nan], [np.nan], [3.0], [9.0]])
    ref = SiblingTorque([1, 2, 3, 4, 5, 6]).reference(
        [1, 2, 3, 4, 5, 6], t, v, [1] * 6, np.full(t.shape, 1.0)
    )
    assert ref[5, 0] == 2.0  # motor 6: the median of 1, 2, 3 (motors 3 and 4 silent)
    assert np.isnan(ref[0, 0])  # motor 1 arrives first (same time, lowest number): no sibling before it
    v[4, 0] = np.nan  # three silent: two left for motor 6
    ref = SiblingTorque([1, 2, 3, 4, 5, 6]).reference(
        [1, 2, 3, 4, 5, 6], t, v, [1] * 6, np.full(t.shape, 1.0)
    )
    assert np.isnan(ref[5, 0])


def test_a_sibling_beyond_its_identified_speeds_is_a_reference_only_at_this_motors_speed() -> None:
    """The torque's model error depends on the speed: a sibling whose model is carried beyond its identified
    speeds is a reference only for a motor within ``alike`` (a share of its speed) of its own; one in its
    range is a reference at any speed (held-out world 1018: three motors saturated at 422 rad/s, a third
    beyond their identified top, lifted the median of a motor at 343 rad/s, docs/flight.md)."""
    motors = [1, 2, 3, 4, 5, 6]
    t = np.arange(6)[:, None] * 0.01  # motors 1..6 arrive in turn: motor 6 sees every sibling's
    v = rows([[0.02], [0.065], [0.025], [0.068], [0.067], [0.019]])
    speed = rows([[342.0], [422.0], [338.0], [421.0], [422.0], [343.0]])
    beyond = rows([[1], [0], [1], [0], [0], [1]]).astype(bool)  # 2, 4, 5 beyond their range
    age = np.full(t.shape, 1.0)

    def reference(stage: VehicleStage, in_range: np.ndarray | None) -> np.ndarray:
        args = (None, None) if in_range is None else (speed, in_range)
        return stage.references(motors, t, {"torque_residual_nm": v}, [1] * 6, age, *args)[
            "torque_residual_nm"
        ]

    every = reference(VehicleStage(list(motors)), None)
    assert (
        every[5, 0] == 0.065
    )  # motor 6 against 0.02, 0.065, 0.025, 0.068, 0.067: the saturated three lift it
    alike = {"torque_residual_nm": 0.1}
    # those beyond their range at another speed do not count: two siblings left, no reference
    assert np.isnan(reference(VehicleStage(list(motors), alike=alike), beyond)[5, 0])
    # all in their range: every sibling counts, whatever its speed
    np.testing.assert_array_equal(
        reference(VehicleStage(list(motors), alike=alike), np.ones((6, 1), bool)), every
    )
    # beyond their range but at motor 6's speed: they count
    speed[[1, 3, 4], 0] = [350.0, 345.0, 330.0]
    assert reference(VehicleStage(list(motors), alike=alike), beyond)[5, 0] == 0.065


def test_with_speeds_pieces_give_what_the_whole_gives() -> None:
    """The latest value of each motor carries its speed and whether it lay in the identified range: a
    split of the samples into calls gives the references of the whole."""
    rng = np.random.default_rng(29)
    motors = [1, 2, 3, 4, 5, 6]
    n = 300
    times = np.array([np.sort(rng.uniform(0, 15, n)) for _ in motors])
    values = np.sin(0.3 * times) + 0.05 * rng.standard_normal(times.shape)
    values[rng.random(times.shape) < 0.05] = np.nan
    speeds = 400.0 + 60.0 * rng.standard_normal(times.shape)
    in_range = rng.random(times.shape) < 0.6
    alike = {"torque_residual_nm": 0.1}
    whole = VehicleStage(list(motors), alike=alike).references(
        motors, times, {"torque_residual_nm": values}, [n] * 6, np.full(times.shape, 0.3), speeds, in_range
    )["torque_residual_nm"]
    assert 0.2 < np.isfinite(whole).mean() < 0.95  # some samples lose their reference, most keep one
    stage = VehicleStage(list(motors), alike=alike)
    pieces = np.full(times.shape, np.nan)
    done = [0] * 6
    for cut in [*np.sort(rng.uniform(0, 15, 25)), np.inf]:
        counts = [int(np.searchsorted(t, cut, side="right")) - d for t, d in zip(times, done)]
        width = max(max(counts), 1)
        cols = [np.zeros((6, width)), np.full((6, width), np.nan), np.full((6, width), np.nan)]
        inside = np.zeros((6, width), dtype=bool)
        for r, (d, k) in enumerate(zip(done, counts)):
            cols[0][r, :k], cols[1][r, :k] = times[r, d : d + k], values[r, d : d + k]
            cols[2][r, :k], inside[r, :k] = speeds[r, d : d + k], in_range[r, d : d + k]
        out = stage.references(
            motors,
            cols[0],
            {"torque_residual_nm": cols[1]},
            counts,
            np.full((6, width), 0.3),
            cols[2],
            inside,
        )["torque_residual_nm"]
        for r, (d, k) in enumerate(zip(done, counts)):
            pieces[r, d : d + k] = out[r, :k]
        done = [d + k for d, k in zip(done, counts)]
    np.testing.assert_array_equal(pieces, whole)


def test_a_whole_log_worked_out_in_parts_gives_the_references_of_one_call(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A call longer than the stage's part (a whole log: :data:`~.siblings.STREAM_CHUNK`) is worked out
    as consecutive calls cut between instants: every quantity's references, the siblings' prediction's
    included, and the latest values it carries to the next call, are those of one call over it all.
    The motors report on one clock (many instants shared by several motors, which a cut must not split)
    and each loses some samples."""
    from mav_motor_health.diagnosis import siblings
    from mav_motor_health.diagnosis.prediction import SiblingPrediction

    rng = np.random.default_rng(31)
    motors = [1, 2, 3, 4, 5, 6]
    n = 700
    # every motor on the same 50-Hz clock, each with its own dropped samples: shared instants
    clock = np.arange(900) * 0.02
    times = np.array([np.sort(rng.choice(clock, n, replace=False)) for _ in motors])
    names = [name for name, _ in siblings.STAGE_QUANTITIES]
    values = {}
    for q, name in enumerate(names):
        v = np.cos((0.2 + 0.1 * q) * times) + 0.05 * rng.standard_normal(times.shape)
        v[rng.random(v.shape) < 0.05 + 0.05 * q] = np.nan
        values[name] = v
    speeds = 400.0 + 60.0 * rng.standard_normal(times.shape)
    in_range = rng.random(times.shape) < 0.9
    age = np.full(times.shape, 0.1)
    angle = np.deg2rad([0, 180, 300, 120, 60, 240])
    mix = np.column_stack([np.ones(6), np.cos(angle), np.sin(angle)])
    sigma = mix @ np.diag([4.0, 9.0, 9.0]) @ mix.T + np.diag(np.full(6, 2.0))
    cov = {m: tuple((o, float(sigma[i, j])) for j, o in enumerate(motors)) for i, m in enumerate(motors)}
    prediction = SiblingPrediction.of(cov, cov, exclude_sigmas=2.5)
    assert prediction is not None

    def run() -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict]:  # type: ignore[type-arg]
        stage = VehicleStage(
            list(motors),
            alike={"torque_residual_nm": 0.1},
            prediction=prediction,
            spreads=("torque_residual_nm",),
        )
        first = stage.references(motors, times, values, [n] * 6, age, speeds, in_range)
        later = {name: v[:, :50] for name, v in values.items()}
        second = stage.references(
            motors, times[:, :50] + 20.0, later, [50] * 6, age[:, :50], speeds[:, :50], in_range[:, :50]
        )
        return first, second, stage.latest

    monkeypatch.setattr(siblings, "STREAM_CHUNK", 10**9)
    whole = run()
    monkeypatch.setattr(siblings, "STREAM_CHUNK", 97)
    assert siblings._chunks(times, [n] * 6) is not None  # the call is cut into parts
    assert siblings._chunks(times, [n] * 6).shape[1] > 30
    parts = run()
    assert set(whole[0]) == {*names, "torque_residual_nm" + siblings.SPREAD}
    for name in whole[0]:
        assert np.isfinite(whole[0][name]).mean() > 0.2, name
        np.testing.assert_array_equal(parts[0][name], whole[0][name], err_msg=name)
        np.testing.assert_array_equal(parts[1][name], whole[1][name], err_msg=name)
    assert parts[2] == whole[2]


def test_a_whole_log_at_one_instant_is_one_call(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A log whose samples share one time stamp (broken time stamps) is not cut at all: one call."""
    from mav_motor_health.diagnosis import siblings

    monkeypatch.setattr(siblings, "STREAM_CHUNK", 5)
    times = np.zeros((6, 40))
    values = np.arange(240, dtype=float).reshape(6, 40)
    assert siblings._chunks(times, [40] * 6) is None
    got = SiblingTorque([1, 2, 3, 4, 5, 6]).reference(
        [1, 2, 3, 4, 5, 6], times, values, [40] * 6, np.ones((6, 40))
    )
    assert np.isfinite(got).any()
