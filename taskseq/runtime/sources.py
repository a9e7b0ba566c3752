"""The project's source files a module runs: its own and those it imports, read from the code, not by running it.

Used to fingerprint code: a result cached under the hash of these files is
served only to the same code. The closure is conservative: every import the
module's text names counts, at the top or inside a function, taken or not,
and with it the `__init__.py` of every package on the way, which Python runs
first.
"""

from __future__ import annotations

import ast
import hashlib
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]  # the folder that holds the `taskseq` package


def _file(module: str) -> Path | None:
    """The source file of a `taskseq` module (its `__init__.py` for a package), or None if there is none."""
    base = ROOT.joinpath(*module.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


@cache
def _imported(module: str, path: Path) -> frozenset[str]:
    """The `taskseq` modules that the text of `module` (at `path`) imports (each file read once per process, as
    several closures share most of their files)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            out.add(base)
            out.update(f"{base}.{alias.name}" for alias in node.names)  # `from pkg import module`
    return frozenset(m for m in out if m.split(".")[0] == "taskseq" and _file(m) is not None)


@cache
def import_closure(module: str) -> tuple[Path, ...]:
    """Every source file `module` runs when imported: its own, its imports' (transitively) and their packages'
    `__init__.py`, sorted. Raises `ValueError` for a module of no `taskseq` file."""
    if _file(module) is None:
        raise ValueError(f"{module}: no such module in {ROOT / 'taskseq'}")
    seen: set[str] = set()
    todo = [module]
    while todo:
        name = todo.pop()
        path = _file(name)
        if name in seen or path is None:
            continue
        seen.add(name)
        parts = name.split(".")
        todo.extend(".".join(parts[:k]) for k in range(1, len(parts)))  # the packages on the way run first
        todo.extend(_imported(name, path))
    return tuple(sorted(p for p in map(_file, seen) if p is not None))


@cache
def code_fingerprint(module: str) -> str:
    """sha256 of the paths (relative to the project) and bytes of `import_closure(module)`."""
    digest = hashlib.sha256()
    for path in import_closure(module):
        digest.update(str(path.relative_to(ROOT)).encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()
