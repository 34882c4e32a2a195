"""Run folders: the checks a run makes before it writes anything, so that no earlier work is lost.

rl-baselines3-zoo never reuses a log folder (each run gets the next numbered one); here a run goes
where ``--out`` says, with the same promise: a new run into a folder that holds anything is refused
unless told to ``overwrite`` it (which removes the files a run writes, :data:`RUN_FILES`, and
nothing else); ``resume`` continues the run in the folder only with the configuration it started
with (what may change: :data:`RESUMABLE_CHANGES`); ``init_from`` (a model a new run starts from,
rl-baselines3-zoo's ``--trained-agent``) must be a model of the configuration's algorithm, env id
and spaces, with finite weights, and leave decisions to train
(:mod:`~emmi_gym.training.warm_start`). :func:`~emmi_gym.training.train.plan_run` makes every
check and says where the run starts.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from ..inputs.errors import excerpt
from .config import AgentConfig, load_agent_config

#: What ``emmi-gym train`` writes into a run folder (all that ``overwrite`` removes).
RUN_FILES = ("config.yaml", "model.zip", "training.yaml", "checkpoints", "eval", "eval_ground_truth.csv", "tb")
#: The fields of a configuration that a resumed run may change: its budget, how its envs run (and are watched), its
#: evaluation and checkpoint schedules. Any other (algorithm, policy, hyperparameters, env id and
#: options, seed) would make the rest of the run another run than its model's and its ``config.yaml``.
RESUMABLE_CHANGES = ("total_timesteps", "n_envs", "vec_env", "policy_lag", "worker_timeout", "eval",
                     "checkpoint_freq")


class RunError(ValueError):
    """A run cannot start as asked (a folder in use, a configuration or model that does not match); says why
    and what to do."""


def run_config_path(model_path) -> Path | None:
    """The ``config.yaml`` written beside a model (in its folder or the run folder above a checkpoint), if any."""
    model_path = Path(model_path)
    return next(
        (
            folder / "config.yaml"
            for folder in (model_path.parent, model_path.parent.parent)
            if (folder / "config.yaml").is_file()
        ),
        None,
    )


def folder_entries(folder: Path) -> list[str]:
    """The names in ``folder``, sorted (none if it does not exist)."""
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []


def check_new_run_folder(folder: Path, overwrite: bool, *, resumable: bool = True, inputs=None,
                         files=RUN_FILES) -> None:
    """Refuse a new run into ``folder`` if it holds anything, unless ``overwrite`` (``resumable``: the
    message offers ``--resume``); with ``overwrite``, refuse it too if one of its ``inputs`` (``{option:
    path or paths}``, None where not given) lies among the ``files`` that overwriting removes
    (:func:`clear_run_folder`): it would be gone before it is read."""
    entries = folder_entries(folder)
    if entries and not overwrite:
        shown = ", ".join(entries[:6]) + (", ..." if len(entries) > 6 else "")
        resume = "continue the run in it with --resume, " if resumable else ""
        raise RunError(
            f"{folder} is not empty (it holds {shown}): a new run would overwrite what is there; "
            f"{resume}replace it with --overwrite, or give another --out"
        )
    if entries:
        check_inputs_kept(folder, inputs or {}, files)


def check_inputs_kept(folder: Path, inputs: dict, files=RUN_FILES) -> None:
    """Refuse an input (``{option: path or paths}``) that lies among the ``files`` of ``folder`` that
    ``--overwrite`` removes (links and ``..`` resolved): the run would remove what it was to read."""
    removed = [(Path(folder) / name).resolve() for name in files]
    for option, paths in inputs.items():
        for path in [] if paths is None else [paths] if isinstance(paths, (str, Path)) else paths:
            if any(Path(path).resolve().is_relative_to(gone) for gone in removed):
                raise RunError(
                    f"{option} {path} is a file of the run in {folder}, which --overwrite would remove before it "
                    f"is read: copy it out of {folder} first, or give another --out"
                )


def clear_run_folder(folder: Path, names=RUN_FILES) -> None:
    """Remove the files and folders ``names`` that a run wrote into ``folder`` (``overwrite``); others stay."""
    for name in names:
        path = folder / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif path.exists() or path.is_symlink():
            path.unlink()


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
    from dataclasses import asdict

    import gymnasium as gym

    from ..env import make_config

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


def check_resumable(config: AgentConfig, folder: Path) -> None:
    """Refuse to resume the run in ``folder`` with ``config`` unless it is the run's own configuration, but for
    :data:`RESUMABLE_CHANGES`: the run's ``config.yaml`` must be there, and nothing is written."""
    own_path = folder / "config.yaml"
    if not own_path.is_file():
        what = f"holds {', '.join(folder_entries(folder)[:6])}" if folder_entries(folder) else "is empty"
        raise RunError(
            f"--resume: {folder} holds no run to continue (no config.yaml; the folder {what})"
            if folder.is_dir()
            else f"--resume: {folder} does not exist"
        )
    differing = differing_fields(load_agent_config(own_path), config)
    if differing:
        absent = "(absent)"
        shown = "; ".join(
            f"{name}: {absent if mine is None else excerpt(mine)} in the run, "
            f"{absent if theirs is None else excerpt(theirs)} in {config.source}"
            for name, (mine, theirs) in list(differing.items())[:8]
        )
        raise RunError(
            f"--resume: {config.source} is not the configuration of the run in {folder} ({own_path}): "
            f"{shown}. A resumed run may change only {', '.join(RESUMABLE_CHANGES)}; resume with "
            f"{own_path} itself, or start a new run with another --out"
        )


@dataclass(frozen=True)
class RunStart:
    """Where a run starts: ``model`` (a checkpoint or ``model.zip`` of the run itself when resuming, the
    ``init_from`` model, or None for a fresh model); ``init_from`` and its ``init_decisions`` (the model
    the run started from, if any, also when resumed); ``record``: the run's ``training.yaml`` as it was
    (resuming) or None; ``overwrite``: the folder's run files are to be removed first."""

    model: Path | None
    init_from: Path | None = None
    init_decisions: int = 0
    record: dict | None = None
    overwrite: bool = False

    def summary(self, decisions: int, total: int) -> str:
        """Where the run starts (its model holding ``decisions``) and how many decisions it trains, to ``total``."""
        to_train = f"{max(total - decisions, 0)} decisions to train, to {total}"
        if self.model is None:
            return f"a fresh model: {to_train}"
        verb = "starting from" if self.model == self.init_from else "continuing from"
        return f"{verb} {self.model} ({decisions} decisions): {to_train}"
