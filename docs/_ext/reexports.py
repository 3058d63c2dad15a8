"""Names re-exported at the top of a package.

``teleopkit.simulate`` is defined in :mod:`teleopkit.sim.simulator` and documented there, so a
reference to ``teleopkit.simulate`` (or ``teleopkit.safety.SafetyLayer``, ``certify.max_delay``,
or an attribute such as ``teleopkit.TraceDelay.from_csv``) finds no target. This extension looks
the name up at build time and retries with the module where the object is defined; a short name
that a docstring takes from another module (``FACTORS``) resolves when one object of the
packages has it. ``.. reexports:: PACKAGE`` is a summary table of a package's names.
"""

from __future__ import annotations

import importlib
import sys
from typing import Any

from docutils import nodes
from sphinx.util.docutils import SphinxDirective
from sphinx.util.parsing import nested_parse_to_nodes

PACKAGES = ("teleopkit", "certify")


def _defining_names(target: str) -> list[str]:
    """``package[.sub].Name[.attr]`` -> ``module.Name[.attr]`` where the object may be documented.

    A function or class names its module; data (a dict, a number) does not, so every submodule
    that exports the same object is a candidate.
    """
    parts = target.split(".")
    if parts[0] not in PACKAGES:
        return []
    for i in range(len(parts) - 1, 0, -1):  # the longest importable module prefix
        module_name = ".".join(parts[:i])
        try:
            obj = getattr(importlib.import_module(module_name), parts[i])
        except ImportError:
            continue
        except AttributeError:
            return []
        rest = ".".join(parts[i:])
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        tail = ".".join(parts[i + 1:])
        if isinstance(module, str) and isinstance(qualname, str) and module != module_name:
            return [f"{module}.{qualname}" + (f".{tail}" if tail else "")]
        return [f"{name}.{rest}" for name, submodule in sorted(sys.modules.items())
                if name.startswith(f"{module_name}.") and submodule is not None
                and parts[i] in getattr(submodule, "__all__", ())
                and getattr(submodule, parts[i], None) is obj]
    return []


def _unique_suffix(domain: Any, target: str) -> str | None:
    """The one object of the packages whose full name ends with ``.target``, if only one does."""
    matches = [name for name in domain.objects
               if name.endswith(f".{target}") and name.split(".")[0] in PACKAGES]
    return matches[0] if len(matches) == 1 else None


def _missing_reference(app: Any, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve a re-exported name, or a short name used in another module's docstring."""
    if node.get("refdomain") != "py":
        return None
    domain = env.get_domain("py")
    target, module = node.get("reftarget", ""), node.get("py:module")
    candidates = _defining_names(target)
    if module:
        candidates += _defining_names(f"{module}.{target}")
    candidates.append(_unique_suffix(domain, target))
    for name in filter(None, candidates):
        found = domain.resolve_xref(env, node.get("refdoc"), app.builder, node["reftype"], name,
                                    node, contnode)
        if found is not None:
            return found
    return None


class ReexportsDirective(SphinxDirective):
    """``.. reexports:: PACKAGE``: a summary table of the names in ``PACKAGE.__all__``."""

    required_arguments = 1

    def run(self) -> list[nodes.Node]:
        """The table, as the autosummary directive would render it."""
        package = self.arguments[0]
        names = importlib.import_module(package).__all__
        # on the package's own page the names are relative to it (autosummary's convention)
        prefix = "" if self.env.ref_context.get("py:module") == package else f"{package}."
        text = "\n".join([".. autosummary::", "   :nosignatures:", "",
                          *(f"   {prefix}{name}" for name in names)])
        return nested_parse_to_nodes(self.state, text, source=self.get_source_info()[0])


def setup(app: Any) -> dict[str, Any]:
    """Register the ``missing-reference`` handler and the ``reexports`` directive."""
    app.connect("missing-reference", _missing_reference)
    app.add_directive("reexports", ReexportsDirective)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
