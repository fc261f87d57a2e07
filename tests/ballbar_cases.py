"""Ballbar campaigns shared by the tests and ``benchmarks/ballbar.py`` (one definition).

The campaign: a bar of 150 mm, its ball 50 mm under the platform's centre, candidate circles
of 12 points at the seven pivots of :func:`hexcal.design.ballbar_plan.pivot_grid` (planes
xy, xz and yz, the platform level or tilted by 8° about x or y, both feed directions), of
which :func:`hexcal.design.ballbar_selection.select_circles` chooses the calibration circles; the
held-out circles are the next best ones at the pivots chosen. The start knows the pivot and
the ball to about a millimetre and the bar's length to half a millimetre (seeded).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hexcal.calibration import estimate
from hexcal.core import NoiseModel, preset
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import forward_kinematics, leg_lengths
from hexcal.design.ballbar_plan import Circles, ballbar_circles
from hexcal.design.ballbar_selection import select_circles
from hexcal.estimation import Problem
from hexcal.estimation.uncertainty import cramer_rao
from hexcal.instruments import BallbarModel, BallbarSetup, Session
from hexcal.simulation import simulate_session
from tracker_cases import general_machines

#: Noise of the campaigns: legs σ 2 µm, the bar's reading σ 1 µm (normal).
NOISE = NoiseModel(leg=0.002, position=0.001, orientation=1e-6, distribution="normal")
QUIET = NoiseModel(leg=0.0, position=0.0, orientation=0.0, distribution="normal")
SETUP = BallbarSetup([0.0, 0.0, 0.0], [0.0, 0.0, -50.0], 150.0)
TILT = np.deg2rad(8.0)


def machines(kind: str) -> tuple[Geometry, Geometry]:
    """(nominal, true): ``paper`` (presets paper-hmt, paper-hmt-true) or ``general`` (an
    irregular 6-6 machine, ``tracker_cases.general_machines``)."""
    if kind == "paper":
        return preset("paper-hmt"), preset("paper-hmt-true")
    return general_machines()


@dataclass(frozen=True)
class Campaign:
    """Calibration and held-out circles, and the true and start instrument of each pivot."""

    nominal: Geometry
    true: Geometry
    circles: Circles
    held: Circles
    pivots: tuple[int, ...]
    true_bars: tuple[BallbarModel, ...]
    start_bars: tuple[BallbarModel, ...]


def campaign(kind: str, n_circles: int = 24, n_held: int = 6, seed: int = 5) -> Campaign:
    """The campaign of ``kind`` (see the module): ``n_circles`` chosen, ``n_held`` held out."""
    nominal, true = machines(kind)
    candidates, _ = ballbar_circles(nominal, SETUP, tilt=TILT, points=12)
    chosen = select_circles(nominal, candidates, n_circles + n_held, NOISE).chosen
    calib, held = chosen[:n_circles], chosen[n_circles:]
    pivots = tuple(int(p) for p in np.unique(candidates.pivot[calib]))
    held = np.array([c for c in held if candidates.pivot[c] in pivots], dtype=np.intp)
    rng = np.random.default_rng(seed)
    true_bars, start_bars = [], []
    for p in pivots:
        bar = candidates.instrument(p)
        true_bars.append(bar)
        s = bar.setup
        start_bars.append(
            BallbarModel(s.with_vector(s.vector() + np.r_[rng.uniform(-1, 1, 6), rng.uniform(-0.5, 0.5)]))
        )
    return Campaign(nominal, true, candidates.subset(calib), candidates.subset(held), pivots,
                    tuple(true_bars), tuple(start_bars))  # fmt: skip


def sessions(
    c: Campaign, circles: Circles, noise: NoiseModel, seed: int, start: bool = True
) -> list[Session]:
    """One simulated session per pivot of the campaign (its circles of ``circles``)."""
    out = []
    for k, p in enumerate(c.pivots):
        rows = np.isin(circles.circle, np.flatnonzero(circles.pivot == p))
        ids = tuple(circles.ids[r] for r in np.flatnonzero(rows))
        sim = simulate_session(c.nominal, c.true, c.true_bars[k], circles.poses[rows], noise, seed + k, ids)
        out.append(Session(sim.data, c.start_bars[k] if start else c.true_bars[k], f"pivot {p + 1}"))
    return out


def fit(c: Campaign, data: list[Session], noise: NoiseModel = NOISE, **options: Any) -> Any:
    """Maximum likelihood under the known noise (no verdict unless asked)."""
    return estimate(c.nominal, data, "ml", noise=noise, **{"verdict": False, "with_bound": False} | options)


def predict_d(geometry: Geometry, bars: list[Any], data: list[Session]) -> np.ndarray:
    """The bar readings of every session predicted from its leg readings (forward kinematics
    on ``geometry``, then the session's bar), concatenated; NaN where FK fails."""
    out = []
    home = geometry.home_pose if geometry.home_pose is not None else np.zeros(6)
    for bar, s in zip(bars, data, strict=True):
        fk = forward_kinematics(geometry, leg_lengths(geometry, s.data.readings), guess=home)
        d = bar.predict(bar.parameters().values, fk.poses, geometry.euler)[:, 0]
        out.append(np.where(fk.converged, d, np.nan))
    return np.concatenate(out)


def prediction_jacobian(problem: Problem, full: np.ndarray, held: list[Session]) -> np.ndarray:
    """d (held-out bar readings predicted) / d (varied parameters), central differences."""
    idx = np.flatnonzero(problem.mask)
    cols = []
    for k, s in zip(idx, problem.scale, strict=True):
        out = []
        for sign in (1, -1):
            f = full.copy()
            f[k] += sign * 1e-3 * s
            out.append(predict_d(problem.geometry(f), problem.instruments(f), held))
        cols.append((out[0] - out[1]) / (2e-3 * s))
    return np.array(cols).T


def monte_carlo(kind: str, trials: int, seed: int = 1000) -> dict[str, Any]:
    """Identify ``trials`` noisy campaigns; the held-out circles' bar readings predicted from
    the (noise-free) leg readings against their true values, beside the Cramér–Rao prediction
    of that error (the bound at the truth through the prediction's Jacobian).

    Returns the per-trial mean squared prediction errors ``ms`` (mm²), the predicted mean
    square ``bound`` (mm²), their ratio ``ratio`` (RMS over predicted RMS), its Monte Carlo
    standard error ``ratio_se`` and the failed trials."""
    c = campaign(kind)
    held = sessions(c, c.held, QUIET, 7, start=False)
    truth = sessions(c, c.circles, QUIET, 9, start=False)  # noise-free: the bound at the truth
    true_problem = Problem(c.true, truth)
    cov = cramer_rao(true_problem, NOISE)
    kmat = prediction_jacobian(true_problem, true_problem.full0, held)
    bound = float(np.trace(kmat @ cov @ kmat.T) / kmat.shape[0])
    actual = np.concatenate([s.data.d for s in held])
    ms, failed = [], 0
    for trial in range(trials):
        try:
            result = fit(c, sessions(c, c.circles, NOISE, seed + 10 * trial))
        except Exception:  # counted, reported by the caller
            failed += 1
            continue
        ms.append(float(np.nanmean((predict_d(result.geometry, result.instruments, held) - actual) ** 2)))
    ms_arr = np.array(ms)
    ratio = float(np.sqrt(ms_arr.mean() / bound))
    se = float(ms_arr.std(ddof=1) / np.sqrt(len(ms_arr)) / ms_arr.mean() / 2 * ratio)
    return {"kind": kind, "ms": ms_arr, "bound": bound, "ratio": ratio, "ratio_se": se, "failed": failed,
            "circles": c.circles.n_circles, "held": c.held.n_circles, "pivots": len(c.pivots),
            "parameters": true_problem.n_free}  # fmt: skip
