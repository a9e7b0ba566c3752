"""Atomic output: a reader sees the old result or the new one, never half of one.

`WRITTEN` lists what this process has replaced, so a command stopped part way
can say whether it left its outputs as they were.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from . import stopping

WRITTEN: list[Path] = []

# The process's umask, read once at import (reading it means setting it, which is not safe once threads run): an
# output gets the permissions `open` would give it, not the owner-only ones of a temporary file.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


def as_opened(tmp: Path, target: Path, directory: bool) -> None:
    """Give `tmp` the permissions of the `target` it replaces, or those a new file or folder takes by default."""
    try:
        mode = target.stat().st_mode & 0o7777
    except FileNotFoundError:
        mode = (0o777 if directory else 0o666) & ~_UMASK
    os.chmod(tmp, mode)


def holds(folder: Path | str, path: Path | str) -> bool:
    """Whether `path` is `folder` or lies inside it (both resolved: links and `..` followed)."""
    folder, path = Path(folder).resolve(), Path(path).resolve()
    return folder == path or folder in path.parents


def refuse_replacing_inputs(output: Path | str, **inputs: Path | str | None) -> None:
    """Stop a command whose output folder, replaced whole (`atomic_directory`), is one of the folders it reads or
    holds one: the replacement would delete its own input (`taskseq ingest --input logs --output logs`). The
    inputs are named by their options (`input=...` for `--input`)."""
    for name, path in inputs.items():
        if path is not None and holds(output, path):
            raise ValueError(f"--output {output} would replace --{name.replace('_', '-')} {path}, which this "
                             "command reads: give another output folder")


@contextmanager
def atomic_directory(target: Path | str, output: bool = True) -> Iterator[Path]:
    """Yield a fresh temporary folder that replaces `target` only if the block succeeds. `output` False: a folder
    kept for the command's own use (a cache), which `WRITTEN` does not list."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield tmp
        stopping.check()  # a stop whose exception was dropped where it landed replaces nothing
        as_opened(tmp, target, directory=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if target.exists():
        old = target.with_name(f".{target.name}.old.{os.getpid()}")
        os.replace(target, old)
    os.replace(tmp, target)
    if output:
        WRITTEN.append(target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


@contextmanager
def atomic_file(path: Path | str, output: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside `path` (same suffix, for writers that go by it) that replaces
    `path` only if the block succeeds: for files written by other libraries (models, figures). `output`
    False: a file kept for the command's own use (a cache), which `WRITTEN` does not list."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        stopping.check()
        as_opened(tmp, path, directory=False)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    if output:
        WRITTEN.append(path)


def write_text_atomic(path: Path | str, text: str) -> None:
    with atomic_file(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_json_atomic(path: Path | str, data: Any) -> None:
    write_text_atomic(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


def write_arrays(path: Path | str, arrays: dict[str, np.ndarray]) -> None:
    """An .npz of `arrays` (no pickles), written atomically, its entries dated alike: the same arrays give the
    same bytes."""
    with atomic_file(path) as tmp, zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as z:
        for name, array in arrays.items():
            with z.open(zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), "w") as fh:
                np.lib.format.write_array(fh, array, allow_pickle=False)
