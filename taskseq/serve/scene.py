"""The scene as a person reads it: a top view (shapes for an inline SVG) and a tree of what stands where.

Only numbers and the objects' names leave this module; the template escapes
every name, so an environment file cannot put markup in the page.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from ..sim.objects import FURNITURE
from ..sim.state import INSIDE, REACH, WorldState

MAX_SCALE = 240.0  # pixels per metre at most
WIDTH = 1060.0  # pixels the room is fitted into at most
MARGIN = 30.0
TOP = 120.0  # room above the wall for the slanted labels of items
LABEL_GAP = 16.0  # pixels between two slanted labels' lines, measured along a row (11 px across the slant)
ROBOT_LABEL_AT = 16.0  # pixels from the robot's centre to where its label starts
CHAR_WIDTH = 8.0  # pixels a character of the robot's bold label takes at most, about, in a sans-serif font
LABEL_LIFT = 3.0  # pixels above its top edge where an item's slanted name starts (scene.html writes it there)
TEXT_WIDTH = 7.5  # pixels a character of a 12 px name takes at most, about (DejaVu Sans: 'a' 7.4, 'm' 11.7, 'i' 3.3)
TEXT_HEIGHT = 12.0  # pixels of a name's line across its baseline, halo and all
WALL_LINE = 22.0  # pixels kept above everything drawn for the line saying where the wall is
PAD = 10.0  # pixels between what is drawn and the edge of the picture


@dataclass(frozen=True)
class Shape:
    """One object's footprint in pixels, with its label (its name, the liquids inside and its shelf level: the
    page draws each liquid's name as a shape of its own, which a click chooses)."""

    id: str
    x: float
    y: float
    w: float
    h: float
    kind: str  # furniture, bin, vessel, item
    label: str
    full: bool  # holds a liquid
    anchor: float  # x where its slanted label starts
    name: str = ""
    liquids: tuple[tuple[str, str], ...] = ()  # (id, name) of each liquid inside
    level: int | None = None  # shelf level it stands on
    # A slanted name moved right of its shape's middle (so as not to write over another name) may start over a
    # neighbouring object and read as that one's: a thin line leads from where it starts back to the middle of its
    # own shape's top edge, where an unmoved name starts. (x1, y1, x2, y2): the name's start, then the shape's edge.
    leader: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class TopView:
    width: float
    height: float
    shapes: list[Shape]
    robot: tuple[float, float]
    reach: float  # radius of the arm's reach, pixels
    held: str | None  # label of the held object, drawn beside the robot

    @property
    def robot_label(self) -> str:
        """What is written right of the robot: `robot, holding water_bottle (water), above cup`."""
        return "robot" + (f", holding {self.held}" if self.held else "")

    @property
    def robot_label_x(self) -> float:
        """Where the robot's label starts, pixels."""
        return round(self.robot[0] + ROBOT_LABEL_AT, 1)

    @property
    def box(self) -> tuple[float, float, float, float]:
        """The part of the picture anything is drawn in, as the SVG's viewBox (x, y, width, height), a line above it
        left for the wall's caption: every shape, every name (a slanted one rises along its length from its start;
        their lengths are reckoned from their characters, generously), the robot, its label and the whole of the arm's
        reach. The room is drawn on `width` x `height`, with room to spare around it; this leaves that out, and
        nothing drawn moves."""
        xs: list[float] = [self.robot[0] - self.reach, self.robot[0] + self.reach,
                           self.robot_label_x + CHAR_WIDTH * len(self.robot_label)]
        ys: list[float] = [self.robot[1] - self.reach, self.robot[1] + self.reach]
        rise = TEXT_HEIGHT / 2 ** 0.5  # a slanted name's line, across: up and to the left of its baseline
        for s in self.shapes:
            xs += [s.x, s.x + s.w]
            ys += [s.y, s.y + s.h]
            if s.kind in ("vessel", "item"):  # rises to the right at 45 degrees from (anchor, top - LABEL_LIFT)
                run = TEXT_WIDTH * len(s.label) / 2 ** 0.5
                xs += [s.anchor - rise, s.anchor + run + rise]
                ys += [s.y - LABEL_LIFT - run - rise]
            else:  # furniture and bins: bold, under the shape (scene.html writes it 15 px below)
                xs += [s.x + 4 + CHAR_WIDTH * len(s.label)]
                ys += [s.y + s.h + 15 + TEXT_HEIGHT / 3]
        x0, x1 = min(xs) - PAD, max(xs) + PAD
        y0, y1 = min(ys) - PAD - WALL_LINE, max(ys) + PAD
        return round(x0, 1), round(y0, 1), round(x1 - x0, 1), round(y1 - y0, 1)


@dataclass
class Node:
    """An object and what rests on or in it."""

    id: str
    name: str
    relation: str  # "on" or "inside" its parent ("" for furniture)
    level: int | None  # shelf level it stands on, from 1 at the bottom
    children: list[Node] = field(default_factory=list)


def _label(state: WorldState, obj: str) -> str:
    name = state.specs[obj].name
    liquids = state.liquids_in(obj)
    return f"{name} ({', '.join(state.specs[li].name for li in liquids)})" if liquids else name


def _level(state: WorldState, obj: str) -> int | None:
    """Which level of a multi-level parent `obj` stands on, if its parent has levels."""
    parent = state.support.get(obj)
    if parent is None or len(state.specs[parent[0]].surface_heights()) < 2:
        return None
    z = state.poses[obj][2] - state.poses[parent[0]][2]
    heights = state.specs[parent[0]].surface_heights()
    return min(range(len(heights)), key=lambda k: abs(heights[k] - z)) + 1


def _leader(anchor: float, middle: float, top: float) -> tuple[float, float, float, float] | None:
    """The line from a slanted name's start back to the middle of its shape's top edge, where the name was moved
    away from there; None where it starts there (the layout moves a name right only: less than a tenth of a
    pixel is rounding)."""
    if anchor - middle < 0.1:
        return None
    return round(anchor, 1), round(top - LABEL_LIFT, 1), round(middle, 1), round(top, 1)


def top_view(state: WorldState) -> TopView:
    """Footprints seen from above, the wall at the top and the robot below; liquids show in their container."""
    shown = [o for o in state.specs if state.specs[o].category != "floor" and o != state.held
             and state.container_of(o) is None]
    furniture = [o for o in shown if state.specs[o].category in FURNITURE or state.specs[o].category == "bin"]
    boxes = [state.box(o) for o in furniture] or [state.box(o) for o in shown]
    xmin = min([b[0] for b in boxes] + [state.robot[0] - 0.5])
    xmax = max([b[3] for b in boxes] + [state.robot[0] + 0.5])
    ymin = min([b[1] for b in boxes] + [state.robot[1] - REACH - 0.05])
    ymax = max([b[4] for b in boxes] + [state.robot[1]])
    scale = min(MAX_SCALE, (WIDTH - 2 * MARGIN) / (xmax - xmin))

    def px(x: float, y: float) -> tuple[float, float]:
        return round(MARGIN + (x - xmin) * scale, 1), round(TOP + (ymax - y) * scale, 1)

    order = sorted(shown, key=lambda o: (state.specs[o].category not in FURNITURE, state.poses[o][2], o))
    shapes: list[Shape] = []
    # An item's label rises to the right at 45 degrees from (anchor, its top edge), so it lies on the line
    # x + y = anchor + top; two labels are apart when their lines are, whatever their rows: items at different depths
    # on a deep shelf or table would otherwise write over each other. A label whose line comes too near one drawn
    # before (a stacked item's, its base's) starts just far enough right: past each such line in turn, in order.
    lines: list[float] = []
    for o in order:
        spec = state.specs[o]
        x0, y0, _, x1, y1, _ = state.box(o)
        (ax, ay), (bx, by) = px(x0, y1), px(x1, y0)
        w, h = max(bx - ax, 8.0), max(by - ay, 8.0)
        kind = ("furniture" if spec.category in FURNITURE else "bin" if spec.category == "bin"
                else "vessel" if spec.has("container") else "item")
        level = _level(state, o)
        label = _label(state, o) + (f" · level {level}" if level else "")
        anchor = ax + w / 2
        if kind in ("vessel", "item"):
            line = anchor + ay
            for drawn in sorted(lines):
                if abs(line - drawn) < LABEL_GAP:
                    line = drawn + LABEL_GAP
            lines.append(line)
            anchor = line - ay
        liquids = tuple((li, state.specs[li].name) for li in state.liquids_in(o))
        shapes.append(Shape(o, ax, ay, round(w, 1), round(h, 1), kind, label, bool(liquids), round(anchor, 1),
                            spec.name, liquids, level, _leader(anchor, ax + w / 2, ay)))
    rx, ry = px(*state.robot)
    held = None
    if state.held is not None:
        held = _label(state, state.held)
        if state.held_above is not None:
            held += f", above {state.specs[state.held_above].name}"
    height = TOP + (ymax - ymin) * scale + 2 * MARGIN + 20
    view = TopView(0.0, round(height, 1), shapes, (rx, ry), round(REACH * scale, 1), held)
    width = max(2 * MARGIN + (xmax - xmin) * scale + 160,  # room for the robot's label, however long
                view.robot_label_x + CHAR_WIDTH * len(view.robot_label) + MARGIN)
    return replace(view, width=round(width, 1))


def support_tree(state: WorldState) -> list[Node]:
    """Furniture (and anything standing on the floor), each with what rests on or in it, recursively."""

    def node(obj: str) -> Node:
        rel = state.support.get(obj, ("", ""))[1]
        n = Node(obj, state.specs[obj].name, "inside" if rel == INSIDE else "on", _level(state, obj))
        n.children = [node(c) for c in state.children(obj)]
        return n

    floor = [o for o in state.specs if state.specs[o].category == "floor"]
    roots = [c for f in floor for c in state.children(f)]
    roots += [o for o in state.specs if o not in state.support and o not in floor and o != state.held]
    return [node(o) for o in sorted(roots, key=lambda o: (state.poses[o][0], o))]
