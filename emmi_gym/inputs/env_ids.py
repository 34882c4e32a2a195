"""Environment ids given as input (an option, a configuration field): registered, or a clear word on what to use.

Gymnasium raises ``DeprecatedEnv`` for an older version of a registered id; the checks here say the same
in the project's one-line form, naming the source and the field, before anything is made.
"""

from __future__ import annotations

import gymnasium as gym

from .errors import FieldError


def env_id_expectation(env_id) -> str:
    """What an option that takes an env id expects instead of ``env_id``, which no environment is registered
    as: the current version where ``env_id`` names another version of a registered id (older versions'
    episodes differ: the CHANGELOG's breaking changes say how), else a registered id of the same namespace."""
    try:
        namespace, name, _ = gym.envs.registration.parse_env_id(env_id)
    except (gym.error.Error, TypeError):
        namespace, name = None, None
    version = gym.envs.registration.find_highest_version(namespace, name) if name else None
    if version is not None:
        current = gym.envs.registration.get_env_id(namespace, name, version)
        return f"the current version of {current.rsplit('-', 1)[0]}, {current!r} (older versions' episodes differ: " \
               "see the CHANGELOG's breaking changes)"
    ids = sorted(i for i in gym.registry if i.startswith(f"{namespace or 'emmi_gym'}/"))
    return f"a registered environment id: one of {ids}"


def check_env_id(env_id, source: str, field: str, error: type[FieldError] = FieldError) -> str:
    """``env_id`` if an environment is registered as it, else ``error`` naming ``source`` and ``field`` and
    saying what to use (:func:`env_id_expectation`)."""
    if not isinstance(env_id, str) or env_id not in gym.registry:
        raise error(source, field, env_id_expectation(env_id), env_id)
    return env_id
