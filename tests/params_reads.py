"""Which keys of params.yaml a stage's `settings` reads: every section it reads through a recording proxy."""

from __future__ import annotations

import importlib
from dataclasses import fields, is_dataclass
from typing import Any

from taskseq.settings import Params


class _Section:
    """A settings section that notes each field read; a property is evaluated on the proxy, so the fields it
    reads are noted too."""

    def __init__(self, name: str, section: Any, seen: set[str]) -> None:
        self._name, self._section, self._seen = name, section, seen

    def __getattr__(self, attr: str) -> Any:
        prop = getattr(type(self._section), attr, None)
        if isinstance(prop, property):
            return prop.fget(self)
        if attr in {f.name for f in fields(self._section)}:
            self._seen.add(f"{self._name}.{attr}")
        return getattr(self._section, attr)

    def every_key(self) -> set[str]:
        return {f"{self._name}.{f.name}" for f in fields(self._section)}


class _Params:
    def __init__(self, params: Params, seen: set[str]) -> None:
        self._params, self._seen = params, seen

    def __getattr__(self, attr: str) -> Any:
        value = getattr(self._params, attr)
        return _Section(attr, value, self._seen) if is_dataclass(value) else value


def _kept_whole(value: Any) -> set[str]:
    """The keys of every section a settings object holds whole (it reads all of it)."""
    if isinstance(value, _Section):
        return value.every_key()
    if is_dataclass(value) and not isinstance(value, type):
        return set().union(*(_kept_whole(getattr(value, f.name)) for f in fields(value)))
    return set()


def keys_read(stage: str, world_seed: int | None = 0) -> set[str]:
    """The dotted params keys the stage's `settings` reads from the whole of params.yaml."""
    seen: set[str] = set()
    module = importlib.import_module(f"taskseq.stages.{stage}")
    settings = module.settings(_Params(Params.load(), seen), world_seed)
    return seen | _kept_whole(settings)
