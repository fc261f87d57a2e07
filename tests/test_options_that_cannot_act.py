"""Options that cannot act are refused in one line, before any work, never ignored (issue 31):
the docs say so, and a user who gives ``--points`` believes the circles have that many points."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hexcal.calibration.validation import check_folds
from hexcal.core import preset, workspace_corners
from hexcal.errors import ValidationError
from hexcal.instruments import FullPoseModel
from instrument_campaigns import run


@pytest.mark.parametrize(
    ("command", "option", "value"),
    [
        ("candidates", "--points", "5"),
        ("candidates", "--pivots", "0,0,700"),
        ("candidates", "--tilt", "3"),
        ("candidates", "--d0", "1"),
        ("candidates", "--planes", "xy"),
        ("select", "--circles", "5"),
    ],
)
def test_ballbar_options_without_ballbar_are_refused(tmp_path: Path, command: str, option: str, value: str):
    """``candidates --points 5`` wrote the 728 workspace poses and exited 0."""
    out = tmp_path / "c.csv"
    done = run(command, "--geometry", "paper-hmt", option, value, "--out", out)
    assert done.code == 1 and not out.exists()
    line = f"hexcal: error: {option} acts only with --ballbar; give --ballbar, or leave {option} out\n"
    assert done.err == line


def test_folds_with_nothing_to_re_register_are_refused_by_the_library(tmp_path: Path) -> None:
    """``validate --folds 3`` of a full-pose session (nothing to re-register, so no fold is
    drawn) was accepted and ignored; the library says so, the command line passes it."""
    g = preset("paper-hmt")
    poses = workspace_corners(g)[:20]
    check_folds(poses, FullPoseModel(), None)  # not given: always fine
    with pytest.raises(ValidationError, match=r"^--folds 3: full pose in the base frame has nothing to"):
        check_folds(poses, FullPoseModel(), 3)
    (tmp_path / "p.csv").write_text("x,y,z,a,b,c\n" + "\n".join(",".join(map(str, p)) for p in poses) + "\n")
    done = run("synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true",
               "--poses", tmp_path / "p.csv", "--out", tmp_path / "m.csv")  # fmt: skip
    assert done.code == 0, done.err
    done = run("validate", "--geometry", "paper-hmt-true", "--data", tmp_path / "m.csv", "--folds", 3,
               "--out", tmp_path / "v.csv")  # fmt: skip
    assert done.code == 1 and "--folds 3: full pose in the base frame has nothing to re-register" in done.err
    assert not (tmp_path / "v.csv").exists()
    done = run("validate", "--geometry", "paper-hmt-true", "--data", tmp_path / "m.csv")
    assert done.code == 0 and np.isfinite(float(done.out.split("leg residual RMS (mm)")[1].split()[0]))


def test_a_leg_model_whose_terms_are_all_held_at_zero_is_refused(tmp_path: Path) -> None:
    """``identify --leg-model stroke --fix stroke`` wrote a stroke model with every term 0: the
    linear legs under another name. Holding some terms, or terms already calibrated, is fine."""
    from hexcal.core.stroke_legs import StrokeLegs
    from hexcal.errors import UsageError
    from hexcal.estimation import Problem
    from hexcal.instruments import Measurements

    g = preset("paper-hmt")
    stroke = g.replace(leg_model=StrokeLegs(3, [0.0] * 6, [495.0] * 6), leg_terms=np.zeros((6, 2)))
    poses = workspace_corners(g)[:20]
    data = Measurements(poses, np.full((20, 6), 100.0))
    with pytest.raises(UsageError, match=r"^--fix holds every term of the stroke leg model at 0"):
        Problem(stroke, data, FullPoseModel(), fit="joints,l0,stroke", fix=("stroke",))
    Problem(stroke, data, FullPoseModel(), fit="joints,l0,stroke", fix=("p2_1",))  # some terms: fine
    calibrated = stroke.replace(leg_terms=np.full((6, 2), 0.01))
    Problem(calibrated, data, FullPoseModel(), fit="joints,l0,stroke", fix=("stroke",))  # held as found
    (tmp_path / "p.csv").write_text("x,y,z,a,b,c\n" + "\n".join(",".join(map(str, p)) for p in poses) + "\n")
    assert run("synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true",
               "--poses", tmp_path / "p.csv", "--out", tmp_path / "m.csv").code == 0  # fmt: skip
    done = run("identify", "--geometry", "paper-hmt", "--data", tmp_path / "m.csv", "--leg-model", "stroke",
               "--fix", "stroke", "--out", tmp_path / "g.yaml")  # fmt: skip
    assert done.code == 1 and "every term of the stroke leg model at 0" in done.err
    assert not (tmp_path / "g.yaml").exists()
