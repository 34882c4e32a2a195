"""Experiments on top of the environment: the paper's A/B loop-closure experiment (Fig. 6)."""

from .ab import POLICIES, ABRun, ABSettings, run_ab, run_arm
from .report import write_report

__all__ = ["ABRun", "ABSettings", "POLICIES", "run_ab", "run_arm", "write_report"]
