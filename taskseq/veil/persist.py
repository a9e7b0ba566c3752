"""A trained people's-demonstrations model as a file: weights, what its rows hold, and the goals it learned.

The file is a NumPy .npz of arrays and JSON text only, loadable with
`allow_pickle=False`, as the paper world's model files are (`taskseq.learn.persist`):
a model from someone else cannot run code when it is loaded, and the same
weights give the same bytes. Beside the weights it keeps the vocabulary (the
columns of an object's row and the objectives it knows), the goal of each
objective derived from its training sequences (`evaluate.derive_goals`), so a
folder of other environments is scored against the goals the model was
trained toward, the environments it was trained on, and the width of the goal
lookahead chosen with it (`lookahead.GoalLookahead`), so the model plans as the
evaluation's best row does.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..runtime.atomic import write_arrays
from .features import Vocabulary
from .methods import DomainScorer

FORMAT = "taskseq.veil-mrf/2"
Goals = dict[str, frozenset[tuple[str, ...]]]


@dataclass
class TrainedModel:
    """A model for use: the fitted MRF, the goals it was trained toward, its environments, the lookahead's width."""

    method: DomainScorer
    goals: Goals
    trained_on: list[str]
    lookahead_width: int


def save_mrf(path: Path | str, model: TrainedModel) -> None:
    method, v = model.method, model.method.vocabulary
    meta = {"format": FORMAT, "name": method.name, "features": method.features, "C": method.C, "tol": method.tol,
            "vocabulary": {"affordances": list(v.affordances), "states": list(v.states),
                           "categories": list(v.categories), "objectives": list(v.objectives)},
            "goals": {o: sorted(list(f) for f in facts) for o, facts in sorted(model.goals.items())},
            "trained_on": sorted(model.trained_on), "lookahead_width": model.lookahead_width}
    write_arrays(path, {"w": np.asarray(method.w_, dtype=np.float64),
                        "meta": np.array(json.dumps(meta, sort_keys=True))})


def load_mrf(path: Path | str) -> tuple[TrainedModel, dict[str, Any]]:
    """The model and the file's metadata; a clear error for anything else."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such model file (run `dvc repro veil/dvc.yaml` or `taskseq veil train`)")
    if not zipfile.is_zipfile(path):  # else NumPy's reason is about pickles, which a model never holds
        raise ValueError(f"{path}: not a readable taskseq VEIL model file (not the .npz archive `taskseq veil train` "
                         "writes)")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            w = np.array(z["w"])
    except KeyError as err:
        raise ValueError(f"{path}: not a taskseq VEIL model file (missing {err.args[0]})") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise ValueError(f"{path}: not a readable taskseq VEIL model file ({err})") from None
    if str(meta.get("format")).startswith("taskseq.mrf"):
        raise ValueError(f"{path}: a model of `taskseq train` (the simulated kitchens), not a VEIL-500 model: give "
                         "one `taskseq veil train` wrote")
    if meta.get("format") != FORMAT:
        raise ValueError(f"{path}: format {meta.get('format')!r}, expected {FORMAT!r}")
    v = meta["vocabulary"]
    vocabulary = Vocabulary(tuple(v["affordances"]), tuple(v["states"]), tuple(v["categories"]),
                            tuple(v["objectives"]))
    method = DomainScorer(meta["name"], vocabulary, meta["features"], C=meta["C"], tol=meta["tol"])
    if w.shape != (method.model_.size_joint_feature,):
        raise ValueError(f"{path}: {w.shape[0]} weights, but its vocabulary makes {method.model_.size_joint_feature}")
    method.w_ = w
    goals = {o: frozenset(tuple(f) for f in facts) for o, facts in meta["goals"].items()}
    return TrainedModel(method, goals, list(meta["trained_on"]), int(meta["lookahead_width"])), meta
