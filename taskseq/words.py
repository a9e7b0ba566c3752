"""Counts that agree with their number, for the messages and lines a person reads."""

from __future__ import annotations

_SPELLED = {0: "no", 1: "one", 2: "two"}


def number(n: int) -> str:
    """A small count in words, as a sentence writes it (`no`, `one`, `two`), a larger one in digits."""
    return _SPELLED.get(n, str(n))


def counted(n: int, noun: str, spelled: bool = False) -> str:
    """`1 sequence`, `3 sequences`; `spelled` writes the small counts in words (`no objects`, `one object`),
    as a sentence does, where a command's summary line keeps digits beside other digits."""
    return f"{number(n) if spelled else n} {noun}{'s' * (n != 1)}"
