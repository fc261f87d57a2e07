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
