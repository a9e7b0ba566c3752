"""Settings files for tests that run stages: params.yaml with a methods section of their own, a selection file."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from taskseq.methods import specs

ROOT = Path(__file__).resolve().parents[1]


def params_with(path: Path, **experiments: str) -> list[str]:
    """`--params` of a copy of params.yaml at `path` whose methods section gives these methods these experiments
    (the rest run in Table I only, at their settings' defaults)."""
    data = yaml.safe_load((ROOT / "params.yaml").read_text())
    data["methods"] = {name: {"experiments": value} for name, value in experiments.items()}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return ["--params", str(path)]


def selection_at(path: Path, C: float) -> Path:
    """A selection file that gives every method the same C, as `select` would write it had it tried only C."""
    path.write_text(json.dumps({"settings": {name: {"C": C} for name in specs()}}))
    return path
