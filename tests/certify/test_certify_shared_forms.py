"""One DPP problem per structure: systems of the same structure share it, and get the answers of
a problem built for them alone; other processes read it back instead of compiling it again."""

from __future__ import annotations

import numpy as np
import pytest

from certify import AffineUncertainty, Direction, PolytopicDelaySystem, form_store, max_delay
from certify import solve as solve_module
from certify.methods import get_method
from certify.solve import SHARED_FORMS, LMIProblem

CORNER = np.array([[1.0, 0.0], [0.0, 0.0]])
DIRECTIONS = (Direction(CORNER, (0.5 * CORNER,)),)


def _family(benchmark_system, low: float, high: float, rates=None) -> PolytopicDelaySystem:
    """The benchmark with ``A0[0, 0]`` and ``A1[0, 0]`` moving along one direction."""
    return PolytopicDelaySystem((benchmark_system,), "switching",
                                AffineUncertainty(DIRECTIONS, [[low], [high]], rates=rates))


@pytest.fixture
def no_shared_forms(monkeypatch):
    monkeypatch.setattr(solve_module, "_SHARED", type(solve_module._SHARED)())


def _alone(system: PolytopicDelaySystem) -> float:
    solve_module._SHARED.clear()
    return max_delay(system, "rcc", rtol=1e-4)


def test_systems_of_one_structure_share_one_dpp_problem(benchmark_system, no_shared_forms):
    first = LMIProblem(_family(benchmark_system, -0.5, 0.1), get_method("rcc"), None)
    second = LMIProblem(_family(benchmark_system, -0.2, 0.4), get_method("rcc"), None)
    assert first.problem is second.problem and first.problem.is_dpp()
    other = LMIProblem(PolytopicDelaySystem((benchmark_system,)), get_method("rcc"), None)
    assert other.problem is not first.problem  # no uncertainty: another structure


@pytest.mark.parametrize("ranges", [((-0.5, 0.1), (-0.2, 0.4)), ((-0.2, 0.4), (-0.5, 0.1))])
def test_a_shared_problem_answers_as_one_built_alone(benchmark_system, no_shared_forms, ranges):
    systems = [_family(benchmark_system, *r) for r in ranges]
    alone = [_alone(system) for system in systems]
    solve_module._SHARED.clear()
    shared = [max_delay(system, "rcc", rtol=1e-4) for system in systems]
    assert shared == pytest.approx(alone, rel=1e-6)
    assert alone[0] != pytest.approx(alone[1], rel=1e-2)  # the systems differ
    cert = LMIProblem(systems[1], get_method("rcc"), None).solve([0.9 * shared[1]])
    assert cert.certified and cert.verify()


def test_a_storage_on_rate_bounded_parameters_keeps_its_own_problem(benchmark_system,
                                                                     no_shared_forms):
    systems = [_family(benchmark_system, -0.5, 0.1, rates=[0.1]),
               _family(benchmark_system, -0.2, 0.4, rates=[0.1])]
    first, second = (LMIProblem(s, get_method("rcc"), None) for s in systems)
    assert first.problem is not second.problem and not solve_module._SHARED


def test_at_most_shared_forms_are_kept(benchmark_system, no_shared_forms):
    for count in range(SHARED_FORMS + 3):  # a new number of points each time: a new structure
        points = np.linspace(-0.5, 0.1, count + 2)[:, None]
        LMIProblem(PolytopicDelaySystem((benchmark_system,), "switching",
                                        AffineUncertainty(DIRECTIONS, points)),
                   get_method("rcc"), None)
    assert sum(len(forms) for forms in solve_module._SHARED.values()) == SHARED_FORMS


@pytest.fixture
def shared_directory(tmp_path, no_shared_forms):
    form_store.share_forms(tmp_path)
    yield tmp_path
    form_store.share_forms(None)


def test_a_compiled_problem_is_read_back_instead_of_compiled_again(benchmark_system,
                                                                   shared_directory,
                                                                   monkeypatch):
    systems = [_family(benchmark_system, *r) for r in ((-0.5, 0.1), (-0.2, 0.4))]
    alone = max_delay(systems[1], "rcc", rtol=1e-4)  # compiled here, saved
    assert len(list(shared_directory.glob("*.pickle"))) == 1
    solve_module._SHARED.clear()  # as in another process of the run

    def no_compile(self):
        raise AssertionError("compiled again")

    monkeypatch.setattr(solve_module._Form, "compile", no_compile)
    assert max_delay(systems[1], "rcc", rtol=1e-4) == pytest.approx(alone, rel=1e-9)
    cert = LMIProblem(systems[0], get_method("rcc"), None).solve([0.5])
    assert cert.certified and cert.verify()


def test_an_unreadable_shared_problem_is_compiled_again(benchmark_system, shared_directory):
    system = _family(benchmark_system, -0.5, 0.1)
    expected = max_delay(system, "rcc", rtol=1e-4)
    (saved,) = shared_directory.glob("*.pickle")
    saved.write_bytes(b"not a pickle")
    solve_module._SHARED.clear()
    assert max_delay(system, "rcc", rtol=1e-4) == pytest.approx(expected, rel=1e-9)


def test_a_process_that_stops_sharing_reads_nothing_back(tmp_path):
    form_store.share_forms(tmp_path)
    form_store.save_form(("key",), {"problem": 1})
    assert form_store.load_form(("key",)) == {"problem": 1}
    assert form_store.load_form(("other",)) is None
    form_store.share_forms(None)
    assert form_store.load_form(("key",)) is None
    form_store.save_form(("new",), {"problem": 2})
    assert len(list(tmp_path.iterdir())) == 1


def test_problems_are_shared_only_through_a_directory(tmp_path):
    with pytest.raises(ValueError, match="not a directory"):
        form_store.share_forms(tmp_path / "missing")
    assert form_store.shared_directory() is None
