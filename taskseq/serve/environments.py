"""The environments a person can work in: any world's catalog environment, or a user's environment file.

Each gets an id that is safe as a file name and that names one initial
state: the id of an environment file carries a hash of its content, so two
different files with the same name never share a log file (whose records
`taskseq ingest` requires to describe the same objects).
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..demonstrations.records import spec_from_dict, spec_to_dict, state_from_dict, state_to_dict
from ..product import parse_environment
from ..sim.catalog import ENVIRONMENTS, ENVIRONMENTS_BY_ID, build_environment
from ..sim.state import WorldState

SAFE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}\Z")  # file names and participant ids: no dots, no slashes,
# no newline (`$` would let a final one through)
MAX_SEED = 2**31 - 1


@dataclass(frozen=True)
class Environment:
    """Where a person works: the initial state, and the id its records are filed under."""

    env_id: str
    label: str  # what the page calls it
    state: WorldState


def world_environment(seed: int, env_id: str) -> Environment:
    """Catalog environment `env_id` as world `seed` draws it (the same jitter as `taskseq generate --world-seed`)."""
    if not 0 <= seed <= MAX_SEED:
        raise ValueError(f"world seed must be a whole number from 0 to {MAX_SEED}, got {seed}")
    if env_id not in ENVIRONMENTS_BY_ID:
        raise ValueError(f"unknown environment {env_id!r}; known: {', '.join(e.id for e in ENVIRONMENTS)}")
    rng = np.random.default_rng(seed)
    for env in ENVIRONMENTS:  # the jitter of each environment depends on those drawn before it
        state = build_environment(env, rng)
        if env.id == env_id:
            return Environment(f"w{seed}-{env_id}", f"{env_id} of world {seed}", state)
    raise AssertionError(env_id)


def file_environment(name: str, text: str) -> Environment:
    """An environment file's content (uploaded or named), checked as `taskseq plan --env` checks it."""
    stem = Path(name).name.removesuffix(".json")
    safe = re.sub(r"[^A-Za-z0-9_-]", "_", stem)[:40].strip("_-") or "environment"
    objects, state_dict = parse_environment(name, text)
    specs = {o["id"]: spec_from_dict(o) for o in objects}
    state = state_from_dict(specs, state_dict)
    content = json.dumps({"objects": [spec_to_dict(s) for s in specs.values()], "state": state_to_dict(state)},
                         sort_keys=True)
    digest = hashlib.sha256(content.encode()).hexdigest()[:8]
    return Environment(f"{safe}-{digest}", f"{Path(name).name}", state)


def named_files(folder: Path) -> list[str]:
    """The environment files a person can pick by name: `*.json` directly in `folder`, safe names only."""
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.glob("*.json") if SAFE_NAME.match(p.stem) and p.is_file())


def read_named(folder: Path, name: str) -> Environment:
    """A named environment file of `folder`; any other name (a path, `..`) is refused, never opened."""
    if name not in named_files(folder):
        raise ValueError(f"no environment file {name!r} in {folder.name}/; choose one of the list")
    return file_environment(name, (folder / name).read_text(encoding="utf-8"))
