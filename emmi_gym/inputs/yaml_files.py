"""Reading the YAML files users hand in (world files, agent configurations), safely.

One reader for all of them: files are capped in size before they are read; they must be UTF-8
text; values nest at most :data:`MAX_YAML_DEPTH` deep (PyYAML builds nested values by recursion,
which a few hundred kB of brackets would take past Python's recursion limit); aliases
(``*name``, YAML's only way to make a few bytes expand into gigabytes, the "billion laughs") and
duplicate keys are refused; ``1e5`` and ``1.0e5`` read as numbers (YAML 1.1, PyYAML's dialect,
would read them as strings); and every error names the file with the line and column, never
echoing more than a short excerpt of the file.
"""

from __future__ import annotations

import re

import yaml

from .errors import FieldError, excerpt
from .text_files import read_text_file
from .user_paths import input_file

#: The largest YAML file read (world files and agent configurations are a few kB).
MAX_YAML_BYTES = 1_000_000
#: The deepest nesting of lists and mappings read (the files' own nest four or five deep).
MAX_YAML_DEPTH = 32
YAML_SUFFIXES = (".yaml", ".yml")


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader without aliases and duplicate keys, with YAML 1.2's exponent floats, nesting at
    most :data:`MAX_YAML_DEPTH` deep."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            raise yaml.composer.ComposerError(None, None, "aliases (*name) are not allowed: write the value out",
                                              self.peek_event().start_mark)
        if self._depth >= MAX_YAML_DEPTH and self.check_event(yaml.CollectionStartEvent):
            raise yaml.composer.ComposerError(None, None, f"lists and mappings nested at most {MAX_YAML_DEPTH} "
                                              "deep", self.peek_event().start_mark)
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: the base class says so
                break
            if duplicate:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {excerpt(key)}",
                                                        key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# YAML 1.2's floats with an exponent and no dot (1e5) or a dot and an unsigned exponent (1.0e5)
_StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def parse_yaml(text: str, source: str, error=FieldError):
    """The data of a YAML document; problems raise ``error`` naming ``source``, line and column."""
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 (a SafeLoader subclass)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f"{source}:{mark.line + 1}:{mark.column + 1}" if mark is not None else source
        context = f" ({exc.context})" if exc.context else ""
        raise error(where, "", f"valid YAML: {exc.problem}{context}") from None
    except yaml.YAMLError as exc:
        raise error(source, "", f"valid YAML: {excerpt(str(exc))}") from None


def read_yaml_file(path, what: str, error=FieldError) -> dict:
    """The mapping in the YAML file ``path`` (``what`` names it in messages: "world file")."""
    path = input_file(path, what, error)
    if path.suffix.lower() not in YAML_SUFFIXES:
        raise error(str(path), "", f"a {what} in YAML, named *{' or *'.join(YAML_SUFFIXES)}")
    text = read_text_file(path, what, MAX_YAML_BYTES, error)
    data = parse_yaml(text, str(path), error)
    if not isinstance(data, dict):
        raise error(str(path), "", f"a mapping of {what} fields at the top level, not a {type(data).__name__}")
    return data
