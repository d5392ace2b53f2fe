"""Package borders and room sizes: no library module imports another package's private
modules or names, the command line lives in ``mimic`` alone, and no file or function
grows past what a newcomer can read."""

from __future__ import annotations

import ast
import functools
import io
import re
import subprocess
import tokenize
from pathlib import Path

import pytest

from tests.conftest import REPO

PACKAGES = ("control", "silhouette_bank", "vision", "mimic")


def _module(path: Path, root: Path = REPO) -> str:
    return ".".join(path.relative_to(root).with_suffix("").parts).removesuffix(".__init__")


def _statements(tree: ast.AST) -> list[ast.AST]:
    """Every statement in ``tree``, nested ones too (in functions, classes, branches,
    ``try`` and ``with``), and none of the expressions, where no import can be: a tenth
    of ``ast.walk``'s nodes."""
    found, todo = [], [tree]
    while todo:
        node = todo.pop()
        found.append(node)
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            todo += getattr(node, field, None) or []
    return found


@functools.cache  # (two tests read the same files' imports)
def _imports(path: Path, root: Path = REPO) -> list[tuple[int, str, list[str]]]:
    """``(line, absolute module, names)`` of every import in ``path``, in its order."""
    me = _module(path, root)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = []
    for node in _statements(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name, []) for a in node.names]
    return sorted(found, key=lambda f: f[0])


def _private(part: str) -> bool:
    return part.startswith("_") and not part.startswith("__")


def private_imports(path: Path, root: Path = REPO) -> list[str]:
    """Imports in ``path`` of a private module or name that belongs to another package
    (a package may use its own private modules; ``control.graph`` may not use
    ``control.motion._text``)."""
    me = _module(path, root)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    where = path.relative_to(root)
    bad = []
    for line, target, names in _imports(path, root):
        parts = target.split(".")
        if parts[0] not in PACKAGES:
            continue
        owner = next((".".join(parts[:i]) for i, p in enumerate(parts) if _private(p)), None)
        if owner is not None and owner != package:
            bad.append(f"{where}:{line}: {target}")
        elif owner is None and target != package:
            bad += [f"{where}:{line}: {target}.{n}" for n in names if _private(n)]
    return bad


def _library_files() -> list[Path]:
    return sorted(p for pkg in PACKAGES for p in (REPO / pkg).rglob("*.py"))


def test_no_library_module_uses_another_packages_private_parts() -> None:
    files = _library_files()
    assert len(files) > 80
    bad = [b for p in files for b in private_imports(p)]
    assert not bad, "\n".join(bad)


def test_the_check_finds_a_private_import(tmp_path: Path) -> None:
    probe = tmp_path / "control" / "graph" / "_probe.py"
    probe.parent.mkdir(parents=True)
    probe.write_text(
        "from ..motion._text import decode\n"
        "from ..motion import _library\n"
        "from ._graph import build_graph\n"  # its own package's private module: fine
        "from ..motion import Clip\n"
    )
    assert private_imports(probe, tmp_path) == [
        "control/graph/_probe.py:1: control.motion._text",
        "control/graph/_probe.py:2: control.motion._library",
    ]


def test_the_command_line_lives_in_mimic_alone() -> None:
    for pkg in ("control", "silhouette_bank", "vision"):
        for p in sorted((REPO / pkg).rglob("*.py")):
            names = {t.split(".")[0] for _, t, _ in _imports(p, REPO)}
            assert "argparse" not in names, f"{p.relative_to(REPO)} holds command-line code"
            assert "mimic" not in names, f"{p.relative_to(REPO)} imports the command line"


@pytest.mark.slow
def test_no_file_over_500_lines_and_no_function_over_80() -> None:
    """Rooms a newcomer can read: numba kernels may be long, nothing else."""
    long = []
    for p in _library_files():
        src = p.read_text()
        if len(src.splitlines()) > 500:
            long.append(f"{p.relative_to(REPO)}: {len(src.splitlines())} lines")
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                kernel = any("jit" in ast.unparse(d) for d in node.decorator_list)
                size = (node.end_lineno or node.lineno) - node.lineno + 1
                if size > 80 and not kernel:
                    long.append(f"{p.relative_to(REPO)}:{node.lineno}: {node.name} {size} lines")
    assert not long, "\n".join(long)


DATE = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")


def _dated_lines(paths: list[Path]) -> list[str]:
    """``path:line`` of every comment or docstring line of ``paths`` with a date."""
    found = []
    for p in paths:
        src = p.read_text()
        lines = src.splitlines()
        docs: set[int] = set()
        for node in ast.walk(ast.parse(src)):
            body = getattr(node, "body", None)
            if isinstance(body, list) and body and isinstance(body[0], ast.Expr):
                first = body[0].value
                if isinstance(first, ast.Constant) and isinstance(first.value, str):
                    docs.update(range(first.lineno, (first.end_lineno or first.lineno) + 1))
        for tok in tokenize.generate_tokens(io.StringIO(src).readline):
            if tok.type == tokenize.COMMENT and DATE.search(tok.string):
                found.append(f"{p}:{tok.start[0]}")
        found += [f"{p}:{n}" for n in sorted(docs) if DATE.search(lines[n - 1])]
    return found


@pytest.mark.slow
def test_comments_say_what_is_not_when() -> None:
    """History, with its dates, goes to git, ``CHANGELOG.md`` and ``benchmarks/HISTORY.md``:
    no comment or docstring of the project's Python carries a date."""
    files = [REPO / f for f in _tracked("*.py")]
    assert not _dated_lines(files), "\n".join(_dated_lines(files))


def test_the_date_check_finds_a_dated_comment(tmp_path: Path) -> None:
    p = tmp_path / "m.py"
    day = "-".join(("2026", "12", "05"))  # (so that this file itself carries no date)
    p.write_text(f'"""A module.\n\nMeasured {day}."""\n\nX = 1  # since {day}\nY = "{day}"\n')
    assert _dated_lines([p]) == [f"{p}:5", f"{p}:3"]  # (a string that is data is not)


def _tracked(pattern: str) -> list[str]:
    out = subprocess.run(
        ["git", "ls-files", pattern], cwd=REPO, capture_output=True, text=True, check=True
    )
    return [line for line in out.stdout.splitlines() if line]
