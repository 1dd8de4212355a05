"""RMSE (paper Eq. 1), zeroing and standard error, checked against values worked out by hand."""

import math

import numpy as np
import pytest

from phri_spring.physics.response.metrics import mean_and_se, rmse, standard_error, zero_on


def test_rmse_zero_when_equal():
    f = np.linspace(-3.0, 7.0, 21)
    assert rmse(f, f) == 0.0


def test_rmse_known_offset_pattern():
    # 7 elements off by +2 N, 14 off by -1 N: sqrt((7*4 + 14*1) / 21) = sqrt(42/21) = sqrt(2)
    sim = np.arange(21, dtype=float)
    meas = sim.copy()
    meas[:7] += 2.0
    meas[7:] -= 1.0
    assert rmse(meas, sim) == pytest.approx(math.sqrt(2.0), abs=1e-12)


def test_rmse_single_element_off():
    # one of 21 elements off by 21 N: sqrt(441 / 21) = sqrt(21)
    meas = np.zeros(21)
    meas[5] = 21.0
    assert rmse(meas, np.zeros(21)) == pytest.approx(math.sqrt(21.0), abs=1e-12)


def test_rmse_is_symmetric_and_uses_n_not_n_minus_1():
    a = np.array([1.0, 2.0, 3.0, 4.0])
    b = np.array([0.0, 0.0, 0.0, 0.0])
    # sqrt((1 + 4 + 9 + 16) / 4) = sqrt(7.5)
    assert rmse(a, b) == pytest.approx(math.sqrt(7.5), abs=1e-12)
    assert rmse(b, a) == pytest.approx(math.sqrt(7.5), abs=1e-12)


def test_rmse_per_row_and_broadcast():
    meas = np.array([[1.0, 1.0, 1.0], [3.0, 0.0, 0.0]])
    sim = np.zeros(3)
    # rows: sqrt(3/3) = 1; sqrt(9/3) = sqrt(3)
    np.testing.assert_allclose(rmse(meas, sim), [1.0, math.sqrt(3.0)], atol=1e-12)


def test_rmse_nan_propagates_and_empty_raises():
    assert math.isnan(rmse([1.0, np.nan], [0.0, 0.0]))
    with pytest.raises(ValueError):
        rmse(np.zeros((2, 0)), np.zeros((2, 0)))


def test_zero_on_subtracts_baseline_row():
    loads = np.array([[1.0, 2.0], [4.0, 2.5], [0.0, 7.0]])
    z = zero_on(loads, loads[0])
    np.testing.assert_allclose(z, [[0.0, 0.0], [3.0, 0.5], [-1.0, 5.0]])


def test_zeroing_removes_constant_offsets_from_rmse():
    rng = np.random.default_rng(3)
    meas = rng.normal(size=(4, 21))
    sim = rng.normal(size=(4, 21))
    offset = rng.uniform(-5, 5, 21)            # a per-sensor offset on every condition
    r0 = rmse(zero_on(meas, meas[0]), zero_on(sim, sim[0]))
    r1 = rmse(zero_on(meas + offset, (meas + offset)[0]), zero_on(sim, sim[0]))
    np.testing.assert_allclose(r0, r1, atol=1e-12)
    assert r0[0] == 0.0


def test_standard_error_of_three_values_by_hand():
    # 1, 2, 4: mean 7/3; squared deviations 16/9 + 1/9 + 25/9 = 42/9; var (ddof 1) = 21/9
    # SD = sqrt(7/3); SE = sqrt(7/3) / sqrt(3) = sqrt(7) / 3
    mean, se = mean_and_se([1.0, 2.0, 4.0])
    assert mean == pytest.approx(7.0 / 3.0, abs=1e-12)
    assert se == pytest.approx(math.sqrt(7.0) / 3.0, abs=1e-12)
    assert standard_error([1.0, 2.0, 4.0]) == pytest.approx(0.881917103688197, abs=1e-12)


def test_standard_error_axis_and_single_sample():
    v = np.array([[1.0, 10.0], [2.0, 10.0], [4.0, 10.0]])
    np.testing.assert_allclose(standard_error(v, axis=0), [math.sqrt(7.0) / 3.0, 0.0],
                               atol=1e-12)
    mean, se = mean_and_se([5.0])
    assert mean == 5.0 and math.isnan(se)
    with pytest.raises(ValueError):
        mean_and_se([])
