"""Score every checkpoint of training runs on the same held-out episodes, in parallel: the learning
curve of a run trained with ``eval.freq: 0``, or one on more episodes than its periodic evaluation.

    python scripts/score_checkpoints.py runs/ppo_plans_emmi_16envs_seed3 --world dungeon_maps/train \\
        --seed 400000 --episodes 16 --workers 16
    python scripts/plot_learning_curves.py runs/ppo_plans_emmi_16envs_seed3 --scores checkpoint_scores.csv \\
        --out curve.png

Writes, in each run folder, ``checkpoint_scores.csv`` (a row per checkpoint: ``timesteps``, then the
mean of each ground-truth measure over the episodes, as ``eval_ground_truth.csv``) and
``checkpoint_episodes.csv`` (every episode), and prints the curve (emmi_gym.training.checkpoint_scores).
"""

import sys

from emmi_gym.training.checkpoint_scores import main

if __name__ == "__main__":
    sys.exit(main())
