"""Which way each reported measure is better, and how its numbers are written: one rule for every
summary table (the A/B experiment, ``evaluate``, ``benchmark``, ``compare-policies``), so that a
column comparing two policies always counts "better", never merely "higher".

Higher is better for map quality (accuracy, wall consistency, coverage), the certainty the paper
rewards (a rise of EMMI, eq. 9) and reaching goals; lower for pose errors (ATE, closure error),
entropies (pose entropy, eq. 3; joint entropy, eq. 4) and time to a target. Counts of what a policy
did (decisions, robot time, revisits, resamplings) and descriptive shares have no better side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

HIGHER, LOWER = 1, -1

#: The measures with a better side: +1 where higher is better, -1 where lower is.
BETTER = {
    **dict.fromkeys(("map_accuracy", "oracle_accuracy", "wall_consistency", "coverage", "building_accuracy",
                     "reached_target",
                     "completed", "loop_closed", "new_area_accuracy", "new_area_accuracy_on_arrival",
                     "emmi_change", "return"), HIGHER),
    **dict.fromkeys(("ate", "loop_ate", "closure_error", "sim_steps_to_target", "pose_entropy_change",
                     "joint_entropy_change", "collisions"), LOWER),
}

#: Measures that count things (steps, decisions): written without decimals, whatever their size.
COUNTS = ("sim_steps", "sim_steps_to_target", "decisions", "collisions", "resamplings", "episode_steps",
          "new_area_cells", "timesteps")


def better_side(column: str) -> str:
    """``"higher"``, ``"lower"`` or ``"-"`` (no better side): the words a table's "better" column holds."""
    return {HIGHER: "higher", LOWER: "lower"}.get(BETTER.get(column), "-")


@dataclass(frozen=True)
class Tally:
    """How paired differences (first minus second) fall on a measure's better side: on how many the first did
    better, on how many the two were level (a difference of exactly zero), on how many it did worse."""

    better: int
    tied: int
    worse: int

    @property
    def pairs(self) -> int:
        return self.better + self.tied + self.worse

    def __str__(self) -> str:
        """``"2/3"``, or ``"1/3 (2 tied)"`` where some were level: a tie never reads as a loss."""
        return f"{self.better}/{self.pairs}" + (f" ({self.tied} tied)" if self.tied else "")


def count_better(differences, column: str) -> Tally | None:
    """How the finite paired ``differences`` (first minus second) favour the first on ``column``'s better side
    (:class:`Tally`); ``None`` where the measure has none."""
    side = BETTER.get(column)
    if side is None:
        return None
    values = np.asarray(differences, dtype=float)
    signed = side * values[np.isfinite(values)]
    return Tally(int(np.sum(signed > 0)), int(np.sum(signed == 0)), int(np.sum(signed < 0)))


def digits(column: str) -> int:
    """Decimals ``column``'s numbers are written with: none for counts, three for the rest."""
    return 0 if column in COUNTS else 3


def format_number(value, column: str, signed: bool = False) -> str:
    """``value`` of ``column`` as the tables write it (``-`` for NaN)."""
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "-"
    return f"{value:{'+' if signed else ''}.{digits(column)}f}"
