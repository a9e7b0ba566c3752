"""Where results kept between runs live: one folder, named by `TASKSEQ_CACHE`, with a subfolder per kind.

Two kinds of work are pure functions of what they read and the code that
does them, and cost most of a re-run: fits (`taskseq.learn.fit_cache`,
in `fits/`) and the outcomes of a method's programs on one fold
(`taskseq.experiments.outcome_cache`, in `outcomes/`). Each keys an entry by
a hash of its inputs and of the source files it runs (`runtime.sources`).

The cache is used only where it is asked for: the pipeline's stages set the
variable from their `--cache` option, and the worker processes they start
inherit it; unset or empty, nothing is read or written. Entries are written
atomically and never pruned: deleting the folder between runs is safe.
"""

from __future__ import annotations

import os
import sys
import warnings
import weakref
import zipfile
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from functools import cache
from importlib.metadata import version
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")

CACHE_ENV = "TASKSEQ_CACHE"


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


def disabled() -> AbstractContextManager[None]:
    """No cache within the block, whatever `TASKSEQ_CACHE` says: a benchmark that times work must do it (usable
    as a decorator too)."""
    return folder(None)


def subfolder(kind: str) -> Path | None:
    """The folder of one kind of entry (`fits`, `outcomes`) under the cache `TASKSEQ_CACHE` names, or None when
    it is unset or empty; `ValueError` when it names a file."""
    root = os.environ.get(CACHE_ENV, "")
    if not root:
        return None
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
    """A folder of entries of one kind, `<key><suffix>` each, in a subfolder named by the key's first two
    characters (a few hundred files a folder at most)."""

    suffix = ""

    def __init__(self, directory: Path | str) -> None:
        self.directory = Path(directory)

    def path(self, key: str) -> Path:
        return self.directory / key[:2] / f"{key}{self.suffix}"

    def read(self, key: str, parse: Callable[[Path], T], then: str) -> T | None:
        """`parse` of the entry under `key`; None if there is none, or (with a warning that it is `then`: done
        again) if it cannot be read, whatever the reason: a half-copied folder, another format, a file edited."""
        path = self.path(key)
        if not path.exists():
            return None
        try:
            return parse(path)
        except (OSError, ValueError, KeyError, TypeError, AttributeError, zipfile.BadZipFile, EOFError) as err:
            warnings.warn(f"{path}: an unreadable entry of the cache is {then} ({err!r})", stacklevel=3)
            return None


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
