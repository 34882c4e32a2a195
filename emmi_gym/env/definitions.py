"""The environments' definition files: one YAML file per id, read and checked.

The package's own are ``envs/<id>.yaml`` at the top of the repository (``emmi_gym/envs`` in an installed
wheel). A file gives:

- ``id``: ``Name-vN``, without a namespace, and the file is named after it (``Name-vN.yaml``);
- ``options``: the ``gym.make`` keywords the id sets, passed on as they are (the env checks them when it
  is made, as any keywords);
- ``versions``: the id's version history, newest first (``vN: {release: ..., changes: ...}``); the newest
  is the id's own, and only it is registered, so ``gym.make`` of an older one raises Gymnasium's
  ``DeprecatedEnv`` naming it;
- ``page`` (optional): the prose of its page in docs/envs/, which ``docs/_scripts/gen_env_pages.py`` writes
  (:data:`PAGE_TEXTS` and :data:`PAGE_OPTIONAL` name its fields).

Every mistake raises :class:`EnvFileError` naming the file, the field, what was expected and what was found.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ..inputs.errors import FieldError
from ..inputs.validation import Mapping, Text, check_value
from ..inputs.yaml_files import read_yaml_file

#: What a file is called in messages.
WHAT = "environment definition file"
#: ``Name-vN``: Gymnasium's form of an id without a namespace.
ID_PATTERN = re.compile(r"[A-Za-z][\w.-]*-v(\d+)")
VERSION_PATTERN = re.compile(r"v(\d+)")
FIELDS = ("id", "options", "versions", "page")
#: The page's texts (Markdown, one section or table cell each): the preview's caption, the index's world and
#: actions columns, then the sections in page order.
PAGE_TEXTS = ("preview", "world", "actions", "description", "action_space", "observation_space", "rewards",
              "starting_state", "episode_end")
#: The page's other fields: what each option sets (a line per option), a note under the options table, and
#: further sections (heading: text) after "Episode end".
PAGE_OPTIONAL = ("configuration", "more")
_TEXT, _MAPPING = Text(), Mapping()


class EnvFileError(FieldError):
    """An environment definition file is malformed; says which file, which field, what was expected."""


@dataclass(frozen=True)
class EnvDefinition:
    """A checked definition file (see the module docstring): ``versions`` maps ``"vN"`` to its ``release``
    (or None) and ``changes``, newest first; ``page`` is empty where the file gives none."""

    id: str
    options: dict
    versions: dict
    page: dict
    source: str

    @property
    def version(self) -> int:
        """The id's version, the newest of its history."""
        return int(ID_PATTERN.fullmatch(self.id).group(1))

    @property
    def name(self) -> str:
        """The id without its version (``LoopCorridor``)."""
        return self.id.rsplit("-v", 1)[0]


def definitions_folder() -> Path:
    """The folder of the package's definition files: ``emmi_gym/envs`` in an installed wheel, else the
    repository's top-level ``envs/`` beside the package (a source checkout, an editable install)."""
    package = Path(__file__).resolve().parents[1]
    installed, checkout = package / "envs", package.parent / "envs"
    for folder in (installed, checkout):
        if folder.is_dir():
            return folder
    raise FileNotFoundError(f"the environments' definition files are in neither {installed} nor {checkout}")


def shipped_definitions() -> list[EnvDefinition]:
    """The package's definition files, read and checked, by file name."""
    return [read_env_file(path) for path in sorted(definitions_folder().glob("*.yaml"))]


def read_env_file(path) -> EnvDefinition:
    """Read and check the definition file ``path`` (see the module docstring)."""
    path = Path(path)
    source = str(path)
    data = read_yaml_file(path, WHAT, EnvFileError)
    unknown = sorted(set(map(str, data)) - set(FIELDS))
    if unknown:
        raise EnvFileError(source, unknown[0], f"one of the fields {list(FIELDS)}")
    env_id = _text(data.get("id"), source, "id")
    match = ID_PATTERN.fullmatch(env_id)
    if not match:
        raise EnvFileError(source, "id", "an id Name-vN (letters, digits, '_', '.', '-'; no namespace)", env_id)
    if path.stem != env_id:
        raise EnvFileError(source, "id", f"the id the file is named after, {path.stem!r}", env_id)
    options = _options(data.get("options"), source)
    versions = _versions(data.get("versions"), int(match.group(1)), source)
    page = _page(data.get("page"), options, source) if "page" in data else {}
    return EnvDefinition(env_id, options, versions, page, source)


def _text(value, source: str, name: str) -> str:
    return check_value(value, _TEXT, source, name, EnvFileError).strip()


def _mapping(value, source: str, name: str) -> dict:
    return check_value(value, _MAPPING, source, name, EnvFileError)


def _options(value, source: str) -> dict:
    options = _mapping(value, source, "options")
    for key in options:
        if not isinstance(key, str) or not key.isidentifier():
            raise EnvFileError(source, "options", "keywords of gym.make (names such as world, laser)", key)
    return options


def _versions(value, current: int, source: str) -> dict:
    """The version history, newest first, the newest being the id's own."""
    history = _mapping(value, source, "versions")
    if not history:
        raise EnvFileError(source, "versions", f"the id's versions, newest first, from v{current}", history)
    numbers = []
    for key in history:
        match = VERSION_PATTERN.fullmatch(str(key))
        if not match:
            raise EnvFileError(source, "versions", "versions named vN (v1, v0)", key)
        numbers.append(int(match.group(1)))
    if numbers[0] != current:
        raise EnvFileError(source, "versions", f"the id's own version, v{current}, first", f"v{numbers[0]}")
    if numbers != sorted(set(numbers), reverse=True):
        raise EnvFileError(source, "versions", "versions newest first, each once", [f"v{n}" for n in numbers])
    checked = {}
    for key, entry in history.items():
        label = f"versions.{key}"
        entry = _mapping(entry, source, label)
        unknown = sorted(set(map(str, entry)) - {"release", "changes"})
        if unknown:
            raise EnvFileError(source, f"{label}.{unknown[0]}", "one of the fields ['release', 'changes']")
        release = entry.get("release")
        checked[key] = {"release": None if release is None else _text(release, source, f"{label}.release"),
                        "changes": _text(entry.get("changes"), source, f"{label}.changes")}
    return checked


def _page(value, options: dict, source: str) -> dict:
    """The page's prose: every text of :data:`PAGE_TEXTS`, a line of ``sets`` per option, the optional rest."""
    page = _mapping(value, source, "page")
    known = (*PAGE_TEXTS, "sets", *PAGE_OPTIONAL)
    unknown = sorted(set(map(str, page)) - set(known))
    if unknown:
        raise EnvFileError(source, f"page.{unknown[0]}", f"one of the fields {list(known)}")
    checked = {name: _text(page.get(name), source, f"page.{name}") for name in PAGE_TEXTS}
    sets = _mapping(page.get("sets"), source, "page.sets")
    if list(sets) != list(options):
        raise EnvFileError(source, "page.sets", f"a line for each option, in their order {list(options)}",
                           list(sets))
    checked["sets"] = {name: _one_line(text, source, f"page.sets.{name}") for name, text in sets.items()}
    if "configuration" in page:
        checked["configuration"] = _text(page["configuration"], source, "page.configuration")
    more = _mapping(page.get("more", {}), source, "page.more")
    checked["more"] = {_one_line(heading, source, "page.more"): _text(text, source, f"page.more.{heading}")
                       for heading, text in more.items()}
    return checked


def _one_line(value, source: str, name: str) -> str:
    text = _text(value, source, name)
    if "\n" in text:
        raise EnvFileError(source, name, "one line", text)
    return text


__all__ = ["EnvDefinition", "EnvFileError", "definitions_folder", "read_env_file", "shipped_definitions"]
