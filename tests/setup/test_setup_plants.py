"""Several plants in one setup: the file's list, the batch, the certificate that covers them.

A batch that mixes plants must run each scenario exactly as a batch of its plant alone would,
in both integrators; the certificate covers the plants only where the closed form, derived
again for each, gives the same set.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.verification import cover_plants, load_certificate
from teleopkit.model.params import PDGains, PlanarArm, Wall
from teleopkit.setup import Setup, SetupError
from teleopkit.sim.energy import remote_energy
from teleopkit.sim.scenarios import Scenario
from teleopkit.sim.simulator import Simulator

PLANTS = """\
plant:
- local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}
- local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}
  remote_arm: {lengths: [0.38, 0.38], masses: [0.75, 0.5]}
  joints: {stiffness: [60, 60], rotor_inertia: [0.4, 0.4]}
- local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}
  environment: {wall: [0.05, .inf], stiffness: 2000}
network:
  forward: {max: 1.0, profile: ["constant:0.3", paper]}
  backward: {max: 1.0, profile: paper}
operator:
  motion:
  - paper
  - sines: {amplitudes: [2.0, 1.6], frequencies: [0.8, 1.3], phases: [0.0, 0.3],
            decays: [0.0, 0.0], gains: [0.2, 1.0]}
start:
- paper
- rest
"""
GAINS = np.array([8.0, 6.0, 30.0, 25.0])


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    path = tmp_path_factory.mktemp("plants") / "plants.yaml"
    path.write_text(PLANTS)
    return Setup.from_file(path)


def test_the_file_lists_three_plants_and_round_trips(setup):
    heavier, walled = setup.other_plants
    assert heavier.remote_arm.masses == (0.75, 0.5)
    assert heavier.joints.stiffness == (60.0, 60.0)
    assert isinstance(walled.environment, Wall) and walled.environment.stiffness == 2000.0
    again = Setup.from_data(setup.to_data())
    assert again.plants == setup.plants
    assert again.fingerprint == setup.fingerprint
    assert replace(setup, other_plants=()).fingerprint != setup.fingerprint


def test_one_plant_writes_and_fingerprints_as_before():
    """A setup of one plant keeps its file form (a mapping) and so its fingerprint."""
    paper = Setup.paper()
    assert isinstance(paper.to_data()["plant"], dict)
    assert paper.plants == (paper.params,)
    assert Setup.from_data({"plant": [paper.to_data()["plant"]]}).fingerprint \
        == paper.fingerprint


@pytest.mark.parametrize(("plant", "message"), [
    ([], "plant: must be a non-empty list"),
    (["free"], "plant[0]: must be a mapping"),
    ([{"local_arm": {"lengths": [0.3], "masses": [1.0]}},
      {"remote_arm": {"lengths": [0.3], "masses": [1.0]}}], "plant[1]: missing key 'local_arm'"),
])
def test_a_bad_list_of_plants_names_the_entry(plant, message):
    with pytest.raises(SetupError, match=re.escape(message)):
        Setup.from_data({"plant": plant})


def test_plants_of_other_sizes_are_refused_in_one_line():
    data = {"plant": [{"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]}},
                      {"local_arm": {"lengths": [0.4], "masses": [1.0]}}]}
    with pytest.raises(SetupError, match=r"plant\[1\]: has 1 joints, the first plant 2"):
        Setup.from_data(data)


def test_every_scenario_runs_as_a_batch_of_its_plant_alone(setup):
    """Bit for bit in the compiled kernel; the numpy integrator agrees to rounding."""
    batch = setup.scenarios(5, batch=40)
    assert set(batch.plant_of) == {0, 1, 2}
    gains = np.broadcast_to(GAINS, (150, batch.batch, 4))
    together = Simulator(batch).advance(gains).state
    readable = Simulator(batch, backend="numpy").advance(gains).state
    np.testing.assert_allclose(readable, together, rtol=0, atol=1e-10)
    for k, params in enumerate(setup.plants):
        alone = replace(setup, params=params, other_plants=()).scenarios(5, batch=40)
        lanes = batch.plant_of == k
        np.testing.assert_array_equal(Simulator(alone).advance(gains).state[:, lanes],
                                      together[:, lanes])


def test_the_wall_and_the_heavier_arm_change_the_runs_they_hold(setup):
    """The plants are not the same plant thrice: each differs from the paper's run."""
    batch = setup.scenarios(5, batch=40)
    together = Simulator(batch).advance(np.broadcast_to(GAINS, (150, 40, 4))).state
    paper = replace(batch, other_plants=(), plant_index=None)
    alone = Simulator(paper).advance(np.broadcast_to(GAINS, (150, 40, 4))).state
    for k in (1, 2):
        lanes = batch.plant_of == k
        assert np.max(np.abs(together[:, lanes] - alone[:, lanes])) > 1e-3


def test_energies_are_read_with_each_scenarios_plant(setup):
    batch = setup.scenarios(5, batch=12)
    state = Simulator(batch).advance(np.broadcast_to(GAINS, (50, 12, 4))).state[-1]
    energies = batch.per_plant(remote_energy, state)
    for b in range(12):
        params = batch.plants[batch.plant_of[b]]
        assert energies[b] == pytest.approx(remote_energy(params, state[b:b + 1])[0], rel=1e-14)


def test_a_batch_repeated_keeps_each_scenarios_plant(setup):
    batch = setup.scenarios(5, batch=6)
    np.testing.assert_array_equal(batch.repeat(3).plant_of, np.tile(batch.plant_of, 3))


@pytest.mark.parametrize(("index", "message"), [
    (np.array([0, 3]), "plant_index needs 2 whole numbers in 0..1"),
    (np.array([0.0, 1.0]), "plant_index needs 2 whole numbers"),
    (np.array([0]), "plant_index needs 2 whole numbers")])
def test_a_bad_plant_index_is_refused(index, message):
    params = Setup.paper().params
    heavier = replace(params, remote_arm=PlanarArm((0.38, 0.38), (1.0, 1.0)))
    with pytest.raises(ValueError, match=message):
        Scenario(params, reference_gains=np.ones((2, 2)), other_plants=(heavier,),
                 plant_index=index)


def test_the_certificate_covers_every_plant_and_rechecks(setup):
    certificate = default_certificate(setup.params, setup.network.reached_bounds, "tank:3",
                                      setup.plants)
    assert len(certificate.other_plants) == 2
    certificate.check(setup.plants, *setup.network.reached_bounds)
    again = load_certificate(certificate.to_json())  # derived again for every plant
    assert again.other_plants == certificate.other_plants
    assert cover_plants(again, setup.plants) is again
    stranger = replace(setup.params, joints=replace(setup.params.joints, stiffness=(10.0, 10.0)))
    with pytest.raises(ValueError, match="none of the certificate's 3 plants"):
        certificate.check(stranger)


def test_a_plant_whose_set_differs_is_not_covered(setup):
    """Other local gains give another closed-form set: no shared certificate."""
    other = replace(setup.params, local_gains=PDGains((40.0, 40.0), (10.0, 10.0)))
    certificate = default_certificate(setup.params, 1.0, "tank:3")
    with pytest.raises(ValueError, match="certify each plant on its own"):
        cover_plants(certificate, [other])


def test_an_edited_plant_record_fails_the_recheck(setup):
    """A further plant whose local damping was edited: its set is not the certificate's."""
    data = default_certificate(setup.params, 1.0, "frozen", setup.plants).to_dict()
    data["other_plants"][1]["local_gains"]["damping"] = [12.0, 12.0]
    with pytest.raises(ValueError, match="gain polytope is not the one"):
        load_certificate(json.dumps(data))


def test_the_environment_trains_on_every_plant(setup):
    from teleopkit.rl.env import FlexTeleopConfig, TeleopBatch

    config = FlexTeleopConfig(setup, episode_length=2.0)
    core = TeleopBatch(config, 12)
    core.start(setup.scenarios(1, batch=12))
    for _ in range(config.max_steps):
        step = core.step(np.broadcast_to(GAINS, (12, 4)))
    assert core.unsafe_actions == 0
    assert np.all(np.isfinite(step.reward))


def test_the_setup_command_names_each_plant(setup, tmp_path):
    path = tmp_path / "plants.yaml"
    path.write_text(PLANTS)
    shown = subprocess.run([sys.executable, "-m", "teleopkit.cli", "setup", str(path)],
                           capture_output=True, text=True, check=True).stdout
    assert "plant 3 of 3, local gains" in shown and "a wall at [0.05, inf] rad" in shown
    assert "plant 2 of 3, remote arm" in shown  # the others by what differs from the first
    assert "plant 2 of 3, local arm" not in shown and "plant 3 of 3, remote arm" not in shown


def test_simulate_says_which_plant_the_seed_drew(setup, tmp_path):
    path = tmp_path / "plants.yaml"
    path.write_text(PLANTS)
    out = tmp_path / "run.csv"
    said = subprocess.run([sys.executable, "-m", "teleopkit.cli", "simulate", "--setup",
                           str(path), "--kr", "5", "--br", "30", "--seed", "1", "--duration",
                           "1", "--out", str(out)], capture_output=True, text=True,
                          check=True).stdout
    drawn = setup.scenarios(1, 1).plant_of[0]
    assert f"(plant {drawn + 1} of 3)" in said


def test_certify_answers_for_every_plant_of_the_setup(tmp_path):
    """The closed form's JSON covers the three plants; the LMI is refused in one line."""
    path = tmp_path / "plants.yaml"
    path.write_text(PLANTS)
    command = [sys.executable, "-m", "teleopkit.cli", "certify", "--setup", str(path), "--kr",
               "1:10", "--br", "30:60"]
    answer = json.loads(subprocess.run([*command, "--json"], capture_output=True, text=True,
                                       check=True).stdout)
    certificate = load_certificate(json.dumps(answer))
    certificate.check(Setup.from_file(path).plants)
    assert answer["certified"] and len(answer["other_plants"]) == 2
    refused = subprocess.run([*command, "--method", "lmi"], capture_output=True, text=True)
    assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1
    assert "the setup has 3 plants" in refused.stderr and "Traceback" not in refused.stderr
