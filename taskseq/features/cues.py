"""Choice cues: which object stands out among like ones, as a person choosing one of several would see it.

Where a task leaves an object open (pour into some vessel, stir with some
stirrer, throw into some bin), the relation features say how each object
compares with the step's reference objects, one object at a time: a linear
score over them can prefer "holds at least 1.75 times the liquid" but not
"the smallest of those that do", since that depends on the other objects in
the room. The cues are those comparisons among objects, each a bit per object:

- `smallest_empty_ge_<r>x_object`: the smallest (by volume) empty movable
  container whose volume is at least r times the task object's, for r in
  steps of a tenth from 1 to 2 (then 2.5, 3, 4): how much of a vessel a
  liquid may fill is for the learner to find, and steps of a quarter (the
  relation columns') put the smallest vessel that holds it at the wrong step
  for 15 of 105 pour scenarios of the development worlds, a tenth for 5;
- `shortest_over_container_by_<m>m`: the shortest (longest side) elongated
  movable object (neither a container nor a liquid, its middle side at most
  half its longest) whose longest side is at least m over the height of the
  container holding the task object. Without "elongated", a book lying flat
  counts as a stick, and is the shortest one long enough in 5 of 100 stir
  scenarios;
- `nearest_of_kind`: the nearest to the robot of the objects sharing its
  binary attributes.

They are read off a step's object rows and relations (sizes, flags, the
liquid a container holds, distances): what perception reports, never a name,
a category or the demonstration. Ties mark every object at the minimum. The
columns are computed from the stored features, so no feature file changes.
"""

from __future__ import annotations

import math

import numpy as np

from .context import BINARY_ATTRIBUTES, LENGTH_MARGINS, OBJECT_COLUMNS, RELATION_COLUMNS

CUE_VOLUME_RATIOS = (*(round(1.0 + k / 10, 1) for k in range(11)), 2.5, 3.0, 4.0)
ELONGATED = 0.5  # middle side over longest side, at most: a stick, not a slab or a box
CUE_COLUMNS = (*(f"smallest_empty_ge_{r:g}x_object" for r in CUE_VOLUME_RATIOS),
               *(f"shortest_over_container_by_{m:g}m" for m in LENGTH_MARGINS),
               "nearest_of_kind")

_OBJ = {c: i for i, c in enumerate(OBJECT_COLUMNS)}
_LOG_RATIO = RELATION_COLUMNS.index("log_volume_ratio_object")  # log10(volume ratio) / 2, clipped to [-1, 1]
_IS_OBJECT = RELATION_COLUMNS.index("is_object")  # the task's object itself: its own relation columns are 0
# a ratio within rounding of a step counts as reaching it (1.2 litres against 1 is "at least 1.2 times")
_LOG_STEPS = np.array([math.log10(r) / 2.0 for r in CUE_VOLUME_RATIOS]) - 1e-12
_REACHES = [RELATION_COLUMNS.index(f"length_over_height_ge_{m:g}m_container") for m in LENGTH_MARGINS]
_FLAGS = [_OBJ[f] for f in BINARY_ATTRIBUTES]


def _least(values: np.ndarray, among: np.ndarray) -> np.ndarray:
    """(..., n, k): 1.0 where object i is in `among[..., :, j]` and has the smallest of their `values` (all 0 when
    none is)."""
    smallest = np.where(among, values[..., None], np.inf).min(axis=-2)
    return (among & (values[..., None] == smallest[..., None, :])).astype(float)


def choice_cues(objects: np.ndarray, relations: np.ndarray, present: np.ndarray | None = None) -> np.ndarray:
    """(..., n, len(CUE_COLUMNS)) from one step's (n, len(OBJECT_COLUMNS)) object rows and (n, len(RELATION_COLUMNS))
    relations, or from a padded batch's (S, n, ...) arrays with `present` (S, n) marking its objects (the padding's
    cues are 0, the other objects' those of their step alone). Volumes and lengths are compared on their scaled
    values, which keep their order."""
    if present is None:
        present = np.ones(objects.shape[:-1], dtype=bool)
    flag = {name: objects[..., _OBJ[name]] > 0.5 for name in ("container", "movable", "liquid", "holds_liquid")}
    # the task's object is no candidate for itself, and without it there is nothing to compare volumes with (the
    # log ratio is 0 in its own row and in every row when it is missing, which would read as "at least 1x")
    is_object = relations[..., _IS_OBJECT] > 0.5
    empty = (flag["container"] & flag["movable"] & ~flag["holds_liquid"] & ~is_object
             & is_object.any(axis=-1, keepdims=True) & present)
    thin = (flag["movable"] & ~flag["container"] & ~flag["liquid"]
            & (objects[..., _OBJ["median_over_max"]] <= ELONGATED) & present)
    flags = objects[..., _FLAGS] > 0.5
    # (..., n, n), symmetric among the objects: column j is j's kind
    same_kind = (flags[..., :, None, :] == flags[..., None, :, :]).all(axis=-1) & present[..., :, None]
    return np.concatenate([
        _least(objects[..., _OBJ["volume"]], empty[..., None] & (relations[..., [_LOG_RATIO]] >= _LOG_STEPS)),
        _least(objects[..., _OBJ["max_wl"]], thin[..., None] & (relations[..., _REACHES] > 0.5)),
        np.diagonal(_least(objects[..., _OBJ["distance"]], same_kind), axis1=-2, axis2=-1)[..., None],
    ], axis=-1)
