"""The environment's options: every keyword ``gym.make`` accepts, with its checks and defaults."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

from ..inputs.validation import (
    Boolean,
    Check,
    Choice,
    Integer,
    Invalid,
    Maybe,
    Options,
    Real,
    Text,
    build,
    check_fields,
    fail,
    option,
    option_of,
)
from ..slam.config import RBPFConfig
from ..world import GeneratorConfig, LaserConfig, OdometryNoise
from ..world.images import DEFAULT_PIXEL_SIZE, PIXEL_SIZE
from ..world.loop_worlds import LoopWorldConfig
from ..world.map_sets import WORLD_FAMILIES
from ..world.presets import LASER_OPTIONS, ODOMETRY_OPTIONS
from .reward_registry import REWARDS, reward_named
from .rewards import Reward

ACTION_MODES = ("waypoint", "velocity")
VELOCITY_ACTIONS = ("continuous", "discrete")
OBSERVATIONS = ("dict", "image")
STARTS = ("decision", "start")
#: When ``info`` holds the ground-truth scores (:data:`~emmi_gym.env.rewards.SCORES`): at the episode's end (its
#: terminating or truncating step), or also after every reset and step.
INFO_SCORES = ("end", "always")
#: Where the options come from, in error messages.
SOURCE = "gym.make"
#: The observation's image side, pixels: the least that the policies' map encoder (SB3's NatureCNN, kernels
#: 8/4/3 with strides 4/2/1) takes, and a most at which its last layer stays within tens of millions of weights.
MIN_OBS_SIZE, MAX_OBS_SIZE = 36, 256
#: The most rewards ``info_rewards`` may name.
MAX_INFO_REWARDS = 64


@dataclass(frozen=True)
class RewardOption(Check):
    """A registered reward's name (:data:`~emmi_gym.env.reward_registry.REWARDS`, read when the check runs) or a
    :class:`~emmi_gym.env.rewards.Reward`; with ``many``, a list of them or ``"all"`` (every registered one)."""

    many: bool = False

    def describe(self) -> str:
        one = f"a registered reward's name (one of {list(REWARDS)}) or a Reward"
        return f"'all' or a list of at most {MAX_INFO_REWARDS} of: {one}" if self.many else one

    def one(self, value):
        if isinstance(value, Reward) or (isinstance(value, str) and value in REWARDS):
            return value
        raise Invalid(self.describe())

    def __call__(self, value):
        if not self.many:
            return self.one(value)
        if isinstance(value, str) and value == "all":
            return value
        if isinstance(value, (str, Reward)):
            value = (value,)
        if not isinstance(value, (list, tuple)) or len(value) > MAX_INFO_REWARDS:
            raise Invalid(self.describe())
        return tuple(self.one(v) for v in value)


@dataclass(frozen=True)
class GeneratorOptions(Options):
    """The ``generator`` option: the options of the generated world's family, built: a
    :class:`~emmi_gym.world.loop_worlds.LoopWorldConfig` for ``world="loop_order"`` (the family's class in
    :data:`~emmi_gym.world.map_sets.WORLD_FAMILIES`), else a :class:`~emmi_gym.world.GeneratorConfig` (what
    ``world=None`` generates; checked, and unused, with a fixed world)."""

    cls: type = GeneratorConfig

    @staticmethod
    def classes() -> tuple[type, ...]:
        """The dataclasses it may build: :class:`GeneratorConfig` and each family's (what docs/options.md lists)."""
        return (GeneratorConfig, *(cls for cls, _ in WORLD_FAMILIES.values()))

    def bound(self, owner, name: str) -> Options:
        return Options(WORLD_FAMILIES.get(owner.world, (GeneratorConfig,))[0])


@dataclass(frozen=True)
class EnvConfig:
    """Options of :class:`~emmi_gym.env.EmmiEnv`; ``gym.make(id, **options)`` sets any of them.

    - ``world``: a built-in name, a world file or map_server map (.yaml), a floor-plan image
      (.png/.pgm, read at ``pixel_size`` metres per pixel), a map set to draw from at every
      reset (``"dungeon_maps/train"``, a folder, a glob; :mod:`emmi_gym.world.map_sets`),
      ``"loop_order"``: a new loop left open beside a new area at every reset (``generator`` holds
      :class:`~emmi_gym.world.loop_worlds.LoopWorldConfig` fields), or ``None``: a new generated
      lattice world at every reset (``generator`` holds :class:`~emmi_gym.world.GeneratorConfig` fields).
    - ``start_at``: ``"decision"`` drives the world's ``to_decision`` route with the RBPF
      running before the first observation (the paper's robot up to its step 65);
      ``"start"`` begins at the start pose.
    - ``reward``: a registered reward's name (:data:`~emmi_gym.env.reward_registry.REWARDS`) or a
      :class:`~emmi_gym.env.rewards.Reward`; ``info_rewards`` names more (or ``"all"``) whose values go in
      ``info["reward_components"]`` beside it. Only what these read is measured: the ground-truth scores
      (:data:`~emmi_gym.env.rewards.SCORES`) at every step only for a reward that reads one, else at the
      episode's end (in its last ``info``), or after every reset and step with ``info_scores="always"``
      (what an evaluation at equal robot time reads).
    - ``update_records``: put the metrics of every RBPF update of a step in
      ``info["rbpf_updates"]`` (a list of rows; the paper's per-update curves, as the A/B
      experiment draws them). Off, the certainty of the particle set is computed once per
      step, after its last update, which is all the reward and the observation read.
    - ``min_loop_spread`` and ``revisit_spacing`` (waypoint mode) leave out revisit targets where
      closing the loop has nothing left to resolve: those whose loop spread (how far apart the
      particles put the robot relative to the place) is at most ``min_loop_spread`` metres, and
      those within ``revisit_spacing`` metres of a place the robot already went back to this
      episode, as Stachniss et al.'s active loop-closing does (both read the filter's belief
      only; 0, the default, leaves none out).
    - ``time_cost`` per simulator step and ``collision_cost`` per colliding step are
      subtracted whatever the reward, so doing nothing never pays.
    - ``laser``, ``odometry_noise``: a preset name (:mod:`emmi_gym.world.presets`:
      ``"sick_lms200"``, ``"poor"``...) or a dict of :class:`LaserConfig` /
      :class:`OdometryNoise` fields (with an optional ``preset`` they change); ``slam``: a
      dict of :class:`RBPFConfig` fields; ``particles`` and ``resolution`` set the filter's
      (not inside ``slam``). Each may also be given as the dataclass itself.

    Every field is typed and bounded (:mod:`emmi_gym.inputs.validation`); a mistake raises an
    ``OptionError`` naming the field. The config holds its nested options built, once, when it is
    made: ``laser`` is a :class:`LaserConfig`, ``odometry_noise`` an :class:`OdometryNoise`, ``slam``
    an :class:`RBPFConfig` (with ``particles`` and ``resolution``), ``generator`` the world family's
    options (:class:`GeneratorOptions`).
    """

    world: str | None = option(
        "loop_corridor", Maybe(Text(), "a generated world per reset"),
        help="a built-in name, world or map_server file, floor-plan image, a shipped set's plan "
             "('dungeon_maps/test/img_10011.png'), map set or 'loop_order'; None: generated")
    generator: GeneratorConfig | LoopWorldConfig = option(
        {}, GeneratorOptions(), help="GeneratorConfig fields (world=None) or LoopWorldConfig ones (world='loop_order')")
    pixel_size: float = option(DEFAULT_PIXEL_SIZE, PIXEL_SIZE,
                               help="metres per pixel of a floor-plan image")
    start_at: str = option(
        "decision", Choice(STARTS),
        help="'decision': reset first drives the world's to_decision route; 'start': begin at the start pose")
    action_mode: str = option(
        "waypoint", Choice(ACTION_MODES),
        help="'waypoint': an action sends the robot to a target slot; 'velocity': (v, omega) for one step")
    velocity_actions: str = option("continuous", Choice(VELOCITY_ACTIONS),
                                   help="in velocity mode: a Box of (v, omega) in [-1, 1], or five discrete commands")
    reward: str | Reward = option("emmi", RewardOption(),
                                  help="the reward paid (docs/rewards.md)")
    info_rewards: tuple | str = option((), RewardOption(many=True),
                                       help="more rewards whose values info['reward_components'] shows")
    info_scores: str = option("end", Choice(INFO_SCORES),
                              help="when info holds the ground-truth scores: the episode's end or every step")
    update_records: bool = option(False, Boolean(),
                                  help="put the measures of every filter update of a step in info['rbpf_updates']")
    reward_scale: float | None = option(None, Maybe(Real(0.0, 1e6, open_lo=True), "the reward's default scale"),
                                        help="factor on the reward's value; None: the reward's own scale")
    time_cost: float = option(0.002, Real(0.0, 1e3),
                              help="subtracted per simulator step, whatever the reward")
    collision_cost: float = option(0.05, Real(0.0, 1e3),
                                   help="subtracted per simulator step spent driving into a wall")
    coverage_target: float = option(0.9, Real(0.0, 1.0, open_lo=True),
                                    help="share of the reachable free space swept by the scans that ends the episode")
    particles: int = option_of(RBPFConfig, "particles", help="particles of the filter (each holds a whole map)")
    resolution: float = option_of(RBPFConfig, "resolution", help="cell side of the filter's maps")
    laser: LaserConfig = option(
        {}, LASER_OPTIONS,
        help="a laser preset's name, or LaserConfig fields with an optional 'preset' they change")
    odometry_noise: OdometryNoise = option(
        {}, ODOMETRY_OPTIONS,
        help="an odometry preset's name, or OdometryNoise fields with an optional 'preset'")
    slam: RBPFConfig = option({}, Options(RBPFConfig, given=("particles", "resolution")),
                              help="RBPFConfig fields (particles and resolution are top-level options)")
    observation: str = option(
        "dict", Choice(OBSERVATIONS),
        help="'dict': map, pose, certainty (and targets in waypoint mode); 'image': the map image alone")
    obs_size: int = option(64, Integer(MIN_OBS_SIZE, MAX_OBS_SIZE, "the policies' CNN (NatureCNN) needs 36 pixels; "
                                                                     "at 256 its last layer holds 26 M weights"),
                           help="side of the observation's map image, pixels")
    egocentric: bool = option(False, Boolean(),
                              help="the image shows a square round the estimated pose instead of the whole world")
    egocentric_extent: float = option(16.0, Real(0.0, 1000.0, open_lo=True, unit="m"),
                                      help="side of the egocentric image's square")
    n_frontiers: int = option(6, Integer(1, 64),
                              help="action slots of frontier targets")
    n_revisits: int = option(2, Integer(0, 64),
                             help="action slots of revisit (loop-closing) targets")
    min_loop_spread: float = option(0.0, Real(0.0, 100.0, unit="m"),
                                    help="revisit targets whose loop spread is at most this are not offered")
    revisit_spacing: float = option(0.0, Real(0.0, 1000.0, unit="m"),
                                    help="revisit targets this near a place already gone back to this episode are "
                                         "not offered")
    max_decisions: int = option(60, Integer(1, 1_000_000),
                                help="waypoint decisions after which the episode is truncated")
    max_sim_steps: int = option(12000, Integer(1, 100_000_000),
                                help="simulator steps (0.1 s each) after which the episode is truncated")
    macro_timeout: int = option(900, Integer(1, 1_000_000),
                                help="simulator steps after which a macro-action ends")

    def __post_init__(self):
        check_fields(self)  # the nested options built too (gym.make and agent configurations fail before any work)
        paid, shown = self.rewards()
        by_name = {}
        for reward in (paid, *shown):
            if by_name.setdefault(reward.name, reward) != reward:
                fail(self, "info_rewards", f"one reward per name (two differ under {reward.name!r})", reward)

    def laser_config(self) -> LaserConfig:
        """Deprecated: :attr:`laser` (built)."""
        return self._deprecated("laser_config", "laser")

    def odometry_config(self) -> OdometryNoise:
        """Deprecated: :attr:`odometry_noise` (built)."""
        return self._deprecated("odometry_config", "odometry_noise")

    def slam_config(self) -> RBPFConfig:
        """Deprecated: :attr:`slam` (built)."""
        return self._deprecated("slam_config", "slam")

    def generator_config(self) -> GeneratorConfig | LoopWorldConfig:
        """Deprecated: :attr:`generator` (built)."""
        return self._deprecated("generator_config", "generator")

    def _deprecated(self, method: str, field: str):
        warnings.warn(f"EnvConfig.{method}() is deprecated: read EnvConfig.{field}, built when the config is made; "
                      "it goes in emmi-gym 0.5.0", FutureWarning, stacklevel=3)
        return getattr(self, field)

    @property
    def scale(self) -> float:
        """The factor on the paid reward's value: ``reward_scale``, else the reward's own scale."""
        return self.reward_scale if self.reward_scale is not None else reward_named(self.reward).scale

    def rewards(self) -> tuple[Reward, tuple[Reward, ...]]:
        """The reward paid and those ``info_rewards`` names (every registered one for ``"all"``)."""
        shown = tuple(REWARDS.values()) if self.info_rewards == "all" else self.info_rewards
        return reward_named(self.reward), tuple(reward_named(r) for r in shown)

    @property
    def n_actions(self) -> int:
        return self.n_frontiers + self.n_revisits


def make_config(**options) -> EnvConfig:
    """An :class:`EnvConfig` from keyword options; any mistake raises an :class:`OptionError` naming the option."""
    return build(EnvConfig, options, "", source=SOURCE)


def deprecated_reward_scales(stacklevel: int = 2) -> dict[str, float]:
    """The scales by name, as ``REWARD_SCALES`` gave them before the rewards had a registry, with a warning."""
    warnings.warn("REWARD_SCALES is deprecated: read REWARDS[name].scale (emmi_gym.env.REWARDS); it goes in "
                  "emmi-gym 0.5.0", FutureWarning, stacklevel=stacklevel + 1)
    return {name: reward.scale for name, reward in REWARDS.items()}


def __getattr__(name: str):
    """``REWARD_SCALES`` (PEP 562): deprecated, see :func:`deprecated_reward_scales`."""
    if name == "REWARD_SCALES":
        return deprecated_reward_scales(stacklevel=2)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
