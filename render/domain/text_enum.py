"""The base of hairdigi's enums of names: each member is its text at the edges (JSON, the command line,
messages), and a value of its own kind inside."""
from __future__ import annotations

import enum


class TextEnum(str, enum.Enum):
    """An enum whose members are their text: equal to it, hashed as it, and printed, formatted and
    written to JSON as it (``str(Framing.CROP) == "crop"``), on every Python hairdigi supports."""

    def __str__(self) -> str:
        return str.__str__(self)

    __format__ = str.__format__

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Every member's text, in order: the choices a command line or a message names."""
        return tuple(member.value for member in cls)
