"""The storage bound stated from a setup's starts: ranges of positions and several starts.

A guarantee holds from a start through ``V(0)``; from starts drawn from ranges it must use the
largest ``V(0)`` of them. The largest is taken joint by joint at the boxes' corners; checked
here against every corner and against points drawn inside, for arms of one to three joints
and with a wall. Text and JSON of ``teleopkit certify`` state the same bounds.
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.nuno.guarantee import start_storage
from teleopkit.cli import main
from teleopkit.setup import Setup, StartMix, StartSpec


def _arm_data(n: int, wall: bool = False, start: object = "rest") -> dict:
    """Setup data of ``n`` joints (about the paper's values per joint), a wall on the first."""
    plant = {"local_arm": {"lengths": [0.35] * n, "masses": [0.5] * n},
             "remote_arm": {"lengths": [0.35] * n, "masses": [0.5] * n},
             "joints": {"stiffness": [100.0] * n, "rotor_inertia": [0.3] * n},
             "local_gains": {"stiffness": [25.0] * n, "damping": [10.0] * n}}
    if wall:
        plant["environment"] = {"wall": [0.05, *[math.inf] * (n - 1)], "stiffness": 1000,
                                "damping": 5}
    return {"plant": plant, "operator": {"stiffness": 10.0, "damping": 2.0, "motion": "still"},
            "start": start}


def _arm_plant(n: int, wall: bool = False):
    return Setup.from_data(_arm_data(n, wall)).params


def _box(rng: np.random.Generator, n: int) -> StartSpec:
    low = rng.uniform(-0.6, 0.2, (3, n))
    return StartSpec(low, low + rng.uniform(0.0, 0.5, (3, n)))


def _storage_of(plant, certificate, positions: np.ndarray) -> float:
    fixed = StartSpec(positions, positions)
    return start_storage(plant, certificate.storage, certificate.scheduled_set.kappa_low,
                         start=fixed)


@pytest.mark.parametrize(("n", "wall"), [(1, False), (2, False), (2, True), (3, True)])
def test_largest_start_storage_is_the_largest_corner(n, wall):
    rng = np.random.default_rng(n + 10 * wall)
    plant = _arm_plant(n, wall)
    certificate = default_certificate(plant, 1.0, "tank:3")
    for _ in range(3):
        box = _box(rng, n)
        stated = start_storage(plant, certificate.storage, certificate.scheduled_set.kappa_low,
                               start=box)
        corners = [np.where(np.array(choice).reshape(3, n), box.high, box.low)
                   for choice in itertools.product((False, True), repeat=3 * n)]
        every = [_storage_of(plant, certificate, c) for c in corners]
        assert stated == pytest.approx(max(every), rel=1e-12)
        inside = rng.uniform(box.low, box.high, (20, 3, n))
        assert max(_storage_of(plant, certificate, p) for p in inside) <= stated


def test_guarantee_from_a_mix_is_the_worst_part():
    certificate = default_certificate(variation="tank:3")
    parts = (StartSpec.named("paper", 2), StartSpec(np.full((3, 2), -0.5), np.full((3, 2), 0.5)))
    each = [certificate.guarantee(part).storage_start for part in parts]
    assert certificate.guarantee(StartMix(parts)).storage_start == pytest.approx(max(each))
    assert each[1] > each[0]
    assert certificate.guarantee().storage_start == pytest.approx(each[0])  # the paper's


def test_rad_tank_holds_from_every_start_of_a_range():
    start = StartSpec(np.array([[-0.4, -0.4], [-0.1, -0.1], [0.0, 0.0]]),
                      np.array([[0.4, 0.4], [0.1, 0.1], [0.0, 0.0]]))  # holds the paper's
    ranged = default_certificate(variation="tank:1.5rad", start=start)
    fixed = default_certificate(variation="tank:1.5rad")
    assert ranged.variation.value < fixed.variation.value  # a larger start leaves a smaller tank
    assert max(ranged.guarantee(start).deflection) <= 1.5
    assert max(ranged.guarantee(start).deflection) == pytest.approx(1.5, rel=1e-5)


def test_guarantee_needs_a_start_beyond_two_joints():
    certificate = default_certificate(_arm_plant(3), 1.0, "tank:3")
    with pytest.raises(ValueError, match="3-joint plant needs its start"):
        certificate.guarantee()
    rest = StartSpec.named("rest", 3)
    assert certificate.guarantee(rest).storage_start == 0.0
    with pytest.raises(ValueError, match="start has 2 joints"):
        certificate.guarantee(StartSpec.named("paper", 2))


def _setup_file(tmp_path, n: int, start: object) -> str:
    path = tmp_path / f"arm{n}.yaml"
    Setup.from_data(_arm_data(n, start=start)).to_file(path)
    return str(path)


@pytest.mark.parametrize("n", [1, 3])
def test_certify_states_the_same_guarantee_in_text_and_json(tmp_path, capsys, n):
    spread = {"min": [-0.3] * n, "max": [0.3] * n}
    path = _setup_file(tmp_path, n, {"local": spread, "remote": spread})
    question = ["certify", "--setup", path, "--kr", "1:10", "--br", "40:150",
                "--gain-variation", "tank:3"]
    assert main(question) == 0
    text = capsys.readouterr().out
    assert main([*question, "--json"]) == 0
    stated = json.loads(capsys.readouterr().out)["guarantee"]
    assert stated["start"]["local"] == spread
    assert f"V(0) = {stated['storage_start']:.4g}" in text
    setup = Setup.from_file(path)
    certificate = default_certificate(setup.params, 1.0, "tank:3")
    corner = StartSpec(np.array([[0.3] * n, [-0.3] * n, [0.0] * n]),
                       np.array([[0.3] * n, [-0.3] * n, [0.0] * n]))
    assert stated["storage_start"] >= certificate.guarantee(corner).storage_start > 0
