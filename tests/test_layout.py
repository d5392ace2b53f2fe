"""Package borders and room sizes: no library module imports another package's private
modules or names, the command line lives in ``mimic`` alone, and no file or function
grows past what a newcomer can read."""

from __future__ import annotations

import ast
from pathlib import Path

from tests.conftest import REPO

PACKAGES = ("control", "silhouette_bank", "vision", "mimic")


def _module(path: Path, root: Path = REPO) -> str:
    return ".".join(path.relative_to(root).with_suffix("").parts).removesuffix(".__init__")


def _imports(path: Path, root: Path = REPO) -> list[tuple[int, str, list[str]]]:
    """``(line, absolute module, names)`` of every import in ``path``."""
    me = _module(path, root)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            found.append((node.lineno, target, [a.name for a in node.names]))
        elif isinstance(node, ast.Import):
            found += [(node.lineno, a.name, []) for a in node.names]
    return found


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
            names = {t.split(".")[0] for _, t, _ in _imports(p)}
            assert "argparse" not in names, f"{p.relative_to(REPO)} holds command-line code"
            assert "mimic" not in names, f"{p.relative_to(REPO)} imports the command line"


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
