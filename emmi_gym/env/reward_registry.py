"""The rewards by name, as Gymnasium keeps its environments by id: what ``gym.make(id, reward=NAME)`` and
``info_rewards`` look names up in, and what the command line's choices, the agent configurations' checks and the
docs read.

:data:`REWARDS` holds the built-ins (:data:`~emmi_gym.env.rewards.BUILT_IN`) and whatever
:func:`register_reward` adds. A reward registered in a module of your own is known wherever that module is
imported; a worker process that makes the env must import it too (or be given the :class:`Reward` itself).
"""

from __future__ import annotations

from .rewards import BUILT_IN, Reward

#: Every reward by name (read it; add with :func:`register_reward`).
REWARDS: dict[str, Reward] = {reward.name: reward for reward in BUILT_IN}


def register_reward(reward: Reward, *, replace: bool = False) -> Reward:
    """Make ``reward`` known by its name (``gym.make(id, reward=reward.name)``); returns it. The same reward twice
    is one registration; another under a name taken raises a ``ValueError`` unless ``replace`` (never a
    built-in's name: ``reward="emmi"`` means one thing in every script)."""
    if not isinstance(reward, Reward):
        raise TypeError(f"register_reward takes a Reward (emmi_gym.env.rewards.Reward), got {type(reward).__name__}")
    known = REWARDS.get(reward.name)
    if known is not None and known != reward:
        if any(reward.name == built_in.name for built_in in BUILT_IN):
            raise ValueError(f"{reward.name!r} is a built-in reward's name: give yours another")
        if not replace:
            raise ValueError(f"a reward named {reward.name!r} is registered already ({known}): give yours another "
                             "name, or pass replace=True")
    REWARDS[reward.name] = reward
    return reward


def reward_named(value: str | Reward) -> Reward:
    """The reward a name stands for (a ``KeyError`` naming the registered ones if none), or ``value`` itself."""
    if isinstance(value, Reward):
        return value
    try:
        return REWARDS[value]
    except (KeyError, TypeError):
        raise KeyError(f"no reward named {value!r}; registered: {sorted(REWARDS)}") from None


def privileged_rewards() -> tuple[str, ...]:
    """The names of the registered rewards that read the ground truth."""
    return tuple(name for name, reward in REWARDS.items() if reward.privileged)
