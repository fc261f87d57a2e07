"""Planning a campaign for a stroke-dependent leg model (issue 20, item 1): ``observability`` and
``select`` analyse the model's own terms through the identification Problem and say how much of
each leg's stroke the poses cover.

- the Problem path agrees with the classical 48-parameter analysis where both apply (linear legs,
  full pose, maximum likelihood): the same Cramér–Rao σ to 1e-6 relative;
- on a stroke geometry, observability ranks the 54 parameters of ``joints,l0,stroke`` (degree 3),
  reports the coverage computed by hand from the poses' readings, and poses that stay in a part of
  the stroke get a warning naming the legs and larger σ of the stroke terms;
- ``select`` chooses poses for the stroke terms and reports their coverage; ``--method length``
  on a stroke geometry is refused in one line.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexcal.cli.main import main
from hexcal.core import NoiseModel, inverse_kinematics, leg_readings, preset, workspace_corners
from hexcal.core.stroke_legs import StrokeLegs
from hexcal.design import analyse_poses
from hexcal.design.analysis import analyse_instrument
from hexcal.design.stroke_coverage import stroke_coverage
from hexcal.instruments import FullPoseModel
from hexcal.io import save_geometry

#: The seed paper's machine with its leg limits' stroke: readings 0 .. 495 mm ((limit - l0) / g).
STROKE = (np.zeros(6), np.full(6, 1100.0 - 604.8652))


def stroke_machine(degree: int = 3):
    machine = preset("paper-hmt")
    return machine.replace(leg_model=StrokeLegs(degree, *STROKE), leg_terms=np.zeros((6, degree - 1)))


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def test_the_problem_path_gives_the_classical_bound_for_linear_legs():
    machine = preset("paper-hmt")
    poses = workspace_corners(machine)[:20]
    noise = NoiseModel()
    classical = analyse_poses(machine, poses, noise, method="ml")
    generic = analyse_instrument(machine, FullPoseModel(), poses, noise)
    assert generic.names[: len(classical.names)] == classical.names
    np.testing.assert_allclose(generic.std_bound[: len(classical.names)], classical.std_bound, rtol=1e-6)
    assert "stroke_coverage" not in classical.to_dict()


def test_coverage_is_the_share_of_the_stroke_the_readings_span():
    machine = stroke_machine()
    poses = workspace_corners(machine)
    dl = leg_readings(machine, inverse_kinematics(machine, poses))
    cover = stroke_coverage(machine, poses)
    by_hand = (dl.max(axis=0) - dl.min(axis=0)) / (STROKE[1] - STROKE[0])  # every reading inside
    np.testing.assert_allclose(cover.covered, by_hand)
    assert np.all(cover.outside == 0) and cover.findings() == []
    # a narrower stroke than the readings: the part outside is counted, coverage capped at 1
    narrow = machine.replace(leg_model=StrokeLegs(3, dl.min(axis=0) + 10, dl.max(axis=0) - 10))
    tight = stroke_coverage(narrow, poses)
    assert np.all(tight.covered == 1.0) and np.all(tight.outside > 0)
    assert any("outside its stroke" in f for f in tight.findings())
    assert stroke_coverage(preset("paper-hmt"), poses) is None


def test_observability_of_a_stroke_geometry(capsys, tmp_path):
    machine = stroke_machine()
    geo = tmp_path / "stroke.yaml"
    save_geometry(machine, geo)
    status, _, _ = run(
        capsys, "candidates", "--geometry", geo, "--candidates", "grid", "--out", tmp_path / "c.csv"
    )
    assert status == 0
    status, out, err = run(
        capsys,
        "observability",
        "--geometry",
        geo,
        "--poses",
        tmp_path / "c.csv",
        "--json",
        tmp_path / "o.json",
    )
    assert status == 0, err
    data = json.loads((tmp_path / "o.json").read_text())
    assert data["n_parameters"] == 54 and data["rank"] == 54 and data["identifiable"]
    assert {f"p{k}_{leg}" for k in (2, 3) for leg in range(1, 7)} <= set(data["parameters"])
    assert "(joints,l0,stroke)" in out and "Stroke covered by the poses' readings" in out
    assert min(data["stroke_coverage"]["covered"]) > 0.5 and data["stroke_coverage"]["findings"] == []


def test_poses_in_part_of_the_stroke_are_named_and_leave_its_terms_poorly_determined():
    machine = stroke_machine()
    noise = NoiseModel()
    corners = workspace_corners(machine)
    wide = analyse_poses(machine, corners, noise, method="ml")
    low = corners[corners[:, 2] == corners[:, 2].min()].copy()  # the lower half of z only
    low[:, :2] *= 0.2  # and near the axis: each leg moves over a small part of its stroke
    narrow = analyse_poses(machine, low, noise, method="ml")
    findings = narrow.stroke.findings()
    assert len(findings) == 6 and all("add poses that extend this leg further" in f for f in findings)
    assert np.all(narrow.stroke.covered < 0.5) and np.all(wide.stroke.covered > 0.5)
    terms = [k for k, n in enumerate(wide.names) if n.startswith("p")]
    # σ of a Legendre term grows as the covered share shrinks (roughly as share^-k): far more than 3x
    assert np.all(narrow.std_bound[terms] > 3 * wide.std_bound[terms])


def test_select_for_a_stroke_geometry_and_length_refused(capsys, tmp_path):
    geo = tmp_path / "stroke.yaml"
    save_geometry(stroke_machine(), geo)
    status, out, err = run(
        capsys,
        "select",
        "--geometry",
        geo,
        "--candidates",
        "grid:3",
        "--n",
        25,
        "--out",
        tmp_path / "s.csv",
        "--json",
        tmp_path / "s.json",
    )
    assert status == 0, err
    data = json.loads((tmp_path / "s.json").read_text())
    assert len(data["ids"]) == 25 and "stroke_coverage" in data
    assert len(data["stroke_coverage"]["covered"]) == 6
    assert "Stroke covered by the poses' readings" in out
    status, out, err = run(
        capsys, "observability", "--geometry", geo, "--poses", tmp_path / "s.csv", "--method", "length"
    )
    assert status != 0 and len(err.strip().splitlines()) == 1
    assert "stroke leg model" in err and "ml" in err


@pytest.mark.parametrize("degree", [2, 4])
def test_degrees_add_their_terms(degree):
    machine = stroke_machine(degree)
    analysis = analyse_poses(machine, workspace_corners(machine), NoiseModel(), method="ml")
    assert len(analysis.names) == 42 + 6 * (degree - 1) and analysis.rank == len(analysis.names)
