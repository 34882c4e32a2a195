"""The safety layer keeps commands off the walls the live scan shows."""

import numpy as np
import pytest

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


def test_touching_a_wall_a_turn_in_place_is_left_as_asked():
    """The escape rotation is for a robot that should drive on: one that only turns (the follower
    faces it to its path first) keeps its own turn rate, whichever side the wall is on."""
    x = np.linspace(0.0, 1.5, 80)
    wall_on_the_left = np.column_stack([x, np.full_like(x, 0.22)])
    assert safe_command(0.0, -1.0, wall_on_the_left, RADIUS, VMAX, WMAX) == (0.0, -1.0)


#: A scan (range m, bearing degrees; every fourth beam within 1.2 m) where a building episode stood still
#: for its last 80 decisions: a door jamb at the left front just inside the margin, a wall on the right.
JAMB_SCAN = [(0.61, -90), (0.613, -86), (0.582, -82), (0.544, -78), (0.521, -74), (0.466, -70), (0.443, -66),
             (0.423, -62), (0.396, -58), (0.4, -54), (0.402, -50), (0.455, -46), (0.472, -42), (0.52, -38),
             (0.675, 34), (0.68, 38), (0.696, 42), (0.706, 46), (0.722, 50), (0.276, 54), (0.294, 58), (0.29, 62),
             (0.299, 66), (0.305, 70), (0.344, 74), (0.358, 78), (0.356, 82), (0.418, 86), (0.896, 90)]


@pytest.mark.parametrize("target", [(1.5, 0.0), (1.5, 0.3), (1.2, 0.5)])
def test_a_jamb_just_inside_the_margin_is_passed_not_stared_at(target):
    """No arc forward is clear of the jamb, and standing still with the follower's command (the cheapest
    safe one) was a deadlock: the same command came back at every step. The robot turns away, then
    drives past to the target beyond, never touching (a unicycle on the scan's walls, a 180-degree view)."""
    from emmi_gym.navigation.follower import WaypointFollower

    bearings = np.radians([a for _, a in JAMB_SCAN])
    echoes = np.column_stack([np.cos(bearings), np.sin(bearings)]) * np.array([r for r, _ in JAMB_SCAN])[:, None]
    walls = [echoes[0]]  # the echoes joined where they are closer than 0.25 m: the walls they lie on
    for p, q in zip(echoes[:-1], echoes[1:], strict=False):
        walls += [p + t * (q - p) for t in np.linspace(0.0, 1.0, 10)[1:]] if np.hypot(*(q - p)) < 0.25 else [q]
    walls = np.array(walls)
    x = y = theta = 0.0
    follower = WaypointFollower([target], VMAX, WMAX, tolerance=0.3)
    closest = np.inf
    for _ in range(100):
        c, s = np.cos(theta), np.sin(theta)
        seen = np.column_stack([c * (walls[:, 0] - x) + s * (walls[:, 1] - y),
                                -s * (walls[:, 0] - x) + c * (walls[:, 1] - y)])
        seen = seen[seen[:, 0] >= 0.0]
        v, omega = safe_command(*follower.command((x, y, theta)), seen, RADIUS, VMAX, WMAX)
        theta += 0.1 * omega
        x, y = x + 0.1 * v * np.cos(theta), y + 0.1 * v * np.sin(theta)
        closest = min(closest, np.min(np.hypot(walls[:, 0] - x, walls[:, 1] - y)))
        if follower.done:
            break
    assert follower.done and closest > RADIUS + 0.5 * MARGIN
