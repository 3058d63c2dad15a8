from __future__ import annotations

import numpy as np
import pytest

from certify import LinearDelaySystem, PolytopicDelaySystem


def test_fields_are_frozen_arrays(benchmark_system):
    assert benchmark_system.n == 2 and benchmark_system.m == 1
    assert isinstance(benchmark_system.A, tuple)
    with pytest.raises(ValueError):
        benchmark_system.A0[0, 0] = 1.0
    np.testing.assert_array_equal(benchmark_system.E_matrix, np.eye(2))


def test_scalars_become_1x1():
    sys = LinearDelaySystem(0.0, [-1.0])
    assert sys.A0.shape == (1, 1) and sys.A[0].shape == (1, 1)


def test_explicit_form_solves_with_E():
    e = np.diag([2.0, 4.0])
    sys = LinearDelaySystem(e @ np.eye(2), [e @ np.ones((2, 2))], E=e)
    a0, (a1,) = sys.explicit()
    np.testing.assert_allclose(a0, np.eye(2))
    np.testing.assert_allclose(a1, np.ones((2, 2)))


def test_dict_round_trip(benchmark_system):
    back = LinearDelaySystem.from_dict(benchmark_system.to_dict())
    np.testing.assert_array_equal(back.A0, benchmark_system.A0)
    np.testing.assert_array_equal(back.A[0], benchmark_system.A[0])
    assert back.E is None


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"A0": np.ones((2, 3)), "A": [np.ones((2, 2))]}, "square"),
        ({"A0": np.eye(2), "A": [np.eye(3)]}, "shape"),
        ({"A0": np.eye(2), "A": []}, "at least one"),
        ({"A0": np.array([[np.nan, 0], [0, 1]]), "A": [np.eye(2)]}, "NaN"),
        ({"A0": np.eye(2), "A": [np.full((2, 2), np.inf)]}, "NaN or inf"),
        ({"A0": np.eye(2), "A": [np.eye(2)], "E": np.zeros((2, 2))}, "singular"),
        ({"A0": np.eye(2), "A": [np.eye(2)], "E": np.eye(3)}, "shape"),
        ({"A0": np.eye(2), "A": np.eye(2)}, "sequence"),
        ({"A0": "abc", "A": [np.eye(2)]}, "numeric"),
    ],
)
def test_bad_input_raises_clear_value_error(kwargs, message):
    with pytest.raises(ValueError, match=message) as info:
        LinearDelaySystem(**kwargs)
    assert "\n" not in str(info.value)


def test_polytope_validation_and_points(benchmark_system):
    other = LinearDelaySystem(2 * benchmark_system.A0, [benchmark_system.A[0]])
    poly = PolytopicDelaySystem.polytope([benchmark_system, other])
    mid = poly.point([0.5, 0.5])
    np.testing.assert_allclose(mid.A0, 1.5 * benchmark_system.A0)
    with pytest.raises(ValueError, match="at least one vertex"):
        PolytopicDelaySystem(())
    with pytest.raises(ValueError, match="vertex 1"):
        PolytopicDelaySystem((benchmark_system, LinearDelaySystem(0.0, [1.0])))
    with pytest.raises(ValueError, match="weights"):
        poly.point([0.7, 0.7])


def test_polytope_variation(benchmark_system):
    frozen = PolytopicDelaySystem.polytope([benchmark_system], variation="frozen")
    assert frozen.frozen and not PolytopicDelaySystem((benchmark_system,)).frozen
    with pytest.raises(ValueError, match="variation"):
        PolytopicDelaySystem((benchmark_system,), variation="sometimes")
