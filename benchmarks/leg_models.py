"""Leg models on a real machine: how each predicts a held-out session, on its stroke and beyond.

Run ``python benchmarks/leg_models.py`` (minutes; ``auto`` is the longest). The data are the
Jugglebot's two motion-capture sessions in ``tests/data/jugglebot`` (``jugglebot.yaml``, the
design geometry, legs in motor revolutions; ``mocap.yaml``, the instrument: frame ``auto``, a
tool). Session 2 covers a narrower stroke than session 1. The design geometry's workspace is
widened to what session 1 reached (x, y ±340 mm, z 600-850 mm, a, b ±16°, c ±12°), so that the
predicted accuracy of a fit on session 2 reaches beyond its stroke (issue 32).

For each leg model (``linear``: the 48 parameters; ``stroke:2`` to ``stroke:4``) and for
``auto`` (chosen by cross-validation on the training session: folds over its poses and the
ends of each leg's stroke) it identifies the machine on one session (joints, ``l0``, gains and
the model's terms; noise learned from the data) and validates it on the other, which
re-registers the instrument's frame and tool by 5-fold cross-validation
(:func:`hexcal.calibration.validate`): the held-out leg, position and orientation RMS, and how
many of the held-out poses take a leg beyond the training session's stroke.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from hexcal.calibration import estimate, validate
from hexcal.calibration.leg_model_choice import choose_leg_model, fit_for, start_for
from hexcal.core import stroke_excess
from hexcal.io import load_geometry, read_sessions

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "jugglebot"
SESSIONS = ("session1_108_poses.csv", "session2_60_poses.csv")
FIT = "joints,l0,gains"
#: x, y, z (mm), a, b, c (rad): what session 1 reached.
WIDE = np.array([[-340, 340], [-340, 340], [600, 850], *np.radians([[-16, 16], [-16, 16], [-12, 12]])])


def main() -> None:
    nominal = load_geometry(DATA / "jugglebot.yaml")
    nominal = nominal.replace(workspace=WIDE)
    sessions = read_sessions([DATA / f for f in SESSIONS], [DATA / "mocap.yaml"], nominal.euler)
    for train, held in ((sessions[0], sessions[1]), (sessions[1], sessions[0])):
        t = time.time()
        choice = choose_leg_model(nominal, [train], fit=FIT)
        print("\n".join(choice.lines()), f"({time.time() - t:.0f} s)")
        for spec in ("linear", "stroke:2", "stroke:3", "stroke:4", f"auto ({choice.choice})"):
            model = choice.choice if spec.startswith("auto") else spec
            start = start_for(model, nominal, [train])
            fit = fit_for(FIT, start.leg_model)
            result = estimate(start, train, "ml", noise="auto", fit=fit, with_bound=False, verdict=False)
            s = validate(result.geometry, held).summary()
            beyond = stroke_excess(result.geometry, held.instrument.readings(held.data))
            where = (
                f"; {beyond.flagged_rows} of {beyond.rows} held-out poses beyond its stroke" if beyond else ""
            )
            print(
                f"fit on {train.label}, validate on {held.label}: {spec:<16} fit leg RMS "
                f"{result.leg_rms_after:.4f} mm; held-out leg {s['leg_rms']:.4f} mm, position "
                f"{s['position_rms']:.4f} mm, orientation {s['orientation_rms']:.5f} rad{where}"
            )


if __name__ == "__main__":
    main()
