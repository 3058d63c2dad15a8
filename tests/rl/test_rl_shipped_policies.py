"""The shipped policies by name: ``GainPolicy.load("covered")``, ``resolve_policy``."""

from __future__ import annotations

import numpy as np
import pytest

from teleopkit.rl.policy import (
    PRETRAINED,
    PRETRAINED_COVERED,
    PRETRAINED_LAW,
    SHIPPED_POLICIES,
    GainPolicy,
    resolve_policy,
)


def same(a: GainPolicy, b: GainPolicy) -> bool:
    return all(np.array_equal(x, y) for (x, _), (y, _) in zip(a.weights, b.weights, strict=True))


def test_every_shipped_name_is_a_shipped_file():
    assert dict(SHIPPED_POLICIES) == {"covered": PRETRAINED_COVERED, "law": PRETRAINED_LAW,
                                      "paper": PRETRAINED}
    for name, file in SHIPPED_POLICIES.items():
        path = resolve_policy(name)
        assert path.name == file and path.is_file()
        assert same(GainPolicy.load(name), GainPolicy.pretrained(file))
        assert same(GainPolicy.pretrained(name), GainPolicy.pretrained(file))


def test_the_names_load_the_right_tuners():
    assert GainPolicy.load("covered").metadata["certificate"]["gain_variation"] == "tank:3"
    assert same(GainPolicy.load("paper"), GainPolicy.pretrained())


def test_the_shipped_law_records_what_it_was_searched_for():
    from teleopkit.setup import Setup, shipped_setup_path

    law = GainPolicy.load("law")
    meta = law.metadata
    assert len(law.weights) == 1 and law.obs_range is not None
    assert meta["observation"] == "adaptive" and meta["gain_variation"] == "tank:3"
    assert meta["setup"] == Setup.from_file(shipped_setup_path("mixed")).record
    assert meta["law_search"]["harm"] == 1.0 and meta["recipe"] == "gain law (CMA-ES)"


@pytest.mark.parametrize("name", ["covered", "law"])
def test_shipped_tuners_carry_their_comparators_for_the_paper_setup(name):
    # evaluate and reproduce read them instead of searching them on a user's first run
    from teleopkit.rl.comparators import Comparators
    from teleopkit.rl.comparison import evaluation_config, policy_certificate
    from teleopkit.setup import Setup

    policy = GainPolicy.load(name)
    certificate = policy_certificate(policy)
    assert Comparators.stored(policy, certificate,
                              evaluation_config(certificate, Setup.paper())) is not None


def test_a_path_still_loads(tmp_path):
    path = tmp_path / "mine.npz"
    GainPolicy.load("paper").save(path)
    assert resolve_policy(path) == path and resolve_policy(str(path)) == path
    assert same(GainPolicy.load(str(path)), GainPolicy.load("paper"))


def test_a_name_beats_a_file_of_that_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "covered").write_text("not a policy")
    assert same(GainPolicy.load("covered"), GainPolicy.pretrained(PRETRAINED_COVERED))
    with pytest.raises(ValueError, match="not a teleopkit policy"):
        GainPolicy.load("./covered")


@pytest.mark.parametrize("source", ["coverd", "/no/such/policy.npz"])
def test_neither_a_name_nor_a_file_is_one_line_listing_the_names(source):
    message = f"{source} is neither a policy file nor a shipped policy (covered, law, paper)"
    with pytest.raises(ValueError) as error:
        GainPolicy.load(source)
    assert str(error.value) == message
    with pytest.raises(ValueError, match="shipped policy"):
        GainPolicy.pretrained("coverd")
