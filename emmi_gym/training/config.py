"""Agent configurations: YAML files in the spirit of rl-baselines3-zoo's hyperparameter files.

A file names the environment (id and ``gym.make`` keywords), the algorithm, its policy and
hyperparameters, the number of environments, the training budget, the seed and the
evaluation and checkpoint schedules. ``discount_unit: N`` makes ``gamma`` apply per N simulator
steps of robot time instead of per decision (semi-Markov discounting of macro-actions, see
:mod:`emmi_gym.training.semi_markov`; PPO, A2C and MaskablePPO). ``base: other.yaml`` (relative to the file) starts
from another configuration and overrides what the file gives (dicts are merged key by key,
but ``hyperparameters`` are replaced whole: they belong to one algorithm), so the reward
variants of one agent are one line each. Every mistake raises
:class:`AgentConfigError` naming the file, the field and what was expected.
"""

from __future__ import annotations

import inspect
from dataclasses import asdict, dataclass, field
from pathlib import Path

import yaml

from ..errors import FieldError

#: The algorithms a configuration may name: Stable-Baselines3's and sb3-contrib's classes.
ALGORITHMS = ("PPO", "A2C", "MaskablePPO", "DQN", "SAC")
POLICIES = ("MultiInputPolicy", "CnnPolicy", "MlpPolicy", "TargetScoringPolicy")
VEC_ENVS = ("subproc", "dummy")
_KEYS = ("base", "env", "algorithm", "policy", "hyperparameters", "discount_unit", "n_envs", "vec_env",
         "total_timesteps", "seed", "eval", "checkpoint_freq")


class AgentConfigError(FieldError):
    """An agent configuration is malformed; says which file, which field, what was expected."""


def policy_argument(name: str):
    """What SB3 takes as ``policy`` for a name of :data:`POLICIES`: SB3's own names as they are, ours as a class."""
    if name == "TargetScoringPolicy":
        from .target_policy import TargetScoringPolicy

        return TargetScoringPolicy
    return name


def algorithm_class(name: str):
    """The class behind an algorithm name of :data:`ALGORITHMS`."""
    if name == "MaskablePPO":
        from sb3_contrib import MaskablePPO

        return MaskablePPO
    import stable_baselines3

    return getattr(stable_baselines3, name)


@dataclass(frozen=True)
class EvalSchedule:
    """Evaluate every ``freq`` environment steps (summed over the envs) on ``episodes`` held-out
    episodes seeded from ``seed`` on (the same episodes at every evaluation)."""

    freq: int = 2000
    episodes: int = 4
    seed: int = 100_000


@dataclass(frozen=True)
class AgentConfig:
    """A resolved agent configuration (see the module docstring)."""

    env_id: str
    env_kwargs: dict
    algorithm: str
    policy: str = "MultiInputPolicy"
    hyperparameters: dict = field(default_factory=dict)
    discount_unit: int | None = None
    n_envs: int = 2
    vec_env: str = "subproc"
    total_timesteps: int = 20_000
    seed: int = 0
    eval: EvalSchedule = EvalSchedule()
    checkpoint_freq: int = 5000
    source: str = "<dict>"

    def as_yaml_dict(self) -> dict:
        """The configuration as a file would give it (what ``train`` writes beside the model)."""
        data = asdict(self)
        return {"env": {"id": data.pop("env_id"), "kwargs": data.pop("env_kwargs")},
                **{k: v for k, v in data.items() if k != "source"}}


def _merge(base: dict, override: dict, whole=("hyperparameters",)) -> dict:
    """``base`` updated by ``override``, dicts key by key except the ``whole`` ones (a file's
    hyperparameters belong to its algorithm, so they replace the base's entirely)."""
    merged = dict(base)
    for key, value in override.items():
        nested = isinstance(value, dict) and isinstance(merged.get(key), dict) and key not in whole
        merged[key] = _merge(merged[key], value, whole=()) if nested else value
    return merged


def _read(path: Path, seen: tuple[Path, ...] = ()) -> dict:
    if not path.is_file():
        raise FileNotFoundError(f"agent configuration {path} does not exist")
    if path.resolve() in seen:
        raise AgentConfigError(str(path), "base", "no cycle of base files", [str(p) for p in seen])
    with open(path) as f:
        try:
            data = yaml.safe_load(f)
        except yaml.YAMLError as exc:
            raise AgentConfigError(str(path), "<file>", f"valid YAML ({exc})") from None
    if not isinstance(data, dict):
        raise AgentConfigError(str(path), "<file>", "a mapping of configuration fields", data)
    if "base" in data:
        if not isinstance(data["base"], str):
            raise AgentConfigError(str(path), "base", "a file name relative to this file", data["base"])
        base = _read(path.parent / data["base"], seen + (path.resolve(),))
        data = _merge(base, {k: v for k, v in data.items() if k != "base"})
    return data


def load_agent_config(path) -> AgentConfig:
    """Read and check an agent configuration file (following ``base`` files)."""
    path = Path(path)
    return parse_agent_config(_read(path), source=str(path))


def _integer(source: str, name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise AgentConfigError(source, name, f"an integer >= {minimum}", value)
    return value


def parse_agent_config(data: dict, source: str = "<dict>") -> AgentConfig:
    """Check a configuration given as a dict (as read from YAML) and resolve it."""
    from ..env import ENV_IDS
    from ..env.config import make_config

    unknown = sorted(set(data) - set(_KEYS))
    if unknown:
        raise AgentConfigError(source, unknown[0], f"one of the fields {list(_KEYS)}")
    env = data.get("env")
    if not isinstance(env, dict) or not isinstance(env.get("id"), str):
        raise AgentConfigError(source, "env", "a mapping with an 'id' (and optional 'kwargs')", env)
    valid_ids = [f"emmi_gym/{name}" for name in ENV_IDS]
    if env["id"] not in valid_ids:
        raise AgentConfigError(source, "env.id", f"one of {valid_ids}", env["id"])
    kwargs = env.get("kwargs") or {}
    if not isinstance(kwargs, dict):
        raise AgentConfigError(source, "env.kwargs", "a mapping of gym.make keywords", kwargs)
    try:
        make_config(**kwargs)
    except (ValueError, TypeError) as exc:
        raise AgentConfigError(source, "env.kwargs", f"valid environment options ({exc})") from None
    algorithm = data.get("algorithm")
    if algorithm not in ALGORITHMS:
        raise AgentConfigError(source, "algorithm", f"one of {list(ALGORITHMS)}", algorithm)
    policy = data.get("policy", "MultiInputPolicy")
    if policy not in POLICIES:
        raise AgentConfigError(source, "policy", f"one of {list(POLICIES)}", policy)
    if policy == "TargetScoringPolicy" and algorithm != "MaskablePPO":
        raise AgentConfigError(source, "policy", "TargetScoringPolicy only with algorithm MaskablePPO", policy)
    hyper = data.get("hyperparameters") or {}
    if not isinstance(hyper, dict):
        raise AgentConfigError(source, "hyperparameters", "a mapping of the algorithm's keywords", hyper)
    reserved = ("self", "policy", "env", "seed", "tensorboard_log", "verbose", "device", "_init_setup_model")
    accepted = [p for p in inspect.signature(algorithm_class(algorithm).__init__).parameters if p not in reserved]
    for name in hyper:
        if name not in accepted:
            raise AgentConfigError(source, f"hyperparameters.{name}", f"a keyword of {algorithm}: one of {accepted}")
    for name in ("rollout_buffer_class", "rollout_buffer_kwargs"):
        if name in hyper and data.get("discount_unit") is not None:
            raise AgentConfigError(source, f"hyperparameters.{name}", "not given with discount_unit (which sets the "
                                   "rollout buffer)")
    discount_unit = data.get("discount_unit")
    if discount_unit is not None:
        from .semi_markov import SUPPORTED

        _integer(source, "discount_unit", discount_unit, 1)
        if algorithm not in SUPPORTED:
            raise AgentConfigError(source, "discount_unit", f"absent for {algorithm} (semi-Markov discounting is "
                                   f"implemented for {list(SUPPORTED)})", discount_unit)
    vec_env = data.get("vec_env", "subproc")
    if vec_env not in VEC_ENVS:
        raise AgentConfigError(source, "vec_env", f"one of {list(VEC_ENVS)}", vec_env)
    schedule = data.get("eval") or {}
    if not isinstance(schedule, dict) or set(schedule) - {"freq", "episodes", "seed"}:
        raise AgentConfigError(source, "eval", "a mapping with freq, episodes and seed", schedule)
    defaults = EvalSchedule()
    eval_schedule = EvalSchedule(
        freq=_integer(source, "eval.freq", schedule.get("freq", defaults.freq), 1),
        episodes=_integer(source, "eval.episodes", schedule.get("episodes", defaults.episodes), 1),
        seed=_integer(source, "eval.seed", schedule.get("seed", defaults.seed), 0))
    return AgentConfig(
        env_id=env["id"], env_kwargs=dict(kwargs), algorithm=algorithm, policy=policy, hyperparameters=dict(hyper),
        discount_unit=discount_unit, n_envs=_integer(source, "n_envs", data.get("n_envs", 2), 1), vec_env=vec_env,
        total_timesteps=_integer(source, "total_timesteps", data.get("total_timesteps", 20_000), 1),
        seed=_integer(source, "seed", data.get("seed", 0), 0), eval=eval_schedule,
        checkpoint_freq=_integer(source, "checkpoint_freq", data.get("checkpoint_freq", 5000), 1), source=source)
