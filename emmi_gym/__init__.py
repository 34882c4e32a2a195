"""emmi-gym: active-SLAM environments with the EMMI certainty reward (Blanco et al., IROS 2006).

Importing the package registers the environments and makes the shipped agents available
(``emmi_gym.pretrained``)::

    import gymnasium as gym, emmi_gym
    gym.register_envs(emmi_gym)
    env = gym.make("emmi_gym/LoopCorridor-v1")
"""

__version__ = "0.2.0"


def _register() -> None:
    from .env.registration import register_envs

    register_envs()


_register()


def __getattr__(name: str):
    """``emmi_gym.pretrained`` without importing it first (PEP 562): the shipped agents' module, loaded on
    first use (the training code it reaches imports this package back)."""
    if name == "pretrained":
        import importlib

        return importlib.import_module(f"{__name__}.pretrained")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
