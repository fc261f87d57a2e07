"""The extension seams: a new instrument and a new leg model, added in the tests only.

``toy_extensions`` writes a ball bar (one distance per observation between a base pivot and
a platform ball, its own six setup parameters, both frames gauge freedoms) and a quadratic
leg model (``l0 + g dl + q dl²``) on the public base classes and registers each by name
(one line each). Through the library's entry points only, with fixed seeds, this checks for
the toy instrument with the toy legs, the toy instrument with linear legs and the full pose
with the toy legs:

- identification (:func:`hexcal.calibration.estimate`) recovers the simulated truth (under
  the gauge convention) within five of the Cramér–Rao standard errors the result reports,
  and the whitened residuals have the variance the noise says;
- the bound at the estimate is the bound at the truth (:func:`hexcal.estimation.cramer_rao`);
- robust fitting leaves out one spoiled observation and only it;
- validation on held-out observations is at the noise level, the nominal machine far off;
- a small Monte Carlo study (:func:`hexcal.simulation.run_study`) attains the bound, and an
  estimator registered from outside (with no batched solver of its own) runs in it, one trial at
  a time, to the built-in one's numbers;
- the planning analysis (:func:`hexcal.design.analyse_poses`) sees the same rank.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from hexcal.calibration import estimate, validate
from hexcal.core import NoiseModel, preset, random_poses
from hexcal.core.geometry import Geometry
from hexcal.design import analyse_poses
from hexcal.errors import InputError
from hexcal.estimation import (
    ESTIMATORS,
    Estimator,
    Problem,
    apply_convention,
    cramer_rao,
    gauge_freedoms,
    register,
)
from hexcal.instruments import FullPoseModel, Measurements, Session, model_by_name
from hexcal.io import export_linuxcnc, load_geometry, read_sessions, save_geometry, write_session_data
from hexcal.simulation import STRATEGIES, instrument_campaign, run_study, simulate_session
from toy_extensions import BallBar, BarMeasurements, QuadraticLegs, registered

NOISE = NoiseModel(leg=0.001, position=0.001, orientation=1e-6, distribution="normal")
#: The two pivots of the ball bar's sessions (base frame) and its ball (platform frame), mm.
PIVOTS = ([120.0, 60.0, 20.0], [-150.0, -90.0, 10.0])
BALL = [10.0, -20.0, -30.0]
CASES = [("ballbar", "quadratic"), ("ballbar", "linear"), ("pose", "quadratic")]
FIT = {"linear": "joints,l0", "quadratic": "joints,l0,quadratic"}


@pytest.fixture(scope="module", autouse=True)
def toys():
    with registered():
        yield


def machines(legs: str) -> tuple[Geometry, Geometry]:
    """(nominal, true): the seed paper's machine with ``legs``; the truth's joints and ``l0``
    off by up to 1 mm and its quadratic terms by up to 2e-5 / mm."""
    nominal = preset("paper-hmt")
    if legs == "quadratic":
        nominal = nominal.replace(leg_model=QuadraticLegs(), leg_terms=np.zeros((6, 1)))
    rng = np.random.default_rng(5)
    vector = nominal.machine_vector()
    vector[:42] += rng.uniform(-1.0, 1.0, 42)
    vector[48:] += rng.uniform(-2e-5, 2e-5, vector.size - 48)
    return nominal, nominal.with_machine_vector(vector)


def instruments(kind: str) -> list[tuple]:
    """``(true, start)`` instrument of each session: two ball-bar pivots whose positions the
    start knows to about a millimetre, or the full pose."""
    if kind == "pose":
        return [(FullPoseModel(), FullPoseModel())]
    rng = np.random.default_rng(9)
    out = []
    for pivot in PIVOTS:
        start = BallBar(np.add(pivot, rng.uniform(-1, 1, 3)), np.add(BALL, rng.uniform(-1, 1, 3)))
        out.append((BallBar(pivot, BALL), start))
    return out


def sessions(nominal, true, kind, n, seed, start=True):
    """Simulated sessions of ``n`` random poses each, with the start (or true) instruments."""
    out = []
    for k, (inst, begin) in enumerate(instruments(kind)):
        poses = random_poses(nominal, n, seed + k)
        sim = simulate_session(nominal, true, inst, poses, NOISE, seed + 10 + k)
        out.append(Session(sim.data, begin if start else inst, f"session {k + 1}"))
    return out


@pytest.fixture(scope="module", params=CASES, ids=lambda c: "-".join(c))
def case(request, toys):
    kind, legs = request.param
    nominal, true = machines(legs)
    n = 40 if kind == "pose" else 100
    data = sessions(nominal, true, kind, n, 1)
    result = estimate(nominal, data, "ml", noise=NOISE, fit=FIT[legs])  # with the verdict
    problem = Problem(nominal, data, fit=FIT[legs])
    setups = [inst.parameters().values for inst, _ in instruments(kind)]
    full = np.concatenate([true.machine_vector(), *setups])
    gauge = gauge_freedoms(problem, problem.full0)
    truth = apply_convention(problem, full, gauge) if gauge.size else full
    return SimpleNamespace(
        kind=kind,
        legs=legs,
        nominal=nominal,
        true=true,
        data=data,
        result=result,
        problem=problem,
        truth=truth,
    )


def test_registered_by_name_and_in_files(toys, tmp_path):
    bar = model_by_name("toybar", PIVOTS[0], BALL)
    assert isinstance(bar, BallBar) and bar.parameters().names[0] == "pivot.x"
    nominal, true = machines("quadratic")
    assert "q_1" in nominal.machine_parameters("joints,l0,quadratic").free_names
    # a geometry file with the toy legs: leg_model: {kind: quadratic, q: [...]}
    save_geometry(true, tmp_path / "true.yaml")
    again = load_geometry(tmp_path / "true.yaml")
    assert isinstance(again.leg_model, QuadraticLegs)
    np.testing.assert_allclose(again.machine_vector(), true.machine_vector(), rtol=1e-14)
    with pytest.raises(InputError, match="quadratic model"):  # genhexkins struts are linear
        export_linuxcnc(true)
    # ball-bar data files through the io registry (READERS, WRITERS)
    data = sessions(nominal, true, "ballbar", 5, 1, start=False)
    paths = [tmp_path / f"bar{k}.csv" for k in range(len(data))]
    for path, session in zip(paths, data, strict=True):
        write_session_data(path, session, nominal.euler)
    read = read_sessions(paths, [s.instrument for s in data], nominal.euler)  # 15 digits written
    for got, session in zip(read, data, strict=True):
        assert got.instrument is session.instrument and got.ids == session.ids
        np.testing.assert_allclose(got.data.lengths, session.data.lengths, rtol=1e-14)
        np.testing.assert_allclose(got.data.readings, session.data.readings, rtol=1e-14)


def test_identify_recovers_the_truth_within_its_bound(case):
    c = case
    assert len(c.result.gauges) == (12 if c.kind == "ballbar" else 0)
    assert c.result.rank == len(c.result.names) - len(c.result.gauges)
    errors = (c.result.values - c.truth[c.problem.mask]) / c.result.bound
    assert np.abs(errors).max() < 5, c.result.names[int(np.argmax(np.abs(errors)))]
    # not vacuous: the start is many standard errors from the truth
    assert np.median(np.abs(c.result.start_values - c.truth[c.problem.mask]) / c.result.bound) > 5
    assert abs(c.result.reduced_chi2 - 1) < 5 * np.sqrt(2 / c.result.dof)
    assert c.result.verdict.status == "pass"


def test_bound_at_the_estimate_is_the_bound_at_the_truth(case):
    c = case
    at_truth = np.sqrt(np.diag(cramer_rao(c.problem, NOISE, c.truth)))
    np.testing.assert_allclose(c.result.bound, at_truth, rtol=0.05)


def spoiled(kind: str, session: Session, j: int) -> Session:
    """The session with observation ``j``'s instrument value 50 standard deviations off."""
    d = session.data
    if kind == "pose":
        poses = np.array(d.poses)
        poses[j, 0] += 0.05
        return session.replace(data=Measurements(poses, d.readings, d.ids))
    lengths = np.array(d.lengths)
    lengths[j] += 0.05
    return session.replace(data=BarMeasurements(d.readings, lengths, d.ids))


def test_robust_fitting_leaves_out_the_spoiled_observation(case):
    c = case
    j = 7
    bad = [spoiled(c.kind, c.data[0], j), *c.data[1:]]
    robust = estimate(c.nominal, bad, "ml", noise=NOISE, fit=FIT[c.legs], verdict=False, robust=True)
    label = c.data[0].ids[j] if len(c.data) == 1 else f"{c.data[0].label}:{c.data[0].ids[j]}"
    assert robust.outliers == (label,)
    assert robust.n_poses == c.result.n_poses - 1
    errors = (robust.values - c.truth[c.problem.mask]) / robust.bound
    assert np.abs(errors).max() < 5


def test_validation_on_held_out_observations(case):
    """Held-out errors are those of the calibration data themselves (noise through the forward
    kinematics), within a factor 2 (the RMS of 40 errors scatters by about 11 %), and the
    nominal machine's are more than 50 times larger."""
    c = case
    held = sessions(c.nominal, c.true, c.kind, 40, 50, start=False)[0]
    key = "position_rms" if c.kind == "pose" else "instrument_bar_rms"
    after = validate(c.result.geometry, Session(held.data, c.result.instruments[0])).summary()[key]
    inside = validate(c.result.geometry, Session(c.data[0].data, c.result.instruments[0])).summary()[key]
    before = validate(c.nominal, held).summary()[key]
    assert inside / 2 < after < 2 * inside
    assert before > 50 * after


def test_monte_carlo_study_attains_the_bound(case):
    """A study of the instrument and legs (the instrument's campaign; for the full pose the
    batched full-pose path): the mean absolute error of the joints and ``l0`` over the trials
    is the Cramér–Rao bound's within five standard errors of that mean."""
    c = case
    trials = 8
    cells = run_study(
        c.nominal,
        c.true,
        methods=("ml",),
        strategies={"interior": STRATEGIES["interior"]},
        pose_counts=(40 if c.kind == "pose" else 150,),
        noises={"toy": NOISE},
        trials=trials,
        rng=3,
        campaign=instrument_campaign(instruments(c.kind)[0][0], fit=FIT[c.legs]),
        fit=FIT[c.legs],
    )
    row = cells[0].row()
    assert row["failures"] == 0
    assert abs(row["error_mean"] - row["bound"]) < 5 * row["error_std"] / np.sqrt(trials)


def fit_toy_ml(problem, noise=None, **options):
    """A registered estimator of the tests' own (maximum likelihood under another name), which
    the batched solvers do not know."""
    from hexcal.estimation.likelihood import fit_ml

    return fit_ml(problem, noise, **options).replace(method="toy-ml")


def test_an_estimator_without_a_batched_solver_runs_in_studies():
    """A study of the toy ball bar with an estimator registered from outside: no trial fails for
    want of a batched solver (one at a time instead), and its numbers are the batched ``ml``'s
    (the same estimator) to the solvers' rounding."""
    nominal, true = machines("linear")
    register(
        Estimator("toy-ml", "maximum likelihood (a test's)", "whitened, 1", "test_extension:fit_toy_ml", True)
    )
    try:
        rows = {
            method: run_study(
                nominal,
                true,
                methods=(method,),
                strategies={"interior": STRATEGIES["interior"]},
                pose_counts=(150,),
                noises={"toy": NOISE},
                trials=3,
                rng=4,
                campaign=instrument_campaign(instruments("ballbar")[0][0]),
            )[0].row()
            for method in ("ml", "toy-ml")
        }
    finally:
        del ESTIMATORS["toy-ml"]
    assert rows["toy-ml"]["failures"] == 0 == rows["ml"]["failures"]
    for key in ("error_mean", "error_std", "bound", "position_rms"):
        assert abs(rows["toy-ml"][key] - rows["ml"][key]) <= 1e-9 * abs(rows["ml"][key]), key


def test_planning_sees_what_identification_sees(case):
    """The observability analysis of planned poses (design) has the identification's rank, for
    every instrument and leg model (a leg model with terms plans through the Problem)."""
    c = case
    mask = c.nominal.machine_parameters(FIT[c.legs]).vary
    instrument = c.data[0].instrument
    poses = random_poses(c.nominal, len(c.data[0]), 1)
    analysis = analyse_poses(c.nominal, poses, NOISE, mask, method="ml", instrument=instrument)
    assert analysis.rank == len(analysis.names) - len(c.result.gauges)
