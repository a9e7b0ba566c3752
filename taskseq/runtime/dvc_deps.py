"""Whether the DVC stage this process runs for lists a project file among its `deps`.

DVC re-runs a stage when a file its `deps` list changes. A stage that loads
code its deps do not list is not re-run when that code changes, and its
outputs go stale without a word. Which method modules a stage loads follows
params.yaml (a method's `experiments`), and `scripts/stage_deps.py` writes
them into dvc.yaml; an edit of params.yaml can outrun that. So a stage that
DVC runs (DVC sets `DVC_ROOT` and `DVC_STAGE` in its environment) checks the
method modules it loads against its deps (`taskseq.methods.spec`) and stops
before any work, saying what to run. Run by hand, a stage checks nothing.
"""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path

import yaml

DVC_ROOT, DVC_STAGE = "DVC_ROOT", "DVC_STAGE"
PARTS = "pipelines"  # the folder of the pipeline's parts, one dvc.yaml (and dvc.lock) each, beside the root's


def pipeline_files(root: Path | str) -> list[Path]:
    """The pipeline's dvc.yaml files: the root's (what `dvc repro` runs), then each part's, by name."""
    root = Path(root)
    return [root / "dvc.yaml", *sorted((root / PARTS).glob("*/dvc.yaml"))]


def undeclared(path: Path | str) -> str | None:
    """Why the running DVC stage's deps should list `path` (a file) and do not: neither it nor a folder holding it
    is among them. None when they list it, when no DVC stage is running, when `path` lies outside the
    repository, or when the stage's dvc.yaml cannot be read (DVC itself reports that)."""
    root, stage = os.environ.get(DVC_ROOT), os.environ.get(DVC_STAGE)
    if not root or not stage:
        return None
    path = Path(path).resolve()
    if Path(root).resolve() not in path.parents:
        return None
    found = _deps(root, stage)
    if found is None:
        return None
    dvcfile, deps = found
    if any(dep == path or dep in path.parents for dep in deps):
        return None
    return (f"{dvcfile}: stage {stage} does not list {path.relative_to(Path(root).resolve())} among its deps, so a "
            "change to it would not run the stage again")


@cache
def _deps(root: str, stage: str) -> tuple[Path, tuple[Path, ...]] | None:
    """The dvc.yaml that defines `stage` (`DVC_STAGE`: `name`, `name@item`, or `path/dvc.yaml:name`) and its
    deps as absolute paths; None if it cannot be read."""
    file, _, name = stage.rpartition(":")
    dvcfile = Path(root) / (file or "dvc.yaml")
    base, _, key = name.partition("@")
    try:
        entry = yaml.safe_load(dvcfile.read_text(encoding="utf-8"))["stages"][base]
        body = entry.get("do", entry)  # a `foreach` stage's deps are its `do`'s, with its item's values in them
        items = entry.get("foreach")
        item = items.get(key) if isinstance(items, dict) else key
        deps = [_with_item(d, key, item) for d in body.get("deps") or [] if isinstance(d, str)]
        wdir = dvcfile.parent / body.get("wdir", ".")  # a part's stages run in the root: their paths are its
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return None
    return dvcfile, tuple((wdir / d).resolve() for d in deps)


def _with_item(dep: str, key: str, item: object) -> str:
    """A dep of a `foreach` stage's run as DVC reads it: `${key}`, `${item}` and `${item.NAME}` filled in."""
    dep = dep.replace("${key}", key)
    if isinstance(item, dict):
        return re.sub(r"\$\{item\.(\w+)\}", lambda m: str(item[m.group(1)]), dep)
    return dep.replace("${item}", str(item))
