"""Progress of an LMI certification from Python: records, and a status line only where asked."""

from __future__ import annotations

import io
import logging
import sys

import pytest

from teleopkit.certification import certify_gains
from teleopkit.certification.gain_sets import GainBox
from teleopkit.model.params import one_joint_setup

BOX = GainBox.uniform((1.0, 50.0), (1.0, 150.0), n_joints=1)  # searched: not all certified


class Terminal(io.StringIO):
    """Standard error as a terminal."""

    def isatty(self) -> bool:
        return True


def certify(progress: bool | None = None) -> None:
    certify_gains(one_joint_setup(), BOX, 1.0, 1.0, method="lmi", workers=1, progress=progress)


def test_an_lmi_certification_logs_its_search(caplog):
    with caplog.at_level(logging.INFO, logger="teleopkit"):
        certify(progress=False)
    messages = [r.getMessage() for r in caplog.records
                if r.name.startswith("teleopkit.certification")]
    assert messages and messages[0].startswith("largest certified cut: trying s = 1")


def test_a_status_line_on_a_terminal_and_the_logger_left_as_it_was(monkeypatch):
    log = logging.getLogger("teleopkit")
    before = (log.level, log.propagate, list(log.handlers))
    monkeypatch.setattr(sys, "stderr", Terminal())
    certify()
    written = sys.stderr.getvalue()
    assert written.startswith("\r\033[K[") and "] largest certified cut: trying s =" in written
    assert written.endswith("\r\033[K") and "\n" not in written
    assert (log.level, log.propagate, list(log.handlers)) == before


@pytest.mark.parametrize(("terminal", "progress"), [(True, False), (False, None)])
def test_nothing_on_stderr_when_off_or_redirected(capsys, monkeypatch, terminal, progress):
    if terminal:
        monkeypatch.setattr(sys, "stderr", Terminal())
    certify(progress)
    written = sys.stderr.getvalue() if terminal else capsys.readouterr().err
    assert written == ""
