"""The package's layers: a light top level, arrows pointing one way, the public names kept."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import teleopkit

ROOT = Path(__file__).resolve().parents[2]
LAYERS = ("model", "delays", "sim", "certification", "safety", "rl", "robustness")
"""Sub-packages from the bottom up: each may import only those before it."""

HEAVY = ("torch", "cvxpy", "control", "matplotlib", "numba", "pandas")


def test_import_teleopkit_loads_no_heavy_dependency():
    code = ("import sys, teleopkit; "
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]"


def test_cli_help_loads_no_heavy_dependency():
    code = ("import sys\nfrom teleopkit.cli import main\ntry:\n    main(['--help'])\n"
            "finally:\n"
            f"    print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_the_closed_form_answer_loads_no_solver():
    # the closed form answers at once: cvxpy alone takes over half a second to import
    code = ("import sys\nfrom teleopkit.cli import main\ntry:\n"
            "    main(['certify', '--kr', '5:10', '--br', '30:60', '--method', 'nuno', '--json'])\n"
            "finally:\n"
            f"    print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.stdout.strip().splitlines()[-1] == "[]"


def _imports(path: Path) -> set[str]:
    """Modules a source file imports (at any depth of the file)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return found


@pytest.mark.parametrize("layer", LAYERS)
def test_layers_import_only_the_layers_below(layer):
    above = set(LAYERS[LAYERS.index(layer) + 1:])
    for path in (ROOT / "teleopkit" / layer).rglob("*.py"):
        for module in _imports(path):
            parts = module.split(".")
            assert not (parts[0] == "teleopkit" and len(parts) > 1 and parts[1] in above), \
                f"{path.relative_to(ROOT)} imports {module}, a layer above {layer}"


def test_certify_never_imports_teleopkit_or_torch():
    for path in (ROOT / "certify").glob("*.py"):
        roots = {module.split(".")[0] for module in _imports(path)}
        assert not roots & {"teleopkit", "torch"}, path.name


def test_no_module_does_two_jobs():
    """Small modules, each opening with the one line that says its job."""
    for path in (ROOT / "teleopkit").rglob("*.py"):
        text = path.read_text()
        assert len(text.splitlines()) <= 600, path
        summary = (ast.get_docstring(ast.parse(text)) or "").split("\n")[0]
        assert summary.endswith(".") and len(summary) <= 100, f"{path}: {summary!r}"


def test_every_public_name_has_one_home():
    """A public function or class is defined in one module only: one meaning per name."""
    homes: dict[str, list[str]] = {}
    for path in (ROOT / "teleopkit").rglob("*.py"):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, ast.FunctionDef | ast.ClassDef) and not node.name.startswith("_"):
                homes.setdefault(node.name, []).append(str(path.relative_to(ROOT)))
    assert {name: where for name, where in homes.items() if len(where) > 1} == {}


@pytest.mark.parametrize("name", ["simulate", "Simulator", "Scenario", "paper_setup",
                                  "paper_scenarios", "FourierDelay", "ConstantDelay",
                                  "SwitchingDelay", "SinusoidalDelay", "TraceDelay",
                                  "certify_gains", "GainCertificate", "SafetyLayer", "GainBox"])
def test_top_level_names(name):
    assert name in teleopkit.__all__ and getattr(teleopkit, name) is not None


def test_unknown_top_level_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        _ = teleopkit.nothing
