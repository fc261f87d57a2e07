"""Issue 22 follow-ups, through the command line, for every instrument where it applies.

- absolute strut lengths (a controller's joint positions, LinuxCNC's genhexkins joints) given as
  readings ``dl``: ``identify`` ends in one line that names the file and says the readings look
  absolute (the fit re-read as ``dl - l0`` fits), nothing written; ``fk`` says the same of rows
  outside the leg limits whose ``dl`` are themselves within them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from instrument_campaigns import INSTRUMENTS, Campaigns, identify, run


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory: pytest.TempPathFactory) -> Campaigns:
    return Campaigns(tmp_path_factory.mktemp("followup"))


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("hexcal: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("kind", list(INSTRUMENTS))
def test_absolute_readings_are_named_for_every_instrument(kind, campaigns):
    data = campaigns.data(kind, "absolute")
    done, files = identify(campaigns, kind, data, f"{kind}-absolute")
    assert done.code == 1
    line = _one_line(done.err)
    assert "absolute strut lengths" in line and data.name in line and "HOME_OFFSET" in line
    assert not any(path.exists() for path in files.values())


def test_fk_says_readings_look_absolute(campaigns, tmp_path: Path):
    data = campaigns.data("pose", "absolute")
    done = run("fk", "--geometry", "paper-hmt", "--legs", data, "--out", tmp_path / "f.csv")
    assert done.code == 1 and "absolute strut lengths" in _one_line(done.err)
    assert not (tmp_path / "f.csv").exists()
