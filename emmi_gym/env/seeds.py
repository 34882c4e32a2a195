"""The package's one convention for episode seeds, the same for every env id, command and page.

``reset(seed=s)`` makes the same episode (world, noise, start) for the same ``s``. Seeds
0 to 999,999 are for training and for choosing (settings, checkpoints, hyperparameters): training
envs start from the configuration's ``seed``, the periodic evaluations during training from
``eval.seed`` (:data:`LEARNING_CURVE_SEED`), behaviour-cloning demonstrations from
:data:`DEMONSTRATION_SEED`. Seeds from :data:`HELD_OUT_SEED` up are held out: the figures a page
reports as held out (``evaluate``, ``benchmark``, ``score-checkpoints``, the A/B experiment's
confirmations) come from there, and nothing is chosen on them. On the floor plans the maps are
held out too: the test split, which no agent trains on.
"""

#: The first held-out seed: every evaluation that reports, not chooses, starts here by default.
HELD_OUT_SEED = 1_000_000
#: The first seed of the periodic evaluations during training (``eval.seed``'s default).
LEARNING_CURVE_SEED = 100_000
#: The first seed of behaviour cloning's demonstration episodes (``clone --seed``'s default).
DEMONSTRATION_SEED = 300_000
