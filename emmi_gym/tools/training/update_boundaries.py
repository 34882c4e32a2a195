"""Where an on-policy run can stop and resume without losing an update.

PPO, A2C and MaskablePPO collect a rollout of ``n_steps`` decisions per env and then update the policy
(SB3's ``OnPolicyAlgorithm.learn``: ``collect_rollouts``, then ``train``). The weights change only in
``train``, so between two updates the model is wholly described by the weights the last update left and
the decisions counted at that update. A checkpoint saved in the middle of a rollout under the count of
that moment claims decisions that no update has used: resumed, the run starts a fresh rollout, and the
half-collected one is never learnt from (one update lost per interruption; the checkpoints after it hold
the weights of the decision counts before them).

:class:`UpdateBoundaries` follows SB3's callback events: ``on_rollout_start`` comes after the previous
update (or at the start), ``on_rollout_end`` just before the next. A run saves its checkpoints at the
boundaries and, when stopped inside a rollout, saves the model under the count of the boundary it is in
(:meth:`UpdateBoundaries.resumable_decisions`); an interrupt inside an update is held until it ends.
"""

from __future__ import annotations

from stable_baselines3.common.callbacks import BaseCallback


class UpdateBoundaries(BaseCallback):
    """The decisions counted at the on-policy model's last update (or at the start of training), and
    whether an update is under way (between a rollout's end and the next one's start)."""

    def __init__(self):
        super().__init__()
        self.decisions: int | None = None
        self.updating = False

    def _on_training_start(self) -> None:
        self.decisions, self.updating = int(self.model.num_timesteps), False

    def _on_rollout_start(self) -> None:
        self.decisions, self.updating = int(self.model.num_timesteps), False

    def _on_rollout_end(self) -> None:
        self.updating = True

    def _on_step(self) -> bool:
        return True

    def resumable_decisions(self) -> int | None:
        """The decision count a checkpoint saved now must carry to resume without losing an update: the last
        boundary's, while a rollout is being collected; ``None`` before training started."""
        return self.decisions
