"""Setup files: the paper's as shipped, round trips, and one-line errors naming the key path."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from teleopkit.setup import Setup, SetupError, paper_setup_path
from teleopkit.sim.scenarios import paper_scenarios
from teleopkit.sim.simulator import Simulator

USER = """\
plant:
  local_arm:  {lengths: [0.3, 0.25], masses: [0.8, 0.5]}
  remote_arm: {lengths: [0.45, 0.35], masses: [1.2, 0.6], com: [0.2, 0.15], inertia: [0.01, 0.005]}
  joints:     {stiffness: [60, 60], rotor_inertia: [0.2, 0.2]}
  local_gains: {stiffness: [20, 20], damping: [8, 8]}
network:
  forward:  {min: 0.05, max: 0.6, profile: csv:fwd.csv}
  backward: {min: 0.05, max: 0.6, profile: ["constant:0.2", "switching:0.05:0.6:50ms"]}
operator: {stiffness: 10, damping: 2, motion: csv:hand.csv}
start: {local: {min: [-0.3, -0.3], max: [0.3, 0.3]}, remote: [0, 0.1]}
"""


@pytest.fixture
def user_file(tmp_path):
    t = np.arange(0, 41.0, 0.01)
    pd.DataFrame({"t": t, "q1": 0.6 * np.sin(0.7 * t), "q2": 0.4 * np.sin(1.1 * t + 0.3)}
                 ).to_csv(tmp_path / "hand.csv", index=False)
    pd.DataFrame({"t": t, "delay_ms": 300 + 250 * np.sin(0.5 * t)}).to_csv(tmp_path / "fwd.csv",
                                                                            index=False)
    path = tmp_path / "my_robot.yaml"
    path.write_text(USER)
    return path


def test_the_shipped_file_is_the_paper_setup_and_draws_its_scenarios():
    setup = Setup.from_file(paper_setup_path())
    assert setup == Setup.paper() and setup.fingerprint == Setup.paper().fingerprint
    drawn, paper = setup.scenarios(3, 5), paper_scenarios(3, 5)
    assert np.array_equal(drawn.reference_gains, paper.reference_gains)
    assert np.array_equal(drawn.forward.scale, paper.forward.scale)
    assert np.array_equal(drawn.backward.scale, paper.backward.scale)
    assert np.array_equal(Simulator(drawn).run(0.5).state, Simulator(paper).run(0.5).state)


def test_a_user_file_round_trips_with_its_relative_paths(user_file, tmp_path):
    setup = Setup.from_file(user_file)
    assert setup.params.remote_arm.com == (0.2, 0.15)
    assert setup.network.bounds == (0.6, 0.6) and setup.network.floors == (0.05, 0.05)
    copy = tmp_path / "copy.yaml"
    setup.to_file(copy)
    assert "csv:hand.csv" in copy.read_text()  # written relative to the file
    assert Setup.from_file(copy) == setup
    assert Setup.from_file(copy).fingerprint == setup.fingerprint


def test_the_fingerprint_covers_the_data_files(user_file, tmp_path):
    before = Setup.from_file(user_file).fingerprint
    (tmp_path / "fwd.csv").write_text("t,delay\n0,0.1\n50,0.2\n")
    assert Setup.from_file(user_file).fingerprint != before


def test_a_batch_carries_a_motion_a_start_and_delays_per_scenario(user_file):
    setup = Setup.from_file(user_file)
    scenario = setup.scenarios(0, 6)
    assert scenario.starts.shape == (6, 3, 2)
    assert len(np.unique(scenario.starts[:, 0, 0])) == 6  # local starts drawn per scenario
    assert np.all(scenario.starts[:, 1] == [0.0, 0.1])  # remote start fixed
    delays = scenario.backward.sample(np.linspace(0, 5, 200))
    assert delays.shape == (200, 6)
    assert set(np.round(delays.min(axis=0), 6)) <= {0.2, 0.05} and delays.max() <= 0.6


def test_each_scenario_of_a_batch_runs_as_it_would_alone():
    """Per-scenario motions and starts: a batch of three equals three runs of one."""
    setup = Setup.from_data({
        "plant": {"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]}},
        "network": {"forward": {"max": 0.5, "profile": "constant:0.3"},
                    "backward": {"max": 0.5, "profile": "constant:0.4"}},
        "operator": {"motion": {"smooth": {"amplitude": [0.2, 1.0], "frequency": [0.1, 1.0]}}},
        "start": {"local": {"min": [-0.3, -0.3], "max": [0.3, 0.3]}}})
    batch = setup.scenarios(4, 3)
    together = Simulator(batch).run(1.0, np.array([5.0, 5.0, 20.0, 20.0])).state
    for b in range(3):
        from dataclasses import replace

        from teleopkit.sim.motions import SineMotion

        motion = batch.motion
        alone = replace(batch, reference_gains=batch.reference_gains[b:b + 1],
                        motion=SineMotion(*(getattr(motion, k)[b:b + 1] for k in (
                            "amplitudes", "frequencies", "phases", "decays"))),
                        start=batch.starts[b:b + 1])
        single = Simulator(alone).run(1.0, np.array([5.0, 5.0, 20.0, 20.0])).state
        np.testing.assert_allclose(together[:, b], single[:, 0], rtol=0, atol=1e-12)


@pytest.mark.parametrize(("text", "message"), [
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1], colour: red}}",
     "plant.local_arm: unknown key 'colour'"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1]}}",
     "plant.local_arm.masses: needs 2 values (one per joint), got 1"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, -2]}}",
     "plant.local_arm.masses[1]: must be positive, got -2"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, .nan]}}",
     "plant.local_arm.masses[1]: must be a finite number"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\n"
     "network: {forward: {min: 0.5, max: 0.2}}", "network.forward.min: min 0.5 s is above max"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\n"
     "network: {forward: {max: 0.5}}", "network.forward.profile: paper reaches delays in"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\n"
     "network: {forward: {max: 0.5, profile: csv:nowhere.csv}}", "network.forward.profile:"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\n"
     "operator: {motion: csv:bad.csv}", "needs columns t, q1..qn"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\nstart: sideways",
     "start: unknown start 'sideways'"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\nnetwork: {sideways: {}}",
     "network: unknown key 'sideways'"),
    ("network: {forward: {max: 1}}", "missing key 'plant'"),
    ("plant: [1, 2", "is not valid YAML"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}, environment: wall}",
     "plant.environment: must be free or {wall: [positions], stiffness, damping}, got 'wall'"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}, torque_limit: 0}",
     "plant.torque_limit: must be positive, got 0"),
    ("plant: {local_arm: {lengths: [0.3, 0.2], masses: [1, 1]}}\nstart: {local: [0.1]}",
     "start.local: needs 2 values (one per joint), got 1"),
    ("", "the setup: must be a mapping of plant, network, operator, start, got None"),
])
def test_every_error_is_one_line_naming_the_key_path(tmp_path, text, message):
    (tmp_path / "bad.csv").write_text("time,angle\n0,1\n1,2\n")
    path = tmp_path / "setup.yaml"
    path.write_text(text)
    with pytest.raises(SetupError, match=None) as error:
        Setup.from_file(path)
    assert message in str(error.value) and "\n" not in str(error.value)
    done = subprocess.run([sys.executable, "-m", "teleopkit.cli", "setup", str(path)],
                          capture_output=True, text=True)
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1
    assert message in done.stderr and "Traceback" not in done.stderr
