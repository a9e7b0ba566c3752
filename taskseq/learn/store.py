"""Fitted models addressed by what they were fitted on, so that each is trained once.

Cross-validation, attribute noise, feedback and recipes all need the MRF
trained on the same training folds with the same settings. The `fold_models` stage
trains every one of them once and writes them here; a later stage asks for the
model of its own training steps and settings and gets the stored one. The
address is a hash of the feature set, every learner setting that changes the
weights and the training steps themselves, so a store written for other data
or other settings can never be served by mistake: a miss means "train".
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..features.context import StepContext
from .estimator import StepScorer
from .fit_cache import hash_steps


def training_key(features: str, params: dict[str, Any], contexts: Sequence[StepContext]) -> str:
    """sha256 of the feature set, the learner's settings and every array of every training step."""
    h = hashlib.sha256()
    h.update(json.dumps({"features": features, **params}, sort_keys=True).encode())
    hash_steps(h, contexts)
    return h.hexdigest()


class ModelStore:
    """A folder of `<key>.npz` model files (see `persist`), one per training set and settings."""

    def __init__(self, directory: Path | str) -> None:
        self.directory = Path(directory)

    def path(self, key: str) -> Path:
        return self.directory / f"{key}.npz"

    def load(self, key: str) -> StepScorer | None:
        path = self.path(key)
        return StepScorer.load(path) if path.exists() else None

    def save(self, key: str, scorer: StepScorer, meta: dict[str, Any]) -> None:
        scorer.save(self.path(key), **meta)
