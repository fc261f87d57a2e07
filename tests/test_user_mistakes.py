"""Mistakes a user makes, diagnosed in one line naming the likely cause (issue 31): swapped
leg or target columns, swapped position columns, a file all in metres, a tracker file given
without its setup. Each campaign: the seed paper's machines, 30 poses selected for the full
pose, the paper's noise (``hexcal synthesize``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hexcal.calibration.diagnosis import likely_cause_first
from hexcal.calibration.reasons import Reason
from instrument_campaigns import read_csv, run, write_csv

TRACKER = """units: mm
instrument_frame: {x: 2500, y: -800, z: 300, a_deg: 2, b_deg: -3, c_deg: 35}
targets:
  t1: [0, 0, 60]
  t2: [150, 20, 55]
  t3: [-40, 160, 70]
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("mistakes")
    (folder / "tracker.yaml").write_text(TRACKER)
    assert run("select", "--geometry", "paper-hmt", "--n", 30, "--out", folder / "poses.csv").code == 0
    for setup, out in ((None, "pose.csv"), (folder / "tracker.yaml", "targets.csv")):
        extra = ["--setup", setup] if setup else []
        done = run("synthesize", "--nominal", "paper-hmt", "--true", "paper-hmt-true",
                   "--poses", folder / "poses.csv", "--noise", "leg=0.01,pos=0.025,ang=0.001", *extra,
                   "--out", folder / out)  # fmt: skip
        assert done.code == 0, done.err
    return folder


def _swapped(source: Path, target: Path, pairs) -> Path:
    comments, header, body = read_csv(source)
    for a, b in pairs:
        i, j = header.index(a), header.index(b)
        header[i], header[j] = header[j], header[i]
    write_csv(target, comments, header, body)
    return target


def _identify(data: Path, *extra) -> str:
    out = data.with_suffix(".yaml")
    done = run("identify", "--geometry", "paper-hmt", "--data", data, *extra, "--out", out)
    assert done.code == 1 and not data.with_suffix(".yaml").exists()
    return done.out + done.err


def test_swapped_leg_columns_are_named(files: Path) -> None:
    """Today: "8 parameter(s) changed beyond 25%: u2.x +433, u1.x -431" and nothing else."""
    text = _identify(_swapped(files / "pose.csv", files / "legs.csv", [("dl1", "dl2")]))
    assert "the leg columns dl1 and dl2 look swapped in the data" in text


@pytest.mark.slow  # fast representative: test_swapped_leg_columns_are_named (one diagnosis of pairs)
def test_swapped_target_columns_are_named(files: Path) -> None:
    data = _swapped(files / "targets.csv", files / "t12.csv", [(f"t1.{a}", f"t2.{a}") for a in "xyz"])
    text = _identify(data, "--setup", files / "tracker.yaml")
    assert "the target columns t1 and t2 look swapped in the data" in text


def test_swapped_position_columns_are_named(files: Path) -> None:
    """Today: leg σ 3.8e+17, a predicted RMS of 3.9e+18 mm and another Euler sequence."""
    text = _identify(_swapped(files / "pose.csv", files / "xy.csv", [("x", "y")]))
    assert "the pose columns x and y look swapped: with them exchanged the residual RMS falls" in text


def test_a_file_all_in_metres_legs_included_is_named(files: Path) -> None:
    """Today: "the solver did not converge ... not determined"."""
    comments, header, body = read_csv(files / "pose.csv")
    for row in body:
        for c in ("x", "y", "z", "dl1", "dl2", "dl3", "dl4", "dl5", "dl6"):
            row[header.index(c)] = repr(float(row[header.index(c)]) / 1000)
    write_csv(files / "metres.csv", comments, header, body)
    assert "everything looks like metres, the leg readings included" in _identify(files / "metres.csv")


def test_a_tracker_file_without_its_setup_is_named(files: Path) -> None:
    """Today: "missing orientation columns: give a, b, c"."""
    data = files / "targets.csv"
    done = run("identify", "--geometry", "paper-hmt", "--data", data, "--out", files / "x.yaml")
    assert done.code == 1 and done.err.count("\n") == 1
    assert "targets.csv: the file looks like target positions (t1.x/y/z, t2.x/y/z, t3.x/y/z), not poses: " \
        "--setup is missing" in done.err  # fmt: skip


def test_the_likely_cause_reads_first() -> None:
    """Radians in ``_deg`` columns: the diagnosis came after about ten "not determined" lines,
    its consequences (the verdict orders its reasons through this)."""
    found = [Reason("not-determined", "fail", "x"), Reason("parameter-change", "fail", "y"),
             Reason("angle-units-degrees", "fail", "z")]  # fmt: skip
    order = [r.code for r in likely_cause_first(found)]
    assert order == ["angle-units-degrees", "not-determined", "parameter-change"]
