"""Model files: NumPy .npz holding only arrays and JSON text, loadable with allow_pickle=False.

A model file from someone else cannot run code when it is loaded. The zip
entries carry a fixed date, so the same weights give the same bytes (and the
same hash in `dvc.lock`) on every run. Its metadata names the method of
Table I it was trained as, that method's settings and the policy its
programs pick steps with; files written before the method or the policy was
recorded load as they did, and say so (`describe`): such a file plans with
the greedy policy, the only one they were ever planned with.

Format 2 names the weights by their families' long names
(`primitive_previous_task1[pour,hold_above->follow_traj_pour]`); format 1 used
the paper's short names (`ppt1[...]`) for the same weights in the same order,
and a file of format 1 still loads: its names are read through `FORMAT_1_BLOCKS`.

Format 3 keeps the same names as one UTF-8 text, a name per line, in a byte
array (`feature_names`: `bytes(z["feature_names"]).decode().split("\n")`): a
fixed-width NumPy string array stored every name in 4 bytes a character at
the longest name's width, 3.3 MB of a 3.4 MB file for the choice-cue model's
9,429 weights (75 kB), in every one of the hundreds of fold models a run
writes and DVC hashes and copies; the text is 0.5 MB. Files of formats 1 and
2 still load.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ..runtime.atomic import write_arrays
from .mrf import StepMRF

FORMAT = "taskseq.mrf/3"
FORMAT_2 = "taskseq.mrf/2"  # the names as a fixed-width string array
FORMAT_1 = "taskseq.mrf/1"
# the block names of format 1 (the paper's short family names) and those that replaced them
FORMAT_1_BLOCKS = {
    "ae1": "argument_environment1", "ae2": "argument_environment2", "ae_pair": "argument_environment_pair",
    "pt": "primitive_task",
    "aet_rel1": "argument_environment_task_relation1", "aet_obj1": "argument_environment_task_object1",
    "aet_rel2": "argument_environment_task_relation2", "aet_obj2": "argument_environment_task_object2",
    "pae1": "primitive_argument_environment1", "pae2": "primitive_argument_environment2",
    "ppt1": "primitive_previous_task1", "ppt2": "primitive_previous_task2",
    "paae1": "primitive_argument_previous_argument1", "paae2": "primitive_argument_previous_argument2",
    "rel1": "relations1", "rel2": "relations2", "rel_pair": "relations_pair",
    "cue1": "cues1", "cue2": "cues2",
}


def save_model(path: Path | str, model: StepMRF, w: np.ndarray, params: dict[str, Any]) -> None:
    meta = {"format": FORMAT, "features": model.features, **params}
    names = np.frombuffer("\n".join(model.feature_names()).encode("utf-8"), dtype=np.uint8)
    write_arrays(path, {"w": np.asarray(w, dtype=np.float64), "feature_names": names,
                        "meta": np.array(json.dumps(meta, sort_keys=True))})


def load_model(path: Path | str) -> tuple[StepMRF, np.ndarray, dict[str, Any]]:
    """The model, its weights and the parameters it was trained with."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such model file (run `dvc repro train` or `taskseq train`)")
    if not zipfile.is_zipfile(path):  # else NumPy's reason is about pickles, which a model never holds
        raise ValueError(f"{path}: not a readable taskseq model file (not the .npz archive `taskseq train` writes)")
    try:
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            arrays = {name: z[name] for name in ("w", "feature_names") if name in z.files}
    except KeyError as err:
        raise ValueError(f"{path}: not a taskseq model file (missing {err.args[0]})") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise ValueError(f"{path}: not a readable taskseq model file ({err})") from None
    if str(meta.get("format")).startswith("taskseq.veil"):
        raise ValueError(f"{path}: a VEIL-500 model (`taskseq veil train`), not one of `taskseq train`: it plans in "
                         "a release's environment files (`taskseq plan --env <release>/Environments/...xml`)")
    for name in ("w", "feature_names"):
        if name not in arrays:
            raise ValueError(f"{path}: not a taskseq model file (missing {name})")
    w, stored = arrays["w"], arrays["feature_names"]
    try:
        names = bytes(stored).decode("utf-8").split("\n") if meta.get("format") == FORMAT else [str(n) for n in stored]
    except ValueError as err:  # a bad UTF-8 text
        raise ValueError(f"{path}: not a readable taskseq model file ({err})") from None
    if meta.get("format") == FORMAT_1:
        names = [_format_1_name(n) for n in names]
    elif meta.get("format") not in (FORMAT, FORMAT_2):
        raise ValueError(f"{path}: format {meta.get('format')!r}, expected {FORMAT!r} (or the older {FORMAT_2!r} or "
                         f"{FORMAT_1!r})")
    model = StepMRF(meta["features"])
    if names != model.feature_names():
        raise ValueError(f"{path}: its feature names do not match this version's {meta['features']!r} model")
    return model, w, meta


def _format_1_name(name: str) -> str:
    """A weight's name in format 2 from its name in format 1 (`ppt1[...]` -> `primitive_previous_task1[...]`)."""
    block, bracket, labels = name.partition("[")
    return FORMAT_1_BLOCKS.get(block, block) + bracket + labels


DEFAULT_POLICY = "greedy"  # the policy of a file that records none: every file before policies were recorded


def policy_of(meta: dict[str, Any]) -> str:
    """The policy a model file's programs pick steps with (`plan.planner.POLICIES` names them)."""
    return str(meta.get("policy", DEFAULT_POLICY))


def describe(meta: dict[str, Any]) -> str:
    """One line on what a model file holds: its method, the settings it was trained with, and how many of its
    training sequences people demonstrated (`taskseq serve`, with `people.train`) where any did."""
    learner = ", ".join(f"{k} {meta[k]:g}" if isinstance(meta[k], float) else f"{k} {meta[k]}"
                        for k in ("C", "tol", "max_iter", "n_slacks") if k in meta)
    policy = (f"policy {meta['policy']}" if "policy" in meta else
              f"policy {DEFAULT_POLICY} (not recorded: a file from before policies were recorded)")
    if "method" not in meta:
        return (f"method not recorded (a model file from before methods were recorded): {meta['features']} feature "
                f"set, {learner}, {policy}")
    noisy = (f"{meta['noise_copies']} noisy copies at flip rate {meta['noise_rate']:g}, "
             if meta.get("noise_copies") else "")
    people = f"people's sequences {meta['people_sequences']}, " if meta.get("people_sequences") else ""
    extra = (f"chained starts {'yes' if meta.get('chained_starts') else 'no'}, "
             f"DAgger rounds {meta.get('dagger_rounds', 0)}, {noisy}{people}{policy}")
    why = f"; {meta['chosen_by']}" if meta.get("chosen_by") else ""
    return (f"{meta.get('label', meta['method'])} (method {meta['method']}: {meta['features']} feature set, {learner}, "
            f"{extra}{why})")
