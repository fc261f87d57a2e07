"""Every instrument, every default (issue 31): a command's defaults follow the instrument it is
given, and its messages describe the setup that was given."""

from __future__ import annotations

from pathlib import Path

from hexcal.estimation import get_estimator
from hexcal.simulation.study import DEFAULT_METHODS, default_methods
from instrument_campaigns import run

TRACKER = """units: mm
instrument_frame: {x: 2500, y: -800, z: 300, a_deg: 2, b_deg: -3, c_deg: 35}
targets:
  t1: [0, 0, 60]
  t2: [150, 20, 55]
  t3: [-40, 160, 70]
"""


def test_a_study_default_methods_are_those_the_instrument_allows(tmp_path: Path) -> None:
    """``simulate --setup TRACKER.yaml`` exited 1 with its default methods ("method paper: it
    needs the platform pose measured ... (frame auto)"), though the file gives the frame."""
    from hexcal.core import preset
    from hexcal.io import load_instrument
    from hexcal.simulation import instrument_campaign

    assert default_methods() == DEFAULT_METHODS
    (tmp_path / "tracker.yaml").write_text(TRACKER)
    tracker = instrument_campaign(load_instrument(tmp_path / "tracker.yaml", preset("paper-hmt").euler))
    assert default_methods(tracker) == ("ml",)
    assert all(not get_estimator(m).needs_pose for m in default_methods(tracker))
    done = run("simulate", "--setup", tmp_path / "tracker.yaml", "--trials", 2, "--poses", 8,
               "--strategies", "interior", "--quiet", "--jobs", 1)  # fmt: skip
    assert done.code == 0, done.err
    rows = [line.split() for line in done.out.splitlines() if line.strip().startswith("interior")]
    assert [r[3] for r in rows] == ["ml"]
    setup = tmp_path / "tracker.yaml"
    done = run("simulate", "--setup", setup, "--methods", "paper", "--trials", 2, "--quiet")
    assert done.code == 1 and "(frame free) does not give it; use ml" in done.err, done.err
    assert "frame auto" not in done.err


def test_a_study_of_too_many_poses_is_refused_before_it_starts() -> None:
    """``simulate --poses 5000000`` ran on (growing) until it was killed."""
    import pytest

    from hexcal.core import preset
    from hexcal.errors import InputError
    from hexcal.simulation import run_study

    with pytest.raises(InputError, match=r"^--poses: 5,000,000 poses in each of 1 trial\(s\) at once"):
        run_study(preset("paper-hmt"), pose_counts=(15, 5_000_000), trials=1)
