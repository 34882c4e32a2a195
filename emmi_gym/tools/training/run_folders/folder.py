"""A training run's folder, :class:`RunFolder`: the files a run writes, and the checks it makes before it writes
anything, so that no earlier work is lost.

A run folder holds ``config.yaml`` (the resolved configuration), ``model.zip`` (the final model),
``checkpoints/`` (``model_<steps>_steps.zip``, with the replay buffer for off-policy algorithms), ``eval/``
(SB3's ``evaluations.npz`` and the best model), ``eval_ground_truth.csv`` (the ground-truth means of every
evaluation), ``training.yaml`` (:mod:`~emmi_gym.tools.training.run_folders.training_record`) and ``tb/``
(TensorBoard logs).

rl-baselines3-zoo never reuses a log folder (each run gets the next numbered one); here a run goes
where ``--out`` says, with the same promise: a new run into a folder that holds anything is refused
unless told to ``overwrite`` it (which removes the files a run writes, :data:`RUN_FILES`, and
nothing else); ``resume`` continues the run in the folder only with the configuration it started
with (what may change: :data:`~emmi_gym.tools.training.run_folders.config_changes.RESUMABLE_CHANGES`), from its latest
loadable checkpoint; ``init_from`` (a model a new run starts from, rl-baselines3-zoo's ``--trained-agent``)
must be a model of the configuration's algorithm and policy class, its network (``policy_kwargs``), its env id
(from the ``config.yaml`` written beside it, where there is one: a warning where there is none) and its
observation and action spaces, with finite weights, and leave decisions to train (its own count towards
``total_timesteps``). :meth:`RunFolder.plan` makes every check and says where the run starts.
"""

from __future__ import annotations

import re
import shutil
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import yaml

from ....formats.atomic_files import write_text_atomically
from ....inputs.errors import excerpt
from ....inputs.user_paths import file_kind
from ..config import AgentConfig, algorithm_class, env_of_file, load_agent_config, policy_argument, sb3_policy_kwargs
from .config_changes import RESUMABLE_CHANGES, differing_fields
from .model_files import ModelFileError, check_model_file, load_model_file, saved_decisions
from .training_record import TRAINING_RECORD, read_training_record, write_training_record

#: What ``emmi-gym train`` writes into a run folder (all that ``overwrite`` removes).
RUN_FILES = ("config.yaml", "model.zip", TRAINING_RECORD, "checkpoints", "eval", "eval_ground_truth.csv", "tb")
_CHECKPOINT = re.compile(r"model_(\d+)_steps\.zip$")


class RunError(ValueError):
    """A run cannot start as asked (a folder in use, a configuration or model that does not match); says why
    and what to do."""


@dataclass(frozen=True)
class WarmStart:
    """A model checked by :meth:`RunFolder.check_init_from`: its ``path`` and the ``decisions`` it holds."""

    path: Path
    decisions: int


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


class RunFolder:
    """The folder of a training run at ``path`` and its files (``files``: those a run writes there, which
    ``overwrite`` removes; :data:`RUN_FILES` for ``emmi-gym train``'s runs)."""

    def __init__(self, path, files=RUN_FILES):
        self.path = Path(path)
        self.files = tuple(files)

    def __repr__(self) -> str:
        return f"RunFolder({str(self.path)!r})"

    @property
    def config_path(self) -> Path:
        """The run's configuration, ``config.yaml``."""
        return self.path / "config.yaml"

    @property
    def model_path(self) -> Path:
        """The model of a finished run, ``model.zip``."""
        return self.path / "model.zip"

    @property
    def checkpoint_dir(self) -> Path:
        """The folder of the run's checkpoints."""
        return self.path / "checkpoints"

    @property
    def eval_dir(self) -> Path:
        """The folder of SB3's periodic evaluations (``evaluations.npz``, the best model)."""
        return self.path / "eval"

    @property
    def ground_truth_path(self) -> Path:
        """The ground-truth means of every periodic evaluation, ``eval_ground_truth.csv``."""
        return self.path / "eval_ground_truth.csv"

    @property
    def tensorboard_dir(self) -> Path:
        """The run's TensorBoard logs."""
        return self.path / "tb"

    def checkpoint_path(self, decisions: int) -> Path:
        """The checkpoint of the model holding ``decisions`` (SB3's ``CheckpointCallback`` names them so too)."""
        return self.checkpoint_dir / f"model_{decisions}_steps.zip"

    @staticmethod
    def replay_buffer_path(checkpoint: Path) -> Path:
        """The replay buffer saved beside ``checkpoint`` (off-policy algorithms)."""
        return checkpoint.with_name(checkpoint.name.replace("model_", "model_replay_buffer_").replace(".zip", ".pkl"))

    @classmethod
    def of_model(cls, model_path) -> RunFolder | None:
        """The run folder of a model: its own folder or, for a checkpoint, the one above it, whichever holds a
        ``config.yaml``; None if neither does."""
        model_path = Path(model_path)
        return next((cls(folder) for folder in (model_path.parent, model_path.parent.parent)
                     if (folder / "config.yaml").is_file()), None)

    @classmethod
    def config_of_model(cls, model_path) -> AgentConfig:
        """The configuration written beside a model (in its folder or the run folder above a checkpoint)."""
        folder = cls.of_model(model_path)
        if folder is None:
            raise FileNotFoundError(f"no config.yaml beside {model_path} or in its run folder: was it written by "
                                    f"'emmi-gym train'?")
        return folder.config()

    def entries(self) -> list[str]:
        """The names in the folder, sorted (none if it does not exist)."""
        return sorted(p.name for p in self.path.iterdir()) if self.path.is_dir() else []

    def check_exists(self) -> None:
        """A ``FileNotFoundError`` unless the folder exists (and is a folder): a run to read."""
        if not self.path.exists():
            raise FileNotFoundError(f"run folder {self.path} does not exist")
        if not self.path.is_dir():
            raise FileNotFoundError(f"{self.path}: expected a run folder of 'emmi-gym train', not "
                                    f"{file_kind(self.path.stat().st_mode)}")

    def check_new(self, overwrite: bool, *, resumable: bool = True, inputs=None) -> None:
        """Refuse a new run into the folder if it holds anything, unless ``overwrite`` (``resumable``: the
        message offers ``--resume``); with ``overwrite``, refuse it too if one of its ``inputs`` (``{option:
        path or paths}``, None where not given) lies among the files that overwriting removes
        (:meth:`check_inputs_kept`): it would be gone before it is read."""
        entries = self.entries()
        if entries and not overwrite:
            shown = ", ".join(entries[:6]) + (", ..." if len(entries) > 6 else "")
            resume = "continue the run in it with --resume, " if resumable else ""
            raise RunError(
                f"{self.path} is not empty (it holds {shown}): a new run would overwrite what is there; "
                f"{resume}replace it with --overwrite, or give another --out"
            )
        if entries:
            self.check_inputs_kept(inputs or {})

    def check_inputs_kept(self, inputs: dict) -> None:
        """Refuse an input (``{option: path or paths}``) that lies among the files of the folder that
        ``--overwrite`` removes (links and ``..`` resolved): the run would remove what it was to read."""
        removed = [(self.path / name).resolve() for name in self.files]
        for option, paths in inputs.items():
            for path in [] if paths is None else [paths] if isinstance(paths, (str, Path)) else paths:
                if any(Path(path).resolve().is_relative_to(gone) for gone in removed):
                    raise RunError(
                        f"{option} {path} is a file of the run in {self.path}, which --overwrite would remove before "
                        f"it is read: copy it out of {self.path} first, or give another --out"
                    )

    def clear(self) -> None:
        """Remove the files and folders a run wrote into the folder (``overwrite``); others stay."""
        for name in self.files:
            path = self.path / name
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            elif path.exists() or path.is_symlink():
                path.unlink()

    def config(self) -> AgentConfig:
        """The run's configuration, as its ``config.yaml`` holds it."""
        return load_agent_config(self.config_path)

    def write_config(self, config: AgentConfig) -> None:
        """Write ``config`` (resolved) as the run's ``config.yaml`` (the folder made if need be)."""
        self.path.mkdir(parents=True, exist_ok=True)
        write_text_atomically(self.config_path, yaml.safe_dump(config.as_yaml_dict(), sort_keys=False))

    def differences(self, config: AgentConfig, ignore=RESUMABLE_CHANGES) -> dict[str, tuple]:
        """Where ``config`` differs from the run's own, outside ``ignore``: ``{dotted name: (the run's, config's)}``
        (:func:`~emmi_gym.tools.training.run_folders.config_changes.differing_fields`)."""
        return differing_fields(self.config(), config, ignore)

    def check_resumable(self, config: AgentConfig) -> None:
        """Refuse to resume the run with ``config`` unless it is the run's own configuration, but for
        :data:`~emmi_gym.tools.training.run_folders.config_changes.RESUMABLE_CHANGES`: the run's ``config.yaml`` must be
        there, and nothing is written."""
        if not self.config_path.is_file():
            entries = self.entries()
            what = f"holds {', '.join(entries[:6])}" if entries else "is empty"
            raise RunError(
                f"--resume: {self.path} holds no run to continue (no config.yaml; the folder {what})"
                if self.path.is_dir()
                else f"--resume: {self.path} does not exist"
            )
        differing = self.differences(config)
        if differing:
            absent = "(absent)"
            shown = "; ".join(
                f"{name}: {absent if mine is None else excerpt(mine)} in the run, "
                f"{absent if theirs is None else excerpt(theirs)} in {config.source}"
                for name, (mine, theirs) in list(differing.items())[:8]
            )
            raise RunError(
                f"--resume: {config.source} is not the configuration of the run in {self.path} ({self.config_path}): "
                f"{shown}. A resumed run may change only {', '.join(RESUMABLE_CHANGES)}; resume with "
                f"{self.config_path} itself, or start a new run with another --out"
            )

    def record(self) -> dict | None:
        """The run's ``training.yaml``: the fields it sets, checked
        (:func:`~emmi_gym.tools.training.run_folders.training_record.read_training_record`: a
        :class:`~emmi_gym.tools.training.run_folders.training_record.TrainingRecordError` naming the file and field
        otherwise); None if it has none."""
        path = self.path / TRAINING_RECORD
        return read_training_record(path) if path.exists() else None

    def write_record(self, earlier: list[dict], start: int, decisions: int, wall_seconds: float | None,
                     init_from=None, init_decisions: int = 0) -> None:
        """Write the run's ``training.yaml``: the ``earlier`` parts and this one, from ``start`` to ``decisions`` in
        ``wall_seconds`` (:func:`~emmi_gym.tools.training.run_folders.training_record.write_training_record`)."""
        write_training_record(self.path / TRAINING_RECORD, earlier, start, decisions, wall_seconds, init_from,
                              init_decisions)

    def checkpoints(self) -> list[tuple[int, Path]]:
        """The run's checkpoints, ``(decisions, path)``, fewest decisions first (as their names say)."""
        return sorted((int(m.group(1)), p) for p in self.checkpoint_dir.glob("model_*_steps.zip")
                      if (m := _CHECKPOINT.search(p.name)))

    def finished_decisions(self) -> int | None:
        """The decisions the run's ``model.zip`` holds; None if the run has none (it has not finished)."""
        return saved_decisions(self.model_path) if self.model_path.is_file() else None

    def model_files(self) -> list[Path]:
        """The run's model files as their names say, whole or not: its checkpoints, fewest decisions first, then
        ``model.zip`` if there is one."""
        return [path for _, path in self.checkpoints()] + ([self.model_path] if self.model_path.exists() else [])

    def latest_checkpoint(self, algorithm: str | None = None) -> Path | None:
        """The checkpoint to continue the run from: of the final ``model.zip`` and the checkpoints that are whole
        (a damaged one is skipped with a warning; with ``algorithm``, so is one that
        is not a model of it), the one with the most decisions, ``model.zip`` on a tie (a run extended to a
        larger budget and stopped holds checkpoints past its old ``model.zip``)."""
        found = [(decisions, False, path) for decisions, path in self.checkpoints()]
        if self.model_path.exists() and _is_whole_checkpoint(self.model_path, algorithm):
            found.append((saved_decisions(self.model_path), True, self.model_path))
        return next((path for *_, path in sorted(found, reverse=True) if path == self.model_path or
                     _is_whole_checkpoint(path, algorithm)), None)

    def whole_checkpoints(self) -> list[tuple[int, Path]]:
        """The whole checkpoints of the run (a damaged one is skipped with a warning), ``(decisions, path)``, each at
        the decisions its model holds (a file's name may say anything), fewest first, and the final ``model.zip``
        where the run finished with more decisions than its last checkpoint (a 3,000-decision budget ends at
        3,072, and a resumed run's last checkpoint may lie 900 decisions before its end); a
        ``FileNotFoundError`` that says which is missing, the folder or its checkpoints."""
        self.check_exists()
        found = sorted((saved_decisions(path), path) for _, path in self.checkpoints() if _is_whole_checkpoint(path))
        if self.model_path.is_file() and _is_whole_checkpoint(self.model_path):
            finished_at = saved_decisions(self.model_path)
            if finished_at > (found[-1][0] if found else 0):
                found.append((finished_at, self.model_path))
        unloadable = None if found else self._unloadable()
        if unloadable is not None:
            raise ModelFileError(str(self.path), "", f"a run with a whole checkpoint or model; its {unloadable[0]} "
                                 f"model file(s) are all damaged, the last: {unloadable[1]}")
        if not found:
            raise FileNotFoundError(f"no checkpoint in {self.checkpoint_dir}: was {self.path} written by "
                                    "'emmi-gym train'?")
        return found

    def _unloadable(self, algorithm: str | None = None) -> tuple[int, str] | None:
        """Where the run saved model files and none was found whole (of ``algorithm``): how many, and what is wrong
        with the last (``model.zip``, else the checkpoint of the most decisions); None where it saved none."""
        files = self.model_files()
        if not files:
            return None
        return len(files), _model_problem(files[-1], algorithm) or f"{files[-1]}: not a model the run can go on from"

    def already_trained(self, config: AgentConfig) -> int | None:
        """The decisions of the run's whole ``model.zip`` if resuming it with ``config`` would train none: the run
        finished ``config.total_timesteps`` and holds no checkpoint past them; None otherwise (and where
        :meth:`plan` is to say what is wrong). Refuses, as :meth:`plan` does, a ``config`` that is not the run's."""
        self.check_resumable(config)
        if not self.model_path.is_file() or _model_problem(self.model_path, config.algorithm) is not None:
            return None
        finished = saved_decisions(self.model_path)
        past = [decisions for decisions, _ in self.checkpoints() if decisions > finished]
        return finished if finished == config.total_timesteps and not past else None

    def check_some_model_loads(self, algorithm: str) -> None:
        """Refuse to resume a run that saved model files of which none is a whole model of ``algorithm`` (its
        ``config.yaml``'s): a :class:`RunError` naming the folder and what is wrong with the last file, and how to
        start over; a run that saved none (it stopped before its first checkpoint) passes."""
        unloadable = self._unloadable(algorithm)
        if unloadable is not None:
            raise RunError(
                f"--resume: none of the {unloadable[0]} model files of the run in {self.path} is a whole {algorithm} "
                f"model, as its {self.config_path.name} names (the last: {unloadable[1]}); nothing was changed. Start "
                "the run over with --overwrite (which removes its files), or give another --out"
            )

    @classmethod
    def check_init_from(cls, path, config: AgentConfig, allow_no_training: bool = False) -> WarmStart:
        """``path`` checked to be a model a new run of ``config`` can start from (see the module docstring):
        :class:`~emmi_gym.tools.training.run_folders.model_files.ModelFileError` naming the file if it is not one that
        loads or its weights are not finite, :class:`RunError` naming the model and the configuration if they do not
        match, or if no decision would train (unless ``allow_no_training``); a warning if no ``config.yaml``
        beside it says which env it was trained on."""
        path = check_model_file(path, config.algorithm)  # the file first: what is missing or damaged, not a warning
        own = cls.of_model(path)
        if own is None:
            warnings.warn(f"--init-from {path}: no config.yaml beside it or in its run folder says which env it was "
                          f"trained on; its spaces are checked against {config.env_id}'s, its env id cannot be",
                          stacklevel=2)
        else:
            env_id = env_of_file(own.config_path)[0]
            if env_id != config.env_id:
                raise RunError(
                    f"--init-from {path}: a model of {env_id} (its configuration {own.config_path}), but "
                    f"{config.source} trains on {config.env_id}: start from a model of {config.env_id}, or "
                    f"train with a configuration of {env_id}"
                )
        decisions = _check_model_fits(path, config, f"--init-from {path}")
        if decisions >= config.total_timesteps and not allow_no_training:
            raise RunError(
                f"--init-from {path}: the model holds {decisions} decisions and {config.source} trains to "
                f"total_timesteps {config.total_timesteps} (its decisions count towards them): no decision "
                f"would train. Give a larger budget (--timesteps above {decisions}), or pass "
                "--allow-no-training to copy the model into a new run as it is"
            )
        return WarmStart(path, decisions)

    def plan(self, config: AgentConfig, *, resume: bool = False, overwrite: bool = False, init_from=None,
             allow_no_training: bool = False) -> RunStart:
        """Make every check of a run of ``config`` into the folder before anything is written (see the module
        docstring) and say where it starts."""
        if resume and overwrite:
            raise RunError("--resume continues the run in the folder and --overwrite replaces it: give one of them")
        if resume and init_from is not None:
            raise RunError("--init-from starts a new run from a model; --resume continues the run in the folder "
                           "(which remembers the model it started from): give one of them")
        if resume:
            return self._resumed(config)
        self.check_new(overwrite, inputs={"--init-from": init_from})
        if init_from is None:
            return RunStart(None, overwrite=overwrite)
        start = self.check_init_from(init_from, config, allow_no_training)
        return RunStart(start.path, start.path, start.decisions, overwrite=overwrite)

    def _resumed(self, config: AgentConfig) -> RunStart:
        """Where the run in the folder goes on with ``config`` (:meth:`plan` with ``resume``): its latest loadable
        checkpoint, or, if it stopped before its first checkpoint (it saved no model file), the model it started
        from or a fresh model. A run whose model files all fail to load (damaged, or of another algorithm than its
        ``config.yaml`` names) is refused (:meth:`check_some_model_loads`): it never starts again from scratch."""
        self.check_resumable(config)
        record = self.record() or {}
        init_path = Path(record["init_from"]) if record.get("init_from") is not None else None
        checkpoint = self.latest_checkpoint(config.algorithm)
        if checkpoint is None:
            self.check_some_model_loads(config.algorithm)
        if checkpoint is None and init_path is not None:  # stopped before its first checkpoint: from its start again
            checkpoint = self.check_init_from(init_path, config, allow_no_training=True).path
        elif checkpoint is not None:
            decisions = _check_model_fits(checkpoint, config, f"--resume: {checkpoint}")
            if decisions > config.total_timesteps:
                raise RunError(f"--resume: the run in {self.path} holds {decisions} decisions ({checkpoint}), more "
                               f"than total_timesteps {config.total_timesteps}: a run is not cut back. Give "
                               f"--timesteps {decisions} or more, or start a new run with another --out")
        return RunStart(checkpoint, init_path, int(record.get("init_decisions", 0)), record)


def _model_problem(path: Path, algorithm: str | None = None) -> str | None:
    """What is wrong with a model file of a run, in words naming it: not a zip archive whose members all read back
    (a save cut short by a kill is not), or not a model (with ``algorithm``: not a model of it, as
    :func:`~emmi_gym.tools.training.run_folders.model_files.check_model_file` checks); None if it is whole."""
    try:
        with zipfile.ZipFile(path) as archive:
            whole = archive.testzip() is None
    except (zipfile.BadZipFile, OSError):
        whole = False
    if not whole:
        return f"{path} (not a whole zip archive)"
    try:
        if algorithm is None:
            saved_decisions(path)
        else:
            check_model_file(path, algorithm)
    except ModelFileError as exc:
        return str(exc)
    return None


def _is_whole_checkpoint(path: Path, algorithm: str | None = None) -> bool:
    """Whether a checkpoint is whole (:func:`_model_problem`); a damaged one is skipped with a warning."""
    problem = _model_problem(path, algorithm)
    if problem is not None:
        warnings.warn(f"skipping the damaged checkpoint {problem}", stacklevel=3)
    return problem is None


def _check_model_fits(path, config: AgentConfig, what: str) -> int:
    """The decisions the model at ``path`` holds, once checked to be one a run of ``config`` can go on from: its
    algorithm, policy class, network and spaces ``config``'s, its weights finite;
    :class:`~emmi_gym.tools.training.run_folders.model_files.ModelFileError` naming the file if it does not load or is
    not finite, :class:`RunError` starting with ``what`` (the option and the file) if it does not match."""
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    model = load_model_file(path, config.algorithm, device="cpu")
    policy = policy_argument(config.policy)
    wanted = policy if isinstance(policy, type) else algorithm_class(config.algorithm).policy_aliases[policy]
    if type(model.policy) is not wanted:
        raise RunError(f"{what}: a model of the policy {type(model.policy).__name__}, but {config.source} names "
                       f"policy {config.policy} ({wanted.__name__}): give a model of that policy, or a "
                       "configuration of the model's")
    network = config.hyperparameters.get("policy_kwargs")
    network = sb3_policy_kwargs(network) if network else {}
    # the keys the configuration gives, and net_arch always (the algorithms add keys of their own: A2C its
    # optimizer, SAC use_sde)
    saved = {key: model.policy_kwargs.get(key) for key in {*network, "net_arch"}}
    if saved != {key: network.get(key) for key in saved}:
        raise RunError(f"{what}: the model's network is policy_kwargs {model.policy_kwargs}, but {config.source} "
                       f"gives {network}: give a model of that network, or a configuration of the model's")
    env = gym.make(config.env_id, **config.env_kwargs)
    try:
        spaces = {
            "observation": (model.observation_space, env.observation_space),
            "action": (model.action_space, env.action_space),
        }
    finally:
        env.close()
    for name, (saved, expected) in spaces.items():
        if saved != expected:
            raise RunError(f"{what}: the model's {name} space is {saved}, but the env of {config.source} "
                           f"({config.env_id} with its env.kwargs) has {expected}")
    return int(model.num_timesteps)
