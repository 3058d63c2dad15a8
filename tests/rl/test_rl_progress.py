"""Progress of the long rl calls: records while they run, a status line only where asked."""

from __future__ import annotations

import inspect
import io
import logging
import sys

import numpy as np
import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.rl.baselines import best_semi_active, best_static_gains
from teleopkit.rl.comparison import Comparators, compare
from teleopkit.rl.env import FlexTeleopConfig
from teleopkit.rl.reproduction import reproduce

SHORT = FlexTeleopConfig(episode_length=0.2)


class Terminal(io.StringIO):
    """Standard error as a terminal."""

    def isatty(self) -> bool:
        return True


def search_static(progress: bool | None = None) -> None:
    best_static_gains(scenarios=2, grid_points=2, max_evaluations=3, config=SHORT,
                      progress=progress)


@pytest.mark.parametrize("function", [best_static_gains, best_semi_active, compare, reproduce])
def test_the_long_calls_take_progress(function):
    parameter = inspect.signature(function).parameters["progress"]
    assert parameter.default is None and parameter.kind is parameter.POSITIONAL_OR_KEYWORD


def test_the_static_search_logs_the_grid_and_each_evaluation(caplog):
    with caplog.at_level(logging.INFO, logger="teleopkit"):
        search_static(progress=False)
    messages = [r.getMessage() for r in caplog.records if r.name == "teleopkit.rl.baselines"]
    assert messages[0].startswith("best static gains: simulating") and "grid" in messages[0]
    assert messages[1].startswith("best static gains: evaluation 1 (budget 3), best cost")


def test_the_semi_active_search_logs_each_evaluation(caplog):
    with caplog.at_level(logging.INFO, logger="teleopkit"):
        best_semi_active(SHORT, scenarios=2, max_evaluations=2, progress=False)
    assert any(r.getMessage().startswith("semi-active law: evaluation 1 (budget 2)")
               for r in caplog.records)


def test_the_comparison_logs_its_rows(policy, caplog):
    static = np.array([3.0, 7.0, 8.0, 18.0])
    key = Comparators.key(default_certificate(), FlexTeleopConfig())
    frozen = Comparators("frozen", key, static, static,
                         None, None)
    with caplog.at_level(logging.INFO, logger="teleopkit"):
        table = compare([policy], 1, 5, duration=0.2, comparators=frozen, progress=False)
    rows = [r.getMessage() for r in caplog.records if r.name == "teleopkit.rl.comparison"]
    assert rows == [f"comparison: row {i + 1} of 3, {name} on 1 scenarios"
                    for i, name in enumerate(["TD3 (frozen)", "best static", "fixed"])]
    assert list(dict.fromkeys(table["controller"])) == ["TD3 (frozen)", "best static", "fixed"]
    assert list(table.index) == list(range(len(table)))


@pytest.mark.parametrize(("terminal", "progress"), [(True, False), (False, None)])
def test_nothing_on_stderr_when_off_or_redirected(capsys, monkeypatch, terminal, progress):
    if terminal:
        monkeypatch.setattr(sys, "stderr", Terminal())
    search_static(progress)
    written = sys.stderr.getvalue() if terminal else capsys.readouterr().err
    assert written == ""


def test_a_status_line_on_a_terminal(monkeypatch):
    monkeypatch.setattr(sys, "stderr", Terminal())
    search_static()
    written = sys.stderr.getvalue()
    assert written.startswith("\r\033[K[") and written.endswith("\r\033[K")
    assert "best static gains: evaluation 3 (budget 3)" in written and "\n" not in written
