"""What the command line refuses before a run (exit 2, one line) and says after one (exit 1).

A wall too stiff for the step, a wall at -inf, a recorded motion shorter than the run and a
campaign's delays as long as its runs are bad input; a run that diverges from good input is a
negative answer, written all the same.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
import yaml

from teleopkit.cli import main
from teleopkit.setup import paper_setup_path
from teleopkit.sim import simulator as simulator_module

TRIAL_START = {"local": [0.8, 0.0], "remote": [0.45, 0.0], "motor": [0.55, 0.0]}
SIMULATE = ["simulate", "--kr", "10", "--br", "30", "--duration", "5"]


def teleopkit(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "teleopkit.cli", *args], capture_output=True,
                          text=True, timeout=300)


def setup_file(folder, name: str, plant: dict | None = None, **entries: object) -> str:
    """The paper's setup file (what ``teleopkit setup`` prints) with some entries changed."""
    data = yaml.safe_load(paper_setup_path().read_text())
    data["plant"].update(plant or {})
    data.update(entries)
    path = folder / name
    path.write_text(yaml.safe_dump(data))
    return str(path)


def one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    """The one line on standard error, nothing having gone to standard output."""
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and not out, (lines, out)
    return lines[0]


def test_the_trials_stiff_wall_is_refused_before_the_run(tmp_path):
    wall = {"environment": {"wall": [0.5, math.inf], "stiffness": 1.0e9, "damping": 5}}
    done = teleopkit(*SIMULATE, "--setup", setup_file(tmp_path, "wallc.yaml", wall,
                                                      start=TRIAL_START),
                     "--out", str(tmp_path / "w.csv"))
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "Traceback" not in done.stderr
    assert lines[0].startswith("teleopkit: error: the wall (stiffness 1e+09 N m/rad, damping 5 "
                               "N m s/rad) on the remote link in contact is beyond what dt = "
                               "2.5 ms integrates stably")
    assert not (tmp_path / "w.csv").exists()


def test_a_wall_at_minus_inf_is_refused_naming_the_key(tmp_path, capsys):
    wall = {"environment": {"wall": [-math.inf, math.inf]}}
    code = main([*SIMULATE, "--setup", setup_file(tmp_path, "walln.yaml", wall),
                 "--out", str(tmp_path / "w.csv")])
    assert code == 2
    assert one_error_line(capsys).endswith(
        "walln.yaml: plant.environment.wall: wall position must be one number per joint in rad, "
        ".inf for no wall on it (-inf would push at every angle), got (-inf, inf)")


def test_a_run_that_diverges_from_good_input_exits_1_with_its_time(tmp_path):
    """Without saturation, K_r = 100 and B_r = 0 behind 1 s delays run away (at 12.43 s)."""
    out = tmp_path / "run.csv"
    done = teleopkit("simulate", "--kr", "100", "--br", "0", "--duration", "15", "--delay",
                     "constant:1", "--setup",
                     setup_file(tmp_path, "free.yaml", {"torque_limit": math.inf}),
                     "--out", str(out))
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert done.stdout == (f"wrote 1501 rows to {out}; the run diverged at t = 12.43 s: a "
                           "position passed 20 rad\n")
    table = pd.read_csv(out)
    positions = table.filter(regex=r"^(ql|qr|theta)_\d$").abs().max(axis=1)
    assert table["t"][positions > 20].iloc[0] == pytest.approx(12.43)


def test_a_state_that_stops_being_finite_is_never_a_silent_success(tmp_path, capsys,
                                                                   monkeypatch):
    """The trial's run itself, its wall let through: no 'RMS tracking error nan', exit 1."""
    monkeypatch.setattr(simulator_module, "check_step", lambda *args: None)
    wall = {"environment": {"wall": [0.5, math.inf], "stiffness": 1.0e9, "damping": 5}}
    out = tmp_path / "w.csv"
    code = main([*SIMULATE, "--setup", setup_file(tmp_path, "wallc.yaml", wall,
                                                  start=TRIAL_START), "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 1 and "nan" not in printed
    at = float(printed.split("diverged at t = ")[1].split(" s")[0])
    assert printed.endswith(": its state stopped being finite\n")
    table = pd.read_csv(out)
    assert np.isfinite(table[table["t"] < at].drop(columns="t").to_numpy()).all()
    assert not np.isfinite(table[table["t"] == at].to_numpy()).all()


def test_a_recorded_motion_shorter_than_the_run_is_refused(tmp_path, capsys):
    t = np.linspace(0.0, 1.0, 101)
    pd.DataFrame({"t": t, "q1": 0.3 * np.sin(t), "q2": 0.0 * t}).to_csv(tmp_path / "hand.csv",
                                                                       index=False)
    hand = setup_file(tmp_path, "hand.yaml", operator={"stiffness": 10, "damping": 2,
                                                        "motion": "csv:hand.csv"})
    code = main(["simulate", "--kr", "10", "--br", "30", "--duration", "2", "--delay",
                 "constant:0.2", "--setup", hand, "--out", str(tmp_path / "x.csv")])
    assert code == 2
    assert one_error_line(capsys) == (
        "teleopkit: error: the recorded operator motion ends at 1 s, before the 2 s run does: "
        "record a longer motion or shorten the run")
    assert main(["simulate", "--kr", "10", "--br", "30", "--duration", "1", "--delay",
                 "constant:0.2", "--setup", hand, "--out", str(tmp_path / "x.csv")]) == 0


@pytest.mark.parametrize("command", ["campaign", "evaluate"])
def test_campaign_and_evaluate_refuse_it_too(tmp_path, capsys, command):
    t = np.linspace(0.0, 1.5, 151)
    pd.DataFrame({"t": t, "q1": 0.3 * np.sin(t), "q2": 0.0 * t}).to_csv(tmp_path / "hand.csv",
                                                                       index=False)
    hand = setup_file(tmp_path, "hand.yaml", operator={"motion": "csv:hand.csv"})
    spec = tmp_path / "spec.yaml"
    spec.write_text("duration: 2\nfactors: {kr: [10]}\n")
    args = {"campaign": [str(spec), "--out", str(tmp_path / "o.csv"), "--scheduler",
                         "synchronous"],
            "evaluate": ["--policy", "paper", "--scenarios", "1", "--duration", "2", "--out",
                         str(tmp_path / "report")]}[command]
    assert main([command, *args, "--setup", hand]) == 2
    assert one_error_line(capsys).endswith(
        "the recorded operator motion ends at 1.5 s, before the 2 s run does: record a longer "
        "motion or shorten the run")
    assert not (tmp_path / "o.csv").exists() and not (tmp_path / "report").exists()


STIFF = {"wall": {"environment": {"wall": [0.5, math.inf], "stiffness": 1.0e6, "damping": 5}},
         "joints": {"joints": {"stiffness": [1.0e6, 1.0e6], "rotor_inertia": [0.3, 0.3]}},
         "rotor": {"joints": {"stiffness": [100.0, 100.0], "rotor_inertia": [0.01, 0.01]}},
         "damping": {"local_gains": {"stiffness": [25.0, 25.0], "damping": [40.0, 40.0]}}}


@pytest.mark.parametrize("model", list(STIFF))
def test_the_step_a_stability_error_proposes_is_accepted_as_printed(tmp_path, capsys, model):
    """The trial's hard wall (and a stiff joint, a light rotor, a strong local damping): the
    message's 0.4167 ms is no divisor of the control period to 1e-9, so it prints the step in
    full, and passed back as printed it is taken and runs."""
    setup = setup_file(tmp_path, f"{model}.yaml", STIFF[model], start=TRIAL_START)
    run = ["simulate", "--setup", setup, "--kr", "5", "--br", "30", "--duration", "0.1",
           "--delay", "constant:0.02", "--out", str(tmp_path / "x.csv")]
    assert main(run) == 2
    message = one_error_line(capsys)
    assert "stab" in message
    step = re.search(r"\(--dt (\d\.\d+)[,)]", message)[1]
    assert main([*run, "--dt", step]) == 0, capsys.readouterr().err
    steps = re.search(r"(\d+) steps per control period", message)[1]
    assert float(step) == pytest.approx(0.01 / int(steps), rel=1e-14)


def short_trace(folder, end: float) -> str:
    """A delay trace (time, delay in seconds) that ends at ``end`` s; its file's name."""
    t = np.arange(0.0, end + 1e-9, 0.01)
    pd.DataFrame({"t": t, "delay": 0.2 + 0.05 * np.sin(t)}).to_csv(folder / "short.csv",
                                                                    index=False)
    return "short.csv"


def test_evaluate_refuses_a_short_delay_trace_before_the_comparators(tmp_path, capsys,
                                                                     monkeypatch):
    """The trial's trace ending at 1.95 s was refused only after the comparator search."""
    from teleopkit.rl import comparison

    monkeypatch.setattr(comparison, "comparators_for", _searched)
    code = main(["evaluate", "--policy", "covered", "--scenarios", "2", "--duration", "5",
                 "--delay", f"csv:{tmp_path / short_trace(tmp_path, 1.95)}", "--out",
                 str(tmp_path / "report")])
    assert code == 2
    assert one_error_line(capsys) == (
        "teleopkit: error: Invalid value for '--delay': the delay trace ends at 1.95 s, before "
        "the 5 s run does: record a longer trace or shorten the run")
    assert not (tmp_path / "report").exists()


def _searched(*args: object, **kwargs: object) -> None:
    raise AssertionError("the work started before the delay trace was checked")


@pytest.mark.parametrize("command", ["train", "search-law", "campaign", "evaluate"])
def test_a_setup_network_trace_shorter_than_the_runs_is_refused_before_any_work(
        tmp_path, capsys, monkeypatch, command):
    """A setup whose network plays a 5 s trace: every command running longer refuses it first
    (train and search-law ran it, holding its last delay, or failed after the first round)."""
    from teleopkit.rl import comparison, law_search, training
    from teleopkit.robustness import campaign

    for module, name in ((training, "train"), (law_search, "law_start"),
                         (campaign, "run_campaign"), (comparison, "comparators_for")):
        monkeypatch.setattr(module, name, _searched)
    channel = {"min": 0.0, "max": 0.6, "profile": f"csv:{short_trace(tmp_path, 5.0)}"}
    setup = setup_file(tmp_path, "net.yaml", network={"forward": channel, "backward": channel})
    spec = tmp_path / "spec.yaml"
    spec.write_text("duration: 10\nfactors: {kr: [10], delay: [setup]}\n")
    out = tmp_path / "out"
    args = {"train": ["--steps", "100", "--envs", "2", "--out", str(out)],
            "search-law": ["--generations", "1", "--population", "2", "--out", str(out)],
            "campaign": [str(spec), "--out", str(tmp_path / "o.csv"), "--scheduler",
                         "synchronous"],
            "evaluate": ["--policy", "covered", "--duration", "10", "--out", str(out)]}[command]
    assert main([command, *args, "--setup", setup]) == 2
    run = {"campaign": 10, "evaluate": 10}.get(command, 40)
    assert one_error_line(capsys) == (
        f"teleopkit: error: Invalid value for '--setup': the delay trace ends at 5 s, before the "
        f"{run} s run does: record a longer trace or shorten the run")
    assert not out.exists() and not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("command", [["train", "--steps", "1", "--envs", "1"],
                                     ["search-law", "--generations", "1", "--scenarios", "1"],
                                     ["evaluate", "--policy", "law", "--scenarios", "1"]])
def test_the_commands_that_simulate_take_the_step(tmp_path, capsys, command):
    """train, search-law and evaluate integrate with --dt: a step beyond the integrator's
    stability limit is refused naming it (the default step would pass)."""
    if command[0] == "train":
        pytest.importorskip("torch")
    assert main([*command, "--out", str(tmp_path / "out"), "--dt", "0.005"]) == 2
    assert "dt = 5 ms is beyond the integrator's stability limit" in one_error_line(capsys)


def test_evaluate_refuses_a_policy_for_another_number_of_joints(tmp_path, capsys):
    arm = {"lengths": [0.3, 0.3, 0.3], "masses": [0.5, 0.4, 0.3]}
    data = {"plant": {"local_arm": arm, "remote_arm": arm,
                      "joints": {"stiffness": [100.0] * 3, "rotor_inertia": [0.3] * 3},
                      "local_gains": {"stiffness": [25.0] * 3, "damping": [10.0] * 3}},
            "operator": {"stiffness": 10.0, "damping": 2.0, "motion": "still"}}
    path = tmp_path / "arm3.yaml"
    path.write_text(yaml.safe_dump(data))
    assert main(["evaluate", "--policy", "law", "--setup", str(path),
                 "--out", str(tmp_path / "out")]) == 2
    message = one_error_line(capsys)
    assert "law tunes the gains of 2 joints, the setup's arms have 3" in message
