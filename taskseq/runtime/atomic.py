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


def _make_parent(path: Path, shown: Path | str) -> None:
    """Make the folder `path` goes into. A file in the way of that folder (`--output notes.txt/sub`) is the
    user's mistake, said in one line (ValueError) instead of the FileExistsError or NotADirectoryError that
    `mkdir` raises for it."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError) as err:
        blocker = next((p for p in (path.parent, *path.parent.parents) if p.exists() and not p.is_dir()), None)
        if blocker is None:
            raise
        raise ValueError(f"{shown}: {blocker} is a file, not a folder, so nothing can be written under it: "
                         "give another path") from err


def _files(folder: Path, folders: bool = False) -> Iterator[str]:
    """The relative paths of what `folder` holds, lazily: every file or link (a link is not followed), and every
    empty folder (with a final `/`), which replacing `folder` would delete as surely as a file; `folders` True:
    every folder, empty or not (what a replacement keeps)."""
    for entry in sorted(os.scandir(folder), key=lambda e: e.name):
        if entry.is_dir(follow_symlinks=False):
            inner = _files(Path(entry.path), folders)
            first = next(inner, None)
            if folders or first is None:
                yield f"{entry.name}/"
            if first is not None:
                yield f"{entry.name}/{first}"
                yield from (f"{entry.name}/{name}" for name in inner)
        else:
            yield entry.name


# how many of the files a replacement would delete its refusal names
_NAMED = 3


def _refuse_deleting(target: Path, new: Path, shown: Path | str) -> None:
    """Refuse to replace the folder `target` with `new` when `target` holds a file `new` does not: the
    replacement would delete it, and a command run by hand on a folder that holds other things (`--output .`,
    `--output ~/results`) must not lose them. A previous output of the same command has the same files and is
    replaced; under DVC a stage's outputs are removed before it runs, so the pipeline never meets this."""
    kept = set(_files(new, folders=True))
    lost = []
    for name in _files(target):  # stops at the few it names: a folder such as `..` may hold a great many
        if name not in kept:
            lost.append(name)
            if len(lost) > _NAMED:
                break
    if lost:
        named = ", ".join(lost[:_NAMED]) + (", ..." if len(lost) > _NAMED else "")
        raise ValueError(f"{shown} holds files this command does not write ({named}), which replacing the folder "
                         "would delete: remove them or give another folder")


@contextmanager
def atomic_directory(target: Path | str, output: bool = True) -> Iterator[Path]:
    """Yield a fresh temporary folder that replaces `target` only if the block succeeds. `output` False: a folder
    kept for the command's own use (a cache), which `WRITTEN` does not list.

    `target` is resolved first, so `.` and `..` have a real name and parent (the temporary folder goes beside
    the real folder, and a link to a folder has the folder it points to replaced). Refused (ValueError naming
    the path): a target that exists and is not a folder, one under a file, the root, the folder the command runs
    in (or one holding it), and an output whose folder
    holds files the block did not write (`_refuse_deleting`; not a cache entry, which is the command's own and
    may be a half-written one being written again). Whatever fails once the temporary folder exists removes it
    and leaves the old folder where it was."""
    shown = target
    try:
        target = Path(target).resolve()
    except (RuntimeError, OSError) as err:  # a loop of links (RuntimeError up to Python 3.12)
        raise ValueError(f"{shown}: {err}") from None
    if target.parent == target:
        raise ValueError(f"{shown} is the root folder, which a command's output cannot replace: give a folder in it")
    if holds(target, Path.cwd()):  # replaced, it would leave the command and its shell in a deleted folder
        raise ValueError(f"{shown} is the folder this command runs in, or holds it: give another folder")
    if target.exists() and not target.is_dir():
        raise ValueError(f"{shown} is a file, not a folder: give a folder to write into")
    _make_parent(target, shown)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    old = target.with_name(f".{target.name}.old.{os.getpid()}")
    try:
        yield tmp
        stopping.check()  # a stop whose exception was dropped where it landed replaces nothing
        as_opened(tmp, target, directory=True)
        if target.exists():
            if not target.is_dir():  # made while the block ran
                raise ValueError(f"{shown} is a file, not a folder: give a folder to write into")
            if output:
                _refuse_deleting(target, tmp, shown)
            os.replace(target, old)
        try:
            os.replace(tmp, target)
        except OSError:
            if output or not target.is_dir():
                raise
            # a cache entry that another process (a parallel job on the same key) put in place since the check
            # above: the same key, so the same content; it stands, and this one is dropped
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        # whatever stopped it, even between the two moves: the old folder goes back where nothing took its place,
        # and is removed where another writer's folder did
        try:
            if old.exists() and not target.exists():
                os.replace(old, target)
            shutil.rmtree(old, ignore_errors=True)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    if output:
        WRITTEN.append(Path(shown))
    shutil.rmtree(old, ignore_errors=True)


@contextmanager
def atomic_file(path: Path | str, output: bool = True) -> Iterator[Path]:
    """Yield a temporary path beside `path` (same suffix, for writers that go by it) that replaces
    `path` only if the block succeeds: for files written by other libraries (models, figures). `output`
    False: a file kept for the command's own use (a cache), which `WRITTEN` does not list.

    Refused before anything is written (ValueError naming the path): a `path` that is a folder (`--model
    models/`), which `os.replace` could not replace, only after the work is done, and one under a file."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path} is a folder; give a file name")
    _make_parent(path, path)
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
