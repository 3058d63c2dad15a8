"""Helpers the API page templates (``docs/_templates/autosummary``) call.

They reach the templates through ``autosummary_context`` in ``conf.py``.
"""

from __future__ import annotations

import importlib
import types

from sphinx.pycode import ModuleAnalyzer


def _lookup(fullname: str) -> object:
    module_name, _, name = fullname.rpartition(".")
    return getattr(importlib.import_module(module_name), name)


def gallery_names(fullname: str) -> str:
    """``fullname`` and every shorter public path of the same object, space-separated.

    Sphinx-gallery records the names a tutorial uses under the shortest import path
    (``teleopkit.simulate`` for ``teleopkit.sim.simulator.simulate``).
    """
    try:
        obj = _lookup(fullname)
    except (ImportError, AttributeError, ValueError):
        return fullname
    module_name, _, name = fullname.rpartition(".")
    parts, names = module_name.split("."), [fullname]
    for i in range(1, len(parts)):
        prefix = ".".join(parts[:i])
        try:
            if getattr(importlib.import_module(prefix), name, None) is obj:
                names.append(f"{prefix}.{name}")
        except ImportError:
            continue
    return " ".join(names)


def is_package(fullname: str) -> bool:
    """Whether the module ``fullname`` is a package (its names are re-exports)."""
    return hasattr(importlib.import_module(fullname), "__path__")


def is_alias(fullname: str) -> bool:
    """Whether ``fullname`` is a type alias such as ``tuple[bool, ...]`` (not autodoc data)."""
    return isinstance(_lookup(fullname), types.GenericAlias)


def alias_doc(fullname: str) -> str:
    """The alias's value and its docstring, as reStructuredText for a ``py:data`` entry."""
    module_name, _, name = fullname.rpartition(".")
    docs = ModuleAnalyzer.for_module(module_name).find_attr_docs()
    lines = docs.get(("", name), [])
    return "\n".join([f":type: {_lookup(fullname)!s}", "", *lines])
