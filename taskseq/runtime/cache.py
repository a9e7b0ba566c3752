"""Where results kept between runs live: one folder, named by `TASKSEQ_CACHE`, with a subfolder per kind.

Four kinds of work are pure functions of what they read and the code that
does them, and cost most of a re-run or are asked for again and again: fits
(`taskseq.learn.fit_cache`, in `fits/`), the outcomes of a method's programs
on one fold (`taskseq.experiments.outcome_cache`, in `outcomes/`), the
training steps of rooms drawn for a method (`taskseq.features.drawn_rooms`,
in `steps/`) and the SAT planner's shortest plans
(`taskseq.plan.symbolic.stored_plans`, in `plans/`).
Each keys an entry by a hash of its inputs and of the source files it runs
(`runtime.sources`).

The cache is used only where it is asked for: the pipeline's stages set the
variable from their `--cache` option, and the worker processes they start
inherit it; unset or empty, nothing is read or written. Entries are written
atomically. Reading an entry marks it used (its modification time), so
`prune` can drop what no run has asked for in a while (`taskseq cache`);
deleting the folder between runs is safe too.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import warnings
import weakref
import zipfile
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager, suppress
from dataclasses import dataclass
from functools import cache
from importlib.metadata import version
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")
E = TypeVar("E", bound="Entries")

CACHE_ENV = "TASKSEQ_CACHE"
# the kinds of entry, each in a subfolder of the cache named as it, and the ending of their names (a step set is a
# folder of the features tables `taskseq features` writes; the others are files)
KINDS = {"fits": ".npz", "outcomes": ".json", "steps": ".steps", "plans": ".json"}
_KEY = re.compile(r"[0-9a-f]{64}")  # a key: a SHA-256 in hex
LEFTOVER_AGE = 3600.0  # seconds after which a writer's temporary file is taken as left by an interrupted run


@contextmanager
def folder(directory: Path | str | None) -> Iterator[None]:
    """`TASKSEQ_CACHE` set to `directory` within the block (None: unset, no cache), for this process and the
    processes started there; as it was afterwards. `ValueError` if `directory` is a file."""
    if directory is not None:
        _check(Path(directory), f"--cache {directory}")
    before = os.environ.get(CACHE_ENV)
    if directory is None:
        os.environ.pop(CACHE_ENV, None)
    else:
        os.environ[CACHE_ENV] = str(directory)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(CACHE_ENV, None)
        else:
            os.environ[CACHE_ENV] = before


class NotStored(Exception):
    """A lookup missed while `stored_only` was in force: the work it stands for is to be done elsewhere."""


_stored_only = False  # this process only: set by `stored_only`, never inherited by the workers it starts


@contextmanager
def stored_only() -> Iterator[None]:
    """Within the block, a lookup that finds no entry (or one that cannot be read) raises `NotStored` instead of
    returning None, so the caller computes nothing and stores nothing; a kind whose misses are cheaper done
    than sent (`Entries.follows_stored_only` False: the planner's plans) is looked up as usual.

    Why: a grid of jobs re-run after a small change mostly reads back what it
    stored (`runtime.jobs.run_jobs(stored_first=True)`); reading an entry
    takes milliseconds, while starting worker processes and importing the
    package there takes seconds. Work that needs computing goes to the
    workers as before.
    """
    global _stored_only
    before, _stored_only = _stored_only, True
    try:
        yield
    finally:
        _stored_only = before


def disabled() -> AbstractContextManager[None]:
    """No cache within the block, whatever `TASKSEQ_CACHE` says: a benchmark that times work must do it (usable
    as a decorator too)."""
    return folder(None)


def in_force() -> bool:
    """Whether a cache is in force: `TASKSEQ_CACHE` set and not empty (whether it is a folder is `subfolder`'s
    business)."""
    return bool(os.environ.get(CACHE_ENV))


def subfolder(kind: str) -> Path | None:
    """The folder of one kind of entry (`fits`, `outcomes`) under the cache `TASKSEQ_CACHE` names, or None when
    it is unset or empty; `ValueError` when it names a file."""
    if not in_force():
        return None
    root = os.environ[CACHE_ENV]
    _check(Path(root), f"{CACHE_ENV}={root}")
    return Path(root) / kind


def _check(root: Path, named: str) -> None:
    if root.exists() and not root.is_dir():
        raise ValueError(f"{named}: not a folder (the cache is a folder of fits and programs' outcomes)")


@cache
def versions(*libraries: str) -> dict[str, str]:
    """Python's version and each library's: what cached bytes depend on beyond the project's own code."""
    return {"python": sys.version.split()[0], **{lib: version(lib) for lib in libraries}}


class Entries:
    """A folder of entries of one kind (`KINDS`), `<key><suffix>` each, in a subfolder named by the key's first
    two characters (a few hundred files a folder at most)."""

    kind = ""
    # whether a miss within `stored_only` raises `NotStored` (work to send elsewhere) or is done here as usual
    follows_stored_only = True

    def __init__(self, directory: Path | str) -> None:
        self.directory = Path(directory)

    @classmethod
    def active(cls: type[E]) -> E | None:
        """The entries of this kind in the cache in force (`subfolder`), or None when no cache is on."""
        directory = subfolder(cls.kind)
        return None if directory is None else cls(directory)

    @property
    def suffix(self) -> str:
        return KINDS[self.kind]

    def path(self, key: str) -> Path:
        return self.directory / key[:2] / f"{key}{self.suffix}"

    def read(self, key: str, parse: Callable[[Path], T], then: str) -> T | None:
        """`parse` of the entry under `key`; None if there is none, or (with a warning that it is `then`: done
        again) if it cannot be read, whatever the reason: a half-copied folder, another format, a file edited.
        Within `stored_only`, either case raises `NotStored` instead (for a kind that `follows_stored_only`)."""
        path = self.path(key)
        send_elsewhere = _stored_only and self.follows_stored_only
        if not path.exists():
            if send_elsewhere:
                raise NotStored(key)
            return None
        try:
            parsed = parse(path)
        except (OSError, ValueError, KeyError, TypeError, AttributeError, zipfile.BadZipFile, EOFError) as err:
            if send_elsewhere:  # the process that redoes the work warns, once
                raise NotStored(key) from err
            warnings.warn(f"{path}: an unreadable entry of the cache is {then} ({err!r})", stacklevel=3)
            return None
        with suppress(OSError):  # a cache on a read-only disk is still read
            os.utime(path)  # used now: `prune` keeps it
        return parsed


class Digests:
    """Digests kept by their object's identity, checked through a weak reference, so a digest never outlives its
    object or serves another one that took its id. For objects never changed once built (steps, scenarios,
    world states), hashed again and again for every method, fold and stage that meets them."""

    def __init__(self, most: int) -> None:
        self.most = most  # objects whose digest is kept; past it all are dropped at once
        self._kept: dict[int, tuple[weakref.ref, bytes]] = {}

    def __call__(self, obj: Any, compute: Callable[[Any], bytes]) -> bytes:
        kept = self._kept.get(id(obj))
        if kept is not None and kept[0]() is obj:
            return kept[1]
        digest = compute(obj)
        if len(self._kept) >= self.most:
            self._kept.clear()
        self._kept[id(obj)] = (weakref.ref(obj), digest)
        return digest

    def clear(self) -> None:
        self._kept.clear()


@dataclass(frozen=True)
class Usage:
    """What a cache holds of one kind of entry."""

    kind: str
    entries: int
    size: int  # bytes
    last_used: float | None  # the newest entry's time (written or read), seconds since the epoch; None if empty


def usage(root: Path | str) -> list[Usage]:
    """Per kind (`KINDS`), the entries the cache folder `root` holds."""
    root, out = _cache_root(root), []
    for kind in KINDS:
        found = [(stat, _size(path)) for path in _entries(root, kind) if (stat := _stat(path)) is not None]
        out.append(Usage(kind, len(found), sum(size for _, size in found),
                         max((stat.st_mtime for stat, _ in found), default=None)))
    return out


def _stat(path: Path) -> os.stat_result | None:
    """The entry's status, or None if it is gone (another process pruned or replaced it meanwhile)."""
    try:
        return path.stat()
    except FileNotFoundError:
        return None


def _size(path: Path) -> int:
    """Bytes of a file, or of the files in a folder entry."""
    if path.is_dir():
        return sum(_size(f) for f in path.rglob("*") if f.is_file())
    stat = _stat(path)
    return 0 if stat is None else stat.st_size


def prune(root: Path | str, unused_for: float | None, now: float) -> tuple[int, int]:
    """Delete the entries of the cache folder `root` not written or read in the last `unused_for` seconds before
    `now` (None: every entry), and the temporary files interrupted writers left; returns (files deleted, bytes
    freed).

    Only the cache's own files go: `root` must hold nothing but the kinds' subfolders, or `ValueError` says what
    else it holds, so a mistyped folder loses nothing.
    """
    root = _cache_root(root)
    removed = freed = 0
    for kind in KINDS:
        found = [(path, unused_for) for path in _entries(root, kind)]
        # a temporary file or folder younger than an hour may be a write under way
        found += [(path, max(unused_for or 0.0, LEFTOVER_AGE)) for path in _leftovers(root, kind)]
        for path, age in found:
            stat = _stat(path)
            if stat is not None and (age is None or now - stat.st_mtime > age):
                size = _size(path)
                if path.is_dir():
                    shutil.rmtree(path, ignore_errors=True)
                else:
                    path.unlink(missing_ok=True)
                removed, freed = removed + 1, freed + size
        for sub in (root / kind).glob("??"):
            if sub.is_dir() and not any(sub.iterdir()):
                sub.rmdir()
    return removed, freed


def _cache_root(root: Path | str) -> Path:
    root = Path(root)
    if not root.is_dir():
        raise ValueError(f"{root}: no such folder (nothing is cached yet: `dvc repro` fills .cache, a stage's "
                         "`--cache DIR` another)")
    strangers = sorted(p.name for p in root.iterdir() if p.name not in KINDS or not p.is_dir())
    if strangers:
        raise ValueError(f"{root}: not a cache folder, it holds {', '.join(strangers[:3])}"
                         f"{' and more' if len(strangers) > 3 else ''} besides {' and '.join(KINDS)}")
    return root


def _entries(root: Path, kind: str) -> list[Path]:
    return sorted(p for p in (root / kind).glob(f"??/*{KINDS[kind]}")
                  if _KEY.fullmatch(p.stem) and p.stem[:2] == p.parent.name)


def _leftovers(root: Path, kind: str) -> list[Path]:
    """Temporary files and folders an interrupted writer left (`runtime.atomic` names them `.<name>.*`)."""
    return sorted(p for p in (root / kind).glob("??/.*") if _KEY.fullmatch(p.name[1:].split(".")[0]))
