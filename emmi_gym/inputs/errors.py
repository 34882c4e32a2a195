"""Errors about bad input (files, options), with short excerpts of the values they found."""

from __future__ import annotations

import reprlib

#: The longest excerpt of a bad value an error message holds.
EXCERPT_CHARS = 80


_SHORT = reprlib.Repr()
_SHORT.maxlevel = 2
_SHORT.maxtuple = _SHORT.maxlist = _SHORT.maxarray = _SHORT.maxdict = _SHORT.maxset = _SHORT.maxfrozenset = 4
_SHORT.maxdeque = 4
_SHORT.maxstring = _SHORT.maxother = 40
_SHORT.maxlong = 40


def excerpt(value) -> str:
    """A short ``repr`` of ``value`` (reprlib's, which never formats what it leaves out: a value
    expanded to billions of characters must not reach, nor be formatted for, a message)."""
    text = _SHORT.repr(value)
    return text if len(text) <= EXCERPT_CHARS else f"{text[:EXCERPT_CHARS]}..."


class FieldError(ValueError):
    """Input is malformed; says where (a file or ``gym.make``), which field (none: the whole file),
    what was expected and (a short excerpt of) what it got."""

    NOTHING = object()  # no value to show (a missing field, an unknown key)

    def __init__(self, source: str, field_path: str, expected: str, got=NOTHING):
        self.source, self.field, self.expected, self.got = source, field_path, expected, got
        got_text = "" if got is FieldError.NOTHING else f", got {excerpt(got)}"
        where = f"{source}: field '{field_path}'" if field_path else source
        super().__init__(f"{where}: expected {expected}{got_text}")

    def __reduce__(self):
        """Pickled by its fields, so that an error raised in a worker process reaches the parent whole."""
        got = () if self.got is FieldError.NOTHING else (self.got,)
        return type(self), (self.source, self.field, self.expected, *got)


#: What the package's readers raise for bad input, and nothing else: a :class:`FieldError` (or one of its
#: kinds: ``OptionError``, ``AgentConfigError``, ``ModelFileError``, ``DemonstrationsError``, ``CsvFileError``,
#: ``TrainingRecordError``, ``WorldFileError``...) naming the file and field, or a ``FileNotFoundError``
#: where there is nothing at the path given. Commands turn these into one-line messages.
INPUT_ERRORS = (FieldError, FileNotFoundError)
