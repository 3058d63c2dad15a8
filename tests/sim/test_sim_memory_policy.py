"""A recorded run may take at most half the memory available: one line otherwise."""

from __future__ import annotations

import pytest

import teleopkit.sim.memory as memory
from teleopkit.sim.scenarios import paper_scenarios
from teleopkit.sim.simulator import Simulator


def test_a_run_that_would_not_fit_is_refused_before_it_starts(monkeypatch):
    sim = Simulator(paper_scenarios(0, batch=4))
    need = sim.record_bytes(100)
    monkeypatch.setattr(memory, "available_memory", lambda: 2 * need - 1)
    with pytest.raises(ValueError, match=r"a run of 1 s of 4 scenario\(s\) records .* GB, more "
                                         "than half"):
        sim.run(1.0)
    monkeypatch.setattr(memory, "available_memory", lambda: 2 * need)
    assert sim.run(1.0).state.shape == (101, 4, 24)
