"""Plant parameters over ranges: read, drawn per scenario, simulated, measured and certified.

Every scenario of a ranged setup runs a plant of its own, drawn uniformly inside the ranges; it
must run exactly as a batch of that plant alone, its energy must be that plant's, and the
certificate must cover every plant of the ranges and nothing outside them.
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
from teleopkit.certification.nuno.guarantee import storage_guarantee
from teleopkit.certification.verification import cover_plants, load_certificate
from teleopkit.model.params import Wall
from teleopkit.model.plant_range import PlantRange, value_of
from teleopkit.rl.env import COVERING_CLASS, FlexTeleopConfig, FlexTeleopVectorEnv
from teleopkit.setup import Setup, SetupError
from teleopkit.sim.energy import BatchRemoteEnergy, remote_energy
from teleopkit.sim.simulator import Simulator

RANGED = """\
plant:
- local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}
  remote_arm: {lengths: [0.38, 0.38], masses: {min: [0.4, 0.3], max: [0.8, 0.5]}}
  joints: {stiffness: {min: [60, 60], max: [140, 140]}, rotor_inertia: [0.3, 0.3]}
- local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}
  joints: {rotor_inertia: {min: [0.2, 0.2], max: [0.4, 0.4]}}
  environment: {wall: [0.05, .inf], stiffness: 2000}
start: [paper, rest]
"""
ONE_RANGED = """\
plant:
  local_arm: {lengths: [0.38, 0.38], masses: [0.5, 0.35]}
  joints: {stiffness: {min: [60, 60], max: [140, 140]}}
"""
GAINS = np.array([8.0, 6.0, 30.0, 25.0])


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    path = tmp_path_factory.mktemp("ranges") / "ranges.yaml"
    path.write_text(RANGED)
    return Setup.from_file(path)


def test_a_range_reads_as_its_midpoint_and_round_trips(setup):
    first, walled = setup.plants
    assert first.remote_arm.masses == pytest.approx((0.6, 0.4))
    assert first.joints.stiffness == (100.0, 100.0)
    assert walled.joints.rotor_inertia == pytest.approx((0.3, 0.3))
    assert set(setup.ranges[0].bounds) == {"remote_arm.masses", "joints.stiffness"}
    again = Setup.from_data(setup.to_data())
    assert again.ranges == setup.ranges and again.plants == setup.plants
    assert again.fingerprint == setup.fingerprint
    assert replace(setup, plant_ranges=()).fingerprint != setup.fingerprint
    described = "\n".join(setup.describe())
    assert "joint stiffness S_r drawn per scenario in [60, 60] to [140, 140]" in described


def test_each_scenario_draws_its_plant_inside_the_ranges(setup):
    batch = setup.scenarios(3, batch=400)
    assert len(batch.plants) == 400 and list(batch.plant_of) == list(range(400))
    covered = [[interval.covers(params, drawn) for params, interval in
                zip(setup.plants, setup.ranges, strict=True)] for drawn in batch.plants]
    assert all(any(row) for row in covered)
    stiffness = np.array([p.joints.stiffness for p, row in zip(batch.plants, covered,
                                                               strict=True) if row[0]])
    # uniform over the range: both ends are approached, each joint drawn on its own
    assert stiffness.min() < 62 and stiffness.max() > 138
    assert abs(np.corrcoef(stiffness.T)[0, 1]) < 0.2
    again = setup.scenarios(3, batch=400)
    assert again.plants == batch.plants


def test_a_ranged_batch_runs_each_scenario_as_its_plant_alone(setup):
    """Bit for bit in the compiled kernel; the numpy integrator agrees to rounding."""
    batch = setup.scenarios(5, batch=12)
    gains = np.broadcast_to(GAINS, (120, batch.batch, 4))
    together = Simulator(batch).advance(gains).state
    readable = Simulator(batch, backend="numpy").advance(gains).state
    np.testing.assert_allclose(readable, together, rtol=0, atol=1e-10)
    for b in (0, 5, 11):
        alone = replace(batch, params=batch.plants[b], other_plants=(), plant_index=None)
        np.testing.assert_array_equal(Simulator(alone).advance(gains).state[:, b],
                                      together[:, b])


def test_the_batch_energy_is_each_scenarios_plant_energy(setup):
    batch = setup.scenarios(5, batch=16)
    assert any(isinstance(p.environment, Wall) for p in batch.plants)
    state = Simulator(batch).advance(np.broadcast_to(GAINS, (60, 16, 4))).state[-1]
    state[:, 2] += 0.2  # some joints pushed into the wall
    energies = BatchRemoteEnergy.of(batch)(state)
    np.testing.assert_array_equal(energies, batch.per_plant(remote_energy, state))
    for b in range(16):
        assert energies[b] == pytest.approx(remote_energy(batch.plants[b], state[b:b + 1])[0],
                                            rel=1e-14)


def test_the_certificate_covers_the_ranges_and_nothing_outside(setup):
    certificate = default_certificate(setup.params, setup.network.reached_bounds,
                                      COVERING_CLASS, setup.plants, setup.ranges)
    assert len(certificate.other_plants) == 1 and all(certificate.plant_ranges)
    drawn = setup.scenarios(9, batch=64).plants
    certificate.check(drawn)
    again = load_certificate(certificate.to_json())  # derived again at every range's ends
    again.check(drawn)
    first = setup.plants[0]
    stiffer = replace(first, joints=replace(first.joints, stiffness=(150.0, 100.0)))
    with pytest.raises(ValueError, match=re.escape(
            "covers joint stiffness S_r from [60.0, 60.0] to [140.0, 140.0], the plant has "
            "[150.0, 100.0]")):
        certificate.check(stiffer)
    assert cover_plants(certificate, setup.plants, setup.ranges) is certificate
    without = default_certificate(setup.params, setup.network.reached_bounds, COVERING_CLASS)
    with pytest.raises(ValueError, match="remote arm masses"):
        without.check(drawn)


def test_a_range_record_is_read_as_a_claim_and_checked(setup):
    """The closed form's set is the same at the ends of any range: a wider range still checks
    (and covers more); a malformed one is refused."""
    certificate = default_certificate(setup.params, plants=setup.plants, ranges=setup.ranges)
    first = setup.plants[0]
    stiffer = replace(first, joints=replace(first.joints, stiffness=(150.0, 100.0)))
    data = json.loads(certificate.to_json())
    data["plant_ranges"][0]["joints.stiffness"]["max"] = [160.0, 160.0]
    load_certificate(json.dumps(data)).check(stiffer)
    data["plant_ranges"][0]["joints.stiffness"]["max"] = [40.0, 40.0]
    with pytest.raises(ValueError, match=r"max \[40.0, 40.0\] is below min"):
        load_certificate(json.dumps(data))
    data["plant_ranges"][0]["joints.stiffness"]["max"] = [140.0, 140.0]
    data["plant_ranges"] = data["plant_ranges"][:1]
    with pytest.raises(ValueError, match="plant_ranges has 1 entries for 2 plants"):
        load_certificate(json.dumps(data))


def test_the_environment_runs_a_ranged_batch_within_the_set(setup):
    env = FlexTeleopVectorEnv(6, FlexTeleopConfig(setup, episode_length=0.5))
    env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(50):
        env.step(rng.uniform(0, 60, (6, 4)))
    assert env.unsafe_actions == 0
    assert env.certificate.plant_ranges


@pytest.mark.parametrize(("plant", "message"), [
    ({"local_arm": {"lengths": [0.38, 0.38], "masses": {"min": [0.4, 0.3], "max": [0.6, 0.4]}}},
     "plant.local_arm.masses: a range ({min, max}) is for the remote arm and the joints only"),
    ({"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]},
      "joints": {"stiffness": {"min": [60, 60], "max": [50, 140]}}},
     "plant.joints.stiffness: max [50, 140] is below min [60, 60]"),
    ({"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]},
      "joints": {"stiffness": {"min": [60, 60]}}},
     "plant.joints.stiffness: missing key 'max'"),
    ({"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]},
      "joints": {"stiffness": {"min": [60], "max": [140]}}},
     "plant.joints.stiffness.min"),
    ({"local_arm": {"lengths": [0.38, 0.38], "masses": [0.5, 0.35]},
      "remote_arm": {"lengths": [0.38, 0.38], "masses": {"min": [0.0, 0.3], "max": [0.5, 0.4]}}},
     "plant.remote_arm.masses.min"),
])
def test_a_bad_range_is_refused_in_one_line(plant, message):
    with pytest.raises(SetupError, match=re.escape(message)):
        Setup.from_data({"plant": plant})


@pytest.mark.parametrize(("bounds", "message"), [
    ({"local_gains.stiffness": ((1.0,), (2.0,))}, "local_gains.stiffness cannot have a range"),
    ({"joints.stiffness": ((1.0, 2.0), (2.0,))}, "min and max need one value per joint"),
    ({"joints.stiffness": ((1.0,), (np.inf,))}, "a range needs finite values"),
])
def test_a_plant_range_checks_its_bounds(bounds, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        PlantRange(bounds)


def test_the_command_line_certifies_and_simulates_a_ranged_setup(setup, tmp_path):
    path = tmp_path / "ranges.yaml"
    path.write_text(RANGED)

    def run(*args):
        return subprocess.run([sys.executable, "-m", "teleopkit.cli", *args],
                              capture_output=True, text=True, check=False)

    certified = run("certify", "--setup", str(path), "--kr", "1:3", "--br", "10:40", "--json")
    assert certified.returncode == 0, certified.stderr
    assert json.loads(certified.stdout)["plant_ranges"][0]["joints.stiffness"]["max"] \
        == [140.0, 140.0]
    one = tmp_path / "one.yaml"
    one.write_text(ONE_RANGED)
    for file, what in ((path, "the setup has 2 plants"),
                       (one, "the setup has a plant with ranges")):
        lmi = run("certify", "--setup", str(file), "--kr", "1:3", "--br", "10:40",
                  "--method", "lmi")
        assert lmi.returncode == 2 and len(lmi.stderr.strip().splitlines()) == 1
        assert what in lmi.stderr
    simulated = run("simulate", "--setup", str(path), "--kr", "5", "--br", "20",
                    "--duration", "2", "--seed", "4", "--out", str(tmp_path / "run.csv"))
    assert simulated.returncode == 0, simulated.stderr
    drawn = setup.scenarios(4, 1).params
    k = 0 if setup.ranges[0].covers(setup.plants[0], drawn) else 1
    assert f"plant {k + 1} of 2" in simulated.stdout
    for name in setup.ranges[k].bounds:
        assert f"{value_of(drawn, name)[0]:.6g}" in simulated.stdout


def test_the_command_line_states_a_guarantee_that_holds_over_the_ranges(setup, tmp_path):
    """``certify --setup`` with a tank asked in rad: sized on the worst plant of the setup."""
    path = tmp_path / "ranges.yaml"
    path.write_text(RANGED)
    answer = subprocess.run([sys.executable, "-m", "teleopkit.cli", "certify", "--setup",
                             str(path), "--kr", "1:3", "--br", "10:40", "--gain-variation",
                             "tank:2rad", "--json"], capture_output=True, text=True, check=False)
    assert answer.returncode == 0, answer.stderr
    data = json.loads(answer.stdout)
    certificate = load_certificate(json.dumps(data))
    assert 2 * (1 - 1e-5) <= max(data["guarantee"]["deflection"]) <= 2.0
    # each drawn plant's own bound, from the same storage and set, stays within the stated one
    drawn = [p for plant, interval in zip(setup.plants, setup.ranges, strict=True)
             for p in interval.draw(plant, 5, 32)]
    own = [max(storage_guarantee(p, certificate.storage, certificate.scheduled_set,
                                 certificate.variation).deflection) for p in drawn]
    assert max(own) <= max(data["guarantee"]["deflection"])
