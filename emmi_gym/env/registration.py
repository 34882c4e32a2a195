"""Registration of the environment ids with Gymnasium (idempotent; runs on ``import emmi_gym``).

Each id is defined by a file of ``envs/`` (:mod:`emmi_gym.env.definitions`): its options become the id's
``gym.make`` defaults. :func:`register_env_file` registers an id of your own from a file of the same form.
"""

from __future__ import annotations

import gymnasium as gym

from ..inputs.env_ids import NAMESPACE
from .definitions import EnvFileError, read_env_file, shipped_definitions

ENTRY_POINT = "emmi_gym.env.emmi_env:EmmiEnv"

_SHIPPED = shipped_definitions()

#: id (without namespace) -> default options, as the files of ``envs/`` give them. An id's version goes up
#: whenever its episodes change (Gymnasium's rule): asked for an older version, ``gym.make`` raises
#: Gymnasium's ``DeprecatedEnv`` naming the current one.
ENV_IDS = {definition.id: definition.options for definition in _SHIPPED}


def register_envs() -> None:
    """Register ``emmi_gym/<Id>`` and, for ``gym.make("emmi_gym:<Id>")``, the bare ``<Id>``."""
    for definition in _SHIPPED:
        for env_id in (f"{NAMESPACE}/{definition.id}", definition.id):
            if env_id not in gym.registry:
                gym.register(id=env_id, entry_point=ENTRY_POINT, kwargs=dict(definition.options))


def register_env_file(path, namespace: str | None = None) -> str:
    """Register the id the definition file ``path`` gives (``namespace/Id`` with a ``namespace``), its options
    the defaults of ``gym.make``, and return it. A file is checked as :func:`~emmi_gym.env.definitions.read_env_file`
    checks the package's; an id of the package's own name (``LoopCorridor``, bare or under ``emmi_gym``) is
    refused (:class:`~emmi_gym.env.definitions.EnvFileError`). Registering a file again replaces the id."""
    definition = read_env_file(path)
    if namespace in (None, NAMESPACE) and definition.name in {shipped.name for shipped in _SHIPPED}:
        raise EnvFileError(definition.source, "id", f"a name of your own ({definition.name} is one of emmi-gym's "
                           "ids), or a namespace of your own", definition.id)
    env_id = f"{namespace}/{definition.id}" if namespace else definition.id
    gym.registry.pop(env_id, None)  # replaced without Gymnasium's warning of an override
    gym.register(id=env_id, entry_point=ENTRY_POINT, kwargs=dict(definition.options))
    return env_id
