"""The base of hairdigi's enums of names: each member is its text at the edges (JSON, the command line,
messages), and a value of its own kind inside.

Text is parsed into its enum once, at the edge (``StructureMode(args.structure)``); inside, a member is
compared with members (``mode is StructureMode.FAMILY``). A member still equals its text, so a record or a
flag's text reads the same; with ``HAIRDIGI_STRICT_ENUMS=1`` comparing a member with a plain string raises
instead, so a comparison with a misspelt text cannot pass silently: the test suite runs strict
(``tests/conftest.py``), so a comparison of a member with text anywhere in the packages fails a test.
"""
from __future__ import annotations

import enum
import os

#: Comparing a member with a plain string raises (``HAIRDIGI_STRICT_ENUMS=1``; read once, at import).
STRICT = os.environ.get("HAIRDIGI_STRICT_ENUMS") == "1"


def text_of(value: object) -> object:
    """A member's text as a plain string, any other value as it is: what a check against a tuple of names, or a
    lookup in a dict keyed by text, takes (a member itself would compare as a member)."""
    return str.__str__(value) if isinstance(value, str) else value


class TextEnum(str, enum.Enum):
    """An enum whose members are their text: equal to it, hashed as it, and printed, formatted and
    written to JSON as it (``str(Framing.CROP) == "crop"``), on every Python hairdigi supports."""

    def __str__(self) -> str:
        return str.__str__(self)

    __format__ = str.__format__

    def __eq__(self, other: object) -> bool:
        if STRICT and isinstance(other, str) and not isinstance(other, TextEnum):
            raise TypeError(f"{type(self).__name__}.{self.name} compared with the text {other!r}: parse the "
                            f"text at the edge ({type(self).__name__}({other!r})) and compare members")
        return str.__eq__(self, other)

    def __ne__(self, other: object) -> bool:
        return not self.__eq__(other)

    __hash__ = str.__hash__

    @classmethod
    def knows(cls, value: object) -> bool:
        """Whether ``value`` is a member, or a text that names one (an edge's check before parsing)."""
        return isinstance(value, cls) or (isinstance(value, str) and text_of(value) in cls._value2member_map_)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Every member's text, in order: the choices a command line or a message names."""
        return tuple(member.value for member in cls)
