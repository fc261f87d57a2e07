"""The ISO tests of ``validate`` against the validation that feeds them, timed in one run.

``python benchmarks/iso.py [--quick]`` simulates (seeded) a ball-bar circle of 7,200 points
(two runs of 3,600, the toy ball bar of ``tests/toy_extensions.py``, pivot and ball fixed) and
a full-pose session of 2,000 commanded poses visited 5 times each (10,000 observations) on the
seed paper's machine, then times, best of 5:

- ``iso230_4``: :func:`hexcal.calibration.circular_tests` of the circle's validation, against
  :func:`hexcal.calibration.validate` of the same session (the baseline);
- ``iso9283``: :func:`hexcal.calibration.pose_tests` (grouping the visits included), against
  ``validate`` of the visits.

It prints each as seconds and as the ratio ISO / validate: the ISO figures should cost a small
fraction of the validation they are computed from (target <= 0.2). ``--quick`` uses a tenth
of the sizes (a smoke run, figures not judged).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse
import sys
import time
from pathlib import Path

TARGET = 0.2


def best(fn, repeats: int = 5) -> float:
    """The best wall time of ``repeats`` calls, seconds."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    import numpy as np

    from hexcal.calibration import circular_tests, pose_tests, validate
    from hexcal.core import NoiseModel, preset, random_poses
    from hexcal.instruments import FullPoseModel
    from hexcal.simulation import simulate_session
    from toy_extensions import BallBar

    scale = 10 if args.quick else 1
    noise = NoiseModel(leg=0.001, position=0.001, orientation=1e-6, distribution="normal")
    nominal = preset("paper-hmt")
    true = nominal.with_machine_vector(
        nominal.machine_vector() + np.r_[np.random.default_rng(5).uniform(-0.5, 0.5, 42), np.zeros(6)]
    )
    n = 3600 // scale
    t = np.r_[np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(2 * np.pi, 0, n, endpoint=False)]
    poses = np.zeros((2 * n, 6))
    poses[:, 0], poses[:, 1], poses[:, 2] = 150 * np.cos(t), 150 * np.sin(t), 800.0
    bar = BallBar([0, 0, 700.0], [0, 0, -100.0], fixed=("pivot", "ball"))
    circle = simulate_session(nominal, true, bar, poses, noise, 3)
    visits = simulate_session(
        nominal, true, FullPoseModel(), np.tile(random_poses(nominal, 2000 // scale, 7), (5, 1)), noise, 4
    )
    rows = []
    for name, session, iso in (
        ("iso230_4", circle, lambda r, s: circular_tests(s, {"nominal": r})),
        ("iso9283", visits, lambda r, s: pose_tests(s, {"nominal": r})),
    ):
        result = validate(nominal, session)
        base = best(lambda s=session: validate(nominal, s))
        own = best(lambda r=result, s=session, f=iso: f(r, s))
        rows.append((name, len(session), own, base))
    for name, m, own, base in rows:
        ratio = own / base
        verdict = "smoke" if args.quick else ("PASS" if ratio <= TARGET else "MISS")
        print(f"{name:>9}: {m} observations, ISO {own:.4f} s, validate {base:.4f} s, "
              f"ratio {ratio:.3f} (target <= {TARGET}) {verdict}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
