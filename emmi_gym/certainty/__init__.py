"""Certainty of a particle set: the paper's EMMI (eqs. 6-11) and the measures it is compared with.

Pure functions of NumPy arrays. Information is in bits (as the paper); entropies of
poses, paths and the joint entropy are in nats (differential entropies).
"""

from .expected_map import (
    emmi,
    emmi_of_parts,
    expected_map,
    expected_map_information_of_parts,
    expected_map_of_cells,
    joint_entropy_of_parts,
    weighted_map_entropy,
)
from .information import (
    DEFAULT_OBSERVED_TOL,
    as_probability,
    cell_entropy,
    cell_information,
    map_entropy,
    map_entropy_of_code_counts,
    map_information,
    mean_information,
    mean_information_of_code_counts,
    observation_labels,
    observed_cells,
)
from .pose import (
    DEFAULT_DET_FLOOR,
    heading_sincos,
    joint_entropy,
    loop_displacement_spread,
    path_entropy,
    path_entropy_of_parts,
    pose_entropy,
    widest_loop_spread,
)
from .weights import effective_sample_size, normalize_weights, weight_entropy

__all__ = [
    "DEFAULT_DET_FLOOR",
    "DEFAULT_OBSERVED_TOL",
    "as_probability",
    "cell_entropy",
    "cell_information",
    "effective_sample_size",
    "emmi",
    "emmi_of_parts",
    "expected_map_information_of_parts",
    "expected_map",
    "expected_map_of_cells",
    "heading_sincos",
    "joint_entropy",
    "joint_entropy_of_parts",
    "loop_displacement_spread",
    "map_entropy",
    "map_entropy_of_code_counts",
    "map_information",
    "mean_information",
    "mean_information_of_code_counts",
    "normalize_weights",
    "observation_labels",
    "observed_cells",
    "path_entropy",
    "path_entropy_of_parts",
    "pose_entropy",
    "weight_entropy",
    "weighted_map_entropy",
    "widest_loop_spread",
]
