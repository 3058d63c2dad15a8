"""The storage bound in the plant's units for ranges of plants and lists of plants.

A certificate covering a range (or several plants) states bounds; each plant of the range has
its own bounds from the same storage and set. The stated ones must hold for every plant, and
be the largest of them where the largest is attained at the ranges' ends.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from teleopkit.certification.certifier import default_certificate
from teleopkit.certification.nuno.guarantee import StorageGuarantee, storage_guarantee
from teleopkit.certification.verification import check_certificate
from teleopkit.model.params import paper_setup
from teleopkit.model.plant_range import PlantRange, with_values

FIELDS = ("storage_start", "storage_bound", "deflection", "motor_speed", "link_speed",
          "local_speed", "mismatch")

SPRINGS_AND_MASSES = PlantRange({
    "joints.stiffness": ((60.0, 80.0), (150.0, 120.0)),
    "joints.rotor_inertia": ((0.2, 0.25), (0.4, 0.3)),
    "remote_arm.masses": ((0.3, 0.2), (0.8, 0.6)),
})

WITH_LENGTHS = PlantRange({**SPRINGS_AND_MASSES.bounds,
                           "remote_arm.lengths": ((0.3, 0.33), (0.45, 0.4))})


def _certificate(ranges: PlantRange, variation: str = "tank:3"):
    nominal = ranges.nominal(paper_setup())
    return nominal, default_certificate(nominal, 1.0, variation, [nominal], [ranges])


def _own(certificate, plant) -> StorageGuarantee:
    """A plant's bounds alone, from the certificate's storage and set."""
    return storage_guarantee(plant, certificate.storage, certificate.scheduled_set,
                             certificate.variation)


def _end_combinations(ranges: PlantRange, nominal) -> list:
    """Every plant with each ranged value of each joint at one of its ends."""
    names = list(ranges.bounds)
    ends = [(lo, hi) for name in names for lo, hi in zip(*ranges.bounds[name], strict=True)]
    plants = []
    for choice in itertools.product(*ends):
        values, k = {}, 0
        for name in names:
            count = len(ranges.bounds[name][0])
            values[name], k = tuple(choice[k:k + count]), k + count
        plants.append(with_values(nominal, values))
    return plants


def _values(guarantee: StorageGuarantee) -> np.ndarray:
    return np.concatenate([np.atleast_1d(getattr(guarantee, name)) for name in FIELDS])


@pytest.mark.parametrize("ranges", [SPRINGS_AND_MASSES, WITH_LENGTHS], ids=["springs", "lengths"])
def test_the_bounds_of_a_range_hold_for_every_plant_of_it(ranges):
    nominal, certificate = _certificate(ranges)
    stated = _values(certificate.guarantee())
    plants = [*_end_combinations(ranges, nominal), *ranges.draw(nominal, 3, 64)]
    own = np.array([_values(_own(certificate, plant)) for plant in plants])
    assert np.all(own <= stated * (1 + 1e-12))
    # the nominal plant alone (what was stated before ranges counted) is not the worst
    assert np.any(_values(_own(certificate, nominal)) < 0.9 * stated)


def test_the_bounds_of_a_range_are_attained_at_its_ends():
    """Without ranged lengths every bound is the largest over the ends' combinations."""
    nominal, certificate = _certificate(SPRINGS_AND_MASSES)
    ends = np.array([_values(_own(certificate, plant))
                     for plant in _end_combinations(SPRINGS_AND_MASSES, nominal)])
    np.testing.assert_allclose(_values(certificate.guarantee()), ends.max(axis=0), rtol=1e-9)


def test_a_list_of_plants_gets_the_largest_bound_of_each():
    paper = paper_setup()
    softer = replace(paper, joints=replace(paper.joints, stiffness=(40.0, 150.0),
                                           rotor_inertia=(0.15, 0.3)))
    certificate = default_certificate(paper, 1.0, "tank:3", [paper, softer])
    each = np.array([_values(_own(certificate, plant)) for plant in (paper, softer)])
    np.testing.assert_allclose(_values(certificate.guarantee()), each.max(axis=0), rtol=1e-12)
    assert each[1, 2] > each[0, 2] and each[1, 3] < each[0, 3]  # each plant is worst somewhere


@pytest.mark.parametrize("ranges", [SPRINGS_AND_MASSES, WITH_LENGTHS], ids=["springs", "lengths"])
def test_a_tank_asked_in_rad_allows_that_deflection_on_every_plant_of_the_range(ranges):
    nominal, certificate = _certificate(ranges, "tank:1.5rad")
    check_certificate(certificate)
    stated = max(certificate.guarantee().deflection)
    assert 1.5 * (1 - 1e-5) <= stated <= 1.5  # the level has six digits, rounded down
    worst = max(max(_own(certificate, plant).deflection)
                for plant in [*_end_combinations(ranges, nominal),
                              *ranges.draw(nominal, 4, 64)])
    assert worst == pytest.approx(stated, rel=1e-12)  # reached at an end, never exceeded
    nominal_only = default_certificate(nominal, 1.0, "tank:1.5rad")
    assert certificate.variation.value < nominal_only.variation.value


def test_a_tank_in_rad_too_small_for_one_plant_of_a_list_is_refused():
    paper = paper_setup()
    softer = replace(paper, joints=replace(paper.joints, stiffness=(20.0, 100.0)))
    default_certificate(paper, 1.0, "tank:1.1rad")  # the paper's plant alone allows it
    with pytest.raises(ValueError, match=r"the start alone allows 1\.811 rad"):
        default_certificate(paper, 1.0, "tank:1.1rad", [paper, softer])
