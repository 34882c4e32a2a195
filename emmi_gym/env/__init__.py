"""The Gymnasium environments: expected-map observations and the EMMI reward."""

from .config import REWARD_SCALES, REWARDS, EnvConfig, make_config
from .emmi_env import EmmiEnv
from .registration import ENV_IDS, register_envs

__all__ = ["ENV_IDS", "REWARDS", "REWARD_SCALES", "EmmiEnv", "EnvConfig", "make_config", "register_envs"]
