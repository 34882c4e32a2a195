"""A policy that scores each target slot with one shared network (for MaskablePPO in waypoint mode).

SB3's ``MultiInputPolicy`` ends in a linear layer with one output per action: slot k's
logit is learnt separately from slot j's, and nothing tells it that slot k *is* the target
described in row k of the observation's ``"targets"``. Here the logit of slot k is
``score([context, targets[k]])``, the same small MLP for every slot, where the context is a
CNN embedding of the map plus the pose and certainty vectors (as pointer networks and the
candidate-scoring policies of learnt frontier selection do). What is learnt about "a
revisit with a strong loop while the pose is uncertain" then holds for whichever slot that
target lands in, and a state where a revisit is worth it need not be told apart by the CNN
alone. The critic is an ordinary MLP over the same features.
"""

from __future__ import annotations

from functools import partial

import numpy as np
import torch as th
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableMultiInputActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, NatureCNN
from torch import nn

MAP_EMBEDDING = 64
HIDDEN = 64
#: Policy keywords the design fixes: refused in ``policy_kwargs`` and not saved with a model.
FIXED_KWARGS = ("net_arch", "features_extractor_class", "share_features_extractor")


class MapPoseTargetsExtractor(BaseFeaturesExtractor):
    """Features ``[CNN(map), pose, certainty, targets.flatten()]``: the context first, then the slot rows."""

    def __init__(self, observation_space: spaces.Dict, map_embedding: int = MAP_EMBEDDING):
        required = {"map", "pose", "certainty", "targets"}
        if not isinstance(observation_space, spaces.Dict) or set(observation_space.spaces) != required:
            raise ValueError(f"TargetScoringPolicy needs the waypoint Dict observation with keys {sorted(required)}, "
                             f"got {observation_space}")
        self.n_slots, self.n_target_features = observation_space["targets"].shape
        self.context_dim = map_embedding + observation_space["pose"].shape[0] + observation_space["certainty"].shape[0]
        super().__init__(observation_space, self.context_dim + self.n_slots * self.n_target_features)
        self.cnn = NatureCNN(observation_space["map"], features_dim=map_embedding, normalized_image=False)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        return th.cat([self.cnn(observations["map"]), observations["pose"], observations["certainty"],
                       observations["targets"].flatten(start_dim=1)], dim=1)


class TargetScorer(nn.Module):
    """SB3's ``mlp_extractor`` role: actor latent = one score per slot (the logits), critic latent = an MLP."""

    def __init__(self, context_dim: int, n_slots: int, n_target_features: int, hidden: int = HIDDEN):
        super().__init__()
        self.context_dim, self.n_slots, self.n_target_features = context_dim, n_slots, n_target_features
        self.slot_mlp = nn.Sequential(nn.Linear(context_dim + n_target_features, hidden), nn.Tanh(),
                                      nn.Linear(hidden, hidden), nn.Tanh())
        self.score = nn.Linear(hidden, 1)
        self.value_net = nn.Sequential(nn.Linear(context_dim + n_slots * n_target_features, hidden), nn.Tanh(),
                                       nn.Linear(hidden, hidden), nn.Tanh())
        self.latent_dim_pi, self.latent_dim_vf = n_slots, hidden

    def forward_actor(self, features: th.Tensor) -> th.Tensor:
        context = features[:, :self.context_dim]
        rows = features[:, self.context_dim:].reshape(-1, self.n_slots, self.n_target_features)
        pairs = th.cat([context.unsqueeze(1).expand(-1, self.n_slots, -1), rows], dim=2)
        return self.score(self.slot_mlp(pairs)).squeeze(-1)

    def forward_critic(self, features: th.Tensor) -> th.Tensor:
        return self.value_net(features)

    def forward(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        return self.forward_actor(features), self.forward_critic(features)


class TargetScoringPolicy(MaskableMultiInputActorCriticPolicy):
    """MaskablePPO's Dict policy with :class:`TargetScorer` in place of the per-action output layer.

    ``net_arch`` and ``features_extractor_class`` are fixed by the design; ``policy_kwargs``
    may still set ``ortho_init``, ``optimizer_class`` and ``optimizer_kwargs``.
    """

    def __init__(self, observation_space, action_space, lr_schedule, **kwargs):
        for fixed in FIXED_KWARGS:
            if fixed in kwargs:
                raise ValueError(f"TargetScoringPolicy fixes {fixed!r}; drop it from policy_kwargs")
        super().__init__(observation_space, action_space, lr_schedule,
                         features_extractor_class=MapPoseTargetsExtractor, **kwargs)

    def _get_constructor_parameters(self) -> dict:
        data = super()._get_constructor_parameters()
        for fixed in FIXED_KWARGS:
            data.pop(fixed, None)
        return data

    def _build(self, lr_schedule) -> None:
        extractor = self.features_extractor
        if self.action_space.n != extractor.n_slots:
            raise ValueError(f"{self.action_space.n} actions but {extractor.n_slots} target rows")
        self.mlp_extractor = TargetScorer(extractor.context_dim, extractor.n_slots, extractor.n_target_features)
        self.action_net = nn.Identity()  # the scores are the logits
        self.value_net = nn.Linear(self.mlp_extractor.latent_dim_vf, 1)
        if self.ortho_init:  # SB3's gains: sqrt(2) for hidden layers, 0.01 for the logits, 1 for the value
            for module, gain in ((self.features_extractor, np.sqrt(2)), (self.mlp_extractor, np.sqrt(2)),
                                 (self.mlp_extractor.score, 0.01), (self.value_net, 1.0)):
                module.apply(partial(self.init_weights, gain=gain))
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)
