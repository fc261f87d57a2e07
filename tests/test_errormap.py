"""Error maps of random parameter errors (design: pose_errors, errormap, paper_claims), after Figs. 4-9.

Provenance: the first-order map is checked against the forward kinematics of every
perturbed machine; the claims are the seed paper's section IV (errors largest on the
workspace boundary and at larger z) evaluated on paper-hmt with its workspace box
(shared/reference/paper-hmt.md).
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from hexcal.core import select_parameters
from hexcal.design import (
    angle_grid_poses,
    claims,
    error_maps,
    line_sweep_poses,
    parameter_error_draws,
    pose_error_samples,
)


@pytest.fixture(scope="module")
def small_maps():
    from hexcal.core import preset

    return error_maps(preset("paper-hmt"), levels=6, points=9, grid=7, draws=40, rng=1, interior=300)


def test_draws_are_uniform_in_the_amplitude_and_seeded():
    draws = parameter_error_draws(2000, amplitude=0.1, rng=3)
    assert draws.shape == (2000, 42)
    assert np.abs(draws).max() <= 0.1
    assert draws.std() == pytest.approx(0.1 / np.sqrt(3), rel=0.02)
    assert_array_equal(draws, parameter_error_draws(2000, amplitude=0.1, rng=3))
    gains = parameter_error_draws(10, select_parameters("gains"), 0.1, rng=0)
    assert np.abs(gains).max() <= 1e-4  # gains in their 1e-3 scale
    with pytest.raises(ValueError, match="at least 1"):
        parameter_error_draws(0)
    with pytest.raises(ValueError, match="amplitude"):
        parameter_error_draws(3, amplitude=-1)


def test_linear_map_agrees_with_forward_kinematics(nominal):
    """±0.1 mm errors move a platform of ~600 mm legs by ~0.5 mm: second order ~1e-3 relative."""
    poses = np.array(
        [[0, 0, 800, 0, 0, 0], [250, -250, 900, 0.17, -0.17, 0.17], [-200, 100, 700, -0.1, 0.05, 0]]
    )
    draws = parameter_error_draws(30, rng=2)
    pos_lin, ang_lin = pose_error_samples(nominal, poses, draws, method="linear")
    pos_fk, ang_fk = pose_error_samples(nominal, poses, draws, method="exact")
    assert pos_lin.shape == (3, 30)
    assert_allclose(pos_lin, pos_fk, rtol=1e-2)
    assert_allclose(ang_lin, ang_fk, rtol=1e-2)
    assert pos_lin.mean() > 0.1  # not trivially zero


def test_linear_errors_scale_with_the_amplitude(nominal):
    poses = np.array([[0, 0, 800, 0, 0, 0], [100, 0, 850, 0, 0.1, 0]])
    draws = parameter_error_draws(5, rng=4)
    p1, a1 = pose_error_samples(nominal, poses, draws)
    p2, a2 = pose_error_samples(nominal, poses, 2.5 * draws)
    assert_allclose(p2, 2.5 * p1, rtol=1e-12)
    assert_allclose(a2, 2.5 * a1, rtol=1e-12)
    zero_p, zero_a = pose_error_samples(nominal, poses, np.zeros((1, 42)))
    assert np.all(zero_p == 0) and np.all(zero_a == 0)
    with pytest.raises(ValueError, match="draws"):
        pose_error_samples(nominal, poses, np.zeros((1, 41)))
    with pytest.raises(ValueError, match="method"):
        pose_error_samples(nominal, poses, draws, method="quadratic")


def test_sweep_and_grid_poses(nominal):
    box = nominal.workspace
    values, levels, poses = line_sweep_poses(box, "x", "z", 5, 3)
    assert poses.shape == (3, 5, 6)
    assert_allclose(values, [-250, -125, 0, 125, 250])
    assert_allclose(levels, [700, 800, 900])
    assert_allclose(poses[:, :, 1], 0)
    assert_allclose(poses[:, :, 3:], 0)
    (v1, v2), zs, grid = angle_grid_poses(box, ("a", "c"), 3, 2)
    assert_allclose(zs, [700, 900])
    assert grid.shape == (2, 3, 3, 6)
    assert_allclose(grid[1, 0, 2, [2, 3, 5]], [900, v1[0], v2[2]])
    assert_allclose(grid[..., 4], 0)


def test_error_maps_shapes(small_maps):
    assert set(small_maps.lines) == {"x", "y", "z"}
    assert set(small_maps.angles) == {"a-b", "a-c", "b-c"}
    assert small_maps.lines["x"].position.shape == (6, 9, 40)
    assert small_maps.lines["z"].level_axis == "x"
    assert small_maps.angles["b-c"].position.shape == (6, 7, 7)
    assert small_maps.corners["position"].shape == (64,)
    assert small_maps.interior["orientation"].shape == (300,)
    assert len(small_maps.parameters) == 42


def test_error_maps_are_seeded(nominal):
    a = error_maps(nominal, levels=2, points=3, grid=3, draws=5, rng=9, interior=10)
    b = error_maps(nominal, levels=2, points=3, grid=3, draws=5, rng=9, interior=10)
    assert_array_equal(a.lines["y"].position, b.lines["y"].position)
    assert_array_equal(a.angles["a-b"].orientation, b.angles["a-b"].orientation)


def test_the_paper_claims_hold_on_paper_hmt(small_maps):
    """Section IV: the error is largest on the boundary of the workspace and at larger z."""
    summary = claims(small_maps)
    for axis in ("x", "y", "z"):
        for key in ("position", "orientation"):
            line = summary["lines"][axis][key]
            assert line["max_at_an_end"] == 1.0
            assert line["end_over_centre"] > 1.0
    for key in ("position", "orientation"):
        for axis in ("x", "y"):
            assert summary["lines"][axis][key]["level_rank_correlation"] == pytest.approx(1.0)
            assert summary["lines"][axis][key]["top_level_over_bottom_level"] > 1.1
        assert summary["lines"]["z"][key]["max_at_upper_end"] == 1.0
        for grid in summary["angles"].values():
            assert grid[key]["max_on_boundary"] == 1.0
            assert grid[key]["top_level_over_bottom_level"] > 1.1
        workspace = summary["workspace"][key]
        assert workspace["corners_over_interior"] > 1.05
        assert workspace["corners_top_z_over_bottom_z"] > 1.05
    from hexcal.report import claims_text

    text = claims_text(summary)
    assert "Boundary claim" in text and "Height claim" in text


def test_error_maps_need_a_workspace_and_sane_sizes(nominal):
    with pytest.raises(ValueError, match="workspace"):
        error_maps(nominal.replace(workspace=None), levels=2, points=3, grid=3, draws=2)
    with pytest.raises(ValueError, match="points"):
        error_maps(nominal, levels=2, points=1, grid=3, draws=2)


def test_error_maps_to_dict_holds_the_mean_maps(small_maps):
    """The JSON form holds settings and mean curves/grids over the draws, not the draws."""
    import json

    data = small_maps.to_dict()
    json.dumps(data)
    assert data["settings"] == {
        "amplitude_mm": 0.1,
        "draws": 40,
        "method": "linear",
        "parameters": list(small_maps.parameters),
    }
    line = small_maps.lines["x"]
    assert_allclose(data["lines"]["x"]["position_mean_mm"], line.position.mean(axis=-1))
    assert_allclose(data["lines"]["x"]["orientation_sd_rad"], line.orientation.std(axis=-1))
    assert data["lines"]["x"]["draws"] == 40 and data["lines"]["x"]["levels"] == line.levels.tolist()
    assert_allclose(data["angles"]["a-b"]["position_mean_mm"], small_maps.angles["a-b"].position)
    assert_allclose(data["corners"]["position"], small_maps.corners["position"])
