"""Wording shared by the reports."""

from __future__ import annotations


def counted(count: int, noun: str, plural: str | None = None) -> str:
    """``count`` and ``noun``, the noun plural unless the count is one: "1 contact", "3 contacts"."""
    return f"{count} {noun if count == 1 else plural or noun + 's'}"
