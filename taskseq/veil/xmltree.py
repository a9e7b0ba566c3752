"""A small XML tree that remembers the line of every element, and the one error type of the VEIL reader.

The standard library's `xml.etree` reports where a file fails to parse but not where a well-formed element sits,
and a missing or malformed element must be reported by its line (docs/veil.md); lxml is not a dependency of the
project, so elements are built here from expat's events, which carry the current line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat


class VeilFormatError(ValueError):
    """One problem in one file of the release: the file, the line, the element and what was wrong.

    A `ValueError`, so the command line turns it into one line and exit code 2.
    """

    def __init__(self, path: Path | str, line: int, element: str, message: str) -> None:
        super().__init__(f"{path}:{line}: {element}: {message}")
        self.path, self.line, self.element, self.message = str(path), line, element, message


@dataclass
class Node:
    """One element: its tag, attributes, stripped text (children's text excluded), children and line."""

    tag: str
    line: int
    attrs: dict[str, str] = field(default_factory=dict)
    text: str = ""
    children: list[Node] = field(default_factory=list)

    def all(self, tag: str) -> list[Node]:
        """Children with this tag (case-insensitive: the release writes `stateName` and `statename`)."""
        return [c for c in self.children if c.tag.lower() == tag.lower()]

    def first(self, tag: str) -> Node | None:
        found = self.all(tag)
        return found[0] if found else None

    def iter(self, tag: str) -> list[Node]:
        """Descendants with this tag, in document order."""
        out: list[Node] = []
        for c in self.children:
            if c.tag.lower() == tag.lower():
                out.append(c)
            out.extend(c.iter(tag))
        return out


def read_xml(path: Path | str) -> Node:
    """Parse a file into `Node`s; a missing or malformed file raises `VeilFormatError` with expat's position."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise VeilFormatError(path, 0, "(file)", f"cannot be read: {err.strerror or err}") from None
    parser = expat.ParserCreate()
    stack: list[Node] = []
    texts: list[list[str]] = []
    root: list[Node] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        node = Node(tag, parser.CurrentLineNumber, dict(attrs))
        if stack:
            stack[-1].children.append(node)
        else:
            root.append(node)
        stack.append(node)
        texts.append([])

    def end(tag: str) -> None:
        node = stack.pop()
        node.text = "".join(texts.pop()).strip()

    def chars(data: str) -> None:
        if texts:
            texts[-1].append(data)

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except expat.ExpatError as err:
        raise VeilFormatError(path, err.lineno, "(xml)", f"not well-formed XML: {expat.ErrorString(err.code)} "
                              f"(column {err.offset + 1})") from None
    return root[0]


def child_text(path: Path | str, node: Node, tag: str) -> tuple[str, int]:
    """The text of `node`'s one child `tag` and its line; a missing child is a `VeilFormatError` at `node`."""
    child = node.first(tag)
    if child is None:
        raise VeilFormatError(path, node.line, f"<{node.tag}>", f"has no <{tag}>")
    return child.text, child.line
