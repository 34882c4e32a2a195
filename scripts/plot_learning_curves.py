"""Learning curves of training runs: the held-out evaluations' ground truth against decisions trained.

    python scripts/plot_learning_curves.py runs/plans_emmi_seed0=scratch runs/plans_emmi_bc_seed0=clone+RL \\
        --baselines-csv results/test50.csv --out docs/plans_learning_curves.png

Each run folder's ``eval_ground_truth.csv`` (``--scores checkpoint_scores.csv``: the file of
``scripts/score_checkpoints.py``) gives one line per measure; ``--baselines-csv`` draws the scripted
policies' means as level lines (emmi_gym.training.learning_curves).
"""

import sys

from emmi_gym.training.learning_curves import main

if __name__ == "__main__":
    sys.exit(main())
