"""Environment ids given as input (an option, a configuration field): one of this package's, or a clear word on
what to use.

Gymnasium raises ``DeprecatedEnv`` for an older version of a registered id; the check here says the same in
the project's one-line form, naming the source and the field, before anything is made.
"""

from __future__ import annotations

import gymnasium as gym

from .errors import FieldError

#: The namespace of this package's ids.
NAMESPACE = "emmi_gym"


def env_id_expectation(env_id) -> str:
    """What an option that takes one of this package's env ids expects instead of ``env_id``: the current
    version where ``env_id`` names another version of one (older versions' episodes differ: the CHANGELOG's
    breaking changes say how), else the ids registered."""
    try:
        namespace, name, _ = gym.envs.registration.parse_env_id(env_id)
    except (gym.error.Error, TypeError):
        namespace, name = None, None
    if name and namespace in (None, NAMESPACE):
        version = gym.envs.registration.find_highest_version(NAMESPACE, name)
        if version is not None:
            current = gym.envs.registration.get_env_id(NAMESPACE, name, version)
            return (f"the current version of {NAMESPACE}/{name}, {current!r} (older versions' episodes differ: "
                    "see the CHANGELOG's breaking changes)")
    ids = sorted(i for i in gym.registry if i.startswith(f"{NAMESPACE}/"))
    return f"one of emmi-gym's environment ids {ids}"


def check_env_id(env_id, source: str, field: str, error: type[FieldError] = FieldError) -> str:
    """``env_id`` if it is one of this package's registered ids (``emmi_gym/Name-vN``), else ``error`` naming
    ``source`` and ``field`` and saying what to use (:func:`env_id_expectation`)."""
    if not isinstance(env_id, str) or not env_id.startswith(f"{NAMESPACE}/") or env_id not in gym.registry:
        raise error(source, field, env_id_expectation(env_id), env_id)
    return env_id
