"""`wbc.checks`: the input checks shared by the core, the robots and the solvers."""

from __future__ import annotations

import numpy as np
import pytest

from wbc.checks import all_finite, check_finite, checked_array
from wbc.errors import NonFiniteError, ShapeError


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", [0, 3, 6])
def test_all_finite_finds_nan_and_inf_anywhere(bad, where):
    x = np.linspace(-1.0, 1.0, 7)
    assert all_finite(x)
    x[where] = bad
    assert not all_finite(x)


def test_all_finite_on_opposite_infinities_and_large_values():
    assert not all_finite(np.array([np.inf, -np.inf]))  # the sum is NaN, not 0
    assert all_finite(np.array([1e300, -1e300, 1e300]))
    assert all_finite(np.zeros(0))


def test_checked_array_shapes_and_messages():
    np.testing.assert_array_equal(checked_array(2.0, (1, 1), "p"), [[2.0]])
    np.testing.assert_array_equal(checked_array([1, 2], (2, 1), "p"), [[1.0], [2.0]])
    assert checked_array(np.eye(2), (2, 2), "p").shape == (2, 2)
    with pytest.raises(ShapeError, match=r"reference 'ee' expects shape \(3,\), got \(2,\)"):
        checked_array([1, 2], (3, 1), "reference 'ee'")
    with pytest.raises(ShapeError, match=r"expects shape \(2, 2\)"):
        checked_array(np.ones(4), (2, 2), "p")
    with pytest.raises(NonFiniteError, match="'J' contains NaN or inf"):
        checked_array([[np.inf]], (1, 1), "'J'")
    bounds = checked_array([-np.inf, 1.0], (2, 1), "bounds", allow_inf=True)
    assert bounds[0, 0] == -np.inf
    with pytest.raises(NonFiniteError, match="contains NaN"):
        checked_array([np.nan, 1.0], (2, 1), "bounds", allow_inf=True)


def test_check_finite_matrix():
    check_finite(np.eye(3), "M")
    M = np.eye(3)
    M[2, 1] = np.nan
    with pytest.raises(NonFiniteError, match="M contains"):
        check_finite(M, "M")
    with pytest.raises(NonFiniteError):
        check_finite(np.asfortranarray(M)[::2], "M")  # non-contiguous views too


def test_checked_vector_without_broadcast_takes_only_a_vector_of_that_length():
    from wbc.checks import checked_vector

    x = np.arange(3.0)
    assert checked_vector(x, 3, "v", broadcast=False) is x  # as is, not copied
    for bad in (1.0, np.ones((1, 3)), np.ones((3, 1)), np.ones(2)):
        with pytest.raises(ShapeError, match=r"v must have shape \(3,\), got"):
            checked_vector(bad, 3, "v", broadcast=False)
    with pytest.raises(NonFiniteError, match="v contains"):
        checked_vector([0.0, np.inf, 0.0], 3, "v", broadcast=False)


def test_checked_2d_takes_any_matrix_but_no_1d_array():
    from wbc.checks import checked_2d

    assert checked_2d(np.zeros((0, 4)), "J").shape == (0, 4)
    assert checked_2d([[1, 2]], "J").dtype == float
    for bad in (np.ones(3), 1.0, np.ones((2, 2, 2))):
        with pytest.raises(ShapeError, match="J must be a 2-D array"):
            checked_2d(bad, "J")
    with pytest.raises(NonFiniteError, match="J contains"):
        checked_2d([[np.nan]], "J")


def test_checked_scalar_refuses_arrays_with_a_shape_error():
    from wbc.checks import checked_scalar
    from wbc.errors import InvalidValueError

    assert checked_scalar(np.array(0.5), "rho") == 0.5 and checked_scalar(2, "rho") == 2.0
    for bad in ([0.1], (0.1, 0.2), np.ones(2)):
        with pytest.raises(ShapeError, match="rho must be a scalar"):
            checked_scalar(bad, "rho")
    with pytest.raises(InvalidValueError, match=r"rho = -1.0: must be >= 0"):
        checked_scalar(-1.0, "rho")
    with pytest.raises(NonFiniteError, match="rho"):
        checked_scalar(np.inf, "rho")


def test_checked_bounds_broadcasts_copies_and_orders():
    from wbc.checks import checked_bounds
    from wbc.errors import BoundsOrderError

    upper = np.array([1.0, np.inf])
    lo, up = checked_bounds(-np.inf, upper, 2, "qd")
    np.testing.assert_array_equal(lo, [-np.inf, -np.inf])
    assert up is not upper and np.array_equal(up, upper)
    with pytest.raises(BoundsOrderError, match="qd: lower > upper at index 1"):
        checked_bounds([0.0, 2.0], [1.0, 1.0], 2, "qd")
    with pytest.raises(NonFiniteError, match="qd: lower contains NaN"):
        checked_bounds([0.0, np.nan], 1.0, 2, "qd")
    with pytest.raises(NonFiniteError, match=r"\+inf"):
        checked_bounds(np.inf, np.inf, 2, "qd")
    with pytest.raises(ShapeError, match="qd: upper"):
        checked_bounds(0.0, np.ones(3), 2, "qd")
