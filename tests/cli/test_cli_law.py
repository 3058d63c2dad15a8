"""``teleopkit search-law``: bad input in one line, and a law file that evaluate runs."""

from __future__ import annotations

import pandas as pd
import pytest

from teleopkit.cli import main
from teleopkit.rl.policy import GainPolicy


@pytest.mark.parametrize(("args", "message"), [
    (["--population", "1"], "'--population': 1 is not in the range"),
    (["--harm", "-1"], "'--harm': -1.0 is not in the range"),
    (["--harm", "inf"], "Invalid value for '--harm': inf is not a finite number"),
    (["--harm", "nan"], "Invalid value for '--harm': nan is not a finite number"),
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
    assert "start: the best constant gains" in said.err
    assert said.out.startswith(("best law at generation", "kept the start gains"))
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


def test_a_search_that_finds_no_better_law_says_so_and_keeps_the_start(monkeypatch, capsys,
                                                                      tmp_path):
    """One generation of two laws (seed 3) finds none better than the start on validation."""
    import numpy as np

    import teleopkit.rl.law_search as law_search

    start = np.array([4.139, 4.139, 10.3475, 18.2949])  # the class's best constant gains
    monkeypatch.setattr(law_search, "law_start", lambda config, progress=None: start)
    out = tmp_path / "law"
    assert main(["search-law", "--harm", "1", "--generations", "1", "--population", "2",
                 "--scenarios", "2", "--seed", "3", "--out", str(out)]) == 0
    said = capsys.readouterr()
    log = pd.read_csv(out / "search_log.csv")
    assert log.loc[1, "validation_cost"] > log.loc[1, "start_cost"]  # the law found is dearer
    warnings = [line for line in said.err.splitlines() if line.startswith("warning:")]
    assert warnings == [
        "warning: no law found beat the start gains on the validation scenarios (the best, at "
        f"generation 1: objective {100 * (log.loc[1, 'validation_objective'] - 1):+.1f} %, "
        f"validation cost {log.loc[1, 'validation_cost']:.5g} against "
        f"{log.loc[1, 'start_cost']:.5g}); {out / 'best_policy.npz'} holds the start gains "
        "themselves (the law with zero weights)"]
    assert said.out.startswith("kept the start gains (generation 0)")
    kept = GainPolicy.load(out / "best_policy.npz")
    assert kept.metadata["generation"] == 0
    obs = np.random.default_rng(0).normal(size=(3, kept.obs_mean.size))
    np.testing.assert_allclose(kept(obs), np.tile(start, (3, 1)), rtol=1e-12)


def test_a_law_dearer_on_average_than_the_start_is_said_to_be(capsys, tmp_path):
    from teleopkit.cli.laws import _report

    log = pd.DataFrame({"generation": [0, 5], "validation_objective": [1.0, 0.9],
                        "validation_cost": [100.0, 120.0], "start_cost": [100.0, 100.0]})
    _report(log, tmp_path / "best_policy.npz")
    said = capsys.readouterr()
    assert said.err.startswith("warning: the law kept costs more on the validation scenarios "
                               "than the start gains on average (120 against 100)")
    assert said.out.startswith("best law at generation 5: validation cost 120 against 100")
