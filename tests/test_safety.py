"""The safety layer keeps commands off the walls the live scan shows."""

import numpy as np

from emmi_gym.navigation.safety import MARGIN, _closest_approach, safe_command, scan_points

RADIUS, VMAX, WMAX = 0.2, 0.6, 1.5
ANGLES = np.linspace(-np.pi, np.pi, 360, endpoint=False)


def wall_ahead(distance: float) -> np.ndarray:
    """Ranges of a scan with a straight wall ``distance`` m ahead, perpendicular to the heading."""
    with np.errstate(divide="ignore"):
        ranges = np.where(np.cos(ANGLES) > 1e-3, distance / np.cos(ANGLES), np.inf)
    return np.minimum(ranges, 8.0)


def test_open_space_leaves_the_command_alone():
    points = scan_points(wall_ahead(5.0), ANGLES, 8.0, within=1.6)
    assert points.size == 0
    assert safe_command(VMAX, 0.3, points, RADIUS, VMAX, WMAX) == (VMAX, 0.3)


def test_a_wall_ahead_slows_or_turns_the_robot_and_the_chosen_arc_is_clear():
    points = scan_points(wall_ahead(0.6), ANGLES, 8.0, within=1.6)
    v, omega = safe_command(VMAX, 0.0, points, RADIUS, VMAX, WMAX)
    assert (v, omega) != (VMAX, 0.0)
    assert _closest_approach(np.array([v]), np.array([omega]), points)[0] >= RADIUS + MARGIN
    # straight on would have hit it within the horizon
    assert _closest_approach(np.array([VMAX]), np.array([0.0]), points)[0] < RADIUS + MARGIN


def test_touching_a_wall_the_robot_backs_away():
    points = scan_points(wall_ahead(0.22), ANGLES, 8.0, within=1.6)
    v, _ = safe_command(VMAX, 0.0, points, RADIUS, VMAX, WMAX)
    assert v < 0
