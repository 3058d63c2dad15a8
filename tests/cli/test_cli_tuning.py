"""Tests of teleopkit.cli.tuning: the train, evaluate and reproduce commands."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from law_helpers import still_law

from teleopkit.certification import certify_gains
from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.gain_sets import GainBox
from teleopkit.cli import main
from teleopkit.model.params import paper_setup
from teleopkit.rl.policy import PRETRAINED_COVERED

BOX = GainBox.uniform((5.0, 20.0), (30.0, 100.0))


def teleopkit(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "teleopkit.cli", *args], capture_output=True,
                          text=True, timeout=300,
                          env={**os.environ, "NUMBA_NUM_THREADS": "1"})


def test_evaluate_command_takes_a_certificate_file(policy, tmp_path):
    path = tmp_path / "policy.npz"
    policy.save(path)
    certificate = tmp_path / "certificate.json"
    certificate.write_text(certify_gains(paper_setup(), BOX, 1.0, 1.0).to_json())
    done = teleopkit("evaluate", "--policy", str(path), "--scenarios", "2", "--duration", "0.3",
                     "--certificate", str(certificate), "--out", str(tmp_path / "report"))
    assert done.returncode == 0, done.stderr
    assert "finding the comparators" in done.stderr and "unsafe actions: 0" in done.stdout


def test_evaluate_command_writes_the_report(policy, tmp_path):
    path = tmp_path / "policy.npz"
    policy.save(path)
    done = teleopkit("evaluate", "--policy", str(path), "--scenarios", "2", "--duration", "0.3",
                     "--out", str(tmp_path / "report"))
    assert done.returncode == 0, done.stderr
    assert "| TD3 (frozen) |" in done.stdout and "unsafe actions: 0" in done.stdout
    summary = pd.read_csv(tmp_path / "report" / "summary.csv", index_col=0)
    assert list(summary.index) == ["TD3 (frozen)", "best static", "fixed"]
    assert {"cost_opening", "cost_rest"} <= set(summary.columns)
    np.testing.assert_allclose(summary["cost_opening"] + summary["cost_rest"], summary["cost"])


@pytest.mark.parametrize(("args", "needle"), [
    (["train", "--steps", "0"], "--steps"),
    (["train", "--envs", "-2"], "--envs"),
    (["train", "--seed", "x"], "--seed"),
    (["evaluate"], "--policy"),
    (["evaluate", "--policy", "/no/such/policy.npz"], "policy.npz"),
    (["evaluate", "--policy", "NOT_A_POLICY"], "not a teleopkit policy"),
    (["evaluate", "--policy", "POLICY", "--scenarios", "0"], "--scenarios"),
    (["evaluate", "--policy", "POLICY", "--duration", "-1"], "--duration"),
    (["reproduce", "--scenarios", "0"], "--scenarios"),
    (["evaluate", "--policy", "POLICY", "--certificate", "/no/such/cert.json"], "cert.json"),
    (["train", "--steps", "10", "--certificate", "NOT_A_POLICY"], "malformed gain certificate"),
    (["train", "--steps", "10", "--certificate", "UNCERTIFIED"], "polytope_certified"),
    (["train", "--steps", "10", "--certificate", "EMPTY"], "no certified gain"),
])
def test_bad_input_exits_2_with_one_line(policy, tmp_path, capsys, args, needle):
    junk = tmp_path / "junk.npz"
    junk.write_text("junk")
    good = tmp_path / "good.npz"
    policy.save(good)
    uncertified = tmp_path / "uncertified.json"
    data = json.loads(certify_gains(paper_setup(), BOX, 1.0, 1.0).to_json())
    uncertified.write_text(json.dumps({**data, "polytope_certified": False}))
    empty = tmp_path / "empty.json"
    empty.write_text(certify_gains(paper_setup(), BOX, 20.0, 20.0).to_json())
    files = {"NOT_A_POLICY": junk, "POLICY": good, "UNCERTIFIED": uncertified, "EMPTY": empty}
    args = [str(files[a]) if a in files else a for a in args]
    assert main([*args, "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], lines
    assert lines[0].startswith("teleopkit: error:")


def test_train_command_refuses_to_mix_runs(tmp_path):
    """A real process: exit 2, one line, no traceback."""
    (tmp_path / "checkpoint.pt").write_bytes(b"x")
    done = teleopkit("train", "--steps", "10", "--out", str(tmp_path))
    assert done.returncode == 2 and "--resume" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr


def test_train_runs_the_fast_recipe_and_resumes_only_with_it(tmp_path, monkeypatch):
    """The fast recipe on request (10 s rounds, a tanh map started at the best constant gains);
    a resumed run keeps its recipe and refuses another in one line."""
    from teleopkit.rl.baselines import StaticGains
    from teleopkit.rl.policy import GainPolicy
    from teleopkit.rl.recipes import RECIPES, TrainConfig

    found = np.array([4.0, 5.0, 10.0, 20.0])  # the search itself is tested in tests/rl
    monkeypatch.setattr("teleopkit.rl.baselines.best_static_gains",
                        lambda *args, **kwargs: StaticGains(found, 0.0, found, 0.0, 1))
    out = tmp_path / "fast"
    assert main(["train", "--recipe", "fast", "--steps", "10", "--envs", "1", "--out",
                 str(out)]) == 0
    recorded = TrainConfig.from_dict(json.loads((out / "config.json").read_text()))
    fast = RECIPES["fast"]
    assert recorded.td3 == fast.td3 and recorded.episode_length == fast.episode_length
    assert recorded.actor_start == "best static"
    assert recorded.learning_starts == 500  # half of the one round of 1000 periods
    assert len(pd.read_csv(out / "train_log.csv")) == 1
    policy = GainPolicy.load(out / "policy.npz")
    assert policy.output == "tanh" and policy.metadata["start_gains"] == found.tolist()
    refused = teleopkit("train", "--steps", "2000", "--envs", "1", "--resume", "--recipe",
                        "paper", "--out", str(out))
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    assert "has --recipe fast" in refused.stderr


@pytest.mark.parametrize("named", [True, False])
def test_train_takes_the_papers_recipe_by_default_and_by_name(tmp_path, monkeypatch, named):
    """The paper's recipe as recorded: its networks, 40 s rounds, a warm-up of one round."""
    import teleopkit.rl.training as training
    from teleopkit.rl.recipes import RECIPES

    given = []

    def record(settings, *args, **kwargs):
        given.append(settings)
        raise KeyboardInterrupt  # the command stops as on Ctrl-C: nothing trained

    monkeypatch.setattr(training, "train", record)
    code = main(["train", *(["--recipe", "paper"] if named else []), "--steps", "100000",
                 "--envs", "2", "--seed", "3", "--out", str(tmp_path / "paper")])
    paper = RECIPES["paper"]
    assert code == 130 and given[0].td3 == paper.td3 and given[0].episode_length == 40
    assert (given[0].num_envs, given[0].seed, given[0].learning_starts) == (2, 3, 8000)
    assert given[0].total_steps == 104_000  # whole rounds of 2 x 4000 periods


@pytest.mark.slow
def test_reproduce_command_writes_figures_and_table(tmp_path):
    done = teleopkit("reproduce", "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr
    names = {p.name for p in tmp_path.iterdir()}
    assert {"delay_profile.png", "adaptive_gains.png", "positions.png", "tracking_error.png",
            "damping_error.png", "summary.md", "summary.csv"} <= names
    rows = pd.read_csv(tmp_path / "summary.csv")
    assert {"TD3 (tank:3)", "gain law (tank:3)", "TD3 (paper, frozen)"} <= set(rows["controller"])


def test_evaluate_refuses_a_certificate_that_does_not_cover_the_policy(tmp_path, capsys):
    from importlib import resources

    frozen = tmp_path / "frozen.json"
    frozen.write_text(default_certificate().to_json())
    with resources.as_file(resources.files("teleopkit") / "data" / PRETRAINED_COVERED) as path:
        code = main(["evaluate", "--policy", str(path), "--certificate", str(frozen),
                     "--out", str(tmp_path / "out")])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1
    assert "class frozen does not cover the policy's class tank:3" in lines[0]
    assert not (tmp_path / "out").exists()


def test_evaluate_runs_unseen_delay_shapes_under_the_policy_certificate(tmp_path):
    from importlib import resources

    with resources.as_file(resources.files("teleopkit") / "data" / PRETRAINED_COVERED) as path:
        done = teleopkit("evaluate", "--policy", str(path), "--scenarios", "2", "--duration",
                         "0.5", "--delay", "switching:0:1:50ms", "--seed", "99", "--out",
                         str(tmp_path / "report"))
    assert done.returncode == 0, done.stderr
    summary = pd.read_csv(tmp_path / "report" / "summary.csv", index_col=0)
    assert summary.index[0] == "TD3 (tank:3)" and summary.loc["best static", "certificate"] == \
        "frozen"
    assert {"semi-active (tank:3)", "open-loop (tank:3)"} <= set(summary.index)
    assert summary["covered"].all() and summary["unsafe_actions"].sum() == 0
    reading = (tmp_path / "report" / "summary.md").read_text()  # the tuner set against its
    assert any(f"{words}, `open-loop (tank:3)`" in reading  # schedule, as rival or after it
               for words in ("strongest other covered row", "Against its own open-loop schedule"))
    # searched for this delay shape and episode length, not reused from the paper's setup
    assert "finding the comparators" in done.stderr
    with resources.as_file(resources.files("teleopkit") / "data" / PRETRAINED_COVERED) as path:
        again = teleopkit("evaluate", "--policy", str(path), "--scenarios", "2", "--duration",
                          "0.5", "--delay", "switching:0:1:50ms", "--seed", "99", "--out",
                          str(tmp_path / "again"))
    assert again.returncode == 0 and "finding the comparators" not in again.stderr  # cached
    cached = pd.read_csv(tmp_path / "again" / "summary.csv", index_col=0)
    # the same comparators (the cached schedule is stored to 6 decimals)
    assert list(cached.index) == list(summary.index)
    np.testing.assert_allclose(cached["cost"], summary["cost"], rtol=1e-5)


def test_evaluate_moves_a_law_onto_a_certificate_with_another_set(tmp_path):
    from teleopkit.rl.baselines import best_static_gains
    from teleopkit.rl.comparison import evaluation_config
    from teleopkit.safety.factory import layer_for

    wide, near = (default_certificate(paper_setup(), (bound, bound), "tank:3")
                  for bound in (1.0, 0.3))
    config = evaluation_config(near, delay="constant:0.3", duration=4.0)
    start = best_static_gains(layer_for(wide), config=config, progress=False).gains
    assert not np.allclose(start, best_static_gains(config=config, progress=False).gains)
    path, certificate = tmp_path / "law.npz", tmp_path / "near.json"
    still_law(start, wide).save(path)
    certificate.write_text(near.to_json())
    done = teleopkit("evaluate", "--policy", str(path), "--certificate", str(certificate),
                     "--delay", "constant:0.3", "--scenarios", "2", "--duration", "4",
                     "--out", str(tmp_path / "report"))
    assert done.returncode == 0, done.stderr
    cost = pd.read_csv(tmp_path / "report" / "summary.csv", index_col=0)["cost"]
    # the law at the best constant gains of its old set plays those of the new set, and so
    # does its open-loop schedule: the comparators were found for the law as it runs here
    for row in ("best static (tank:3)", "open-loop (tank:3)"):
        assert cost["gain law (tank:3)"] == pytest.approx(cost[row], rel=1e-9)


def test_evaluate_refuses_a_duration_of_no_whole_number_of_periods(tmp_path, capsys):
    code = main(["evaluate", "--policy", "covered", "--duration", "4.005", "--scenarios", "2",
                 "--out", str(tmp_path / "ev")])
    assert code == 2 and capsys.readouterr().err == (
        "teleopkit: error: Invalid value for '--duration': duration 4.005 s is not a whole "
        "number of control periods of 0.01 s\n")
    assert not (tmp_path / "ev").exists()


def with_class(policy, variation: str, path) -> str:
    """``policy`` saved to ``path`` as if trained under ``variation`` (no recorded certificate)."""
    import copy

    marked = copy.copy(policy)
    marked.metadata = {**policy.metadata, "gain_variation": variation}
    marked.save(path)
    return str(path)


def test_evaluate_names_two_policies_of_classes_one_certificate_cannot_run(policy, tmp_path,
                                                                          capsys):
    def refusal(*policies: str) -> str:
        args = [a for p in policies for a in ("--policy", p)]
        assert main(["evaluate", *args, "--out", str(tmp_path / "ev")]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and "--certificate'" not in lines[0]  # none was given
        return lines[0].removeprefix("teleopkit: error: Invalid value for '--policy': ")

    assert refusal("covered", "paper") == (
        "covered was trained under tank:3 and paper under frozen, and every policy runs under "
        "one certificate (the first one's): neither class covers the other, so evaluate them "
        "in separate runs")
    small, large = (with_class(policy, f"tank:{t}", tmp_path / f"tank{t}.npz") for t in (1, 3))
    assert refusal(small, large) == (
        f"{small} was trained under tank:1 and {large} under tank:3, and every policy runs "
        "under one certificate (the first one's): its class does not cover tank:3, which "
        f"covers both: give --policy {large} first, or a --certificate of that class")
    assert not (tmp_path / "ev").exists()


def test_evaluate_runs_a_law_beside_a_td3_tuner_each_with_its_own_observation(policy,
                                                                              tmp_path):
    """One row each; each row costs what the policy costs run alone with its observation."""
    from dataclasses import replace

    from teleopkit.rl.comparison import comparators_for, evaluation_config
    from teleopkit.rl.evaluation import rollout

    certificate = default_certificate()
    config = evaluation_config(certificate, duration=0.3)
    # a law at the best constant gains of its class for this question: it does not step aside
    static = comparators_for(policy, certificate, config).class_static
    law = still_law(static, certificate)
    paths = tmp_path / "td3.npz", tmp_path / "law.npz"
    policy.save(paths[0])
    law.save(paths[1])
    done = teleopkit("evaluate", "--policy", str(paths[0]), "--policy", str(paths[1]),
                     "--scenarios", "2", "--duration", "0.3", "--out", str(tmp_path / "ev"))
    assert done.returncode == 0, done.stderr
    rows = pd.read_csv(tmp_path / "ev" / "per_scenario.csv")
    summary = pd.read_csv(tmp_path / "ev" / "summary.csv", index_col=0)
    assert summary.index[0] == "TD3 (frozen)" and summary.index[-1] == "gain law (frozen)"
    assert "steps aside" not in done.stderr
    for name, alone, observation in (("TD3 (frozen)", policy, "paper"),
                                     ("gain law (frozen)", law, "adaptive")):
        expected = rollout(alone, 2, 7_777, replace(config, observation=observation)).metrics()
        np.testing.assert_allclose(rows.loc[rows["controller"] == name, "cost"],
                                   expected["cost"], rtol=1e-12)
    assert "`gain law (frozen)`: another tuner given with --policy (1 policy)" in \
        (tmp_path / "ev" / "summary.md").read_text()


def narrow_covered(tmp_path) -> tuple[str, str]:
    """The covered tuner as if trained on a network of at most 0.6 s, and that certificate."""
    import copy

    from teleopkit.rl.policy import GainPolicy, resolve_policy

    narrow = default_certificate(paper_setup(), (0.6, 0.6), "tank:3")
    policy = copy.copy(GainPolicy.load(resolve_policy("covered")))
    policy.metadata = {**policy.metadata, "certificate": narrow.to_dict()}
    paths = tmp_path / "narrow.npz", tmp_path / "narrow.json"
    policy.save(paths[0])
    paths[1].write_text(narrow.to_json())
    return str(paths[0]), str(paths[1])


NARROW = "the forward delay can reach {} s, beyond the certificate's bound 0.6 s"
IN_MS = " (delays in seconds: a value in milliseconds needs the ms unit)"


@pytest.mark.parametrize(("args", "message"), [
    ([], "the policy's certificate covers forward delays up to 0.6 s and the setup's network "
         "reaches 1 s: give a --setup or --delay that stays within it, or a policy trained for "
         "this network"),
    (["--certificate", "CERTIFICATE"],
     "the --certificate covers forward delays up to 0.6 s and the setup's network reaches 1 s: "
     "give a --setup or --delay that stays within it, or a --certificate for these delays"),
    (["--delay", "constant:0.8"], "Invalid value for '--delay': " + NARROW.format(0.8)),
    (["--delay", "sine:700ms:100ms:0.5"], "Invalid value for '--delay': " + NARROW.format(0.8)),
    (["--delay", "constant:800ms"], "Invalid value for '--delay': " + NARROW.format(0.8)),
    (["--delay", "paper"], "Invalid value for '--delay': " + NARROW.format(1)),
    (["--delay", "constant:800"], "Invalid value for '--delay': " + NARROW.format(800) + IN_MS),
    (["--delay", "switching:0:300:1"],
     "Invalid value for '--delay': " + NARROW.format(300) + IN_MS),
])
def test_evaluate_hints_at_milliseconds_only_for_a_typed_bare_delay(tmp_path, capsys, args,
                                                                    message):
    """The trial: a policy certified to 0.6 s on the paper's network (1 s), no delay typed,
    was told that a value in milliseconds needs the ms unit."""
    policy, certificate = narrow_covered(tmp_path)
    args = [certificate if a == "CERTIFICATE" else a for a in args]
    code = main(["evaluate", "--policy", policy, "--scenarios", "2", "--duration", "1", *args,
                 "--out", str(tmp_path / "ev")])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err == f"teleopkit: error: {message}\n"
    assert not (tmp_path / "ev").exists()


@pytest.mark.parametrize("command", ["train", "search-law"])
def test_a_certificate_file_short_of_the_network_says_so_without_units(tmp_path, capsys,
                                                                       command):
    certificate = narrow_covered(tmp_path)[1]
    code = main([command, "--certificate", certificate, "--out", str(tmp_path / "run")])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err == (
        "teleopkit: error: the --certificate covers forward delays up to 0.6 s and the setup's "
        "network reaches 1 s: certify for the setup's delays (teleopkit certify --setup FILE "
        "--json) or give a --setup whose network stays within them\n")
    assert not (tmp_path / "run").exists()
