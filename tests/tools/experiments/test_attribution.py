"""What a benchmark's routes explain of its maps (emmi_gym.tools.experiments.attribution)."""

import numpy as np
import pytest

from emmi_gym.tools.experiments.attribution import PREDICTORS, attribution, markdown


def episodes(offsets: dict[str, float], worlds: int = 12, noise: float = 0.0, seed: int = 0) -> list[dict]:
    """Episode rows as benchmark_episodes.csv holds them: every policy on every world, its ATE a world
    effect plus known effects of the order, the revisits and the time, plus the policy's own offset."""
    rng = np.random.default_rng(seed)
    rows = []
    for world in range(worlds):
        world_effect = rng.uniform(0.2, 0.8)
        for policy, offset in offsets.items():
            closed, revisits, steps = float(rng.integers(0, 2)), rng.uniform(0, 0.5), rng.uniform(800, 1400)
            ate = world_effect - 0.05 * closed - 0.2 * revisits + 0.01 * steps / 1000 + offset
            rows.append({"episode_seed": 1000 + world, "kind": "agent" if policy == "emmi" else "baseline",
                         "variant": policy, "ate": ate + noise * rng.normal(), "oracle_accuracy": 1.0 - ate,
                         "closed_loop_first": closed, "revisit_share": revisits, "sim_steps": steps})
    return rows


def test_the_fit_recovers_the_effects_within_worlds_and_leaves_no_residual():
    estimate, low, high, names, worlds, _ = attribution(episodes({"emmi": 0.0, "a": 0.0, "b": 0.0}), "ate", 200)
    assert worlds == 12 and names == ["emmi agents", "a", "b"]
    np.testing.assert_allclose(estimate[:len(PREDICTORS)], [-0.05, -0.2, 0.01], atol=1e-9)
    assert estimate[len(PREDICTORS)] == pytest.approx(1.0)
    np.testing.assert_allclose(estimate[len(PREDICTORS) + 1:], 0.0, atol=1e-9)


def test_a_policy_that_maps_better_than_its_route_explains_has_a_negative_residual():
    estimate, low, high, names, _, _ = attribution(episodes({"emmi": -0.03, "a": 0.0, "b": 0.0}, noise=0.005), "ate",
                                                500)
    k = len(PREDICTORS) + 1
    residual = dict(zip(names, zip(estimate[k:], high[k:], strict=True), strict=True))
    mine, upper = residual["emmi agents"]
    assert upper < 0, "the interval of the better policy's residual excludes 0"
    others = np.mean([residual["a"][0], residual["b"][0]])
    assert mine - others == pytest.approx(-0.03, abs=0.006)


def test_the_bootstrap_is_reproducible_and_the_tables_name_every_policy():
    rows = episodes({"emmi": -0.03, "explore_first": 0.0}, noise=0.01)
    assert markdown(rows, 100) == markdown(rows, 100)
    assert "residual of emmi agents" in markdown(rows, 100) and "residual of explore_first" in markdown(rows, 100)


def test_rows_without_the_routes_are_refused_with_what_is_expected():
    rows = [{"episode_seed": 1, "kind": "agent", "variant": "emmi", "ate": 0.3}]
    with pytest.raises(ValueError, match="revisit_share and sim_steps.*benchmark_episodes.csv"):
        attribution(rows, "ate", 100)
    with pytest.raises(ValueError, match="revisit_share and sim_steps"):
        attribution([dict(row, revisit_share=0.1) for row in rows], "ate", 100)


def test_without_a_loop_order_the_routes_are_the_revisits_and_the_time():
    """Floor plans have no loop to close first: the fit keeps the revisits and the time, from an evaluation's rows
    (a world is a world and seed, the policy its own)."""
    rows = [{"world": f"plan{row['episode_seed']}", "seed": 7, "policy": row["variant"], "ate": row["ate"] + 0.05 *
             row["closed_loop_first"], "oracle_accuracy": row["oracle_accuracy"], "closed_loop_first": np.nan,
             "revisit_share": row["revisit_share"], "sim_steps": row["sim_steps"]}
            for row in episodes({"agent": 0.0, "frontier": 0.0})]
    estimate, low, high, names, worlds, predictors = attribution(rows, "ate", 200)
    assert predictors == ["revisit_share", "sim_steps"] and worlds == 12 and names == ["agent", "frontier"]
    np.testing.assert_allclose(estimate[:2], [-0.2, 0.01], atol=1e-9)
    assert estimate[2] == pytest.approx(1.0)  # R^2: the revisits and the time explain it all
    np.testing.assert_allclose(estimate[3:], 0.0, atol=1e-9)
    assert "closed the loop first" not in markdown(rows, 50) and "| revisit share |" in markdown(rows, 50)


def test_only_the_worlds_every_policy_played_are_fitted_and_none_shared_is_refused():
    """Evaluations pooled from separate runs: a world one policy lacks compares nothing, and runs on different
    worlds (another install's paths, other seeds) are an error naming what each played, not residuals of zero."""
    rows = [{"world": f"plan{row['episode_seed']}", "seed": 7, "policy": row["variant"], "ate": row["ate"],
             "oracle_accuracy": row["oracle_accuracy"], "revisit_share": row["revisit_share"],
             "sim_steps": row["sim_steps"]} for row in episodes({"agent": 0.0, "frontier": 0.0})]
    extra = dict(rows[0], world="plan99")
    assert attribution([*rows, extra], "ate", 50)[4] == 12
    elsewhere = [dict(row, seed=8) if row["policy"] == "agent" else row for row in rows]
    with pytest.raises(ValueError, match="no world and seed was played by every policy.*agent played e.g. plan1000 #8"):
        attribution(elsewhere, "ate", 50)
