"""LMI certificates carry their proofs, re-checked from the plant when read."""

from __future__ import annotations

import copy
import json
from dataclasses import replace

import numpy as np
import pytest

from teleopkit.certification import certify_gains, load_certificate
from teleopkit.certification.gain_certificate import GainCertificate
from teleopkit.certification.gain_sets import GainBox, GainPolytope
from teleopkit.certification.lmi.cover import cover_certificate
from teleopkit.certification.lmi.proof import check_proof, cover_proof
from teleopkit.certification.lmi.systems import DelayQuestion
from teleopkit.model.params import ElasticJoints
from teleopkit.model.records import plant_record

NARROW = GainBox.uniform((5.0, 10.0), (30.0, 60.0), n_joints=1)
SET = GainPolytope.from_box(NARROW)
BOTH = ("frozen", "switching")


@pytest.fixture(scope="module")
def frozen(one_joint):
    """Constant gains of a small one-joint box: one LMI with gain-dependent functional."""
    return certify_gains(one_joint, NARROW, 1.0, 1.0, method="lmi")


@pytest.fixture(scope="module")
def proof(one_joint):
    """A cover of cells (1.45 s lies between the switching and the frozen margin)."""
    cover = cover_certificate(DelayQuestion(one_joint, (1.45, 1.45)), SET)
    assert cover.certified and len(cover.cells) > 1
    return cover_proof(cover, (1.45, 1.45))


def _edited(cert: GainCertificate, edit) -> str:
    data = json.loads(cert.to_json())
    edit(data)
    return json.dumps(data)


def test_a_certificate_read_back_is_verified(frozen):
    assert frozen.certified and frozen.details["proof"]["variation"] == "frozen"
    back = load_certificate(frozen.to_json())
    assert back.polytope.same_as(frozen.polytope) and back.delay_margin == frozen.delay_margin


def _matrix(data):
    matrices = data["details"]["proof"]["cells"][0]["lmi"]["matrices"]
    name = sorted(matrices)[0]
    matrices[name] = (10.0 * np.asarray(matrices[name]) - 1.0).tolist()


def _grow_box(data):
    data["box"]["kr"][0][1] = 12.0


def _bounds(data):
    data["delay_bounds"] = [1.2, 1.2]


def _proof_bounds(data):
    data["details"]["proof"]["bounds"] = [2.0, 2.0]


def _margin(data):
    data["delay_margin"] *= 1.5


def _no_margin_proof(data):
    data["details"]["margin_proof"] = None


def _switching(data):
    data["gain_variation"] = "switching"


@pytest.mark.parametrize(("edit", "message"), [
    (_matrix, "LMI solution of cell 0"),
    (_grow_box, "gain polytope is not the one"),
    (_bounds, "gain polytope is not the one|do not cover"),
    (_proof_bounds, "LMI solution of cell 0"),
    (_margin, "do not cover"),
    (_no_margin_proof, "no LMI proof of it"),
    (_switching, "assumptions"),
])
def test_a_tampered_certificate_is_refused(frozen, edit, message):
    with pytest.raises(ValueError, match=message):
        load_certificate(_edited(frozen, edit))


def test_a_certificate_moved_to_another_plant_is_refused(frozen, one_joint):
    softer = replace(one_joint, joints=ElasticJoints((50.0,), (0.3,)))

    def move(data):
        data["plant"] = plant_record(softer)

    with pytest.raises(ValueError, match="LMI solution of cell 0"):
        load_certificate(_edited(frozen, move))


def test_a_cover_proof_verifies(one_joint, proof):
    check_proof(one_joint, SET, proof, (1.45, 1.45), BOTH)
    check_proof(one_joint, SET, proof, (1.0, 1.2), BOTH)  # smaller bounds are covered
    with pytest.raises(ValueError, match="do not cover"):
        check_proof(one_joint, SET, proof, (1.5, 1.45), BOTH)


def _tampered(proof, edit):
    changed = copy.deepcopy(proof)
    edit(changed)
    return changed


def _drop_cell(p):
    p["cells"].pop()


def _overlap(p):
    p["cells"][1]["box"] = p["cells"][0]["box"]


def _leave(p):
    p["cells"][0]["box"][1][0] = 11.0


def _false_empty(p):
    p["empty"].append(p["cells"].pop()["box"])


def _swap_solutions(p):
    p["cells"][0]["lmi"], p["cells"][1]["lmi"] = p["cells"][1]["lmi"], p["cells"][0]["lmi"]


@pytest.mark.parametrize(("edit", "message"), [
    (_drop_cell, "do not cover its gain set"),
    (_overlap, "overlap"),
    (_leave, "leaves the gain set"),
    (_false_empty, "calls empty meets the gain set"),
    (_swap_solutions, "LMI solution of cell"),
])
def test_a_tampered_cover_is_refused(one_joint, proof, edit, message):
    with pytest.raises(ValueError, match=message):
        check_proof(one_joint, SET, _tampered(proof, edit), (1.45, 1.45), BOTH)


def test_a_switching_claim_needs_switching_cells(one_joint, proof, frozen):
    check_proof(one_joint, SET, proof, (1.45, 1.45), ("switching",))
    with pytest.raises(ValueError, match="for frozen gains"):
        check_proof(one_joint, SET, frozen.details["proof"], (1.0, 1.0), ("switching",))
