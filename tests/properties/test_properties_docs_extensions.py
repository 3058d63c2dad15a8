"""The documentation's own extensions (``docs/_ext``): CLI page rewriting and re-export lookup."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "docs" / "_ext"))

api_pages = pytest.importorskip("api_pages")
cli_page = pytest.importorskip("cli_page")
reexports = pytest.importorskip("reexports")


@pytest.mark.parametrize(("line", "expected"), [
    ("  :default: ``'runs/train'``", "  :default: ``runs/train``"),
    ("  :default: ``25.0``", "  :default: ``25.0``"),
    ("Address of a scheduler (tcp://HOST:8786) instead", "Address of a scheduler "
     "(``tcp://HOST:8786``) instead"),
    ("already ``tcp://HOST:8786`` literal", "already ``tcp://HOST:8786`` literal"),
])
def test_cli_lines_are_plain(line: str, expected: str) -> None:
    assert cli_page.plain_line(line) == expected


def test_gallery_names_list_every_public_path() -> None:
    names = api_pages.gallery_names("teleopkit.sim.simulator.simulate").split()
    assert names[0] == "teleopkit.sim.simulator.simulate"
    assert {"teleopkit.simulate", "teleopkit.sim.simulate"} <= set(names)
    assert api_pages.gallery_names("teleopkit.no.such.thing") == "teleopkit.no.such.thing"


def test_packages_and_aliases_are_told_apart() -> None:
    assert api_pages.is_package("teleopkit.sim")
    assert not api_pages.is_package("teleopkit.sim.simulator")
    assert api_pages.is_alias("certify.conditions.DelayPoint")
    assert not api_pages.is_alias("certify.conditions.VariableSpec")
    assert "tuple[bool, ...]" in api_pages.alias_doc("certify.conditions.DelayPoint")


def test_reexports_lead_to_the_defining_module() -> None:
    assert reexports._defining_names("teleopkit.simulate") == ["teleopkit.sim.simulator.simulate"]
    assert "teleopkit.rl.registration.ENV_ID" in reexports._defining_names("teleopkit.rl.ENV_ID")
    assert reexports._defining_names("numpy.ndarray") == []
    assert reexports._defining_names("teleopkit.no_such_name") == []
