"""hairlut's public surface stays narrow and documented.

Each package's ``__all__`` is what a user calls (readers, bake entry points, queries, the dataclasses a user
receives, a kind's ``BAKER``/``SCHEMA``/``resolve_recipe``); the wiring between packages stays importable by
name (a package's ``_LAZY`` map) but is not listed.  The documentation's API pages render ``__all__``
(mkdocstrings), so every listed function or class must carry a docstring of its own.  ``hairlut.__all__``
names the packages and modules above the foundation (DESIGN.md's floors 1 and up), ``errors``, the version and
the few top-level entry points, each of which must resolve.  A cap on the number of public names keeps the
surface from growing quietly: raise it only together with the names a user needs.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import re
import types
from pathlib import Path

import pytest

import hairlut

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "hairlut"
PACKAGES = sorted(p.parent.name for p in PACKAGE.glob("*/__init__.py"))

#: The most names all of hairlut's public modules may list in their ``__all__`` together: 154 today (134 in the
#: packages, 20 in ``errors``), + ~10 %.
CAP = 170


def floor_table() -> dict[str, int]:
    """DESIGN.md's ``floor N  name name ...`` lines: top-level module or package → floor (read as
    tests/test_layering.py reads them)."""
    text = (ROOT / "DESIGN.md").read_text()
    table = {
        name: int(n)
        for n, names in re.findall(r"^floor (\d+)\s+(.+)$", text, re.M)
        for name in re.findall(r"[\w.]+", names.split("#")[0])
    }
    assert table, "DESIGN.md has no floor table"
    return table


def public_modules() -> dict[str, types.ModuleType]:
    """Every module named in ``hairlut.__all__`` that lists its own ``__all__`` (each package, ``errors``, ...)."""
    out = {}
    for name in hairlut.__all__:
        value = getattr(hairlut, name)
        if isinstance(value, types.ModuleType) and hasattr(value, "__all__"):
            out[name] = value
    return out


def undocumented(value) -> bool:
    """Whether a listed function or class lacks a docstring of its own (data is documented where it is defined).
    A dataclass or named tuple without one gets ``Name(field, ...)`` from Python, which documents nothing."""
    if isinstance(value, types.ModuleType) or not (inspect.isclass(value) or callable(value)):
        return False
    doc = (value.__doc__ or "").strip()
    if inspect.isclass(value) and doc.startswith(f"{value.__name__}("):
        return True
    return not doc


@pytest.mark.parametrize("package", PACKAGES)
def test_all_is_written_out_sorted(package):
    """``__all__`` is a sorted list of names written in the package's ``__init__``, not derived from its lazy map."""
    tree = ast.parse((PACKAGE / package / "__init__.py").read_text())
    assigned = [
        node.value
        for node in tree.body
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
    ]
    assert len(assigned) == 1, f"hairlut.{package} assigns __all__ {len(assigned)} times"
    (value,) = assigned
    assert isinstance(value, ast.List) and all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in value.elts), (
        f"hairlut.{package}.__all__ is not a list of names"
    )
    names = [e.value for e in value.elts]
    assert names == sorted(set(names)), f"hairlut.{package}.__all__ is not sorted or repeats a name"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_resolves_and_is_documented(package):
    module = importlib.import_module(f"hairlut.{package}")
    missing, bare = [], []
    for name in module.__all__:
        try:
            value = getattr(module, name)
        except AttributeError:
            missing.append(name)
            continue
        if undocumented(value):
            bare.append(name)
    assert not missing, f"hairlut.{package}.__all__ names what it does not have: {missing}"
    assert not bare, f"hairlut.{package}: public names without a docstring (the API pages would show them bare): {bare}"


def test_errors_are_documented():
    from hairlut import errors

    bare = [name for name in errors.__all__ if undocumented(getattr(errors, name))]
    assert not bare, f"hairlut.errors: exceptions without a docstring: {bare}"


def test_the_root_lists_what_exists():
    """``hairlut.__all__``: the version, ``errors``, every unit on floors 1 and up, and attributes that resolve."""
    names = hairlut.__all__
    assert len(names) == len(set(names)), "hairlut.__all__ repeats a name"
    for name in names:
        assert getattr(hairlut, name) is not None, name
    modules = {n for n in names if isinstance(getattr(hairlut, n), types.ModuleType)}
    above = {unit for unit, floor in floor_table().items() if floor >= 1}
    extra = sorted(modules - above - {"errors"})
    assert modules == above | {"errors"}, (
        f"hairlut.__all__'s modules differ from DESIGN.md's floors 1 and up: missing {sorted(above - modules)}, extra {extra}"
    )
    for unit in above:  # every unit of the floor table exists as a package or a module
        assert (PACKAGE / unit / "__init__.py").is_file() or (PACKAGE / f"{unit}.py").is_file(), unit
    assert isinstance(hairlut.__version__, str)
    for name in set(names) - modules - {"__version__"}:  # a top-level entry point is its package's own public name
        value = getattr(hairlut, name)
        home = value.__module__.split(".")[1]
        assert name in getattr(hairlut, home).__all__, f"hairlut.{name} is not in hairlut.{home}.__all__"
        assert not undocumented(value), f"hairlut.{name} has no docstring"
    with pytest.raises(AttributeError):
        hairlut.no_such_name  # noqa: B018


def test_no_kernel_is_public():
    kernels = [f"{m}.{n}" for m, module in public_modules().items() for n in module.__all__ if n.endswith("_kernel")]
    kernels += [n for n in hairlut.__all__ if n.endswith("_kernel")]
    assert not kernels, f"jitted kernels are wiring, not public API: {kernels}"


def test_the_surface_stays_narrow():
    counts = {m: len(module.__all__) for m, module in public_modules().items()}
    assert set(PACKAGES) <= set(counts), "a package is missing from hairlut.__all__"
    total = sum(counts.values())
    assert total <= CAP, (
        f"{total} public names ({counts}) exceed the cap of {CAP}: list only what a user calls, and import wiring from its module"
    )


def test_the_docstring_check_can_fail():
    @dataclasses.dataclass
    class Bare:
        x: int

    @dataclasses.dataclass
    class Documented:
        """A documented dataclass."""

        x: int

    def bare():
        pass

    assert undocumented(Bare) and undocumented(bare)
    assert not undocumented(Documented) and not undocumented(3) and not undocumented(hairlut)


def test_the_api_pages_are_hairlut_all():
    """The docs' API reference has one page per package in ``hairlut.__all__`` (a ``::: hairlut.NAME`` block), in
    the site's navigation, and no page for anything else."""
    import types

    import hairlut

    root = Path(__file__).resolve().parents[1]
    packages = {n for n in hairlut.__all__ if isinstance(getattr(hairlut, n), types.ModuleType)}
    pages = {}
    for page in (root / "docs" / "reference").glob("*.md"):
        for name in re.findall(r"^::: (hairlut(?:\.\w+)?)\s*$", page.read_text(), re.M):
            pages[name] = page.name
    assert set(pages) == {"hairlut"} | {f"hairlut.{n}" for n in packages}
    nav = (root / "mkdocs.yml").read_text()
    assert all(f"reference/{page}" in nav for page in pages.values())
