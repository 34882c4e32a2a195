"""One mechanism for checking what users hand in: option dataclasses, their fields and bounds.

Each checked dataclass declares its fields with :func:`option` (a default and a :class:`Check`);
its ``__post_init__`` calls :func:`check_fields`, and :func:`build` makes one from a dict of
options (unknown names, wrong types and values out of bounds all raise :class:`OptionError`
naming the option, what was expected and a short excerpt of what was found). A field of nested
options (:class:`Options`) holds the built dataclass, so a tree of options is built and checked
once, and its errors name the whole path (``laser.n_beams``). Upper bounds keep a few bytes of
input from asking for gigabytes; where a bound is about memory the message says how much the
value would take.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, fields

from .errors import FieldError, excerpt

#: The longest laser range anything accepts, metres (real 2D scanners reach 80 m at most).
MAX_LASER_RANGE = 100.0
#: The most episodes one command plays or scores (a count past it is a typo, not an experiment: at a
#: second an episode it would take a day on 16 cores).
MAX_EPISODES = 100_000


class OptionError(FieldError):
    """An option (``gym.make`` keyword, nested option dict, configuration field) is invalid."""


class Invalid(Exception):
    """Raised by a :class:`Check` with the text of what was expected."""


class Check:
    """Validates and normalises one value; ``describe`` is the 'expected ...' text. A check raises
    :class:`Invalid`, or the :class:`OptionError` of a nested option (its field path relative to the value)."""

    def __call__(self, value):
        raise NotImplementedError

    def describe(self) -> str:
        raise NotImplementedError

    def bound(self, owner, name: str) -> Check:
        """The check of field ``name`` of ``owner`` (whose fields before it are checked already): itself,
        unless what it accepts depends on those fields (:class:`Options`' ``given``)."""
        return self


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


@dataclass(frozen=True)
class Real(Check):
    """A finite number in [lo, hi] (open ends with ``open_lo``/``open_hi``); ints become floats."""

    lo: float = -math.inf
    hi: float = math.inf
    open_lo: bool = False
    open_hi: bool = False
    unit: str = ""

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        if self.lo == -math.inf and self.hi == math.inf:
            return f"a finite number{unit}"
        lo = "(-inf" if self.lo == -math.inf else ("(" if self.open_lo else "[") + f"{self.lo:g}"
        hi = "inf)" if self.hi == math.inf else f"{self.hi:g}" + (")" if self.open_hi else "]")
        return f"a finite number in {lo}, {hi}{unit}"

    def __call__(self, value):
        if not _is_number(value) or not math.isfinite(value):
            raise Invalid(self.describe())
        too_low = value <= self.lo if self.open_lo else value < self.lo
        too_high = value >= self.hi if self.open_hi else value > self.hi
        if too_low or too_high:
            raise Invalid(self.describe())
        return float(value)


@dataclass(frozen=True)
class Integer(Check):
    """A whole number in [lo, hi] (``3.0`` is not one: a count written as a float is a mistake)."""

    lo: int = 0
    hi: int = 2**31 - 1
    note: str = ""  # why the upper bound (the memory a large value implies)

    def describe(self) -> str:
        note = f" ({self.note})" if self.note else ""
        return f"an integer in [{self.lo}, {self.hi}]{note}"

    def __call__(self, value):
        if isinstance(value, bool) or not isinstance(value, int) or not self.lo <= value <= self.hi:
            raise Invalid(self.describe())
        return int(value)


@dataclass(frozen=True)
class Boolean(Check):
    def describe(self) -> str:
        return "true or false"

    def __call__(self, value):
        if not isinstance(value, bool):
            raise Invalid(self.describe())
        return value


@dataclass(frozen=True)
class Choice(Check):
    values: tuple

    def describe(self) -> str:
        return f"one of {list(self.values)}"

    def __call__(self, value):
        if not isinstance(value, (str, type(None))) or value not in self.values:
            raise Invalid(self.describe())
        return value


@dataclass(frozen=True)
class Text(Check):
    """A non-empty string (a name or a path)."""

    def describe(self) -> str:
        return "a non-empty string"

    def __call__(self, value):
        if not isinstance(value, str) or not value:
            raise Invalid(self.describe())
        return value


@dataclass(frozen=True)
class Mapping(Check):
    """A dict of nested options (checked by whoever builds from it)."""

    def describe(self) -> str:
        return "a mapping of options"

    def __call__(self, value):
        if not isinstance(value, dict):
            raise Invalid(self.describe())
        return dict(value)


@dataclass(frozen=True)
class _Preset(Check):
    """Deprecated (:class:`Options` builds the options it names): a preset's name or a dict, returned as given."""

    names: tuple

    def describe(self) -> str:
        return f"a preset name (one of {list(self.names)}) or a mapping of options"

    def __call__(self, value):
        if isinstance(value, dict):
            return dict(value)
        if not isinstance(value, str) or value not in self.names:
            raise Invalid(self.describe())
        return value


@dataclass(frozen=True)
class Options(Check):
    """Nested options, built: an instance of ``cls``, or a dict of its fields; with ``presets`` (name ->
    fields), also a preset's name, or a dict whose ``preset`` key names the preset its fields change.

    ``given`` names fields of ``cls`` that the owner's fields of the same names set (declared before
    this one, with :func:`option_of`): a dict may not hold them, and an instance must agree with the owner."""

    cls: type
    presets: dict | None = None
    given: tuple = ()
    # as bound to an owner (:meth:`bound`): its field's name and (name, value) of the given fields
    owner_field: str = ""
    owner_values: tuple = ()

    def describe(self) -> str:
        name = self.cls.__name__
        kind = f"a mapping of options or {'an' if name[0] in 'AEIOU' else 'a'} {name}"
        return f"a preset name (one of {list(self.presets)}), {kind}" if self.presets else kind

    def bound(self, owner, name: str) -> Options:
        if not self.given:
            return self
        return Options(self.cls, self.presets, self.given, name, tuple((g, getattr(owner, g)) for g in self.given))

    def __call__(self, value):
        if isinstance(value, self.cls):
            for given, owners in self.owner_values:
                if getattr(value, given) != owners:
                    raise OptionError("", given, f"{owners!r}, as the top-level option {given} (which sets "
                                      f"{self.owner_field}'s) is", getattr(value, given))
            return value
        if self.presets and isinstance(value, str):
            value = {"preset": value}
        if not isinstance(value, dict):
            raise Invalid(self.describe())
        fields_ = dict(value)
        for given, _ in self.owner_values:
            if given in fields_:
                raise OptionError("", given, f"no {given} inside {self.owner_field}: give it as the top-level option "
                                  f"{given}, which sets {self.owner_field}'s", fields_[given])
        if self.presets and "preset" in fields_:
            name = check_value(fields_.pop("preset"), Choice(tuple(self.presets)), "", "preset")
            fields_ = dict(self.presets[name], **fields_)
        return build(self.cls, {**fields_, **dict(self.owner_values)}, "", source=self.cls.__name__)


@dataclass(frozen=True)
class Maybe(Check):
    """``None`` or what ``inner`` accepts."""

    inner: Check
    meaning: str = ""

    def describe(self) -> str:
        meaning = f" ({self.meaning})" if self.meaning else ""
        return f"{self.inner.describe()} or null{meaning}"

    def __call__(self, value):
        if value is None:
            return None
        try:
            return self.inner(value)
        except Invalid:
            raise Invalid(self.describe()) from None


@dataclass(frozen=True)
class Tuple(Check):
    """A fixed-length list or tuple whose every item ``inner`` accepts."""

    inner: Check
    length: int

    def describe(self) -> str:
        return f"{self.length} items, each {self.inner.describe()}"

    def __call__(self, value):
        if not isinstance(value, (list, tuple)) or len(value) != self.length:
            raise Invalid(self.describe())
        try:
            return tuple(self.inner(v) for v in value)
        except Invalid:
            raise Invalid(self.describe()) from None


def option(default, check: Check, help: str = ""):
    """A dataclass field with a default, the :class:`Check` that :func:`check_fields` applies, and a
    one-line ``help`` (what the field sets; docs/options.md is generated from it)."""
    metadata = {"check": check, "help": help}
    if isinstance(default, (dict, list)):
        return field(default_factory=lambda: type(default)(default), metadata=metadata)
    return field(default=default, metadata=metadata)


def check_fields(instance) -> None:
    """Apply every field's :class:`Check` to a (frozen) dataclass instance, in their order, storing the
    normalised values (nested options built)."""
    for f in fields(instance):
        check = f.metadata.get("check")
        if check is not None:
            value = check_value(getattr(instance, f.name), check.bound(instance, f.name), type(instance).__name__,
                                f.name)
            object.__setattr__(instance, f.name, value)


def option_of(cls, name: str, help: str | None = None):
    """The field ``name`` of the option dataclass ``cls`` declared again, for an owner that sets it
    (:class:`Options`' ``given``): the same default and check, one declaration."""
    declared = next(f for f in fields(cls) if f.name == name)
    return option(declared.default, declared.metadata["check"], declared.metadata["help"] if help is None else help)


def fail(instance, name: str, expected: str, got=FieldError.NOTHING):
    """Raise the :class:`OptionError` of a rule across fields (checked after :func:`check_fields`)."""
    raise OptionError(type(instance).__name__, name, expected, got)


def build(cls, options, label: str, source: str = "option", error=OptionError):
    """``cls(**options)``: unknown names and bad values raise ``error`` (a :class:`FieldError`) naming
    ``source`` (``"gym.make"``, a file) and the field ``label.name``."""
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise error(source, label or "<options>", "a mapping of options", options)
    valid = [f.name for f in fields(cls)]
    unknown = sorted(set(map(str, options)) - set(valid))
    if unknown:
        raise error(source, field_path(label, unknown[0]), f"one of the known options {valid}")
    try:
        return cls(**options)
    except OptionError as exc:
        raise error(source, field_path(label, exc.field), exc.expected, exc.got) from None


def check_value(value, check: Check, source: str, name: str, error=OptionError):
    """``check(value)``, or ``error`` naming ``source`` and the field ``name`` (``name.path`` for an error
    inside nested options)."""
    try:
        return check(value)
    except Invalid as exc:
        raise error(source, name, str(exc), value) from None
    except OptionError as exc:
        raise error(source, field_path(name, exc.field), exc.expected, exc.got) from None


def field_path(label: str, name: str) -> str:
    """The dotted name of field ``name`` of the options at ``label`` ("" for the top level)."""
    return ".".join(part for part in (label, name) if part)


def __getattr__(name: str):
    """``Preset`` (PEP 562): deprecated, see :class:`_Preset`."""
    if name == "Preset":
        warnings.warn("emmi_gym.inputs.validation.Preset is deprecated: Options(cls, presets) builds the options "
                      "a preset names; it goes in emmi-gym 0.5.0", FutureWarning, stacklevel=2)
        return _Preset
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["MAX_LASER_RANGE", "Boolean", "Check", "Choice", "Integer", "Invalid", "Mapping", "Maybe", "OptionError",
           "Options", "Real", "Text", "Tuple", "build", "check_fields", "check_value", "excerpt", "fail", "field_path",
           "option", "option_of"]
