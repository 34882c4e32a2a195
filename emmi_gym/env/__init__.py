"""The Gymnasium environments: expected-map observations and rewards as parts (the change of EMMI by default)."""

from .config import EnvConfig, deprecated_reward_scales, make_config
from .emmi_env import EmmiEnv
from .registration import ENV_IDS, register_env_file, register_envs
from .reward_registry import REWARDS, register_reward
from .rewards import Reward

__all__ = ["ENV_IDS", "REWARDS", "EmmiEnv", "EnvConfig", "Reward", "make_config", "register_env_file", "register_envs",
           "register_reward"]


def __getattr__(name: str):
    """``REWARD_SCALES`` (PEP 562): deprecated, see :func:`~emmi_gym.env.config.deprecated_reward_scales`."""
    if name == "REWARD_SCALES":
        return deprecated_reward_scales(stacklevel=2)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
