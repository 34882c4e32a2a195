"""Callbacks of training: periodic evaluation on held-out seeds that also logs the ground-truth metrics,
the check that stops training at the first non-finite number, and the decisions trained so far as a
progress bar (a line at least every 30 s in a log)."""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, EvalCallback

from ...concurrency.progress import progress_bar
from ...formats.atomic_files import write_text_atomically
from ...inputs.csv_files import read_csv_file
from ..evaluation.episodes import GROUND_TRUTH, nanmean
from ..evaluation.loop_order import LOOP_ORDER_KEY

#: The folder, inside the evaluation's, where SB3 writes its files before they are renamed into place.
STAGING = ".writing"


class NonFiniteError(ValueError):
    """Training or cloning produced a non-finite (NaN or infinite) loss, gradient or weight, or was fed a
    non-finite observation or reward; nothing of it was saved."""


def first_non_finite(module) -> str | None:
    """The first weight (or its gradient) of the torch ``module`` (a policy) holding a NaN or an infinity, in
    words (``"the weight 'value_net.weight' holds 3 NaN or infinite values (of 64)"``); None if none does."""
    import torch as th

    for name, parameter in module.named_parameters():
        for what, tensor in (("weight", parameter), ("gradient of the weight", parameter.grad)):
            if tensor is not None:
                finite = th.isfinite(tensor)
                if not bool(finite.all()):
                    return f"the {what} {name!r} holds {int((~finite).sum())} NaN or infinite values (of " \
                           f"{tensor.numel()})"
    return None


class DecisionProgress(BaseCallback):
    """The decisions trained, as SB3's ``ProgressBarCallback`` counts them (each step of the vectorised envs
    is one decision per env), on :func:`~emmi_gym.concurrency.progress.progress_bar`: tqdm's bar on a
    terminal, and written to a file or a pipe a line at least every 30 s, through the PPO updates and
    numba's first compile too (SB3's rich bar writes nothing off a terminal until training ends).
    ``close()`` ends the bar wherever training stopped."""

    def __init__(self, decisions: int, first: int = 0):
        super().__init__()
        self.decisions, self.first = decisions, first
        self.bar = None

    def _on_training_start(self) -> None:
        self.bar = progress_bar(total=self.first + self.decisions, initial=self.first, desc="training",
                                unit="decision")

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        self.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class StopOnNonFinite(BaseCallback):
    """Stop training at the first non-finite number, before a checkpoint could hold it: the observations and
    rewards of every step (as SB3's ``VecCheckNan`` checks a vectorised env's), and after every update
    (which SB3 runs between rollouts) the losses it logged and every weight and gradient of the policy.
    Raises :class:`NonFiniteError` saying what and at which decision."""

    def _on_step(self) -> bool:
        rewards = np.asarray(self.locals.get("rewards", ()), dtype=float)
        if not np.isfinite(rewards).all():
            self._stop(f"the env returned a non-finite reward ({rewards.tolist()})")
        observations = self.locals.get("new_obs")
        parts = observations.items() if isinstance(observations, dict) else [("", observations)]
        for key, value in parts:
            value = np.asarray(value)
            if value.dtype.kind == "f" and not np.isfinite(value).all():
                self._stop(f"the env returned a non-finite observation{f' {key!r}' if key else ''}")
        return True

    def _on_rollout_start(self) -> None:
        check_weights(self.model, "after the update")
        losses = {key: value for key, value in self.logger.name_to_value.items()
                  if key.startswith("train/") and isinstance(value, float) and not math.isfinite(value)}
        if losses:
            self._stop(f"the update's {', '.join(f'{key} = {value}' for key, value in losses.items())}")

    def _stop(self, what: str) -> None:
        raise NonFiniteError(f"training stopped at decision {self.num_timesteps}: {what}")


def check_weights(model, when: str) -> None:
    """:class:`NonFiniteError` if a weight or gradient of ``model``'s policy is not finite (``when``: in words)."""
    bad = first_non_finite(model.policy)
    if bad is not None:
        raise NonFiniteError(f"training stopped at decision {model.num_timesteps}: {when}, {bad}")


class OnRunSchedule:
    """For an SB3 callback that acts every ``freq`` calls (``n_calls % freq == 0``: checkpoints, periodic
    evaluations): count the calls from the start of the run, not of this ``learn``, so that a resumed run
    acts at the same decision counts as one never interrupted (SB3 counts from zero at each ``learn``: a
    run stopped at 1140 decisions and resumed evaluated at 2140, 3140, ... instead of 2000, 3000).
    ``run_origin``: the decisions of the model the run started from (0 for a fresh model; those of the
    ``init_from`` model), subtracted from the model's count."""

    def __init__(self, *args, run_origin: int = 0, **kwargs):
        super().__init__(*args, **kwargs)
        self.run_origin = int(run_origin)

    def _init_callback(self) -> None:
        super()._init_callback()
        self.n_calls = max(int(self.model.num_timesteps) - self.run_origin, 0) // max(int(self.model.n_envs), 1)


class GroundTruthEvalMixin(OnRunSchedule):
    """For an SB3 ``EvalCallback``: every evaluation runs the same held-out episodes (the eval env is
    reseeded with ``eval_seed`` first) and logs the mean of each ground-truth measure at the
    episodes' ends as ``eval/<measure>`` (TensorBoard and stdout), appending them to
    ``ground_truth_csv``; on ``LoopCorridor-v1`` also the fraction of episodes that closed the
    loop before entering the new area, ``eval/closed_loop_first`` (episodes that did neither
    left out). SB3's own files (``evaluations.npz`` in ``log_path``, ``best_model.zip`` in
    ``best_model_save_path``) are written into a staging folder, :data:`STAGING`, and renamed into
    place, so a run killed while SB3 writes one leaves the previous one whole.

    A resumed run goes on with the evaluations of the checkpoint it starts from
    (:meth:`_on_training_start`)."""

    def __init__(self, *args, eval_seed: int, ground_truth_csv: Path, log_path=None, best_model_save_path=None,
                 **kwargs):
        def staging(folder):
            return None if folder is None else str(Path(folder) / STAGING)

        super().__init__(*args, log_path=staging(log_path), best_model_save_path=staging(best_model_save_path),
                         **kwargs)
        self.eval_seed = eval_seed
        self.ground_truth_csv = Path(ground_truth_csv)
        self._finished: list[dict] = []
        self._evaluations_file = None if log_path is None else Path(log_path) / "evaluations.npz"
        self._staged = {Path(folder) / STAGING / name: Path(folder) / name
                        for folder, name in ((log_path, "evaluations.npz"), (best_model_save_path, "best_model.zip"))
                        if folder is not None}

    def _on_training_start(self) -> None:
        """Where a run resumes at ``start`` decisions (its checkpoint's), keep the evaluations made up to
        ``start`` and drop those of a continuation that was lost (a run killed after an evaluation its
        newest checkpoint does not hold), in ``eval_ground_truth.csv`` and in SB3's ``evaluations.npz``,
        whose best mean reward so far is restored (the best model is replaced only by a better one). If
        ``start`` is on the schedule and its evaluation is missing (a Ctrl-C or SIGTERM cut it short, and
        the checkpoint was saved at that decision), make it now, with the same weights: a resumed run's
        learning curve has every point an uninterrupted run's has."""
        super()._on_training_start()
        start = int(self.model.num_timesteps)
        evaluated = self._keep_ground_truth_up_to(start)
        self._keep_sb3_evaluations_up_to(start)
        if self.eval_freq > 0 and self.n_calls > 0 and self.n_calls % self.eval_freq == 0 and start not in evaluated:
            self._on_step()

    def _keep_ground_truth_up_to(self, start: int) -> set[int]:
        """Drop the rows of ``eval_ground_truth.csv`` made after ``start`` decisions; the decision counts of
        those kept."""
        if not self.ground_truth_csv.exists():
            return set()
        rows = read_csv_file(self.ground_truth_csv, "run's periodic evaluations (eval_ground_truth.csv)",
                             required=("timesteps",))
        kept = [row for row in rows if float(row["timesteps"]) <= start]
        if len(kept) < len(rows):
            text = io.StringIO()
            writer = csv.DictWriter(text, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(kept)
            write_text_atomically(self.ground_truth_csv, text.getvalue())
        return {int(float(row["timesteps"])) for row in kept}

    def _keep_sb3_evaluations_up_to(self, start: int) -> None:
        """Continue SB3's ``evaluations.npz`` with its evaluations up to ``start`` decisions (SB3 starts its
        lists empty at each ``learn`` and would overwrite the file with the resumed part's alone), and its
        best mean reward among them. Evaluations of another number of episodes (the resumed run changed
        ``eval.episodes``) cannot share the file's arrays: it is kept as ``evaluations_to_<start>.npz``."""
        if self._evaluations_file is None or not self._evaluations_file.exists():
            return
        with np.load(self._evaluations_file) as saved:
            timesteps, results, lengths = (np.asarray(saved[key]) for key in ("timesteps", "results", "ep_lengths"))
        if results.ndim != 2 or results.shape[1] != self.n_eval_episodes:
            os.replace(self._evaluations_file, self._evaluations_file.with_name(f"evaluations_to_{start}.npz"))
            return
        keep = timesteps <= start
        self.evaluations_timesteps = [int(t) for t in timesteps[keep]]
        self.evaluations_results = [row.tolist() for row in results[keep]]
        self.evaluations_length = [row.tolist() for row in lengths[keep]]
        if self.evaluations_results:
            self.best_mean_reward = max(float(np.mean(row)) for row in self.evaluations_results)

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
        for staged, place in self._staged.items():
            if staged.exists():
                os.replace(staged, place)
        if evaluating and self._finished:
            self._append_row()
        return result

    def _append_row(self) -> None:
        row = {"timesteps": self.num_timesteps, "mean_reward": self.last_mean_reward,
               **{k: nanmean([m.get(k, np.nan) for m in self._finished]) for k in self._finished[0]}}
        earlier = self.ground_truth_csv.read_text() if self.ground_truth_csv.exists() else ""
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=list(row))
        if not earlier:
            writer.writeheader()
        writer.writerow(row)
        write_text_atomically(self.ground_truth_csv, earlier + text.getvalue())


class GroundTruthEvalCallback(GroundTruthEvalMixin, EvalCallback):
    """SB3's EvalCallback with held-out seeds and the ground-truth metrics."""


def eval_callback_class(algorithm: str):
    """The evaluation callback for an algorithm: sb3-contrib's masked one for MaskablePPO."""
    if algorithm == "MaskablePPO":
        from sb3_contrib.common.maskable.callbacks import MaskableEvalCallback

        return type("MaskableGroundTruthEvalCallback", (GroundTruthEvalMixin, MaskableEvalCallback), {})
    return GroundTruthEvalCallback
