"""Choice cues: which object stands out among like ones, as a person choosing one of several would see it.

Where a task leaves an object open (pour into some vessel, stir with some
stirrer, throw into some bin), the relation features say how each object
compares with the step's reference objects, one object at a time: a linear
score over them can prefer "holds at least 1.75 times the liquid" but not
"the smallest of those that do", since that depends on the other objects in
the room. The cues are those comparisons among objects, each a bit per object:

- `smallest_empty_ge_<r>x_object`: the smallest (by volume) empty movable
  container whose volume is at least r times the task object's;
- `shortest_over_container_by_<m>m`: the shortest (longest side) movable
  object that is neither a container nor a liquid and whose longest side is
  at least m over the height of the container holding the task object;
- `nearest_of_kind`: the nearest to the robot of the objects sharing its
  binary attributes.

They are read off a step's object rows and relations (sizes, flags, the
liquid a container holds, distances): what perception reports, never a name,
a category or the demonstration. Ties mark every object at the minimum. The
columns are computed from the stored features, so no feature file changes.
"""

from __future__ import annotations

import numpy as np

from .context import BINARY_ATTRIBUTES, LENGTH_MARGINS, OBJECT_COLUMNS, RELATION_COLUMNS, VOLUME_RATIOS

CUE_COLUMNS = (*(f"smallest_empty_ge_{r:g}x_object" for r in VOLUME_RATIOS),
               *(f"shortest_over_container_by_{m:g}m" for m in LENGTH_MARGINS),
               "nearest_of_kind")

_OBJ = {c: i for i, c in enumerate(OBJECT_COLUMNS)}
_VOLUME_GE = [RELATION_COLUMNS.index(f"volume_ge_{r:g}x_object") for r in VOLUME_RATIOS]
_REACHES = [RELATION_COLUMNS.index(f"length_over_height_ge_{m:g}m_container") for m in LENGTH_MARGINS]
_FLAGS = [_OBJ[f] for f in BINARY_ATTRIBUTES]


def _least(values: np.ndarray, among: np.ndarray) -> np.ndarray:
    """(n, k): 1.0 where object i is in `among[:, j]` and has the smallest of their `values` (all 0 when none is)."""
    smallest = np.where(among, values[:, None], np.inf).min(axis=0)
    return (among & (values[:, None] == smallest[None, :])).astype(float)


def choice_cues(objects: np.ndarray, relations: np.ndarray) -> np.ndarray:
    """(n, len(CUE_COLUMNS)) from one step's (n, len(OBJECT_COLUMNS)) object rows and (n, len(RELATION_COLUMNS))
    relations. Volumes and lengths are compared on their scaled values, which keep their order."""
    flag = {name: objects[:, _OBJ[name]] > 0.5 for name in ("container", "movable", "liquid", "holds_liquid")}
    empty = flag["container"] & flag["movable"] & ~flag["holds_liquid"]
    thin = flag["movable"] & ~flag["container"] & ~flag["liquid"]
    flags = objects[:, _FLAGS] > 0.5
    same_kind = (flags[:, None, :] == flags[None, :, :]).all(axis=2)  # (n, n), symmetric: column j is j's kind
    return np.hstack([
        _least(objects[:, _OBJ["volume"]], empty[:, None] & (relations[:, _VOLUME_GE] > 0.5)),
        _least(objects[:, _OBJ["max_wl"]], thin[:, None] & (relations[:, _REACHES] > 0.5)),
        _least(objects[:, _OBJ["distance"]], same_kind).diagonal()[:, None],
    ])
