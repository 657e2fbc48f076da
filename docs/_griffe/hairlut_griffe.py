"""Griffe extension for the API pages (mkdocs.yml): hairlut's lazy re-exports, and a warning for each
public object without a docstring.

hairlut's packages re-export their names lazily (PEP 562, ``hairlut/_lazy.py``): an ``__init__`` holds a dict
literal ``_LAZY = {name: private module}`` (``_ATTRIBUTES`` in ``hairlut/__init__.py``) and computes ``__all__``
from it.  Griffe reads source statically, so it sees neither the names nor ``__all__``; this extension adds each
name as an alias of ``<package>.<module>.<name>`` and evaluates ``__all__`` from those literals.  Nothing is
imported.

The docstrings use reStructuredText roles (``:func:`name```); the pages are Markdown, so the roles are rewritten
as plain code spans.

A public module without a docstring, or a class, function or public method that one exports, is logged as a
warning, which ``mkdocs build --strict`` turns into a failure.
"""

from __future__ import annotations

import ast
import logging
import re
from pathlib import Path

import griffe

logger = logging.getLogger("mkdocs.plugins.hairlut_griffe")

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|attr|data|exc|obj|const):`~?([^`]+)`")
LAZY_DICTS = ("_LAZY", "_ATTRIBUTES")  # {public name: module relative to the package}


def _literals(tree: ast.Module) -> dict[str, object]:
    """The module-level names bound to a literal (dicts, sets, lists of strings)."""
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            try:
                out[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass
    return out


def _all(tree: ast.Module, namespace: dict[str, object]) -> list[str] | None:
    """``__all__`` evaluated with ``sorted`` and the module's literals only."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            code = compile(ast.Expression(node.value), "__all__", "eval")
            return list(eval(code, {"__builtins__": {}, "sorted": sorted}, dict(namespace)))
    return None


class LazyExports(griffe.Extension):
    """Resolve ``_LAZY`` re-exports into aliases and exports (see the module docstring)."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        for module in _modules(pkg):
            if not isinstance(module.filepath, Path) or module.filepath.name != "__init__.py":
                continue
            tree = ast.parse(module.filepath.read_text(encoding="utf-8"))
            literals = _literals(tree)
            lazy = {}
            for key in LAZY_DICTS:
                if isinstance(literals.get(key), dict):
                    lazy.update(literals[key])
            for name, where in lazy.items():
                if name not in module.members:
                    module.set_member(name, griffe.Alias(name, f"{module.path}.{where.lstrip('.')}.{name}", parent=module))
            names = _all(tree, literals)
            if names is not None:
                module.exports = names


def _modules(module: griffe.Module):
    yield module
    for member in module.modules.values():
        if not member.is_alias:
            yield from _modules(member)


class MissingDocstrings(griffe.Extension):
    """Warn about each public module, and each class, function or public method it exports, without a docstring."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        seen = set()
        for module in _modules(pkg):
            if module.is_public and not any(part.startswith("_") for part in module.path.split(".")):
                _need_doc(module, seen)
                for name in module.exports or ():
                    member = module.members.get(str(name))
                    if member is None:
                        continue
                    try:
                        target = member.final_target if member.is_alias else member
                    except griffe.AliasResolutionError:
                        continue  # imported from outside hairlut
                    if target.kind is griffe.Kind.MODULE:
                        continue  # a subpackage: checked on its own
                    _need_doc(target, seen)
                    if target.kind is griffe.Kind.CLASS:
                        for method in target.members.values():
                            if (
                                not method.is_alias
                                and method.kind is griffe.Kind.FUNCTION
                                and method.is_public
                                and not method.name.startswith("__")
                            ):
                                _need_doc(method, seen)


def _need_doc(obj, seen: set) -> None:
    if obj.path in seen or obj.kind not in (griffe.Kind.MODULE, griffe.Kind.CLASS, griffe.Kind.FUNCTION):
        return
    seen.add(obj.path)
    if not obj.docstring:
        logger.warning("%s:%s: %s %s has no docstring", obj.relative_filepath, obj.lineno or 0, obj.kind.value, obj.path)


class SphinxRoles(griffe.Extension):
    """Rewrite ``:role:`target``` in every docstring as the code span ``target``."""

    def on_package(self, *, pkg: griffe.Module, **kwargs) -> None:
        _strip_roles(pkg)


def _strip_roles(obj) -> None:
    if obj.docstring is not None:
        obj.docstring.value = ROLE.sub(r"`\1`", obj.docstring.value)
    for member in obj.members.values():
        if not member.is_alias:
            _strip_roles(member)
