"""``--setup`` on the command line: the same numbers as Python, and the plant named."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

import teleopkit as tk
from teleopkit.setup import Setup, paper_setup_path

ARM = """\
plant:
  local_arm:  {lengths: [0.3, 0.25], masses: [0.8, 0.5]}
  remote_arm: {lengths: [0.45, 0.35], masses: [1.2, 0.6]}
  joints:     {stiffness: [60, 60], rotor_inertia: [0.2, 0.2]}
  local_gains: {stiffness: [20, 20], damping: [8, 8]}
network:
  forward:  {min: 0.05, max: 0.6, profile: "sine:0.3:0.2:0.5"}
  backward: {min: 0.05, max: 0.6, profile: csv:back.csv}
operator: {motion: {sines: {amplitudes: [0.5, 0.4], frequencies: [1, 2], decays: [0, 0]}}}
start: rest
"""


def teleopkit(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "teleopkit.cli", *args], capture_output=True,
                          text=True)


@pytest.fixture
def arm_file(tmp_path):
    t = np.arange(0, 45.0, 0.05)
    pd.DataFrame({"t": t, "delay": 0.3 + 0.25 * np.cos(0.4 * t)}).to_csv(tmp_path / "back.csv",
                                                                       index=False)
    path = tmp_path / "arm.yaml"
    path.write_text(ARM)
    return path


def test_setup_prints_the_paper_file_and_describes_a_file(arm_file):
    done = teleopkit("setup")
    assert done.returncode == 0 and done.stdout == paper_setup_path().read_text()
    done = teleopkit("setup", str(arm_file))
    assert done.returncode == 0
    assert "remote arm: 2 links, lengths [0.45, 0.35] m" in done.stdout
    assert "backward delay: 0.05-0.6 s" in done.stdout
    assert f"fingerprint {Setup.from_file(arm_file).fingerprint}" in done.stdout


def test_simulate_with_a_setup_gives_the_numbers_of_python(arm_file, tmp_path):
    out = tmp_path / "run.csv"
    done = teleopkit("simulate", "--setup", str(arm_file), "--kr", "5", "--br", "30",
                     "--duration", "2", "--seed", "3", "--out", str(out))
    assert done.returncode == 0, done.stderr
    table = tk.simulate((5.0, 30.0), duration=2.0, seed=3, setup=Setup.from_file(arm_file))
    cli = pd.read_csv(out)
    for column in ("ql_1", "qr_2", "theta_1", "Tl", "Tr", "e_track_1", "e_damp_2"):
        np.testing.assert_allclose(cli[column].to_numpy(), table[column].to_numpy(),
                                   rtol=1e-12, atol=1e-15)
    assert cli["Tr"].max() <= 0.6 and cli["ql_1"].iloc[0] == 0.0  # its network, its start


def test_certify_answers_for_the_setup_plant_and_names_it(arm_file):
    ours = teleopkit("certify", "--setup", str(arm_file), "--kr", "1:20", "--br", "10:100")
    paper = teleopkit("certify", "--kr", "1:20", "--br", "10:100")
    assert ours.stdout.startswith("plant: local arm l [0.3, 0.25] m")
    assert paper.stdout.startswith("plant: local arm l [0.38, 0.38] m")
    assert "T_l* = 0.6 s" in ours.stdout and "T_l* = 1 s" in paper.stdout
    answer = json.loads(teleopkit("certify", "--setup", str(arm_file), "--kr", "1:20", "--br",
                                  "10:100", "--json").stdout)
    assert answer["delay_bounds"] == [0.6, 0.6]
    assert answer["plant"]["local_gains"]["stiffness"] == [20.0, 20.0]
    assert answer["setup"]["network"]["backward"]["min"] == 0.05
    # K_l = 20, B_l = 8: the closed form's margin of the box is sqrt(4 * 8 * 10 / (20 * 20)) / 2
    assert answer["delay_margin"] == pytest.approx(np.sqrt(4 * 8 * 10 / (20 * 20)) / 2)


def test_a_bad_setup_file_is_one_line_and_exit_2(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("plant: {local_arm: {lengths: [0.3], masses: [1]}}\nstart: paper\n")
    done = teleopkit("simulate", "--setup", str(path), "--kr", "1", "--br", "3", "--out",
                     str(tmp_path / "x.csv"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert "start: unknown start 'paper' for 1 joints" in done.stderr


def test_train_records_the_setup_and_the_observation(arm_file, tmp_path):
    out = tmp_path / "run"
    done = teleopkit("train", "--setup", str(arm_file), "--steps", "10", "--envs", "1",
                     "--observation", "adaptive", "--out", str(out))
    assert done.returncode == 0, done.stderr
    from teleopkit.rl.policy import GainPolicy

    policy = GainPolicy.load(out / "policy.npz")
    assert policy.metadata["observation"] == "adaptive"
    assert policy.metadata["setup"] == Setup.from_file(arm_file).record
    assert policy.metadata["certificate"]["delay_bounds"] == [0.5, 0.55]  # what the net reaches


def test_a_shipped_setup_is_taken_by_name(tmp_path, monkeypatch):
    from teleopkit.setup import SHIPPED_SETUPS, shipped_setup_path

    assert Setup.from_file(shipped_setup_path("paper")) == Setup.paper()
    mixed = Setup.from_file(shipped_setup_path("mixed"))
    run = ("simulate", "--duration", "2", "--seed", "3", "--kr", "5", "--br", "30", "--out")
    named = teleopkit(*run, str(tmp_path / "named.csv"), "--setup", "mixed")
    filed = teleopkit(*run, str(tmp_path / "filed.csv"), "--setup",
                      str(shipped_setup_path("mixed")))
    assert named.returncode == filed.returncode == 0, named.stderr
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "named.csv"),
                                  pd.read_csv(tmp_path / "filed.csv"))
    assert mixed.fingerprint != Setup.paper().fingerprint
    monkeypatch.chdir(tmp_path)
    unknown = teleopkit("simulate", "--setup", "nosuch")
    assert unknown.returncode == 2 and unknown.stderr.count("\n") == 1
    assert f"nor a shipped setup ({', '.join(SHIPPED_SETUPS)})" in unknown.stderr
    with pytest.raises(ValueError, match="no shipped setup"):
        shipped_setup_path("nosuch")


def test_a_bad_file_given_to_setup_blames_the_file_argument(tmp_path, capsys):
    from teleopkit.cli import main

    path = tmp_path / "bad.yaml"
    path.write_text("plant: {local_arm: {lengths: [0.3], masses: [1]}}\nstart: paper\n")
    assert main(["setup", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "--setup" not in lines[0]
    assert lines[0].startswith(f"teleopkit: error: Invalid value for 'FILE': {path}: start: "
                               "unknown start 'paper' for 1 joints")


def test_setup_describes_the_centres_of_mass_and_link_inertias(tmp_path):
    path = tmp_path / "com.yaml"
    path.write_text(ARM.replace("local_arm:  {lengths: [0.3, 0.25], masses: [0.8, 0.5]}",
                                "local_arm:  {lengths: [0.3, 0.25], masses: [0.8, 0.5], "
                                "com: [0.15, 0.1], inertia: [0.006, 0.002]}"))
    (tmp_path / "back.csv").write_text("t,delay\n0,0.3\n50,0.3\n")
    done = teleopkit("setup", str(path))
    assert done.returncode == 0, done.stderr
    assert ("local arm: 2 links, lengths [0.3, 0.25] m, masses [0.8, 0.5] kg, centres of mass "
            "[0.15, 0.1] m, link inertias [0.006, 0.002] kg m^2") in done.stdout
    assert ("remote arm: 2 links, lengths [0.45, 0.35] m, masses [1.2, 0.6] kg (point masses at "
            "the link tips)") in done.stdout
