"""Errors about bad input files, shared by the world files and the agent configurations."""

from __future__ import annotations


class FieldError(ValueError):
    """A file (or dict) is malformed; says which file, which field, what was expected and what it got."""

    def __init__(self, source: str, field_path: str, expected: str, got=None):
        self.source, self.field, self.expected, self.got = source, field_path, expected, got
        got_text = "" if got is None else f", got {got!r}"
        super().__init__(f"{source}: field '{field_path}': expected {expected}{got_text}")
