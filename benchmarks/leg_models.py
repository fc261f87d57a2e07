"""Leg models on a real machine: does the stroke model predict a held-out session better?

Run ``python benchmarks/leg_models.py [FOLDER]`` (default ``/tmp/jb``; it exits cleanly,
saying so, when the folder is absent). The folder holds a Jugglebot hexapod measured by motion
capture in two sessions: ``jugglebot.yaml`` (the design geometry; legs in motor revolutions,
gains in mm/rev), ``r2/mocap.yaml`` (the instrument: frame ``auto``, a tool) and
``session1_108_poses_hexcal.csv``, ``session2_60_poses_hexcal.csv``.

For each leg model (``linear``: the 48 parameters; ``stroke:2``, ``stroke:3``) and for
``auto`` (chosen by 5-fold cross-validation over the poses of the training session) it
identifies the machine on one session (joints, ``l0``, gains and the model's terms; noise
learned from the data) and validates it on the other, which re-registers the instrument's
frame and tool by 5-fold cross-validation (:func:`hexcal.calibration.validate`): the held-out
leg, position and orientation RMS. About a minute on one core.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from hexcal.calibration import estimate, validate
from hexcal.calibration.leg_model_choice import choose_leg_model, fit_for, start_for
from hexcal.instruments import Session, instrument_for
from hexcal.io import load_geometry, load_setup, read_measurements

SESSIONS = ("session1_108_poses_hexcal.csv", "session2_60_poses_hexcal.csv")
FIT = "joints,l0,gains"


def main(folder: Path) -> None:
    if not (folder / "jugglebot.yaml").exists():
        print(f"{folder}: no Jugglebot data here; nothing to measure")
        return
    nominal = load_geometry(folder / "jugglebot.yaml")
    setup = load_setup(folder / "r2" / "mocap.yaml").in_euler(nominal.euler)
    sessions = [
        Session(read_measurements(folder / f, nominal.euler), instrument_for(setup), f) for f in SESSIONS
    ]
    for train, held in ((sessions[0], sessions[1]), (sessions[1], sessions[0])):
        t = time.time()
        choice = choose_leg_model(nominal, [train], fit=FIT)
        print("\n".join(choice.lines()), f"({time.time() - t:.0f} s)")
        for spec in ("linear", "stroke:2", "stroke:3", f"auto ({choice.choice})"):
            model = choice.choice if spec.startswith("auto") else spec
            start = start_for(model, nominal, [train])
            fit = fit_for(FIT, start.leg_model)
            result = estimate(start, train, "ml", noise="auto", fit=fit, with_bound=False, verdict=False)
            s = validate(result.geometry, held).summary()
            print(
                f"fit on {train.label}, validate on {held.label}: {spec:<16} fit leg RMS "
                f"{result.leg_rms_after:.4f} mm; held-out leg {s['leg_rms']:.4f} mm, position "
                f"{s['position_rms']:.4f} mm, orientation {s['orientation_rms']:.5f} rad"
            )


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("/tmp/jb"))
