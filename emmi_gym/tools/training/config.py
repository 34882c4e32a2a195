"""Agent configurations: YAML files in the spirit of rl-baselines3-zoo's hyperparameter files.

A file names the environment (id and ``gym.make`` keywords), the algorithm, its policy and
hyperparameters, the number of environments, the training budget, the seed and the
evaluation and checkpoint schedules. ``discount_unit: N`` makes ``gamma`` apply per N simulator
steps of robot time instead of per decision (semi-Markov discounting of macro-actions, see
:mod:`emmi_gym.tools.training.semi_markov`; PPO, A2C and MaskablePPO). ``base: other.yaml`` (relative to the file)
starts
from another configuration and overrides what the file gives (dicts are merged key by key,
but ``hyperparameters`` are replaced whole: they belong to one algorithm), so the reward
variants of one agent are one line each. ``policy_lag: 1`` lets rollout workers play the next
fragment while the learner updates (see :mod:`emmi_gym.tools.training.rollout_workers`); ``worker_timeout``: the
seconds a rollout worker may go without playing a decision before the run stops, naming it. Every mistake raises
:class:`AgentConfigError` naming the file, the field and what was expected.
"""

from __future__ import annotations

import inspect
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ...inputs.env_ids import check_env_id
from ...inputs.errors import FieldError
from ...inputs.validation import (
    Boolean,
    Check,
    Choice,
    Integer,
    Mapping,
    Maybe,
    Real,
    build,
    check_fields,
    check_value,
    option,
)
from ...inputs.yaml_files import YAML_SUFFIXES, read_yaml_file

#: The algorithms a configuration may name: Stable-Baselines3's and sb3-contrib's classes.
ALGORITHMS = ("PPO", "A2C", "MaskablePPO", "DQN", "SAC")
POLICIES = ("MultiInputPolicy", "CnnPolicy", "MlpPolicy", "TargetScoringPolicy")
#: How the envs run: rollout workers in local processes or Ray actors (on-policy algorithms; see
#: :mod:`emmi_gym.tools.training.rollout_workers`), or Stable-Baselines3's synchronous vector envs: subprocesses, this
#: process, or subprocesses' worker loops in Ray actors (:mod:`emmi_gym.tools.training.ray_vec_env`).
VEC_ENVS = ("workers", "ray_workers", "subproc", "dummy", "ray")
ROLLOUT_WORKERS = ("workers", "ray_workers")
#: The algorithms that learn from rollouts (collected by rollout workers by default).
ON_POLICY = ("PPO", "A2C", "MaskablePPO")
_KEYS = ("base", "env", "algorithm", "policy", "hyperparameters", "discount_unit", "n_envs", "vec_env",
         "policy_lag", "worker_timeout", "total_timesteps", "seed", "eval", "checkpoint_freq")


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
    episodes seeded from ``seed`` on (the same episodes at every evaluation). ``env_kwargs``
    override the training env's ``gym.make`` keywords in every held-out evaluation (the periodic
    one, ``evaluate`` and the benchmark's), e.g. ``world: dungeon_maps/test`` to evaluate on the
    test split of floor plans (rl-baselines3-zoo's ``eval_env_kwargs``). ``freq: 0``: no periodic
    evaluation (it plays one episode at a time in the learner's process, which on a many-core
    machine idles the env workers; score the checkpoints afterwards with
    :func:`emmi_gym.tools.training.checkpoint_scores.score_checkpoints`)."""

    freq: int = option(2000, Integer(0, 10**10))
    episodes: int = option(4, Integer(1, 10**5))
    seed: int = option(100_000, Integer(0, 2**32 - 1))
    env_kwargs: dict = option({}, Mapping())

    def __post_init__(self):
        check_fields(self)


@dataclass(frozen=True)
class AgentConfig:
    """A resolved agent configuration (see the module docstring)."""

    env_id: str
    env_kwargs: dict
    algorithm: str
    policy: str = "MultiInputPolicy"
    hyperparameters: dict = field(default_factory=dict)
    discount_unit: int | None = None
    n_envs: int = field(default_factory=lambda: default_n_envs())
    vec_env: str = "subproc"
    policy_lag: int = 0
    worker_timeout: float = 600.0
    total_timesteps: int = 20_000
    seed: int = 0
    eval: EvalSchedule = EvalSchedule()
    checkpoint_freq: int = 5000
    source: str = "<dict>"

    @property
    def eval_env_kwargs(self) -> dict:
        """The ``gym.make`` keywords of the held-out evaluations: the training env's, updated by ``eval.env_kwargs``."""
        return {**self.env_kwargs, **self.eval.env_kwargs}

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


#: The longest chain of ``base`` files followed (the shipped configurations use two).
MAX_BASE_CHAIN = 16


def _read(path: Path, seen: tuple[Path, ...] = ()) -> dict:
    if path.resolve() in seen:
        raise AgentConfigError(str(path), "base", "no cycle of base files", [str(p) for p in seen])
    if len(seen) >= MAX_BASE_CHAIN:
        raise AgentConfigError(str(seen[0]), "base", f"a chain of at most {MAX_BASE_CHAIN} configuration files "
                               f"linked by base (this one goes on past {path})")
    data = read_yaml_file(path, "agent configuration", AgentConfigError)
    if "base" in data:
        base = data["base"]
        if not isinstance(base, str) or Path(base).suffix.lower() not in YAML_SUFFIXES:
            raise AgentConfigError(str(path), "base", "the name of a .yaml file, relative to this file", base)
        data = _merge(_read(path.parent / base, seen + (path.resolve(),)),
                      {k: v for k, v in data.items() if k != "base"})
    return data


def load_agent_config(path) -> AgentConfig:
    """Read and check an agent configuration file (following ``base`` files)."""
    path = Path(path)
    return parse_agent_config(_read(path), source=str(path))


#: Upper bounds of an agent configuration's sizes: each env is a process with its own filter and maps
#: (about 100-300 MB), so 64 fill a large machine.
MAX_ENVS = 64
_STEPS = Integer(1, 10**10)
#: Ranges of the hyperparameters whose meaning bounds them (others are checked by their type).
_HYPERPARAMETER_RANGES = {
    "learning_rate": Real(0.0, 1.0, open_lo=True), "gamma": Real(0.0, 1.0), "gae_lambda": Real(0.0, 1.0),
    "n_steps": Integer(1, 10**6), "batch_size": Integer(1, 10**6), "n_epochs": Integer(1, 10**4),
    "buffer_size": Integer(1, 10**7, "the replay buffer holds that many observations"),
    "clip_range": Real(0.0, 10.0, open_lo=True), "ent_coef": Real(0.0, 10.0), "vf_coef": Real(0.0, 10.0),
    "max_grad_norm": Real(0.0, 1e6, open_lo=True), "tau": Real(0.0, 1.0), "exploration_fraction": Real(0.0, 1.0),
    "exploration_initial_eps": Real(0.0, 1.0), "exploration_final_eps": Real(0.0, 1.0),
}
#: Which action spaces each algorithm can drive, and which observation spaces each policy reads.
_ACTION_SPACES = {"PPO": ("Discrete", "Box"), "A2C": ("Discrete", "Box"), "MaskablePPO": ("Discrete",),
                  "DQN": ("Discrete",), "SAC": ("Box",)}
_OBSERVATION_SPACES = {"MultiInputPolicy": "Dict", "TargetScoringPolicy": "Dict", "CnnPolicy": "Box",
                       "MlpPolicy": "Box"}


def default_n_envs() -> int:
    """Envs when a configuration gives none: one per core (each env's worker keeps a core busy)."""
    return max(1, min(os.cpu_count() or 1, MAX_ENVS))


def _hyperparameter_check(name: str, default) -> Check | None:
    """The check of a hyperparameter: its range if known, else one by the type of the algorithm's default."""
    if name in _HYPERPARAMETER_RANGES:
        return _HYPERPARAMETER_RANGES[name]
    if isinstance(default, bool):
        return Boolean()
    if isinstance(default, int):
        return Integer(-10**9, 10**9)
    if isinstance(default, float):
        return Real()
    if isinstance(default, dict) or name.endswith("_kwargs"):
        return Maybe(Mapping())
    return None  # strings, tuples, None defaults: SB3 checks what it accepts


#: What ``policy_kwargs`` may set from a file, by name (classes named by a word: see :func:`sb3_policy_kwargs`;
#: a key a policy class takes but not listed here is refused, as are keys it does not take).
ACTIVATIONS = ("ReLU", "Tanh", "ELU", "LeakyReLU", "GELU", "SiLU", "Sigmoid")
OPTIMIZERS = ("Adam", "AdamW", "RMSprop", "SGD")
FEATURE_EXTRACTORS = ("NatureCNN", "CombinedExtractor", "FlattenExtractor")
#: The widest and deepest network ``net_arch`` may ask for (a few million weights).
MAX_LAYER_WIDTH, MAX_LAYERS = 1024, 8
_LAYER = Integer(1, MAX_LAYER_WIDTH, "units of a layer")
_POLICY_KWARGS = {
    "activation_fn": Choice(ACTIVATIONS), "optimizer_class": Choice(OPTIMIZERS),
    "features_extractor_class": Choice(FEATURE_EXTRACTORS),
    "ortho_init": Boolean(), "full_std": Boolean(), "use_expln": Boolean(), "normalize_images": Boolean(),
    "share_features_extractor": Boolean(), "log_std_init": Real(-20.0, 20.0),
    "clip_mean": Real(0.0, 100.0, open_lo=True),
    "n_critics": Integer(1, 16),
}
_NESTED_KWARGS = {
    "features_extractor_kwargs": {"features_dim": _LAYER, "cnn_output_dim": _LAYER, "normalized_image": Boolean()},
    "optimizer_kwargs": {"eps": Real(0.0, 1.0, open_lo=True), "weight_decay": Real(0.0, 1.0),
                         "alpha": Real(0.0, 1.0), "momentum": Real(0.0, 1.0), "amsgrad": Boolean(),
                         "centered": Boolean(), "nesterov": Boolean()},
}
#: The keys of a ``net_arch`` mapping (separate networks) each algorithm's policies take; DQN takes a list only.
_NET_ARCH_KEYS = {"PPO": ("pi", "vf"), "A2C": ("pi", "vf"), "MaskablePPO": ("pi", "vf"), "SAC": ("pi", "qf"),
                  "DQN": ()}


def _policy_class(algorithm: str, policy: str):
    if policy == "TargetScoringPolicy":
        from sb3_contrib.common.maskable.policies import MaskableMultiInputActorCriticPolicy

        return MaskableMultiInputActorCriticPolicy
    return algorithm_class(algorithm).policy_aliases[policy]


def _check_policy_kwargs(source: str, algorithm: str, policy: str, value) -> dict:
    """``policy_kwargs`` checked key by key against what the policy class takes (and what SB3 would only find
    wrong when it builds the network, or not at all: a negative layer width, a string for a class)."""
    label = "hyperparameters.policy_kwargs"
    kwargs = check_value(value, Maybe(Mapping()), source, label, AgentConfigError)
    if kwargs is None:
        return None
    fixed = ()
    if policy == "TargetScoringPolicy":
        from .target_policy import FIXED_KWARGS as fixed
    takes = set(inspect.signature(_policy_class(algorithm, policy).__init__).parameters)
    allowed = [k for k in ("net_arch", *_POLICY_KWARGS, *_NESTED_KWARGS) if k in takes and k not in fixed]
    checked = {}
    for key, item in kwargs.items():
        field_name = f"{label}.{key}"
        if key not in allowed:
            raise AgentConfigError(source, field_name, f"one of the keys {policy} of {algorithm} takes from a "
                                   f"configuration: {allowed}")
        if key == "net_arch":
            checked[key] = _check_net_arch(source, field_name, algorithm, item)
        elif key in _NESTED_KWARGS:
            inner = check_value(item, Mapping(), source, field_name, AgentConfigError)
            unknown = sorted(set(map(str, inner)) - set(_NESTED_KWARGS[key]))
            if unknown:
                raise AgentConfigError(source, f"{field_name}.{unknown[0]}", f"one of {list(_NESTED_KWARGS[key])}")
            checked[key] = {name: check_value(sub, _NESTED_KWARGS[key][name], source, f"{field_name}.{name}",
                                              AgentConfigError) for name, sub in inner.items()}
        else:
            checked[key] = check_value(item, _POLICY_KWARGS[key], source, field_name, AgentConfigError)
    return checked


def _check_net_arch(source: str, field_name: str, algorithm: str, value):
    """A list of layer widths, or (where the algorithm's policies take one) a mapping of such lists by network."""
    def layers(item, name):
        if not isinstance(item, list) or len(item) > MAX_LAYERS:
            raise AgentConfigError(source, name, f"a list of at most {MAX_LAYERS} layer widths", item)
        return [check_value(width, _LAYER, source, f"{name}[{k}]", AgentConfigError) for k, width in enumerate(item)]

    keys = _NET_ARCH_KEYS[algorithm]
    if isinstance(value, dict) and keys:
        unknown = sorted(set(map(str, value)) - set(keys))
        if unknown:
            raise AgentConfigError(source, f"{field_name}.{unknown[0]}", f"one of the networks {list(keys)}")
        return {key: layers(item, f"{field_name}.{key}") for key, item in value.items()}
    return layers(value, field_name)


def sb3_policy_kwargs(policy_kwargs: dict) -> dict:
    """Checked ``policy_kwargs`` as SB3 takes them: the classes named by a word (``activation_fn: ReLU``) as
    the classes (``torch.nn.ReLU``)."""
    import torch
    from stable_baselines3.common import torch_layers

    modules = {"activation_fn": torch.nn, "optimizer_class": torch.optim, "features_extractor_class": torch_layers}
    return {key: getattr(modules[key], value) if key in modules else value for key, value in policy_kwargs.items()}


def _check_hyperparameters(source: str, algorithm: str, hyper: dict, policy: str = "MultiInputPolicy") -> dict:
    reserved = ("self", "policy", "env", "seed", "tensorboard_log", "verbose", "device", "_init_setup_model")
    parameters = {name: p for name, p in inspect.signature(algorithm_class(algorithm).__init__).parameters.items()
                  if name not in reserved}
    checked = {}
    for name, value in hyper.items():
        if name not in parameters:
            raise AgentConfigError(source, f"hyperparameters.{name}", f"a keyword of {algorithm}: one of "
                                   f"{list(parameters)}")
        if name == "policy_kwargs":
            checked[name] = _check_policy_kwargs(source, algorithm, policy, value)
            continue
        check = _hyperparameter_check(name, parameters[name].default)
        checked[name] = value if check is None else check_value(value, check, source, f"hyperparameters.{name}",
                                                                AgentConfigError)
    return checked


def _spaces(source: str, env_id: str, kwargs: dict, label: str):
    """Make the env once, here in the main process (a mistake then fails before any worker starts), and
    return its action and observation spaces; a bad keyword names the field under ``label``."""
    import gymnasium as gym

    import emmi_gym  # noqa: F401  (registers the ids)

    from ...env.config import SOURCE

    try:
        env = gym.make(env_id, **kwargs)
    except FieldError as exc:
        if exc.source == SOURCE:
            raise AgentConfigError(source, f"{label}.{exc.field}", exc.expected, exc.got) from None
        # a file an option names (a world, a map of a set) is broken: that option, and the file's own message
        key = next((key for key, value in kwargs.items() if isinstance(value, str) and value and (
            Path(exc.source) == Path(value) or Path(value) in Path(exc.source).parents)), None)
        raise AgentConfigError(source, f"{label}.{key}" if key else label, f"an option naming a valid file ({exc})") \
            from None
    except ValueError as exc:
        raise AgentConfigError(source, label, f"valid environment options ({exc})") from None
    spaces = env.action_space, env.observation_space
    env.close()
    return spaces


def _check_env(source: str, config: AgentConfig) -> None:
    """Check that the env and its evaluation variant can be made, that the algorithm can drive their
    actions and the policy read their observations (the same spaces in both)."""
    action_space, observation_space = _spaces(source, config.env_id, config.env_kwargs, "env.kwargs")
    action, observation = type(action_space).__name__, type(observation_space).__name__
    if action not in _ACTION_SPACES[config.algorithm]:
        raise AgentConfigError(source, "algorithm", f"an algorithm for the {action} actions of {config.env_id} (one "
                               f"of {[a for a, kinds in _ACTION_SPACES.items() if action in kinds]})",
                               config.algorithm)
    if observation != _OBSERVATION_SPACES[config.policy]:
        raise AgentConfigError(source, "policy", f"a policy for the {observation} observations of {config.env_id} "
                               f"(one of {[p for p, kind in _OBSERVATION_SPACES.items() if kind == observation]})",
                               config.policy)
    if config.eval.env_kwargs:
        spaces = _spaces(source, config.env_id, config.eval_env_kwargs, "eval.env_kwargs")
        if spaces != (action_space, observation_space):
            raise AgentConfigError(source, "eval.env_kwargs", "options that keep the training env's action and "
                                   f"observation spaces ({action_space}, {observation_space})",
                                   f"{spaces[0]}, {spaces[1]}")


def _vec_env(source: str, algorithm: str, value) -> str:
    """The ``vec_env`` field: rollout workers by default for the on-policy algorithms, subprocesses for the others
    (whose updates come between single steps)."""
    if value is None:
        return "workers" if algorithm in ON_POLICY else "subproc"
    value = check_value(value, Choice(VEC_ENVS), source, "vec_env", AgentConfigError)
    if value in ROLLOUT_WORKERS and algorithm not in ON_POLICY:
        raise AgentConfigError(source, "vec_env", f"one of {[v for v in VEC_ENVS if v not in ROLLOUT_WORKERS]} for "
                               f"{algorithm} (rollout workers collect for {list(ON_POLICY)})", value)
    return value


def _env_field(data: dict, source: str) -> tuple[str, dict]:
    """The env id and keywords of a configuration's ``env`` field, checked as far as a configuration can
    without making the env."""
    env = data.get("env")
    if not isinstance(env, dict) or not isinstance(env.get("id"), str) or set(env) - {"id", "kwargs"}:
        raise AgentConfigError(source, "env", "a mapping with an 'id' (and optional 'kwargs')", env)
    env_id = check_env_id(env["id"], source, "env.id", AgentConfigError)
    return env_id, dict(check_value(env.get("kwargs") or {}, Mapping(), source, "env.kwargs", AgentConfigError))


def env_of_file(path) -> tuple[str, dict]:
    """The env id and ``gym.make`` keywords of the configuration file ``path`` (following ``base`` files),
    without the rest of its checks (nor the import of Stable-Baselines3 they need)."""
    path = Path(path)
    return _env_field(_read(path), str(path))


def parse_agent_config(data: dict, source: str = "<dict>") -> AgentConfig:
    """Check a whole configuration given as a dict (as read from YAML), making its env once, and resolve it."""
    def field(name: str, check: Check, default=None):
        return check_value(data.get(name, default), check, source, name, AgentConfigError)

    unknown = sorted(set(map(str, data)) - set(_KEYS))
    if unknown:
        raise AgentConfigError(source, unknown[0], f"one of the fields {list(_KEYS)}")
    env_id, kwargs = _env_field(data, source)
    algorithm = field("algorithm", Choice(ALGORITHMS))
    policy = field("policy", Choice(POLICIES), "MultiInputPolicy")
    if policy == "TargetScoringPolicy" and algorithm != "MaskablePPO":
        raise AgentConfigError(source, "policy", "TargetScoringPolicy only with algorithm MaskablePPO", policy)
    hyper = _check_hyperparameters(source, algorithm, field("hyperparameters", Maybe(Mapping())) or {}, policy)
    discount_unit = field("discount_unit", Maybe(Integer(1, 10**6)))
    if discount_unit is not None:
        from .semi_markov import SUPPORTED

        if algorithm not in SUPPORTED:
            raise AgentConfigError(source, "discount_unit", f"absent for {algorithm} (semi-Markov discounting is "
                                   f"implemented for {list(SUPPORTED)})", discount_unit)
        for name in ("rollout_buffer_class", "rollout_buffer_kwargs"):
            if name in hyper:
                raise AgentConfigError(source, f"hyperparameters.{name}", "not given with discount_unit (which sets "
                                       "the rollout buffer)")
    eval_schedule = build(EvalSchedule, field("eval", Maybe(Mapping())), "eval", source, AgentConfigError)
    config = AgentConfig(
        env_id=env_id, env_kwargs=dict(kwargs), algorithm=algorithm, policy=policy, hyperparameters=hyper,
        discount_unit=discount_unit, n_envs=field("n_envs", Integer(1, MAX_ENVS, "each env is a process with its "
                                                                    "own filter, 100-300 MB"), default_n_envs()),
        vec_env=_vec_env(source, algorithm, data.get("vec_env")), policy_lag=field("policy_lag", Integer(0, 1), 0),
        worker_timeout=field("worker_timeout", Real(0.0, 86_400.0, open_lo=True), 600.0),
        total_timesteps=field("total_timesteps", _STEPS, 20_000),
        seed=field("seed", Integer(0, 2**32 - 1), 0), eval=eval_schedule,
        checkpoint_freq=field("checkpoint_freq", _STEPS, 5000), source=source)
    if config.policy_lag and not rollout_workers(config.n_envs, config.vec_env):
        raise AgentConfigError(source, "policy_lag", "0 unless rollout workers collect (vec_env workers with n_envs > "
                               f"1, or ray_workers): it lets them play ahead of the learner; here vec_env is "
                               f"{config.vec_env} with n_envs {config.n_envs}", config.policy_lag)
    _check_env(source, config)
    return config


def rollout_workers(n_envs: int, vec_env: str) -> bool:
    """Whether the envs run in rollout workers (one env under ``workers`` runs in the learner's process)."""
    return vec_env == "ray_workers" or (vec_env == "workers" and n_envs > 1)
