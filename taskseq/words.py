"""Counts that agree with their number, for the messages and lines a person reads."""

from __future__ import annotations

_SPELLED = {0: "no", 1: "one", 2: "two"}


def counted(n: int, noun: str, spelled: bool = False) -> str:
    """`1 sequence`, `3 sequences`; `spelled` writes the small counts in words (`no object`, `two objects`),
    as a sentence does, where a command's summary line keeps digits beside other digits."""
    number = _SPELLED.get(n, str(n)) if spelled else str(n)
    return f"{number} {noun}{'s' * (n != 1)}"
