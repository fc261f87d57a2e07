"""The planning commands end to end: errormap, observability, candidates, select.

Commands run in-process through :func:`hexcal.cli.main`. A known failure must give a
non-zero status, exactly one line ``hexcal: error: ...`` on stderr and no output file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from hexcal.cli import main
from hexcal.core.presets import preset
from hexcal.core.workspace import workspace_corners
from hexcal.design import analyse_poses
from hexcal.io import read_poses, read_table, write_poses

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def assert_one_error_line(status: int, err: str) -> str:
    assert status != 0
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("hexcal: error:")
    return lines[0]


def listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


@pytest.fixture
def paper():
    return preset("paper-hmt")


@pytest.fixture
def flat_poses(tmp_path, paper) -> Path:
    """16 corners with the angles set to zero: the platform never rotates."""
    poses = workspace_corners(paper)[::4].copy()
    poses[:, 3:] = 0.0
    path = tmp_path / "flat.csv"
    write_poses(path, poses, [f"f{k}" for k in range(len(poses))])
    return path


# -- select -----------------------------------------------------------------------------------


def test_select_writes_optimal_poses_and_compares_them(capsys, tmp_path, paper):
    out, js = tmp_path / "sel.csv", tmp_path / "sel.json"
    status, stdout, err = run(capsys, "select", "--geometry", "paper-hmt", "--out", out, "--json", js)
    assert status == 0, err
    poses, ids = read_poses(out, "XYZ")
    assert poses.shape == (15, 6) and len(set(ids)) == 15
    assert all(i.startswith("g") for i in ids)  # from the default boundary grid
    box = paper.workspace
    at_bound = np.isclose(poses, box[:, 0]) | np.isclose(poses, box[:, 1])
    assert at_bound.any(axis=1).all()
    for text in (
        "A-optimal",  # the default criterion, as simulate's selected strategy
        "candidate indices",
        "the seed paper",
        "random interior",
        "lower predicted error",
    ):
        assert text in stdout
    data = json.loads(js.read_text())
    assert data["ids"] == list(ids) and len(data["indices"]) == 15
    predicted = data["predicted_mean_abs_error_mm"]
    assert predicted["selected"]["estimator"] < 0.8 * predicted["paper"]["estimator"]
    assert predicted["paper"]["estimator"] < predicted["interior"]["estimator"]
    assert data["value"] >= data["greedy_value"]
    # the JSON prediction is the analysis of the written poses (ml: the Cramér–Rao bound;
    # the unweighted least-squares prediction under "length")
    analysis = analyse_poses(paper, poses)
    assert predicted["selected"]["estimator"] == pytest.approx(analysis.mean_error_bound)
    assert predicted["selected"]["length"] == pytest.approx(analysis.mean_error_estimator)


def test_select_is_deterministic_under_the_seed(capsys, tmp_path):
    files = []
    for k in range(2):
        out = tmp_path / f"sel{k}.csv"
        argv = ["select", "--geometry", "paper-hmt", "--candidates", "corners+random:300", "--n", "10"]
        assert run(capsys, *argv, "--criterion", "A", "--seed", "4", "--out", out)[0] == 0
        files.append(out.read_bytes())
    assert files[0] == files[1]


@pytest.mark.parametrize("criterion", ["E", "O4"])
def test_select_other_criteria(capsys, tmp_path, criterion):
    out = tmp_path / "sel.csv"
    status, stdout, err = run(
        capsys, "select", "--geometry", "paper-hmt", "--candidates", "corners", "--criterion", criterion,
        "--n", "12", "--out", out,
    )  # fmt: skip
    assert status == 0, err
    assert f"{criterion}-optimal" in stdout
    assert len(read_poses(out, "XYZ")[0]) == 12


def test_select_paper_strategy(capsys, tmp_path, paper):
    out = tmp_path / "paper.csv"
    status, stdout, err = run(
        capsys, "select", "--geometry", "paper-hmt", "--strategy", "paper", "--out", out
    )
    assert status == 0, err
    poses, ids = read_poses(out, "XYZ")
    corners = workspace_corners(paper)
    assert all(i.startswith("c") for i in ids)
    assert_allclose(poses, corners[[int(i[1:]) for i in ids]])
    assert "seed paper's strategy" in stdout


def test_select_never_proposes_infeasible_candidates(capsys, tmp_path, paper):
    candidates = np.vstack([workspace_corners(paper), [[0, 0, 1100, 0, 0, 0], [0, 0, 800, 0, 0, np.pi / 2]]])
    ids = [f"c{k}" for k in range(64)] + ["too_high", "singular"]
    path, out = tmp_path / "cands.csv", tmp_path / "sel.csv"
    write_poses(path, candidates, ids)
    status, _, err = run(
        capsys, "select", "--geometry", "paper-hmt", "--candidates", path, "--n", "64", "--out", out
    )
    assert status == 0, err
    assert "too_high" in err and "singular" in err and "never proposed" in err
    assert not {"too_high", "singular"} & set(read_poses(out, "XYZ")[1])
    # asking for more poses than are feasible fails, in one line
    status, _, err = run(
        capsys,
        "select",
        "--geometry",
        "paper-hmt",
        "--candidates",
        path,
        "--n",
        "65",
        "--out",
        tmp_path / "x.csv",
    )
    assert "only 64 feasible candidate pose(s) (2 infeasible left out)" in assert_one_error_line(status, err)
    assert not (tmp_path / "x.csv").exists()


def test_candidates_command(capsys, tmp_path):
    out = tmp_path / "cands.csv"
    status, stdout, err = run(
        capsys, "candidates", "--geometry", "paper-hmt", "--candidates", "edges", "--out", out
    )
    assert status == 0, err
    poses, ids = read_poses(out, "XYZ")
    assert len(poses) == 256 and ids[0] == "e000"
    assert "256 feasible of 256" in stdout


# -- observability -----------------------------------------------------------------------------


def test_observability_reports_indices_and_predictions(capsys, tmp_path, paper, corner_poses):
    poses, js = tmp_path / "poses.csv", tmp_path / "obs.json"
    write_poses(poses, corner_poses)
    status, stdout, err = run(
        capsys, "observability", "--geometry", "paper-hmt", "--poses", poses, "--json", js
    )
    assert status == 0, err
    assert "rank 42 of 42" in stdout and "O4 =" in stdout and "Cramér-Rao" in stdout
    data = json.loads(js.read_text())
    expected = analyse_poses(paper, corner_poses, test_poses=workspace_corners(paper))
    assert data["rank"] == 42 and data["unidentifiable"] == []
    assert_allclose(data["singular_values"], expected.indices.singular_values)
    for key in ("O1", "O2", "O3", "O4", "O5"):
        assert data[key] == pytest.approx(getattr(expected.indices, key))
    assert data["test_poses"]["n"] == 64
    # identify's default estimator, ml: its covariance is the Cramér–Rao bound
    assert data["parameters"]["l0_3"]["std_estimator"] == data["parameters"]["l0_3"]["std_bound"] > 0


def test_observability_options(capsys, tmp_path, corner_poses):
    poses, test, js = tmp_path / "poses.csv", tmp_path / "test.csv", tmp_path / "obs.json"
    write_poses(poses, corner_poses)
    write_poses(test, corner_poses[:3])
    status, _, err = run(
        capsys, "observability", "--geometry", "paper-hmt", "--poses", poses, "--json", js,
        "--fit", "joints,l0,gains", "--scaling", "parameter", "--weighted", "--test-poses", test,
        "--noise", "leg=0.002,pos=0.01,ang=0.0002", "--noise-dist", "normal", "--method", "paper",
    )  # fmt: skip
    assert status == 0, err
    data = json.loads(js.read_text())
    assert data["rank"] == 48 and data["scaling"] == "parameter" and data["weighted"]
    assert data["test_poses"]["n"] == 3
    assert data["noise"]["distribution"] == "normal" and data["noise"]["sigmas"][0] == 0.002
    assert "g6" in data["parameters"]


def test_observability_names_what_a_flat_pose_set_cannot_identify(capsys, tmp_path, flat_poses):
    js = tmp_path / "flat.json"
    status, stdout, err = run(
        capsys, "observability", "--geometry", "paper-hmt", "--poses", flat_poses, "--json", js
    )
    assert status == 0, err
    assert "rank 24 of 42" in stdout and "NOT identifiable" in stdout and "u1.x + s1.x" in stdout
    data = json.loads(js.read_text())
    assert data["rank"] == 24 and len(data["unidentifiable"]) == 18
    assert data["parameters"]["u1.x"]["std_estimator"] is None
    assert data["parameters"]["l0_1"]["std_estimator"] > 0
    assert data["predicted_mean_abs_error_mm"]["estimator"] is None


def test_observability_warns_about_infeasible_planned_poses(capsys, tmp_path, corner_poses):
    poses = tmp_path / "poses.csv"
    write_poses(poses, np.vstack([corner_poses, [[0, 0, 1100, 0, 0, 0]]]), [f"p{k}" for k in range(16)])
    status, stdout, err = run(capsys, "observability", "--geometry", "paper-hmt", "--poses", poses)
    assert status == 0
    assert err.startswith("hexcal: warning:") and "p15" in err and "upper limit" in err
    assert "rank 42 of 42" in stdout


def test_select_refuses_candidates_that_cannot_identify(capsys, tmp_path, flat_poses):
    out = tmp_path / "sel.csv"
    status, _, err = run(
        capsys, "select", "--geometry", "paper-hmt", "--candidates", flat_poses, "--n", "10", "--out", out
    )
    assert "rank 24 of 42" in assert_one_error_line(status, err)
    assert not out.exists()


# -- errormap -----------------------------------------------------------------------------------


def test_errormap_writes_figures_tables_and_claims(capsys, tmp_path):
    out = tmp_path / "maps"
    status, stdout, err = run(
        capsys, "errormap", "--geometry", "paper-hmt", "--out", out, "--levels", "4", "--points", "5",
        "--grid", "5", "--draws", "10",
    )  # fmt: skip
    assert status == 0, err
    names = listing(out)
    for fig in ("fig4_x", "fig5_y", "fig6_z", "fig7_a-b", "fig8_a-c", "fig9_b-c"):
        assert f"{fig}.png" in names
        assert (out / f"{fig}.png").read_bytes()[:8] == PNG_MAGIC
    table = read_table(out / "errormap_x.csv")
    assert len(table.rows) == 4 * 5
    assert {"x", "z", "position_mm", "orientation_rad", "level_z"} <= set(table.columns)
    assert len(read_table(out / "errormap_a-b.csv").rows) == 4 * 5 * 5
    assert read_poses(out / "errormap_corners.csv", "XYZ")[0].shape == (64, 6)
    data = json.loads((out / "claims.json").read_text())
    assert data["settings"]["levels"] == 4
    assert data["claims"]["lines"]["x"]["position"]["max_at_an_end"] == 1.0
    assert "Boundary claim" in stdout and "Height claim" in stdout
    assert not [n for n in names if n.endswith(".tmp") or ".tmp." in n]


# -- bad inputs -----------------------------------------------------------------------------------


@pytest.fixture
def no_workspace(tmp_path, paper) -> Path:
    data = paper.to_dict()
    del data["workspace"]
    path = tmp_path / "nowork.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["select", "--geometry", "paper-hmt", "--criterion", "G"], "--criterion"),
        (["select", "--geometry", "paper-hmt", "--n", "6"], "at least 7"),
        (["select", "--geometry", "paper-hmt", "--candidates", "corners", "--n", "65"], "only 64 feasible"),
        (["select", "--geometry", "paper-hmt", "--candidates", "faces"], "neither"),
        (["select", "--geometry", "paper-hmt", "--candidates", "random"], "needs a number"),
        (["select", "--geometry", "paper-hmt", "--candidates", "random:x"], "whole number"),
        (["select", "--geometry", "paper-hmt", "--candidates", "grid:1"], "at least 2"),
        (["select", "--geometry", "paper-hmt", "--candidates", "missing.csv"], "missing.csv"),
        (["select", "--geometry", "paper-hmt", "--strategy", "best"], "--strategy"),
        (["select", "--geometry", "paper-hmt", "--noise", "leg=-1"], "--noise"),
        (["select", "--geometry", "paper-hmt", "--fit", "joints,wheels"], "--fit"),
        (["select", "--geometry", "paper-hmt", "--min-distance", "-1"], "--min-distance"),
        (["select", "--geometry", "paper-hmt", "--strategy", "paper", "--n", "70"], "feasible corners"),
        (["select", "--geometry", "NOWORK", "--candidates", "corners"], "workspace"),
        (["select", "--geometry", "NOWORK", "--strategy", "paper"], "workspace"),
        (["select", "--geometry", "no-such.yaml"], "no-such.yaml"),
    ],
)
def test_select_bad_inputs(capsys, tmp_path, no_workspace, argv, needle):
    out = tmp_path / "sel.csv"
    argv = [str(no_workspace) if a == "NOWORK" else a for a in argv]
    before = listing(tmp_path)
    status, _, err = run(capsys, *argv, "--out", out)
    assert needle in assert_one_error_line(status, err)
    assert listing(tmp_path) == before


def test_select_output_folder_must_exist(capsys, tmp_path):
    status, _, err = run(capsys, "select", "--geometry", "paper-hmt", "--out", tmp_path / "nope" / "sel.csv")
    assert "does not exist" in assert_one_error_line(status, err)


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--scaling", "unit"], "--scaling"),
        (["--method", "gls"], "--method"),
        (["--noise-dist", "cauchy"], "--noise-dist"),
        (["--test-poses", "absent.csv"], "absent.csv"),
        (["--json", "nope/obs.json"], "does not exist"),
    ],
)
def test_observability_bad_inputs(capsys, tmp_path, corner_poses, extra, needle):
    poses = tmp_path / "poses.csv"
    write_poses(poses, corner_poses)
    before = listing(tmp_path)
    status, _, err = run(capsys, "observability", "--geometry", "paper-hmt", "--poses", poses, *extra)
    assert needle in assert_one_error_line(status, err)
    assert listing(tmp_path) == before


def test_observability_bad_pose_file(capsys, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,z,a,b\n1,2,3,4,5\n", encoding="utf-8")
    status, _, err = run(capsys, "observability", "--geometry", "paper-hmt", "--poses", bad)
    assert "bad.csv" in assert_one_error_line(status, err)


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--levels", "0"], "--levels"),
        (["--draws", "0"], "--draws"),
        (["--amplitude", "0"], "--amplitude"),
        (["--method", "cubic"], "--method"),
        (["--fit", "nothing"], "--fit"),
    ],
)
def test_errormap_bad_inputs(capsys, tmp_path, extra, needle):
    out = tmp_path / "maps"
    status, _, err = run(capsys, "errormap", "--geometry", "paper-hmt", "--out", out, *extra)
    assert needle in assert_one_error_line(status, err)
    assert not out.exists()


def test_errormap_refuses_a_file_as_folder_and_a_geometry_without_workspace(capsys, tmp_path, no_workspace):
    afile = tmp_path / "file.txt"
    afile.write_text("keep", encoding="utf-8")
    status, _, err = run(capsys, "errormap", "--geometry", "paper-hmt", "--out", afile)
    assert "not a folder" in assert_one_error_line(status, err)
    assert afile.read_text(encoding="utf-8") == "keep"
    out = tmp_path / "maps"
    status, _, err = run(capsys, "errormap", "--geometry", no_workspace, "--out", out)
    assert "workspace" in assert_one_error_line(status, err)
    assert not out.exists()
