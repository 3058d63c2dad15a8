"""``teleopkit search-law``: bad input in one line, and a law file that evaluate runs."""

from __future__ import annotations

import pandas as pd
import pytest

from teleopkit.cli import main
from teleopkit.rl.policy import GainPolicy


@pytest.mark.parametrize(("args", "message"), [
    (["--population", "1"], "'--population': 1 is not in the range"),
    (["--harm", "-1"], "'--harm': -1.0 is not in the range"),
    (["--gain-variation", "tank:3", "--certificate", __file__],
     "give a --certificate or a --gain-variation, not both"),
    (["--gain-variation", "sometimes"], "--gain-variation"),
])
def test_bad_input_is_one_line_and_exit_2(args, message, capsys, tmp_path):
    assert main(["search-law", "--out", str(tmp_path / "law"), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_a_searched_law_is_a_policy_evaluate_runs(tmp_path, capsys):
    out = tmp_path / "law"
    assert main(["search-law", "--generations", "2", "--population", "3", "--scenarios", "2",
                 "--gain-variation", "frozen", "--out", str(out)]) == 0
    law = GainPolicy.load(out / "best_policy.npz")
    assert law.metadata["observation"] == "adaptive" and law.obs_range is not None
    said = capsys.readouterr()
    assert "start: the best constant gains" in said.err and "best law at generation" in said.out
    assert main(["evaluate", "--policy", str(out / "best_policy.npz"), "--scenarios", "2",
                 "--duration", "2", "--out", str(tmp_path / "eval")]) == 0
    summary = pd.read_csv(tmp_path / "eval" / "summary.csv", index_col=0)
    assert summary.index[0] == "gain law (frozen)"  # named for what it is, not TD3


def test_a_model_failure_is_one_line_and_exit_1(monkeypatch, capsys, tmp_path):
    import teleopkit.rl.law_search as law_search

    def failing(*args, **kwargs):
        raise RuntimeError("a certified controller left the state bound (a model failure)")

    monkeypatch.setattr(law_search, "law_start", failing)
    assert main(["search-law", "--out", str(tmp_path / "law")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == ("teleopkit: error: a certified controller left the state bound (a model "
                       "failure)")
    assert not any("Traceback" in line for line in err)
