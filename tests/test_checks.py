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
