"""The package's structure, measured: module and function sizes, import cycles and imports of
another module's private names.

Run from the repository's root::

    python scripts/structure.py            # the figures, and every place over a limit
    python scripts/structure.py --check    # the same, exit status 1 when a limit is broken

Limits: no module over 500 lines, no function body (its docstring left out) over 60 lines, no
import cycle between the package's modules (imports inside functions count: they run too),
no module that imports another's private name (``from camvlp.x import _y``, or ``x._y`` of
an imported camvlp module ``x``).  A private module (``_app.py``) may be imported within its
own package.
"""

from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

REPO = Path(__file__).resolve().parents[1]
ROOT = REPO / "src"
PACKAGE = "camvlp"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 60


@dataclass
class Module:
    """One module of the package: its name, file, lines and what it imports."""

    name: str
    path: Path
    lines: int
    tree: ast.Module
    imports: set[str] = field(default_factory=set)


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def modules(root: Path = ROOT) -> dict[str, Module]:
    """Every module of the package under ``root``, by dotted name."""
    out = {}
    for path in sorted((root / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        text = path.read_text(encoding="utf-8")
        name = ".".join(parts)
        where = path.relative_to(REPO) if path.is_relative_to(REPO) else path
        out[name] = Module(name, where, len(text.splitlines()), ast.parse(text, str(path)))
    return out


def _resolve(mod: Module, node: ast.ImportFrom) -> str:
    """The absolute module name of a ``from ... import`` (relative ones resolved)."""
    if not node.level:
        return node.module or ""
    base = mod.name.split(".")
    is_package = mod.path.name == "__init__.py"
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join([*base, node.module] if node.module else base)


def _owner(name: str, known: dict[str, Module]) -> str | None:
    """The package module that ``name`` (a dotted import) is, or lies in."""
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def _private_module_outside(target: str, importer: str) -> bool:
    """Whether ``target`` is, or lies in, a private module (``pkg._app``) and ``importer`` is
    outside that module's package (``pkg`` and everything in it may import it)."""
    parts = target.split(".")
    for k in range(1, len(parts)):
        if _private(parts[k]):
            parent = ".".join(parts[:k])
            if not (importer == parent or importer.startswith(parent + ".")):
                return True
    return False


def _dotted(node: ast.expr) -> list[str] | None:
    """``a.b.c`` as ``["a", "b", "c"]``; None for anything but names and attributes."""
    if isinstance(node, ast.Name):
        return [node.id]
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value)
        return None if head is None else [*head, node.attr]
    return None


def _imports(mod: Module, mods: dict[str, Module], found: list[str]) -> dict[str, str]:
    """Fill ``mod.imports`` with the package modules it imports; add its imports of private
    names and modules to ``found``; return its local names bound to package modules."""
    aliases: dict[str, str] = {}  # local name -> package module
    for node in ast.walk(mod.tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                target = _owner(a.name, mods)
                if not target:
                    continue
                mod.imports.add(target)
                if a.asname:
                    aliases[a.asname] = target
                else:  # ``import camvlp.x`` binds ``camvlp``
                    aliases[a.name.partition(".")[0]] = _owner(a.name.partition(".")[0], mods)
                if _private_module_outside(a.name, mod.name):
                    found.append(f"{mod.path}:{node.lineno}: import {a.name}")
        elif isinstance(node, ast.ImportFrom):
            source = _resolve(mod, node)
            if source.partition(".")[0] != PACKAGE:
                continue
            for a in node.names:
                full = f"{source}.{a.name}"
                target = _owner(full, mods) if full in mods else _owner(source, mods)
                if target is None:
                    continue
                mod.imports.add(target)
                if full in mods:  # a module
                    aliases[a.asname or a.name] = full
                    private = _private_module_outside(full, mod.name)
                else:
                    private = _private_module_outside(source, mod.name) or (
                        _private(a.name) and target != mod.name
                    )
                if private:
                    found.append(f"{mod.path}:{node.lineno}: from {source} import {a.name}")
    return {k: v for k, v in aliases.items() if v}


def imports_and_private_uses(mods: dict[str, Module]) -> list[str]:
    """Fill each module's ``imports`` (package modules only); return every use of another
    module's private name, as ``file:line: what``: ``from camvlp.x import _y``, ``m._y`` of a
    module imported as ``m`` (``camvlp.x._y`` after ``import camvlp.x``), and the import of a
    private module (``camvlp.cli._app``) from outside its package."""
    found: list[str] = []
    for mod in mods.values():
        aliases = _imports(mod, mods, found)
        for node in ast.walk(mod.tree):
            if not (isinstance(node, ast.Attribute) and _private(node.attr)):
                continue
            chain = _dotted(node.value)
            if not chain or chain[0] not in aliases:
                continue
            owner = ".".join([aliases[chain[0]], *chain[1:]])
            if owner in mods and owner != mod.name:
                found.append(f"{mod.path}:{node.lineno}: {'.'.join(chain)}.{node.attr}")
    return found


def private_uses(root: Path = ROOT) -> list[str]:
    """Every use of another module's private name in the package under ``root`` (see
    ``imports_and_private_uses``), as ``file:line: what``."""
    return imports_and_private_uses(modules(root))


def import_cycles(root: Path = ROOT) -> list[list[str]]:
    """The import cycles between the modules of the package under ``root`` (see ``cycles``)."""
    mods = modules(root)
    imports_and_private_uses(mods)
    return cycles(mods)


def cycles(mods: dict[str, Module]) -> list[list[str]]:
    """The package's import cycles: each strongly connected set of two or more modules
    (a package's ``__init__`` importing its own modules does not count)."""
    names = sorted(mods)
    index = {n: k for k, n in enumerate(names)}
    rows, cols = [], []
    for m in mods.values():
        for t in m.imports:
            if t == m.name:
                continue
            if mods[t].path.name == "__init__.py" and m.name.startswith(t + "."):
                continue  # a module importing its own package's __init__
            rows.append(index[m.name])
            cols.append(index[t])
    graph = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(names),) * 2)
    n, labels = connected_components(graph, directed=True, connection="strong")
    groups = [[names[k] for k in np.flatnonzero(labels == c)] for c in range(n)]
    return [g for g in groups if len(g) > 1]


def long_functions(mods: dict[str, Module]) -> list[tuple[int, str]]:
    """Functions whose body, their docstring left out, is over the limit: (lines, where)."""
    out = []
    for mod in mods.values():
        for node in ast.walk(mod.tree):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            body = node.body
            doc = (
                isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)
            )
            first = body[1] if doc and len(body) > 1 else body[0]
            length = node.end_lineno - first.lineno + 1
            if length > MAX_FUNCTION_LINES:
                out.append((length, f"{mod.path}:{node.lineno} {node.name}"))
    return sorted(out, reverse=True)


def main(argv: list[str] | None = None) -> int:
    """Print the figures and the places over a limit; with ``--check``, 1 when any."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when a limit is broken")
    args = parser.parse_args(argv)
    mods = modules()
    private = imports_and_private_uses(mods)
    big = sorted(
        ((m.lines, str(m.path)) for m in mods.values() if m.lines > MAX_MODULE_LINES), reverse=True
    )
    fns = long_functions(mods)
    loops = cycles(mods)
    total = sum(m.lines for m in mods.values())
    print(f"{len(mods)} modules, {total} lines; the largest {max(m.lines for m in mods.values())}")
    report = [
        (f"modules over {MAX_MODULE_LINES} lines", [f"{n:5d} {p}" for n, p in big]),
        (f"functions over {MAX_FUNCTION_LINES} body lines", [f"{n:5d} {w}" for n, w in fns]),
        ("import cycles", [" -> ".join(c) for c in loops]),
        ("imports of another module's private names", private),
    ]
    for title, items in report:
        print(f"{title}: {len(items)}")
        for item in items:
            print(f"  {item}")
    broken = any(items for _, items in report)
    return 1 if args.check and broken else 0


if __name__ == "__main__":
    sys.exit(main())
