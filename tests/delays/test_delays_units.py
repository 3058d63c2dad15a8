"""Tests of teleopkit.delays.units: times in seconds unless they carry a unit."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.delays import TraceDelay, parse_delay
from teleopkit.sim.simulator import simulate


def test_units_of_a_trace_come_from_its_column_names(tmp_path):
    (tmp_path / "ms.csv").write_text("t,delay_ms\n0,300\n2,310\n")
    (tmp_path / "s.csv").write_text("time_s,latency\n0,0.3\n2000,0.31\n")
    in_ms = TraceDelay.from_csv(tmp_path / "ms.csv")
    np.testing.assert_allclose(in_ms.delays, [0.3, 0.31])
    np.testing.assert_allclose(TraceDelay.from_csv(tmp_path / "s.csv", unit="ms").times,
                               [0.0, 2000.0])  # the suffix wins over the unit option
    plain = tmp_path / "plain.csv"
    plain.write_text("t,delay\n0,300\n1000,310\n")
    np.testing.assert_allclose(TraceDelay.from_csv(plain, unit="ms").delays, [0.3, 0.31])
    assert parse_delay("constant:500ms")[0].bound == pytest.approx(0.5)


def test_a_float_delay_is_a_constant_one_in_seconds():
    table = simulate((10.0, 30.0), duration=1.0, delay=0.2)
    assert table["Tl"].eq(0.2).all() and table["Tr"].eq(0.2).all()
