"""Objects of the world and the 14 attributes the model sees of them.

An object is an axis-aligned box. Its `category` and `name` carry the world's
semantics (what is a bin, what is a stirrer) for the simulator, the goal tests
and the demonstrator; the model never sees them, only `attributes()`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

CONTINUOUS_ATTRIBUTES = (
    "height",
    "max_wl",
    "min_wl",
    "volume",
    "min_over_max",
    "median_over_max",
)
BINARY_ATTRIBUTES = (
    "cylinder",
    "box",
    "liquid",
    "container",
    "handle",
    "movable",
    "large_surface",
    "multi_surface",
)
ATTRIBUTE_NAMES = CONTINUOUS_ATTRIBUTES + BINARY_ATTRIBUTES

# Categories the simulator gives meaning to. Anything else is a plain item.
FURNITURE = frozenset({"floor", "table", "shelf"})
VESSELS = frozenset({"cup", "mug", "glass", "bowl", "teacup", "pot", "tumbler", "beaker", "ramekin"})
POURERS = frozenset({"bottle", "pitcher", "carton", "can", "kettle", "jar", "jug", "flask", "thermos"})
CATEGORIES = FURNITURE | VESSELS | POURERS | frozenset({"bin", "liquid", "stirrer", "item"})


@dataclass(frozen=True)
class ObjectSpec:
    """What never changes about an object: identity, size and perceived flags."""

    id: str
    name: str
    category: str
    size: tuple[float, float, float]  # width (x), length (y), height (z), metres
    flags: frozenset[str] = field(default_factory=frozenset)
    # Heights, above the object's base, of the surfaces objects can rest on.
    # Empty means the top face only; a shelf lists one height per level.
    levels: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.category not in CATEGORIES:
            raise ValueError(f"object {self.id}: unknown category {self.category!r}")
        if len(self.size) != 3 or not all(np.isfinite(s) and s > 0 for s in self.size):
            raise ValueError(f"object {self.id}: size must be three positive numbers, got {self.size}")
        unknown = set(self.flags) - set(BINARY_ATTRIBUTES)
        if unknown:
            raise ValueError(f"object {self.id}: unknown flags {sorted(unknown)}")

    @property
    def w(self) -> float:
        return self.size[0]

    @property
    def l(self) -> float:  # noqa: E743 - the paper's name for the length
        return self.size[1]

    @property
    def h(self) -> float:
        return self.size[2]

    def has(self, flag: str) -> bool:
        return flag in self.flags

    def surface_heights(self) -> tuple[float, ...]:
        return self.levels if self.levels else (self.h,)

    def attributes(self) -> dict[str, float]:
        return attributes_of_box(self.size, self.flags)


def attributes_of_box(size: tuple[float, float, float], flags: frozenset[str] | set[str]) -> dict[str, float]:
    """The paper's 14 attributes: six from the box geometry, eight binary flags."""
    w, l, h = (float(s) for s in size)  # noqa: E741
    dims = sorted((w, l, h))
    out = {
        "height": h,
        "max_wl": max(w, l),
        "min_wl": min(w, l),
        "volume": w * l * h,
        "min_over_max": dims[0] / dims[2],
        "median_over_max": dims[1] / dims[2],
    }
    for flag in BINARY_ATTRIBUTES:
        out[flag] = 1.0 if flag in flags else 0.0
    return out
