"""Documentation checks: docstrings of the public API, doctests, API reference coverage.

* Every public function, class and method of ``teleopkit`` and ``certify`` (the names in each
  public module's ``__all__``, and the public methods those classes define) has a docstring, and
  every parameter of its signature appears in the numpydoc ``Parameters`` section (for a class:
  the parameters of its constructor, in ``Parameters`` or, for record types, ``Attributes``).
* The doctests of both packages pass (what ``python -m pytest --doctest-modules teleopkit
  certify`` runs).
* Every public module is in the API reference (``docs/api/*.rst``): an ``autosummary`` entry
  (a page with a summary table and a page per object) or an ``automodule`` / ``click`` entry.
"""

from __future__ import annotations

import doctest
import enum
import importlib
import inspect
import pkgutil
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

import pytest

PACKAGES = ("teleopkit", "certify")
ROOT = Path(__file__).resolve().parents[2]

_HEADER = re.compile(r"^(?P<title>[A-Z][A-Za-z ]+)\n-{3,}\s*$", re.MULTILINE)
_ENTRY = re.compile(r"^(?P<names>\*{0,2}[A-Za-z_][\w]*(?:\s*,\s*\*{0,2}[A-Za-z_][\w]*)*)"
                    r"\s*(?::.*)?$")

def public_modules(package: str) -> list[str]:
    """Names of the importable modules of ``package`` whose names do not start with ``_``."""
    root = importlib.import_module(package)
    names = [package]
    for info in pkgutil.walk_packages(root.__path__, prefix=f"{package}."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            names.append(info.name)
    return sorted(names)


def _sections(doc: str) -> dict[str, list[str]]:
    """Split a numpydoc docstring into ``{section title: lines}`` (summary under ``""``)."""
    out: dict[str, list[str]] = {}
    matches = list(_HEADER.finditer(doc))
    out[""] = doc[:matches[0].start()].splitlines() if matches else doc.splitlines()
    for k, match in enumerate(matches):
        end = matches[k + 1].start() if k + 1 < len(matches) else len(doc)
        out[match.group("title").strip()] = doc[match.end():end].splitlines()
    return out


def documented_names(doc: str, sections: tuple[str, ...] = ("Parameters",)) -> set[str]:
    """Names listed in the given numpydoc sections (``a, b : type`` gives ``a`` and ``b``)."""
    found: set[str] = set()
    parsed = _sections(doc)
    for title in sections:
        for line in parsed.get(title, []):
            if not line.strip() or line[:1].isspace():
                continue  # descriptions are indented under their entry
            match = _ENTRY.match(line.strip())
            if match:
                found.update(n.strip().lstrip("*") for n in match.group("names").split(","))
    return found


def _signature_names(func: Callable[..., object]) -> list[str] | None:
    """Parameter names of ``func`` without ``self`` and ``cls`` (None if it has no signature)."""
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):
        return None
    return [name for name in signature.parameters if name not in ("self", "cls")]


def _own(obj: object) -> bool:
    """Whether ``obj`` is defined in one of the two packages (not re-exported from elsewhere)."""
    module = getattr(obj, "__module__", None) or ""
    return module.split(".")[0] in PACKAGES


def _check(qualname: str, doc: str | None, params: list[str] | None,
           sections: tuple[str, ...]) -> Iterator[str]:
    """Report a missing docstring or the parameters missing from its ``sections``."""
    if not doc or not doc.strip():
        yield f"{qualname}: no docstring"
        return
    if params:
        listed = documented_names(doc, sections)
        for name in params:
            if name not in listed:
                yield f"{qualname}: undocumented parameter {name!r}"


def _class_gaps(qualname: str, cls: type) -> Iterator[str]:
    """Gaps of a class: its docstring and constructor, then its public methods and properties.

    The constructor's parameters may be listed under ``Parameters`` or, for dataclasses and
    named tuples, ``Attributes``. Enums, protocols and abstract classes are not constructed by
    users, so only their docstrings count. Methods inherit docstrings from their bases (as
    autodoc shows them).
    """
    doc = inspect.getdoc(cls)
    params = None
    if not (issubclass(cls, enum.Enum) or inspect.isabstract(cls)
            or getattr(cls, "_is_protocol", False)):
        init = cls.__init__ if "__init__" in _mro_dicts(cls) else None
        if init is not None:
            params = _signature_names(init)
        elif _is_record(cls):
            params = _signature_names(cls)
    yield from _check(qualname, doc, params, ("Parameters", "Attributes"))
    for name, member in vars(cls).items():
        if name.startswith("_"):
            continue
        target = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
        if isinstance(member, property):
            yield from _check(f"{qualname}.{name}", inspect.getdoc(member), None, ())
        elif inspect.isfunction(target):
            doc = inspect.getdoc(getattr(cls, name))
            yield from _check(f"{qualname}.{name}", doc, _signature_names(target),
                              ("Parameters",))


def _mro_dicts(cls: type) -> dict[str, object]:
    """Members defined by ``cls`` and by its bases inside the two packages."""
    out: dict[str, object] = {}
    for base in reversed(cls.__mro__):
        if base is cls or _own(base):
            out.update(vars(base))
    return out


def _is_record(cls: type) -> bool:
    """Dataclass or named tuple (its fields are the constructor's parameters)."""
    return hasattr(cls, "__dataclass_fields__") or hasattr(cls, "_fields")


def find_gaps() -> list[str]:
    """Every missing docstring or undocumented parameter of the public API."""
    gaps: list[str] = []
    seen: set[int] = set()
    for package in PACKAGES:
        for module_name in public_modules(package):
            module = importlib.import_module(module_name)
            if not (module.__doc__ or "").strip():
                gaps.append(f"{module_name}: no module docstring")
            for name in getattr(module, "__all__", ()):
                obj = getattr(module, name)
                if id(obj) in seen or not _own(obj):
                    continue
                if inspect.isclass(obj):
                    seen.add(id(obj))
                    gaps.extend(_class_gaps(f"{obj.__module__}.{obj.__qualname__}", obj))
                elif inspect.isfunction(obj):
                    seen.add(id(obj))
                    qualname = f"{obj.__module__}.{obj.__qualname__}"
                    gaps.extend(_check(qualname, inspect.getdoc(obj), _signature_names(obj),
                                       ("Parameters",)))
    return sorted(set(gaps))


def test_documented_names_parser() -> None:
    """The numpydoc section parser reads grouped, untyped and starred entries."""
    doc = inspect.cleandoc("""Summary.

        Parameters
        ----------
        a, b : float
            Two numbers.
        c
            Untyped.
        **overrides
            Keywords.

        Returns
        -------
        d : float
            Not a parameter.
        """)
    assert documented_names(doc) == {"a", "b", "c", "overrides"}


def test_public_api_is_documented() -> None:
    """Every public name and every parameter is documented."""
    gaps = find_gaps()
    assert not gaps, "undocumented public API:\n" + "\n".join(gaps)


def _doctests() -> list[tuple[str, doctest.DocTest]]:
    """Every doctest of the public modules, by name (what ``--doctest-modules`` collects)."""
    finder = doctest.DocTestFinder(exclude_empty=True)
    out = []
    for package in PACKAGES:
        for module_name in public_modules(package):
            module: ModuleType = importlib.import_module(module_name)
            out += [(test.name, test) for test in finder.find(module) if test.examples]
    return sorted(out, key=lambda item: item[0])


@pytest.mark.parametrize("test", [pytest.param(t, id=name) for name, t in _doctests()])
def test_doctest(test: doctest.DocTest) -> None:
    """One docstring's examples pass (``ELLIPSIS`` enabled, as pytest's doctest default)."""
    report: list[str] = []
    result = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS).run(test, out=report.append)
    if result.failed:
        pytest.fail("".join(report), pytrace=False)


def _api_pages_text() -> str:
    """The text of every page of the API reference."""
    return "\n".join(p.read_text(encoding="utf-8") for p in (ROOT / "docs" / "api").glob("*.rst"))


@pytest.mark.parametrize("module_name", [m for p in PACKAGES for m in public_modules(p)])
def test_module_in_api_reference(module_name: str) -> None:
    """Each public module is documented in ``docs/api/*.rst`` (autosummary or automodule)."""
    text = _api_pages_text()
    name = re.escape(module_name)
    directive = rf"^\.\. (automodule|click):: {name}(:\w+)?\s*$"
    summarised = rf"^\.\. autosummary::\n(   :.*\n)*\n(   \S+\n)*   {name}\s*$"
    assert re.search(directive, text, re.MULTILINE) or re.search(summarised, text, re.MULTILINE), (
        f"{module_name} is in no autosummary or automodule entry of docs/api/*.rst")
