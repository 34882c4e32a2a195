"""Whether a run's policy has settled: on the held-out episodes its final model plays, the share of
decisions at which an earlier checkpoint would have taken the same action (each acting deterministically,
with the same action masks). This is the policy churn of Schaul et al., "The phenomenon of policy churn"
(NeurIPS 2022), read across checkpoints instead of across one update.

A level learning curve alone does not say whether more training would change the agent: a policy whose
choices still change from checkpoint to checkpoint while its maps do not is moving along a plateau of its
reward; one whose choices no longer change has converged, and more of the same budget would teach it
nothing new. Only discrete actions (the waypoint envs' targets) can be the same or not.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...inputs.validation import MAX_EPISODES
from ..evaluation.episodes import ModelActor, play_episodes
from .evaluate import EVALUATION_SEED, load_model
from .run_folders import RunFolder
from .train import make_agent_env

#: The fractions of the final model's decisions whose nearest checkpoints are compared by default.
DEFAULT_FRACTIONS = (0.25, 0.5, 0.75)


class _ActsWithTheFinalModel:
    """An actor (:func:`~emmi_gym.tools.evaluation.episodes.play_episode`) that acts with the final model and
    counts, for each other model, the decisions at which it would have taken the same action."""

    def __init__(self, final: ModelActor, others: list[ModelActor]):
        self.final, self.others = final, others
        self.decisions, self.same = 0, [0] * len(others)

    def reset(self, seed: int) -> None:
        pass

    def __call__(self, env, observation):
        action = self.final(env, observation)
        for index, other in enumerate(self.others):
            self.same[index] += bool(np.array_equal(other(env, observation), action))
        self.decisions += 1
        return action


def agreement_with_final(final_path, other_paths, episodes: int = 4, seed: int = EVALUATION_SEED) -> list[dict]:
    """For each model of ``other_paths`` (checkpoints of the run of ``final_path``), a row ``{"model",
    "decisions", "same_action", "agreement"}``: over ``episodes`` episodes of the run's held-out evaluation
    env (the training env with ``eval.env_kwargs``; seeds ``seed``, ``seed + 1``, ...) played by the model of
    ``final_path``, the decisions at which that model would have chosen the final model's action."""
    if not 1 <= episodes <= MAX_EPISODES:
        raise ValueError(f"episodes: expected an integer in [1, {MAX_EPISODES}], got {episodes!r}")
    final, config = load_model(final_path)
    if not hasattr(final.action_space, "n"):
        raise ValueError(f"{final_path}: policy churn counts the decisions with the same discrete action, but the "
                         f"model acts in {final.action_space} (continuous actions are never the same)")
    others = [ModelActor(load_model(path, config)[0]) for path in other_paths]
    actor = _ActsWithTheFinalModel(ModelActor(final), others)
    env = make_agent_env(config.env_id, config.eval_env_kwargs)
    try:
        play_episodes(env, actor, range(seed, seed + episodes))
    finally:
        env.close()
    return [{"model": str(path), "decisions": actor.decisions, "same_action": same,
             "agreement": same / actor.decisions} for path, same in zip(other_paths, actor.same, strict=True)]


def checkpoints_to_compare(run_dir, decisions=None) -> tuple[tuple[int, Path], list[tuple[int, Path]]]:
    """The final model of the run in ``run_dir`` (``model.zip`` if it finished, else its newest whole
    checkpoint) and its whole checkpoints to compare with it, each ``(decisions, path)``: those at ``decisions``
    (a ``ValueError`` naming the run's checkpoints if one is missing), by default the checkpoints nearest
    :data:`DEFAULT_FRACTIONS` of the final model's decisions."""
    folder = RunFolder(run_dir)
    found = folder.whole_checkpoints()
    finished = folder.finished_decisions()
    final_decisions, final = (finished, folder.model_path) if finished is not None else found[-1]
    earlier = {count: path for count, path in found if path != final}
    if not earlier:
        raise ValueError(f"{folder.path}: no checkpoint but the final model ({final}) to compare with it")
    if decisions is None:
        decisions = sorted({min(earlier, key=lambda count: abs(count - fraction * final_decisions))
                            for fraction in DEFAULT_FRACTIONS})
    missing = [count for count in decisions if count not in earlier]
    if missing:
        raise ValueError(f"{folder.path}: no whole checkpoint at {missing} decisions; its checkpoints are at "
                         f"{sorted(earlier)}")
    return (final_decisions, final), [(count, earlier[count]) for count in decisions]
