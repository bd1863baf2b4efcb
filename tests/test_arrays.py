"""The hot path's replacements of numpy.nan_to_num, numpy.isin and numpy.broadcast_to give numpy's own
arrays (issue 18), and the plain-int state codes are the enum's."""

from __future__ import annotations

import numpy as np
import pytest

from mav_motor_health._arrays import broadcast_to, nan_to_zero, one_of
from mav_motor_health.diagnosis.states import Code, MotorState


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_nan_to_zero_is_nan_to_num(dtype) -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(3, 50)).astype(dtype)
    x[rng.random(x.shape) < 0.2] = np.nan
    x.flat[:4] = [np.inf, -np.inf, -0.0, np.nan]
    for values in (x, x[:, 4:], x[0], x[:, :0], np.where(np.isnan(x), 1.0, x).astype(dtype)[:, 4:]):
        got, want = nan_to_zero(values), np.nan_to_num(values)
        assert got.dtype == want.dtype and got.shape == want.shape
        np.testing.assert_array_equal(got, want)
        np.testing.assert_array_equal(np.signbit(got), np.signbit(want))
        assert not np.shares_memory(got, values)
    np.testing.assert_array_equal(nan_to_zero(np.arange(4)), np.nan_to_num(np.arange(4)))


def test_one_of_is_isin() -> None:
    rng = np.random.default_rng(1)
    states = rng.integers(0, 13, (6, 40)).astype(np.int8)
    for codes in ((), (3,), (1, 3, 4), (2, 5, 7, 8, 10, 12)):
        np.testing.assert_array_equal(one_of(states, codes), np.isin(states, codes))


def test_one_of_takes_enum_members_as_their_codes() -> None:
    states = np.array([[0, 1, 3], [4, 6, 1]], dtype=np.int8)
    codes = (MotorState.F1_1, MotorState.UNKNOWN)
    np.testing.assert_array_equal(one_of(states, codes), np.isin(states, [1, 6]))


def test_broadcast_to_is_numpys_and_gives_an_array_of_that_shape_back_as_it_is() -> None:
    x = np.arange(6.0).reshape(2, 3)
    assert broadcast_to(x, (2, 3)) is x
    for values, shape in ((x[:1], (2, 3)), (x[:, :1], (2, 3)), (2.5, (3,)), (x[0], (4, 3))):
        got, want = broadcast_to(values, shape), np.broadcast_to(values, shape)
        assert got.shape == want.shape and got.dtype == want.dtype
        np.testing.assert_array_equal(got, want)
    with pytest.raises(ValueError):
        broadcast_to(x, (3, 2))


def test_each_plain_state_code_is_its_states() -> None:
    for state in MotorState:
        code = getattr(Code, state.name)
        assert type(code) is int and code == int(state)
