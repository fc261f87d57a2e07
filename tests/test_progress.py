"""Progress of long commands (issue 31): library loops report through hexcal.core.progress,
silent unless a caller turns it on; the command line turns it on for a terminal (or
HEXCAL_PROGRESS=1), as lines on stderr after a few seconds. Clocks are the tests' own: no
test waits."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from hexcal.core.progress import reporting, task
from instrument_campaigns import run


def _clock(step: float = 10.0):
    """A clock that advances ``step`` seconds at each look: every step is past the delay."""
    return itertools.count(0.0, step).__next__


def test_tasks_are_silent_unless_reporting_is_on() -> None:
    with task("loop", 3) as step:
        for _ in range(3):
            step()  # nothing to see, nothing raised
    lines: list[str] = []
    with reporting(lines.append, delay=1.0, every=1.0, clock=_clock()):
        with task("outer", 2) as outer:
            with task("inner", 1) as inner:
                inner()
            outer(2)
    assert lines == [
        "hexcal: outer: inner: 1/1 (10 s)",
        "hexcal: outer: inner: done, 1/1 (20 s)",
        "hexcal: outer: 2/2 (40 s)",
        "hexcal: outer: done, 2/2 (50 s)",
    ]


def test_library_loops_report_through_it() -> None:
    """The ballbar selection, the pose selection and the Monte Carlo runner each say how far
    they are (with the caller's clock, every step is past the delay)."""
    from ballbar_cases import NOISE, SETUP, TILT
    from hexcal.core import preset
    from hexcal.design.ballbar_plan import ballbar_circles
    from hexcal.design.ballbar_selection import select_circles
    from hexcal.simulation import map_trials

    g = preset("paper-hmt")
    lines: list[str] = []
    with reporting(lines.append, delay=0.0, every=0.0, clock=_clock()):
        circles, _ = ballbar_circles(g, SETUP, np.array([[0, 0, 750.0]]), tilt=TILT, points=3)
        select_circles(g, circles, 6, NOISE)
        map_trials(_squares, 0, 4, chunk_size=2)
    assert "hexcal: circle plans: done, 12/12" in " ".join(lines)
    assert any(line.startswith("hexcal: trials: 2/4") for line in lines) and "trials: done, 4/4" in lines[-1]


def _squares(offset, idx):
    return {"value": idx**2 + offset}


@pytest.mark.parametrize(("env", "shown"), [("1", True), ("0", False)])
def test_the_command_line_turns_lines_on_for_a_terminal_or_when_asked(monkeypatch, tmp_path, env, shown):
    """Off for a pipe by default (the tests' stderr), on with HEXCAL_PROGRESS=1 (here with no
    delay), never with --quiet."""
    import argparse
    import contextlib

    from hexcal.cli import safety
    from hexcal.core import progress

    assert isinstance(safety.progress_lines(argparse.Namespace(quiet=True)), contextlib.nullcontext)
    monkeypatch.setenv(safety.PROGRESS_VARIABLE, env)
    monkeypatch.setattr(progress, "DEFAULT_DELAY", 0.0)
    monkeypatch.setattr(progress, "DEFAULT_EVERY", 0.0)
    bar = tmp_path / "bar.yaml"
    bar.write_text("units: mm\nballbar: {pivot: [0, 0, 750], ball: [0, 0, -50], length: 150}\n")
    done = run("select", "--geometry", "paper-hmt", "--ballbar", bar, "--pivots", "0,0,750", "--points", 3,
               "--circles", 6, "--out", tmp_path / "s.csv")  # fmt: skip
    assert done.code == 0, done.err
    assert ("hexcal: circle plans: done, 12/12" in done.err) is shown


def test_a_calibration_says_how_far_it_is():
    # the workflow's stages and the leg model's cross-validation fits, one line each with no
    # delay (the command line shows them after 3 s, every 5 s)
    import hexcal
    from hexcal.core.progress import reporting
    from hexcal.core.workspace import random_poses
    from hexcal.simulation import simulate_session

    nominal = hexcal.preset("paper-hmt")
    session = simulate_session(
        nominal, hexcal.preset("paper-hmt-true"), None, random_poses(nominal, 30, 1), rng=2
    )
    lines: list[str] = []
    with reporting(lines.append, delay=0.0, every=0.0):
        hexcal.calibrate(nominal, [session], leg_model="auto")
    fits = [line for line in lines if "leg model: cross-validation fits:" in line]
    assert fits and fits[-1].startswith("hexcal: calibration: leg model: cross-validation fits: done")
    assert lines[-1].startswith("hexcal: calibration: done")
