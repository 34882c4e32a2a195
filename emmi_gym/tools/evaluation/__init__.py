"""Evaluation episodes, for trained agents and scripted policies alike, and what they measure: an episode played
under the ground truth (:mod:`.episodes`), the order in which it closed a loop (:mod:`.loop_order`), its map at
equal robot time (:mod:`.robot_time`), which side of each measure is better (:mod:`.directions`), intervals over
episodes (:mod:`.intervals`) and policies compared on the same episodes (:mod:`.comparison`).

Training (its periodic evaluation, checkpoint curves, the reward benchmark) and the experiments (the A/B
experiment, sweeps, reports) both build on it; neither imports the other."""
