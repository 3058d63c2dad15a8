"""teleopkit.progress and the commands' --progress: one status line, only where asked."""

from __future__ import annotations

import io
import logging
import sys

import pytest

from teleopkit.cli.options import progress as command_progress
from teleopkit.progress import reports_progress, show_progress

LOG = logging.getLogger("teleopkit.tests")


class Terminal(io.StringIO):
    """Standard error as a terminal."""

    def isatty(self) -> bool:
        return True


@reports_progress
def work(steps: int = 2, progress: bool | None = None) -> int:
    """Log ``steps`` progress records, then a warning."""
    for step in range(steps):
        LOG.info("step %d", step + 1)
    LOG.warning("careful")
    return steps


def as_terminal(monkeypatch: pytest.MonkeyPatch) -> Terminal:
    """Standard error replaced by a terminal (in the test: capturing resets it between steps)."""
    stream = Terminal()
    monkeypatch.setattr(sys, "stderr", stream)
    return stream


def test_a_terminal_gets_one_status_line_cleared_for_a_warning(monkeypatch):
    terminal = as_terminal(monkeypatch)
    assert work() == 2
    written = terminal.getvalue()
    assert written.startswith("\r\033[K[") and "] step 1\r\033[K[" in written
    assert written.endswith("] step 2\r\033[K") and "\n" not in written  # cleared once


def test_progress_true_writes_lines_where_stderr_is_no_terminal(capsys):
    work(progress=True)
    lines = capsys.readouterr().err.splitlines()
    assert [line.split("] ")[1] for line in lines] == ["step 1", "step 2"]
    assert not any("\r" in line for line in lines)


def test_an_inner_call_follows_the_outer_choice(monkeypatch):
    terminal = as_terminal(monkeypatch)
    with show_progress(False):
        work(progress=True)
    assert terminal.getvalue() == ""
    with show_progress(True):
        work(progress=False)
    assert terminal.getvalue().count("step") == 2


def test_records_reach_logging_you_set_up_as_well(monkeypatch, caplog):
    terminal = as_terminal(monkeypatch)
    with caplog.at_level(logging.INFO, logger="teleopkit"):
        work()
    assert [r.getMessage() for r in caplog.records] == ["step 1", "step 2", "careful"]
    assert terminal.getvalue().count("step") == 2


def test_only_the_records_nobody_asked_for_stay_off_the_root_handlers(monkeypatch):
    as_terminal(monkeypatch)
    seen: list[logging.LogRecord] = []
    handler = logging.Handler()
    handler.emit = seen.append  # type: ignore[method-assign]
    logging.getLogger().addHandler(handler)
    try:
        work()
    finally:
        logging.getLogger().removeHandler(handler)
    assert [r.getMessage() for r in seen if r.name == LOG.name] == ["careful"]


@pytest.mark.parametrize(("enabled", "shown"), [(True, True), (False, False)])
def test_the_progress_option_shows_on_a_terminal_only(monkeypatch, capsys, enabled, shown):
    terminal = as_terminal(monkeypatch)
    with command_progress(enabled):
        work()
    assert ("step 2" in terminal.getvalue()) is shown
    monkeypatch.undo()  # back to the captured, redirected stderr
    with command_progress(enabled):
        work()
    assert capsys.readouterr().err == ""
