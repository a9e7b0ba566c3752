"""selection.json, read in one place: each method's C, and the method the development world ranked first.

It is to the choice of the `select` stage what `settings.py` is to params.yaml,
and as light: the stages that fit one model (teach, people) read it too.

The `select` stage writes the file (`taskseq.experiments.selection`); every
stage that fits a model takes each method's C from it through `read_selection`.
A method the file has no C for is an error that says how to give it one, never
another method's C. Without a file (no `--selection`, as in a quick try on one
world) every method takes `UNTUNED_C`, as the option's help says.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

UNTUNED_C = 3.0  # every method's C when no selection file is given: the middle of the grid, untuned


@dataclass(frozen=True)
class Selection:
    """Each method's C as the `select` stage chose it (`settings` of the file), and its ranking's first method."""

    C: Mapping[str, float] = field(default_factory=dict)
    method: str | None = None  # ranked first on the development world
    source: str | None = None  # the file, for messages; None: no file, every method at UNTUNED_C

    def of(self, name: str) -> float:
        """The C of method `name`; raises `ValueError` naming the file when it holds none for it."""
        if self.source is None:
            return UNTUNED_C
        if name not in self.C:
            raise ValueError(f"{self.source}: no C for method {name}: add select to methods.{name}.experiments in "
                             "params.yaml and run `dvc repro select` again (which first chooses its C: "
                             f"`taskseq choose_C --method {name}`)")
        return self.C[name]

    @classmethod
    def uniform(cls, C: float, names: tuple[str, ...]) -> Selection:
        """The same C for the methods `names` (the `select` stage's candidates)."""
        return cls(dict.fromkeys(names, C), source=f"C={C:g}")


def _positive(path: Path, key: str, value: Any) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or value <= 0:
        raise ValueError(f"{path}: field {key!r} must be a positive number, got {value!r}")
    return float(value)


def read_selection(path: Path | str | None) -> Selection:
    """The choice a `select` stage wrote to its JSON file (None: no file), with an error that names the file and
    field."""
    if path is None:
        return Selection()
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no selection file; run `dvc repro select` (each method's "
                                "`taskseq choose_C`, then `taskseq select`)") from None
    except ValueError as err:
        raise ValueError(f"{path}: not valid JSON: {err}") from None
    settings = data.get("settings") if isinstance(data, dict) else None
    if not isinstance(settings, dict):
        raise ValueError(f"{path}: field 'settings' must map each method to its choice, got {settings!r}; run "
                         "`taskseq select` again")
    C = {name: _positive(path, f"settings.{name}.C", choice.get("C") if isinstance(choice, dict) else None)
         for name, choice in settings.items()}
    method = data.get("method")
    return Selection(C, method if isinstance(method, str) and method else None, str(path))
