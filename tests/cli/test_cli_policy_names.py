"""``teleopkit evaluate --policy NAME``: the shipped policies by name, paths as before."""

from __future__ import annotations

import pandas as pd
import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.cli import main
from teleopkit.rl.policy import SHIPPED_POLICIES


def error_line(capsys: pytest.CaptureFixture[str]) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def test_the_help_names_every_shipped_policy(capsys):
    assert main(["evaluate", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--policy FILE|NAME" in text
    assert all(f"{name} (" in text for name in SHIPPED_POLICIES)


def test_evaluate_runs_a_shipped_policy_by_name(tmp_path, capsys):
    out = tmp_path / "report"
    code = main(["evaluate", "--policy", "paper", "--scenarios", "1", "--duration", "0.2",
                 "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert "| TD3 (frozen) |" in capsys.readouterr().out
    assert pd.read_csv(out / "summary.csv", index_col=0).index[0] == "TD3 (frozen)"


def test_a_name_reaches_the_policy_it_names(tmp_path, capsys):
    """The covered tuner's class (tank:3) is read from the file the name stands for."""
    frozen = tmp_path / "frozen.json"
    frozen.write_text(default_certificate().to_json())
    code = main(["evaluate", "--policy", "covered", "--certificate", str(frozen), "--out",
                 str(tmp_path / "out")])
    assert code == 2
    assert "class frozen does not cover the policy's class tank:3" in error_line(capsys)


@pytest.mark.parametrize(("value", "message"), [
    ("coverd", "coverd is neither a policy file nor a shipped policy (covered, law, paper)"),
    ("{tmp}/missing.npz", "File '{tmp}/missing.npz' does not exist."),
    ("{tmp}", "File '{tmp}' is a directory."),
])
def test_a_bad_policy_is_one_line(tmp_path, capsys, value, message):
    code = main(["evaluate", "--policy", value.format(tmp=tmp_path), "--out",
                 str(tmp_path / "out")])
    assert code == 2
    assert error_line(capsys) == ("teleopkit: error: Invalid value for '--policy': "
                                  + message.format(tmp=tmp_path))
