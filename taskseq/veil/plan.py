"""Planning in one environment file: the domain read from the release folder it came from, the state from the file.

`taskseq veil plan` needs only an environment file, an objective and a model:
the domain (`domainKnowledge.pddl`), the categories (`Objects.xml`) and the
instructions (`ControllerInstructions.xml`) come from the folder that holds the
file's `Environments/` folder, or from `--release`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from .pddl import Domain, read_domain
from .release import ROOMS, Catalog, read_environment, read_instructions, read_objects
from .state import State, initial_state
from .xmltree import VeilFormatError

_NUMBER = re.compile(r"(\d+)$")


@dataclass(frozen=True)
class DomainFiles:
    """What a release says of its domain, apart from its environments and sequences."""

    domain: Domain
    catalog: Catalog
    instructions: dict[str, tuple[tuple[str, ...], ...]]


def domain_of(environment: Path | str, release: Path | str | None = None) -> DomainFiles:
    """The domain files of `release`, or of the release folder `environment` lies in (`Environments/<room>/`)."""
    environment = Path(environment)
    root = Path(release) if release is not None else environment.resolve().parent.parent.parent
    missing = [f for f in ("Objects.xml", "domainKnowledge.pddl", "ControllerInstructions.xml")
               if not (root / f).is_file()]
    if missing:
        raise FileNotFoundError(f"{root}: no {', '.join(missing)} (give the release folder with --release)")
    return DomainFiles(read_domain(root / "domainKnowledge.pddl"), read_objects(root / "Objects.xml"),
                       read_instructions(root / "ControllerInstructions.xml"))


def environment_state(path: Path | str, files: DomainFiles) -> State:
    """The initial state of an environment file named as the release names them (`kitchen3.xml`,
    `livingRoom5.xml`)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such environment file")
    room = next((r for r in ROOMS if path.stem.lower().startswith(r.lower())), None)
    number = _NUMBER.search(path.stem)
    if room is None or number is None:
        raise VeilFormatError(path, 0, "(file name)", f"expected a name like {ROOMS[0]}3.xml or {ROOMS[1]}5.xml")
    return initial_state(read_environment(path, room, int(number.group(1))), files.catalog)
