"""The scripted baselines for the waypoint environments: frontier, random, active loop-closing,
and the paper's two goal sequences (A: close the loop first, B: explore first).

``make_policy(name)`` builds one by name; see :mod:`emmi_gym.tools.policies.baselines`.
"""

from .baselines import (
                        GOAL_RADIUS,
                        POLICY_NAMES,
                        TARGET_SNAP,
                        ActiveLoopClosingPolicy,
                        FrontierPolicy,
                        GoalSequencePolicy,
                        RandomPolicy,
                        make_policy,
)

__all__ = ["GOAL_RADIUS", "POLICY_NAMES", "TARGET_SNAP", "ActiveLoopClosingPolicy", "FrontierPolicy",
           "GoalSequencePolicy", "RandomPolicy", "make_policy"]
