"""emmi-gym: active-SLAM environments with the EMMI certainty reward (Blanco et al., IROS 2006).

Importing the package registers the environments and makes the shipped agents available
(``emmi_gym.pretrained``)::

    import gymnasium as gym, emmi_gym
    gym.register_envs(emmi_gym)
    env = gym.make("emmi_gym/LoopCorridor-v0")
"""

__version__ = "0.1.0"


def _register() -> None:
    from .env.registration import register_envs

    register_envs()


_register()

from . import pretrained  # noqa: E402  (after the ids are registered; it imports nothing heavy)

__all__ = ["__version__", "pretrained"]
