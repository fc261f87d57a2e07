"""Campaign studies and the `hexcal simulate` and `hexcal paper` commands' new rows."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.simulation import fixed_strategy, run_paper_experiment, run_study


@pytest.fixture(scope="module")
def study():
    return run_study(
        preset("paper-hmt"),
        preset("paper-hmt-true"),
        methods=("paper", "ml"),
        pose_counts=(15, 30),
        noises={"paper": NoiseModel(), "none": NoiseModel(0, 0, 0)},
        trials=12,
        rng=5,
    )


def test_study_has_every_cell(study):
    keys = {(c.strategy, c.n_poses, c.noise, c.method) for c in study}
    assert len(keys) == len(study) == 2 * 2 * 2 * 2


def test_noise_free_campaigns_are_exact(study):
    for cell in study:
        if cell.noise == "none":
            assert np.nanmax(cell.errors) < 1e-6
            assert np.all(np.isnan(cell.bounds))


def test_ml_is_near_its_bound_and_beats_the_paper_estimator(study):
    rows = {(c.strategy, c.n_poses, c.method): c.row() for c in study if c.noise == "paper"}
    for strategy in ("corners", "interior"):
        for n in (15, 30):
            ml, paper = rows[(strategy, n, "ml")], rows[(strategy, n, "paper")]
            # 12 trials: the mean error has a relative sampling error of about 0.3/sqrt(12) = 9 %
            assert 0.7 < ml["efficiency"] < 1.3
            assert ml["error_mean"] < 0.75 * paper["error_mean"]
            assert ml["position_rms"] < paper["position_rms"]


def test_more_poses_and_corners_give_smaller_bounds(study):
    rows = {(c.strategy, c.n_poses, c.method): c.row() for c in study if c.noise == "paper"}
    assert rows[("corners", 30, "ml")]["bound"] < rows[("corners", 15, "ml")]["bound"]
    assert rows[("corners", 15, "ml")]["bound"] < rows[("interior", 15, "ml")]["bound"]


def test_study_is_reproducible_and_cells_do_not_depend_on_each_other():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    a = run_study(nominal, true, methods=("length",), pose_counts=(15,), trials=4, rng=9)
    b = run_study(nominal, true, methods=("length", "paper"), pose_counts=(15, 20), trials=4, rng=9)
    first = {(c.strategy, c.n_poses, c.method): c.errors for c in b}
    for cell in a:
        np.testing.assert_array_equal(cell.errors, first[(cell.strategy, cell.n_poses, cell.method)])


def test_fixed_strategy_measures_the_same_poses_every_trial():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    from hexcal.core.workspace import workspace_corners

    poses = workspace_corners(nominal)[:16]
    cells = run_study(
        nominal,
        true,
        methods=("ml",),
        strategies={"fixed": fixed_strategy({16: poses})},
        pose_counts=(16,),
        trials=3,
        rng=1,
    )
    # same commanded poses and machine: the bound differs only through the leg noise (< 0.1 %)
    assert np.ptp(cells[0].bounds) < 1e-3 * cells[0].bounds.mean()


def test_paper_experiment_ml_row_uses_the_same_data():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    base = run_paper_experiment(nominal, true, trials=6, rng=4)
    extra = run_paper_experiment(
        nominal, true, trials=6, rng=4, extra_rows=(("boundary_ml", "boundary", "ml"),)
    )
    np.testing.assert_array_equal(base.boundary_vectors, extra.boundary_vectors)
    errors = extra.mean_abs_errors()
    assert np.mean(errors["boundary_ml"]) < 0.7 * np.mean(errors["boundary"])
    assert np.allclose(extra.bound_of("boundary_ml"), extra.bound_of("boundary"))


def test_simulate_command_writes_its_files(tmp_path, capsys):
    out = tmp_path / "study"
    status = main(
        [
            "simulate",
            "--poses",
            "15",
            "--trials",
            "3",
            "--methods",
            "length,ml",
            "--quiet",
            "--strategies",
            "corners",
            "--noise-levels",
            "0.5,1",
            "--out",
            str(out),
        ]
    )
    assert status == 0
    printed = capsys.readouterr().out
    assert "corners" in printed and "x0.5" in printed
    data = json.loads((out / "study.json").read_text())
    assert {c["method"] for c in data["cells"]} == {"length", "ml"}
    assert len(data["cells"]) == 4
    assert (out / "study.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "study.csv").read_text().count("\n") == 1 + 1 + 4  # comment, header, rows


@pytest.mark.parametrize(
    "argv, text",
    [
        (["--methods", "best"], "--methods"),
        (["--strategies", "moon"], "--strategies"),
        (["--poses", "15,x"], "--poses"),
        (["--poses", "0"], "--poses"),
        (["--noise-levels", "a"], "--noise-levels"),
        (["--noise", "leg=-2"], "--noise"),
        (["--trials", "0"], "--trials"),
    ],
)
def test_simulate_bad_options_give_one_error_line(tmp_path, capsys, argv, text):
    out = tmp_path / "study"
    status = main(["simulate", "--quiet", "--out", str(out), *argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert status != 0
    assert len(err) == 1 and err[0].startswith("hexcal: error:") and text in err[0]
    assert not out.exists()


def test_paper_command_prints_the_ml_row_and_bounds(tmp_path, capsys):
    status = main(["paper", "--trials", "4", "--quiet", "--jobs", "1", "--out", str(tmp_path / "p")])
    assert status == 0
    printed = capsys.readouterr().out
    assert "maximum likelihood" in printed and "bound" in printed
    table = json.loads((tmp_path / "p" / "table1.json").read_text())
    assert table["boundary_ml"] < table["boundary"]
    assert 0.5 < table["bound"]["boundary_ml"]["efficiency"] < 2


def test_simulate_selected_strategy_beats_random_corners(capsys):
    """A-optimal poses: a smaller bound than random corners (0.10 vs about 0.16 mm measured)."""
    status = main(
        [
            "simulate",
            "--strategies",
            "corners,selected",
            "--poses",
            "15",
            "--trials",
            "3",
            "--methods",
            "gls",
            "--quiet",
            "--jobs",
            "1",
        ]
    )
    assert status == 0
    rows = [
        line.split()
        for line in capsys.readouterr().out.splitlines()
        if line.strip().startswith(("corn", "sel"))
    ]
    bound = {r[0]: float(r[6]) for r in rows}
    assert bound["selected"] < 0.8 * bound["corners"]


def test_study_does_not_depend_on_chunks_or_processes(study):
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    kwargs = {
        "methods": ("paper", "ml"),
        "pose_counts": (15, 30),
        "noises": {"paper": NoiseModel(), "none": NoiseModel(0, 0, 0)},
        "trials": 12,
        "rng": 5,
    }
    poses = {15: preset("paper-hmt").workspace[:, 0] + np.zeros((15, 6))}
    for options in ({"chunk_size": 5}, {"chunk_size": 1, "jobs": 2}):
        again = run_study(nominal, true, **options, **kwargs)
        for a, b in zip(study, again, strict=True):
            assert (a.strategy, a.n_poses, a.noise, a.method) == (b.strategy, b.n_poses, b.noise, b.method)
            for name in ("errors", "bounds", "position_rms", "orientation_rms"):
                # other chunks: maximum likelihood's last digits differ (trials solved together)
                # (noise-free bounds are rounding, about 1e-12: compared absolutely)
                np.testing.assert_allclose(
                    getattr(a, name), getattr(b, name), rtol=1e-9, atol=1e-11, err_msg=name
                )
            assert json.dumps(a.to_dict()) == json.dumps(a.row())  # NaN != NaN
    # the fixed strategy is picklable: it runs in worker processes too
    strategies = {"fixed": fixed_strategy(poses)}
    one = run_study(nominal, None, ("length",), strategies, (15,), trials=4, rng=2)
    two = run_study(nominal, None, ("length",), strategies, (15,), trials=4, rng=2, jobs=2, chunk_size=1)
    np.testing.assert_array_equal(one[0].errors, two[0].errors)


def test_unreachable_campaigns_are_failed_trials_of_their_cell():
    nominal = preset("paper-hmt")
    vector = nominal.to_vector()
    vector[:18] *= 10.0  # base joints 3 m out: legs of 0.6-1.1 m cannot reach
    cells = run_study(nominal, nominal.with_vector(vector), methods=("length",), trials=3, rng=0)
    for cell in cells:
        row = cell.row()
        assert row["failures"] == 3
        assert np.isnan(row["error_mean"])


def test_study_result_to_dict_is_the_json_of_the_cells(study):
    data = study.to_dict(trials=12, seed=5)
    assert list(data) == ["trials", "seed", "cells"]
    assert json.dumps(data["cells"]) == json.dumps([c.row() for c in study])
    assert isinstance(study, list)
