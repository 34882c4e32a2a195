"""Trained agents that ship with the package, each in a folder of its name: ``model.zip`` (the model
``emmi-gym train`` wrote), ``config.yaml`` (its run's configuration) and ``MODEL_CARD.md``
(configuration, budget, seed, training time and its evaluation table).

One line loads one (needs the ``train`` extra), another makes the env it was trained for (its
configuration's ``gym.make`` keywords, which need not be the registered defaults)::

    model = emmi_gym.pretrained.load("explore_plans_emmi")
    env = emmi_gym.pretrained.make_env("explore_plans_emmi", world="dungeon_maps/test")

and ``emmi-gym evaluate --pretrained explore_plans_emmi`` plays it.
"""

from __future__ import annotations

from pathlib import Path

from ...inputs.extras import missing_extra

FOLDER = Path(__file__).resolve().parent


def names() -> list[str]:
    """The names of the shipped agents."""
    return sorted(p.parent.name for p in FOLDER.glob("*/model.zip"))


def model_path(name: str) -> Path:
    """The ``model.zip`` of the shipped agent ``name`` (its ``config.yaml`` and ``MODEL_CARD.md`` beside it)."""
    if name not in names():
        raise ValueError(f"no pretrained agent {name!r}; the package ships {names()}")
    return FOLDER / name / "model.zip"


def config(name: str):
    """The :class:`~emmi_gym.tools.training.config.AgentConfig` the agent ``name`` was trained with."""
    from ..training.run_folders import RunFolder

    return RunFolder.config_of_model(model_path(name))


def load(name: str):
    """The Stable-Baselines3 model of the shipped agent ``name``, on the CPU; without the ``train``
    extra a :class:`~emmi_gym.inputs.extras.MissingExtraError` naming the line that installs it."""
    try:
        from ..training.evaluate import load_model
    except ModuleNotFoundError as error:
        missing = missing_extra(error, f"emmi_gym.pretrained.load({name!r})")
        if missing is None:
            raise
        raise missing from None
    return load_model(model_path(name))[0]


def make_env(name: str, **overrides):
    """``gym.make`` of the env the shipped agent ``name`` was trained in: its configuration's env id and
    keywords, updated by ``overrides`` (e.g. ``world="dungeon_maps/test"`` for held-out floor plans)."""
    import gymnasium as gym

    from ..training.config import env_of_file

    env_id, kwargs = env_of_file(model_path(name).with_name("config.yaml"))
    return gym.make(env_id, **{**kwargs, **overrides})
