"""Periodic evaluation on held-out seeds that also logs the ground-truth metrics."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import EvalCallback

from ..experiments.episodes import GROUND_TRUTH, nanmean
from ..experiments.loop_order import LOOP_ORDER_KEY


class GroundTruthEvalMixin:
    """For an SB3 ``EvalCallback``: every evaluation runs the same held-out episodes (the eval env is
    reseeded with ``eval_seed`` first) and logs the mean of each ground-truth measure at the
    episodes' ends as ``eval/<measure>`` (TensorBoard and stdout), appending them to
    ``ground_truth_csv``; on ``LoopCorridor-v0`` also the fraction of episodes that closed the
    loop before entering the new area, ``eval/closed_loop_first`` (episodes that did neither
    left out)."""

    def __init__(self, *args, eval_seed: int, ground_truth_csv: Path, **kwargs):
        super().__init__(*args, **kwargs)
        self.eval_seed = eval_seed
        self.ground_truth_csv = Path(ground_truth_csv)
        self._finished: list[dict] = []

    def _log_success_callback(self, locals_, globals_) -> None:
        super()._log_success_callback(locals_, globals_)
        if locals_["done"]:
            info = locals_["info"]
            measures = {k: float(info[k]) for k in (*GROUND_TRUTH, LOOP_ORDER_KEY) if k in info}
            self._finished.append(measures)
            for key, value in measures.items():
                if np.isfinite(value):
                    self.logger.record_mean(f"eval/{key}", value)

    def _on_step(self) -> bool:
        evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0
        if evaluating:
            self.eval_env.seed(self.eval_seed)
            self._finished = []
        result = super()._on_step()
        if evaluating and self._finished:
            self._append_row()
        return result

    def _append_row(self) -> None:
        row = {"timesteps": self.num_timesteps, "mean_reward": self.last_mean_reward,
               **{k: nanmean([m.get(k, np.nan) for m in self._finished]) for k in self._finished[0]}}
        new = not self.ground_truth_csv.exists()
        with open(self.ground_truth_csv, "a", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(row))
            if new:
                writer.writeheader()
            writer.writerow(row)


class GroundTruthEvalCallback(GroundTruthEvalMixin, EvalCallback):
    """SB3's EvalCallback with held-out seeds and the ground-truth metrics."""


def eval_callback_class(algorithm: str):
    """The evaluation callback for an algorithm: sb3-contrib's masked one for MaskablePPO."""
    if algorithm == "MaskablePPO":
        from sb3_contrib.common.maskable.callbacks import MaskableEvalCallback

        return type("MaskableGroundTruthEvalCallback", (GroundTruthEvalMixin, MaskableEvalCallback), {})
    return GroundTruthEvalCallback
