"""How two agent configurations differ, field by field: what ``--resume`` compares (the run's own
``config.yaml`` against the configuration given) and what a resumed run may change
(:data:`RESUMABLE_CHANGES`)."""

from __future__ import annotations

from dataclasses import asdict

from ..config import AgentConfig

#: The fields of a configuration that a resumed run may change: its budget, how its envs run (and are watched), its
#: evaluation and checkpoint schedules. Any other (algorithm, policy, hyperparameters, env id and
#: options, seed) would make the rest of the run another run than its model's and its ``config.yaml``.
RESUMABLE_CHANGES = ("total_timesteps", "n_envs", "vec_env", "policy_lag", "worker_timeout", "eval",
                     "checkpoint_freq")


def _flat(data, prefix: str = "") -> dict:
    """A nested dict as ``{"dotted.name": value}``."""
    if not isinstance(data, dict) or not data:
        return {prefix: data}
    flat = {}
    for key, value in data.items():
        flat.update(_flat(value, f"{prefix}.{key}" if prefix else str(key)))
    return flat


def _resolved_env_options(env_id: str, kwargs: dict) -> dict:
    """The env's options as ``gym.make(env_id, **kwargs)`` resolves them (registered keywords and defaults
    filled in), so that a keyword given at its default is no change."""
    import gymnasium as gym

    from ....env import make_config

    return asdict(make_config(**{**gym.spec(env_id).kwargs, **kwargs}))


def differing_fields(own: AgentConfig, other: AgentConfig, ignore=RESUMABLE_CHANGES) -> dict[str, tuple]:
    """The fields (dotted names) where ``other`` differs from ``own``, outside ``ignore``: ``{name: (own's,
    other's)}``; the env options compared as the env resolves them."""

    def comparable(config: AgentConfig) -> dict:
        data = {k: v for k, v in config.as_yaml_dict().items() if k not in ignore}
        data["env"] = {"id": config.env_id, "kwargs": _resolved_env_options(config.env_id, config.env_kwargs)}
        return _flat(data)

    mine, theirs = comparable(own), comparable(other)  # a field one lacks counts as None (absent)
    return {
        name: (mine.get(name), theirs.get(name))
        for name in sorted(set(mine) | set(theirs))
        if mine.get(name) != theirs.get(name)
    }
