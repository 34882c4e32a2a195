"""Model files (Stable-Baselines3 ``.zip``): checked before SB3 unpacks them, loaded with errors that name them.

SB3 reads a model's members whole: a ``data`` member that deflates to gigabytes from a few MB
takes that much memory before anything is checked, a zip without ``data`` ends in an
``AssertionError``, and a model of another algorithm than its run's configuration says fails
deep inside the policy's constructor. Here the members' sizes (as the zip declares them: Python's
zipfile never inflates a member past its declared size) are bounded, every member's CRC-32 is
checked (a damaged file is named as damaged, not as "not a zip file"), ``data`` must be JSON nested
at most a hundred deep (deeper, Python's parser would end in a ``RecursionError``), the weights must
be in torch's format, and the policy class ``data`` names must be one of the configured algorithm's.

A model file can run code: SB3 saves the spaces, schedules and classes of ``data`` as pickles (cloudpickle),
and unpickling calls whatever a pickle names. Here every pickle of ``data`` is unpickled before SB3 sees it
(and handed to SB3 as its ``custom_objects``, so SB3 unpickles none itself) by an unpickler that refuses a
pickle naming anything but classes of :data:`TRUSTED_PACKAGES`, builtins' plain types and the functions
numpy's arrays and random generators are rebuilt with (:data:`REBUILDERS`); the weights are read by SB3
with ``torch.load(weights_only=True)``. A file trusted (:func:`trust_model_files`: ``--trust-model``, or
the paths in :data:`TRUST_VARIABLE`) is unpickled by SB3 as it is.
"""

from __future__ import annotations

import base64
import binascii
import io
import os
import pickle
import zipfile
import zlib
from contextlib import contextmanager
from pathlib import Path

from .... import MOVED_TO_TOOLS
from ....inputs.errors import FieldError
from ....inputs.json_files import parse_json
from ....inputs.user_paths import input_file
from ..config import ALGORITHMS, algorithm_class

#: The most a model's members may take unpacked, and its ``data`` member (the hyperparameters and spaces as
#: JSON; a few hundred kB); the shipped agent takes 2 MB in all.
MAX_MODEL_BYTES = 256 * 2**20
MAX_DATA_BYTES = 16 * 2**20
MAX_MEMBERS = 64

#: The packages whose classes a model's pickles may name (an untrusted model's: :func:`trust_model_files`).
TRUSTED_PACKAGES = ("stable_baselines3", "sb3_contrib", "torch", "numpy", "gymnasium", "emmi_gym")
#: The builtins a model's pickles may name: plain types.
SAFE_BUILTINS = frozenset({"bool", "bytearray", "bytes", "complex", "dict", "float", "frozenset", "int", "list",
                           "range", "set", "slice", "str", "tuple"})
#: The functions (not classes) a model's pickles may name, ``(module, name)``: what rebuilds numpy's arrays, scalars
#: and random generators (``numpy.core`` before numpy 2), the standard library's containers and objects.
REBUILDERS = frozenset({
    *((f"numpy.{core}.multiarray", name) for core in ("_core", "core") for name in ("_reconstruct", "scalar")),
    *((f"numpy.{core}.numeric", "_frombuffer") for core in ("_core", "core")),
    *(("numpy.random._pickle", name) for name in ("__generator_ctor", "__bit_generator_ctor", "__randomstate_ctor")),
    ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
    ("collections", "OrderedDict"), ("collections", "deque"), ("copyreg", "_reconstructor"),
})
#: The variable that names trusted model files (or folders of them), separated by ``os.pathsep``; what
#: ``--trust-model`` sets, so that the processes a command starts trust them too.
TRUST_VARIABLE = "EMMI_GYM_TRUSTED_MODELS"


class ModelFileError(FieldError):
    """A model file is not one that its run's configuration can load; names the file and what is wrong."""


def current_module(module: str) -> str:
    """The name the module ``module`` has now: a model saved before 0.3.0 names its policy and rollout-buffer
    classes by the tools' old modules (``emmi_gym.training.target_policy``), before they moved under
    ``emmi_gym.tools`` (:data:`emmi_gym.MOVED_TO_TOOLS`)."""
    parts = module.split(".")
    if len(parts) > 1 and parts[0] == "emmi_gym" and parts[1] in MOVED_TO_TOOLS:
        return ".".join(["emmi_gym", "tools", *parts[1:]])
    return module


class _CurrentModules(pickle.Unpickler):
    """Unpickles a class a model names by reference, looking it up under its module's current name."""

    def find_class(self, module, name):
        return super().find_class(current_module(module), name)


class _Refused(pickle.UnpicklingError):
    """A pickle names a global that an untrusted model's may not (:class:`_TrustedNamesOnly`)."""


class _TrustedNamesOnly(_CurrentModules):
    """Unpickles only what names classes of :data:`TRUSTED_PACKAGES`, :data:`SAFE_BUILTINS` and :data:`REBUILDERS`
    (looked up under their modules' current names); :class:`_Refused` for anything else, before it is imported."""

    def find_class(self, module, name):
        module = current_module(module)
        named = f"{module}.{name}"
        if module == "builtins":
            if name not in SAFE_BUILTINS:
                raise _Refused(named)
        elif (module, name) not in REBUILDERS and module.split(".")[0] not in TRUSTED_PACKAGES:
            raise _Refused(named)
        found = super().find_class(module, name)
        if not isinstance(found, type) and (module, name) not in REBUILDERS:
            raise _Refused(f"{named} (a {type(found).__name__}, not a class)")
        return found


def trust_model_files(paths) -> None:
    """Trust the model files at ``paths`` (a folder: every model under it) in this process and those it starts
    (:data:`TRUST_VARIABLE`): SB3 unpickles them as they are, which can run any code they hold."""
    trusted = [entry for entry in os.environ.get(TRUST_VARIABLE, "").split(os.pathsep) if entry]
    os.environ[TRUST_VARIABLE] = os.pathsep.join([*trusted, *(str(Path(path).resolve()) for path in paths)])


def is_trusted(path) -> bool:
    """Whether the model file ``path`` is trusted (:func:`trust_model_files`), links resolved."""
    resolved = Path(path).resolve()
    return any(resolved.is_relative_to(Path(entry)) for entry in os.environ.get(TRUST_VARIABLE, "").split(os.pathsep)
               if entry)


def _data_objects(data: dict, where: str, trusted: bool) -> dict:
    """SB3 ``custom_objects`` for the pickled entries of a model's ``data``: each unpickled by
    :class:`_TrustedNamesOnly` (SB3 then unpickles none itself), or, for a ``trusted`` file, only those that name a
    class by a module from before 0.3.0 (from its module's current name, so that an older model loads without the
    deprecated aliases); :class:`ModelFileError` naming the file and entry for a pickle refused or unreadable."""
    objects = {}
    for key, value in data.items():
        if not (isinstance(value, dict) and ":serialized:" in value):
            continue
        module = value.get("__module__")
        moved = isinstance(module, str) and current_module(module) != module
        if trusted and not moved:
            continue
        unpickler = _CurrentModules if trusted else _TrustedNamesOnly
        try:
            objects[key] = unpickler(io.BytesIO(base64.b64decode(value[":serialized:"]))).load()
        except _Refused as exc:
            raise ModelFileError(where, f"data.{key}", "a pickle naming only classes of "
                                 f"{', '.join(TRUSTED_PACKAGES)} and builtins' plain types (a model file can run "
                                 "code: pass --trust-model to load one you trust)", str(exc)) from None
        except (KeyError, TypeError, ValueError, binascii.Error, EOFError, pickle.UnpicklingError, ImportError,
                AttributeError) as exc:
            raise ModelFileError(where, "data", f"its {key!r} as an object this package has "
                                 f"({type(exc).__name__}: {str(exc)[:200]})") from None
    return objects


def _policy_modules(algorithm: str) -> set[str]:
    """The modules of the policy classes a model of ``algorithm`` may have been saved with."""
    modules = {cls.__module__ for cls in algorithm_class(algorithm).policy_aliases.values()}
    if algorithm == "MaskablePPO":
        modules.add("emmi_gym.tools.training.target_policy")
    return modules


def check_model_file(path, algorithm: str) -> Path:
    """``path`` checked to be a model that ``algorithm`` can load (:func:`checked_model_data`)."""
    return checked_model_data(path, algorithm)[0]


def checked_model_data(path, algorithm: str) -> tuple[Path, dict]:
    """``path`` checked to be a model that ``algorithm`` (one of :data:`ALGORITHMS`) can load, its members bounded
    by the sizes the zip declares before any is read: each member's CRC-32, the weights' format (``*.pth``:
    torch.save's zip; SB3 reads them with ``torch.load(weights_only=True)``) and the ``data`` member's
    JSON (nesting bounded); :class:`ModelFileError` naming the file (and member) otherwise. Returns the path and
    the parsed ``data`` member."""
    with _model_archive(path) as (archive, path, names):
        where = str(path)
        damaged = archive.testzip()  # every member read (bounded above), its CRC-32 checked
        if damaged is not None:
            raise ModelFileError(where, damaged, "an undamaged member (its CRC-32 does not match its data: the "
                                 "file is damaged)")
        for name in names:
            if name.endswith(".pth"):
                with archive.open(name) as member:
                    if member.read(4) != b"PK\3\4":
                        raise ModelFileError(where, name, "PyTorch weights as torch.save writes them (a zip "
                                             "archive) and Stable-Baselines3 saves them")
        data = _data_member(archive, where)
    policy_class = data.get("policy_class") if isinstance(data, dict) else None
    module = policy_class.get("__module__") if isinstance(policy_class, dict) else None
    if not isinstance(module, str):
        raise ModelFileError(where, "", "a Stable-Baselines3 model, whose data names its policy class")
    module = current_module(module)
    if module not in _policy_modules(algorithm):
        saved = [name for name in ALGORITHMS if module in _policy_modules(name)]
        raise ModelFileError(where, "", f"a {algorithm} model, as its run's configuration says (algorithm: "
                             f"{algorithm}); its policy comes from {module}, "
                             f"{'a ' + ' or '.join(saved) + ' policy' if saved else 'no algorithm this package runs'}")
    return path, data


def saved_data(path) -> dict:
    """The ``data`` member of a model file, the JSON that SB3 writes (counts and hyperparameters as they are, the
    entries it pickles left as their JSON text), read without loading the model or unpickling anything;
    :class:`ModelFileError` naming the file otherwise."""
    with _model_archive(path) as (archive, path, _):
        data = _data_member(archive, str(path))
    if not isinstance(data, dict):
        raise ModelFileError(str(path), "data", "a Stable-Baselines3 model, whose data is a JSON object",
                             type(data).__name__)
    return data


def saved_decisions(path) -> int:
    """The decisions a model file was trained for (SB3's ``num_timesteps`` in its ``data`` member, :func:`saved_data`),
    read without loading the model; :class:`ModelFileError` naming the file otherwise."""
    decisions = saved_data(path).get("num_timesteps")
    if not isinstance(decisions, int) or isinstance(decisions, bool) or decisions < 0:
        raise ModelFileError(str(path), "data", "a Stable-Baselines3 model, whose data holds num_timesteps (a count)",
                             repr(decisions))
    return decisions


@contextmanager
def _model_archive(path):
    """The model zip ``path`` opened, ``(archive, path, member names)``, its members checked in number and size
    (:func:`_checked_members`); a zip that cannot be opened or read, in the block too, is a
    :class:`ModelFileError` naming the file."""
    path = input_file(path, "model file", ModelFileError)
    where = str(path)
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise ModelFileError(where, "", "a model .zip written by 'emmi-gym train' (this is not a zip file)") from None
    except (OSError, EOFError, zipfile.LargeZipFile, ValueError) as exc:
        raise ModelFileError(where, "", f"a zip file that can be read ({exc})") from None
    try:
        with archive:
            yield archive, path, _checked_members(archive, where)
    except (OSError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, zlib.error) as exc:
        raise ModelFileError(where, "", f"a zip file that can be read ({type(exc).__name__}: {exc})") from None


def _data_member(archive: zipfile.ZipFile, where: str):
    """The ``data`` member of a model zip, parsed as JSON (nesting bounded)."""
    return parse_json(archive.read("data"), where, "a 'data' member of JSON, as Stable-Baselines3 writes it",
                      ModelFileError)


def _checked_members(archive: zipfile.ZipFile, where: str) -> list[str]:
    """The names of a model zip's members, checked in number and declared size, ``data`` among them."""
    members = archive.infolist()
    if len(members) > MAX_MEMBERS:
        raise ModelFileError(where, "", f"a model zip of at most {MAX_MEMBERS} members", f"{len(members)}")
    total = sum(member.file_size for member in members)
    if total > MAX_MODEL_BYTES:
        largest = max(members, key=lambda member: member.file_size)
        raise ModelFileError(where, "", f"a model of at most {MAX_MODEL_BYTES // 2**20} MB unpacked; its members "
                             f"would unpack to {total / 2**20:,.0f} MB ({largest.filename!r}: "
                             f"{largest.file_size / 2**20:,.0f} MB)")
    names = {member.filename: member for member in members}
    if "data" not in names:
        raise ModelFileError(where, "", "a Stable-Baselines3 model, which holds a 'data' member (this zip holds "
                             f"{sorted(names)[:8]})")
    if names["data"].file_size > MAX_DATA_BYTES:
        raise ModelFileError(where, "", f"a 'data' member of at most {MAX_DATA_BYTES // 2**20} MB",
                             f"{names['data'].file_size / 2**20:,.0f} MB")
    return list(names)


def load_model_file(path, algorithm: str, **kwargs):
    """The SB3 model in ``path`` as ``algorithm``, after :func:`check_model_file`; ``kwargs`` go to SB3's
    ``load`` (with ``env`` rollout workers, a model that collects from them). What SB3 still finds wrong, and
    weights that are not all finite (which would act as a torch error printing the tensors), are a
    :class:`ModelFileError` naming the file. A model saved before 0.3.0 loads its classes from their modules'
    current names (:func:`current_module`). Its pickles are unpickled by :func:`_data_objects` unless the file is
    trusted (:func:`trust_model_files`)."""
    from ..callbacks import first_non_finite
    from ..rollout_workers import algorithm_for

    path, data = checked_model_data(path, algorithm)
    objects = _data_objects(data, str(path), is_trusted(path))
    kwargs["custom_objects"] = {**objects, **(kwargs.get("custom_objects") or {})}
    try:
        model = algorithm_for(algorithm_class(algorithm), kwargs.get("env")).load(path, **kwargs)
    except (ValueError, TypeError, KeyError, AssertionError, AttributeError, RuntimeError, EOFError,
            zipfile.BadZipFile, pickle.UnpicklingError) as exc:  # torch.load(weights_only=True) raises the last
        raise ModelFileError(str(path), "", f"a {algorithm} model that Stable-Baselines3 can load "
                             f"({type(exc).__name__}: {str(exc)[:200]})") from None
    bad = first_non_finite(model.policy)
    if bad is not None:
        raise ModelFileError(str(path), "", f"a model whose weights are all finite; {bad}")
    return model
