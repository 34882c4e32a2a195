"""The loop-order family of worlds (emmi_gym.world.loop_worlds), drawn as ``LoopOrder-v1`` draws them: the
loop and the new area with their own loops, seeded, pillared as asked, options checked, as docs/world.md says."""

from dataclasses import fields

import gymnasium as gym
import numpy as np
import pytest
from helpers import ROOT, independent_loops

import emmi_gym  # noqa: F401
from emmi_gym.inputs.validation import OptionError
from emmi_gym.tools.experiments.ab import check_world
from emmi_gym.world import rasterise
from emmi_gym.world.loop_worlds import LoopWorldConfig, generate_loop_world


@pytest.mark.parametrize("new_area_loop, loops", [(True, 2), (False, 1)])
def test_a_generated_world_is_the_loop_and_the_new_area_with_its_own_loop(new_area_loop, loops):
    world = generate_loop_world(4, LoopWorldConfig(new_area_loop=new_area_loop, size_jitter=0.15))
    check_world(world)  # decision, target_a, target_b and the route to the decision point
    assert independent_loops(world) == loops
    truth = rasterise(world, 0.1)
    for name in ("decision", "target_a", "target_b"):
        assert truth.reachable[truth.geometry.cell_of(*world.place(name).xy)]


def test_the_same_seed_draws_the_same_world_and_others_differ():
    config = LoopWorldConfig(size_jitter=0.15, loop_pillar_spacing=5.0)
    a, b, c = (generate_loop_world(s, config) for s in (7, 7, 8))
    assert np.array_equal(a.walls, b.walls) and a.places == b.places
    assert not (a.walls.shape == c.walls.shape and np.array_equal(a.walls, c.walls))


def pillar_corners(world):
    """The lower-left corners of the pillars (rectangles, four walls in a row, under 0.7 m each) of a world."""
    walls = world.walls
    short = walls[np.hypot(walls[:, 2] - walls[:, 0], walls[:, 3] - walls[:, 1]) < 0.7].reshape(-1, 4, 5)
    return {(round(float(p[:, [0, 2]].min()), 3), round(float(p[:, [1, 3]].min()), 3)) for p in short}


def test_pillars_line_the_walls_they_are_asked_for():
    plain = pillar_corners(generate_loop_world(1, LoopWorldConfig(new_area_pillar_spacing=0.0)))
    assert len(plain) == 2 and all(x > 0 for x, _ in plain)  # the two landmarks where the loop closes
    pillared = pillar_corners(generate_loop_world(1, LoopWorldConfig(new_area_pillar_spacing=2.0)))
    top = sorted(x for x, y in pillared if x < 0 and y > 9)  # on the new area's north wall (y = 10)
    assert len(top) >= 3 and np.allclose(np.diff(top), 2.0)
    looped = pillar_corners(generate_loop_world(1, LoopWorldConfig(new_area_pillar_spacing=0.0,
                                                                   loop_pillar_spacing=4.0)))
    assert len(looped) > 2 + 4 and all(x > 0 for x, _ in looped)


@pytest.mark.parametrize("options, field", [
    (dict(new_area_length=2.5), "new_area_length"),
    (dict(loop_height=16.0, size_jitter=0.3), "loop_height"),
    (dict(corridor_width=9.0), "corridor_width"),
])
def test_a_family_option_out_of_range_names_its_field(options, field):
    with pytest.raises(OptionError, match=field):
        gym.make("emmi_gym/LoopOrder-v1", generator=options)




def test_the_world_page_states_every_family_option():
    text = (ROOT / "docs" / "world.md").read_text()
    block = text.split("<!-- loop-world-options")[1].split("<!-- /loop-world-options -->")[0]
    stated = [[cell.strip().strip("`") for cell in line.strip().strip("|").split(" | ")]
              for line in block.splitlines()[3:] if line.startswith("|")]
    assert stated == [[f.name, str(f.default), f.metadata["help"]] for f in fields(LoopWorldConfig)]
