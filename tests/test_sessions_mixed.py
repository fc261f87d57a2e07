"""One calibration from sessions of different instruments (issue "Real campaigns", item 1):
a laser-tracker session (three targets, its own frame) and a 6-DOF probe session (a tool, a frame
of its own), the machine shared. Through the library and the command line."""

from __future__ import annotations

import numpy as np

from hexcal.calibration import estimate, validate
from hexcal.cli.main import main
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.instruments import Session, instrument_for
from hexcal.instruments.setup import Setup
from hexcal.io import load_setup, save_setup_dict, write_session_data
from tracker_cases import TARGETS3, poses, simulate

NOISE = NoiseModel(leg=0.005, position=0.015, orientation=5e-5, distribution="normal")
TRACKER = Setup(np.array([2500.0, -800.0, 300.0, 0.03, -0.05, 0.6]), TARGETS3)
PROBE = Setup(np.array([-1200.0, 1500.0, 200.0, 0.1, 0.2, -2.0]), tool=[10.0, -20.0, 80.0, 0.1, 0.0, 0.5])


def _campaign():
    nominal, true = preset("paper-hmt"), preset("paper-hmt-true")
    tracker = simulate(nominal, true, TRACKER, poses(nominal, 30, 1), NOISE, 0.0, 2)
    probe = simulate(nominal, true, PROBE, poses(nominal, 30, 3), NOISE, 0.0, 4)
    starts = (Setup(None, {k: np.array(v) + 1.0 for k, v in TARGETS3.items()}),
              Setup(None, tool=[11.0, -19.0, 79.0, 0.1, 0.0, 0.5]))  # fmt: skip
    return nominal, true, tracker, probe, starts


def test_a_tracker_and_a_probe_session_calibrate_one_machine():
    nominal, true, tracker, probe, (t_start, p_start) = _campaign()
    sessions = [Session(tracker, instrument_for(t_start)), Session(probe, instrument_for(p_start))]
    both = estimate(nominal, sessions, "ml", noise=NOISE, fit="joints,l0")
    assert both.verdict.status != "fail", [r.message for r in both.verdict.reasons]
    # each session its own instrument, the noise groups per session
    assert [i.name for i in both.instruments] == ["targets", "tool"]
    # 6 base gauges (the two frames move with it) + 6 platform ones (targets and tool with it):
    # a second free frame adds none, the data tie it to the machine
    assert len(both.gauges) == 12
    # one machine predicts a third session (the probe set up again) at the noise level
    moved = Setup(PROBE.frame + [30.0, -20.0, 10.0, 0.0, 0.02, 0.1], tool=PROBE.tool)
    held = simulate(nominal, true, moved, poses(nominal, 30, 9), None, 0.0, 5)
    check = validate(both.geometry, Session(held, instrument_for(Setup(None, tool=PROBE.tool))), noise=NOISE)
    assert check.summary()["leg_rms"] < 10 * NOISE.sigmas[0]
    one = estimate(nominal, sessions[1:], "ml", noise=NOISE, fit="joints,l0", verdict=False)
    # the two sessions together determine the machine better than the probe alone
    assert np.median(both.stderr[:42]) < np.median(one.stderr[:42])


def test_cli_pairs_data_and_setups_and_writes_a_setup_per_session(tmp_path, capsys):
    nominal, _, tracker, probe, (t_start, p_start) = _campaign()
    files = []
    for name, data, start in (("tracker", tracker, t_start), ("probe", probe, p_start)):
        inst = instrument_for(TRACKER if name == "tracker" else PROBE)
        write_session_data(tmp_path / f"{name}.csv", Session(data, inst), nominal.euler)
        save_setup_dict(
            instrument_for(start).setup_dict() | {"instrument_frame": "auto"}, tmp_path / f"{name}.yaml"
        )
        files += ["--data", tmp_path / f"{name}.csv", "--setup", tmp_path / f"{name}.yaml"]
    args = [
        "identify",
        "--geometry",
        "paper-hmt",
        *files,
        "--noise",
        "leg=0.005,pos=0.015,ang=5e-5",
        "--noise-dist",
        "normal",
        "--out",
        tmp_path / "cal.yaml",
        "--setup-out",
        tmp_path / "setups",
    ]
    assert main([str(a) for a in args]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "tracker.csv" in out and "probe.csv" in out
    written = sorted(p.name for p in (tmp_path / "setups").iterdir())
    assert len(written) == 2, written
    kinds = {load_setup(tmp_path / "setups" / name).kind for name in written}
    assert kinds == {"targets", "tool"}
