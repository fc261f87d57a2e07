"""Leg models with covariates (issue 30): the thermal and compliance terms, the seam that
carries each pose's conditions to the leg equations, the geometry file form, and the
done-when figures (three sessions at 17, 21, 25 °C predict 30 °C; payloads; a warm-up).

The figures' campaigns are ``benchmarks/covariate_legs.py``'s (it prints them with the
linear model's beside): the seed paper's machine off by up to 1 mm, a precise full-pose
instrument (legs 1 µm, positions 2 µm, angles 1e-5 rad, uniform), 50 poses a session.
"""

from __future__ import annotations

import numpy as np
import pytest

from hexcal.calibration import validate
from hexcal.calibration.leg_model_choice import auto_candidates, fit_for, parse_leg_model, start_for
from hexcal.core import NoiseModel, compensate, pose_errors, preset, random_poses
from hexcal.core.covariate_legs import (
    KINDS,
    CovariateLegs,
    axial_forces,
    geometry_inputs,
)
from hexcal.core.kinematics import forward_with_covariates, inverse_kinematics, leg_lengths, leg_readings
from hexcal.core.legs import LEG_MODELS, LinearLegs
from hexcal.core.stroke_legs import StrokeLegs, with_leg_model
from hexcal.errors import InputError
from hexcal.estimation import Problem
from hexcal.instruments import Covariates, Session
from hexcal.io import load_geometry, save_geometry
from hexcal.simulation import constant_temperature, payload_cases, simulate_session, warm_up
from hexcal.workflow import calibrate

NOISE = NoiseModel(leg=0.001, position=0.002, orientation=1e-5)


def models() -> list[CovariateLegs]:
    stroke = StrokeLegs(3, np.zeros(6), np.full(6, 400.0))
    return [
        CovariateLegs(thermal=True),
        CovariateLegs(thermal=True, per_length=True, reference=22.5),
        CovariateLegs(compliance=True, platform_mass=12.0, platform_com=[1, 2, 30]),
        CovariateLegs(thermal=True, compliance=True),
        CovariateLegs(stroke, thermal=True),
        CovariateLegs(stroke, thermal=True, compliance=True, gravity=[0, -9.81, 0]),
    ]


def machine(model, seed: int = 0):
    rng = np.random.default_rng(seed)
    geometry = with_leg_model(preset("paper-hmt"), model)
    return geometry.replace(leg_terms=rng.normal(0.0, 1e-3, geometry.leg_terms.shape))


def inputs_for(model, m: int, rng) -> np.ndarray:
    """Random inputs: ΔT of a few kelvin, forces of some hundred newtons."""
    scale = {"dT": 5.0, "force": 300.0}
    return np.stack([rng.normal(0, scale[k], (m, 6)) for k in model.inputs], axis=-1)


def test_kinds_registered_and_named():
    assert set(KINDS) == {
        "thermal",
        "compliance",
        "thermal+compliance",
        "stroke+thermal",
        "stroke+compliance",
        "stroke+thermal+compliance",
    }
    assert all(LEG_MODELS[k] is CovariateLegs for k in KINDS)
    legs = CovariateLegs(StrokeLegs(2), thermal=True, compliance=True)
    assert legs.name == "stroke+thermal+compliance" and legs.terms == ("p2", "kt", "kc")
    assert list(legs.groups()) == ["l0", "gains", "stroke", "thermal", "compliance"]
    assert legs.covariates == ("temperatures", "payload_kg") and legs.inputs == ("dT", "force")
    # scales: 1 mm for a stroke term, 0.01 mm/K, 1e-4 mm/N
    np.testing.assert_array_equal(legs.term_scales(), [1.0, 0.01, 1e-4])
    assert CovariateLegs(thermal=True, per_length=True).terms == ("cte",)


@pytest.mark.parametrize("k", range(6))
def test_jacobian_matches_differences_and_inverse(k):
    model = models()[k]
    geometry = machine(model)
    block = geometry.leg_block()
    rng = np.random.default_rng(k)
    readings = rng.uniform(50.0, 350.0, (5, 6))
    inputs = inputs_for(model, 5, rng)
    jac = model.jacobian(block, readings, inputs)
    numeric = np.zeros_like(jac)
    for j in range(block.size):
        step = np.zeros(block.size)
        step[j] = 1e-6 * max(1.0, abs(block[j]))
        numeric[..., j] = (
            model.lengths(block + step, readings, inputs) - model.lengths(block - step, readings, inputs)
        ) / (2 * step[j])
    # central differences of a function at most quadratic in the parameters: exact to rounding
    np.testing.assert_allclose(jac, numeric, atol=1e-6)
    lengths = model.lengths(block, readings, inputs)
    np.testing.assert_allclose(model.readings(block, lengths, inputs), readings, atol=1e-9)


def test_terms_move_the_legs_as_documented():
    model = CovariateLegs(thermal=True, compliance=True)
    block = np.concatenate([np.full(6, 600.0), np.ones(6), np.full(6, 0.007), np.full(6, 2e-5)])
    inputs = np.stack([np.full((1, 6), 5.0), np.full((1, 6), 500.0)], axis=-1)
    # 600 + 100 + 0.007 mm/K * 5 K - 2e-5 mm/N * 500 N
    np.testing.assert_allclose(model.lengths(block, np.full((1, 6), 100.0), inputs), 700.025, atol=1e-12)
    # without inputs: the reference conditions, the base model alone
    np.testing.assert_allclose(model.lengths(block, np.full((1, 6), 100.0)), 700.0, atol=1e-12)
    expansion = CovariateLegs(thermal=True, per_length=True)
    block = np.concatenate([np.full(6, 600.0), np.ones(6), np.full(6, 1.2e-5)])
    np.testing.assert_allclose(
        expansion.lengths(block, np.full((1, 6), 100.0), np.full((1, 6, 1), 10.0)), 700.0 * (1 + 1.2e-4)
    )


def test_axial_forces_hold_the_weight():
    hmt = preset("paper-hmt")
    poses = random_poses(hmt, 20, 1)
    mass, com = 80.0, np.array([10.0, -20.0, 40.0])
    forces = axial_forces(hmt.base_joints, hmt.platform_joints, poses, hmt.euler, [(mass, com)])
    # the legs' forces along their unit vectors balance the weight and its moment about the origin
    from hexcal.core.kinematics import leg_vectors_from_arrays, rotation_matrices

    legs, rotated = leg_vectors_from_arrays(hmt.base_joints, hmt.platform_joints, poses, hmt.euler)
    unit = legs / np.linalg.norm(legs, axis=-1, keepdims=True)
    weight = mass * np.array([0.0, 0.0, -9.80665])
    arm = np.einsum("mjk,k->mj", rotation_matrices(poses[:, 3:], hmt.euler), com)
    np.testing.assert_allclose(
        np.einsum("mi,mij->mj", forces, unit), np.broadcast_to(-weight, (20, 3)), atol=1e-9
    )
    moment = np.einsum("mi,mij->mj", forces, np.cross(rotated, unit))
    np.testing.assert_allclose(moment, -np.cross(arm, weight), atol=1e-6)


@pytest.mark.parametrize("k", range(6))
def test_geometry_file_round_trip(tmp_path, k):
    geometry = machine(models()[k])
    save_geometry(geometry, tmp_path / "g.yaml")
    again = load_geometry(tmp_path / "g.yaml")
    assert again.leg_model == geometry.leg_model
    np.testing.assert_array_equal(again.machine_vector(), geometry.machine_vector())
    save_geometry(again, tmp_path / "again.yaml")
    assert (tmp_path / "again.yaml").read_text() == (tmp_path / "g.yaml").read_text()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("leg_model: {kind: warm}", "unknown kind 'warm'"),
        ("leg_model: {kind: thermal, terms: {kc: [1, 1, 1, 1, 1, 1]}}", "kc not terms of thermal"),
        ("leg_model: {kind: thermal, compliance: {platform_mass: 3}}", "no compliance term"),
        (
            "leg_model: {kind: compliance, compliance: {platform_mass: -3}}",
            "platform_mass: -3 kg is negative",
        ),
        ("leg_model: {kind: thermal, thermal: {reference: 300}}", "300 °C is not a plausible"),
        ("leg_model: {kind: thermal, degree: 3}", "degree and stroke belong to a kind with stroke"),
    ],
)
def test_bad_geometry_files_say_one_line(tmp_path, extra, message):
    save_geometry(preset("paper-hmt"), tmp_path / "g.yaml")
    with open(tmp_path / "g.yaml", "a") as f:
        f.write(extra + "\n")
    with pytest.raises(InputError, match=message):
        load_geometry(tmp_path / "g.yaml")


def test_missing_covariates_are_one_line():
    geometry = machine(CovariateLegs(thermal=True))
    poses = random_poses(geometry, 10, 0)
    with pytest.raises(InputError, match="the targets: the thermal leg model needs the legs' temperatures"):
        compensate(geometry, poses, covariates=Covariates(payload_kg=np.zeros(10)))
    plain = preset("paper-hmt")
    session = simulate_session(plain, plain, None, poses, NOISE, 0)  # no covariates
    with pytest.raises(InputError, match="session 1: the thermal leg model needs"):
        Problem(geometry, session)
    compliance = machine(CovariateLegs(compliance=True))
    with pytest.raises(InputError, match="payload's mass"):
        geometry_inputs(compliance, constant_temperature(10, 20.0), poses)


def test_without_covariate_terms_nothing_changes():
    """A model of readings sees no inputs, whatever the data carry: the same residuals."""
    nominal = preset("paper-hmt")
    poses = random_poses(nominal, 30, 2)
    plain = simulate_session(nominal, nominal, None, poses, NOISE, 3)
    carried = simulate_session(nominal, nominal, None, poses, NOISE, 3, covariates=warm_up(30, 20.0, 4.0))
    assert geometry_inputs(nominal, carried.instrument.covariates(carried.data), poses) is None
    a, b = Problem(nominal, plain), Problem(nominal, carried)
    assert a.inputs is None and b.inputs is None
    np.testing.assert_array_equal(a.leg_residuals(a.full0), b.leg_residuals(b.full0))


def test_kinematics_compensation_and_simulation_honour_the_conditions():
    geometry = machine(CovariateLegs(thermal=True, compliance=True, platform_mass=30.0))
    targets = random_poses(geometry, 15, 4)
    cov = payload_cases(15, [0.0, 60.0], [0, 0, 40], temperature=28.0)
    comp = compensate(geometry, targets, covariates=cov)
    cold = compensate(
        geometry, targets, covariates=payload_cases(15, [0.0, 60.0], [0, 0, 40], temperature=20.0)
    )
    # 8 K of a leg growing about 1 µm/K moves each reading by the growth (up to a few µm)
    assert np.abs(comp.readings - cold.readings).max() > 1e-3
    # the machine of the model, under the conditions, reaches the targets with these readings
    fk, inputs = forward_with_covariates(geometry, comp.readings, cov, targets)
    position, angle = pose_errors(targets, fk.poses, geometry.euler)
    assert position.max() < 1e-8 and angle.max() < 1e-10
    np.testing.assert_allclose(
        leg_lengths(geometry, comp.readings, inputs), inverse_kinematics(geometry, fk.poses), atol=1e-7
    )
    np.testing.assert_allclose(leg_readings(geometry, comp.lengths, inputs), comp.readings, atol=1e-6)


def test_names_and_candidates():
    assert parse_leg_model("thermal") == ("thermal", None)
    assert parse_leg_model("stroke+thermal") == ("stroke+thermal", 3)
    assert parse_leg_model("stroke:2+thermal+compliance") == ("stroke+thermal+compliance", 2)
    assert fit_for("joints,l0", CovariateLegs(StrokeLegs(2), thermal=True)) == "joints,l0,stroke,thermal"
    nominal = preset("paper-hmt")
    poses = random_poses(nominal, 12, 5)
    warm = simulate_session(
        nominal, nominal, None, poses, NOISE, 5, covariates=constant_temperature(12, 21.0)
    )
    plain = simulate_session(nominal, nominal, None, poses, NOISE, 5)
    assert auto_candidates([plain]) == ("linear", "stroke:2", "stroke:3", "stroke:4")
    assert auto_candidates([warm]) == (
        "linear",
        "stroke:2",
        "stroke:3",
        "stroke:4",
        "thermal",
        "stroke:3+thermal",
    )
    assert auto_candidates([warm, plain]) == auto_candidates([plain])  # every session must carry them
    start = start_for("stroke:2+thermal", nominal, [warm])
    assert start.leg_model.name == "stroke+thermal" and start.leg_model.base.degree == 2
    # the nominal's covariate settings are kept
    given = with_leg_model(nominal, CovariateLegs(compliance=True, platform_mass=25.0))
    assert start_for("thermal+compliance", given).leg_model.platform_mass == 25.0
    assert isinstance(start_for("linear", given).leg_model, LinearLegs)


# -- the done-when figures ----------------------------------------------------------------------
KT = np.linspace(0.006, 0.009, 6)  # mm/K: steel struts of about 600 mm
KC = np.linspace(2e-5, 4e-5, 6)  # mm/N


def true_machine(model, terms, seed: int = 1):
    nominal = preset("paper-hmt")
    rng = np.random.default_rng(seed)
    true = nominal.with_vector(nominal.to_vector() + rng.uniform(-1.0, 1.0, 42))
    return nominal, with_leg_model(true, model).replace(leg_terms=terms[:, None])


def sessions_at(nominal, true, conditions, seed: int) -> list[Session]:
    rng = np.random.default_rng(seed)
    out = []
    for k, cov in enumerate(conditions):
        poses = random_poses(nominal, len(cov), rng)
        ids = tuple(f"{k + 1}-{i + 1}" for i in range(len(cov)))
        out.append(
            simulate_session(nominal, true, None, poses, NOISE, rng, ids, cov).replace(label=f"s{k + 1}")
        )
    return out


def held_out(nominal, true, geometry, held, targets_cov, seed):
    """Held-out leg RMS of ``geometry`` and the largest position error of its compensation."""
    v = validate(geometry, held)
    targets = random_poses(nominal, len(targets_cov), np.random.default_rng(seed))
    comp = compensate(geometry, targets, covariates=targets_cov)
    fk, _ = forward_with_covariates(true, comp.readings, targets_cov, targets)
    position, _ = pose_errors(targets, fk.poses, nominal.euler)
    return float(np.sqrt(np.mean(v.leg_residuals**2))), float(position.max())


def test_thermal_model_predicts_and_compensates_outside_its_range():
    """Issue 30's first figure: 17, 21, 25 °C calibrate; 30 °C held out. The reference is the
    true machine (its held-out error is the noise alone); 1.3 is the issue's bound. With σ
    of 1 µm legs, 2 µm positions over 150 poses, kt is found to about 1e-5 mm/K (the
    benchmark: 0.0066 fitted for 0.0066 true), 1e-4 mm at 9 K beyond the mean: the
    compensation's 0.01 mm has a margin of five (the benchmark's largest error is 0.002 mm)."""
    nominal, true = true_machine(CovariateLegs(thermal=True), KT)
    train = sessions_at(nominal, true, [constant_temperature(50, t) for t in (17.0, 21.0, 25.0)], 2)
    fit = calibrate(nominal, train, leg_model="thermal").geometry
    np.testing.assert_allclose(fit.leg_terms[:, 0], KT, atol=3e-4)
    held = sessions_at(nominal, true, [constant_temperature(50, 30.0)], 3)[0]
    legs, worst = held_out(nominal, true, fit, held, constant_temperature(40, 30.0), 4)
    reference, _ = held_out(nominal, true, true, held, constant_temperature(40, 30.0), 4)
    assert legs <= 1.3 * reference
    assert worst <= 0.01


def test_payload_model_predicts_and_compensates_another_payload():
    """The same for a payload campaign: 0, 40, 80 kg calibrate (a 30 kg platform given); 120 kg
    held out."""
    model = CovariateLegs(compliance=True, platform_mass=30.0)
    nominal, true = true_machine(model, KC)
    nominal = with_leg_model(nominal, model)
    cases = [payload_cases(50, [m], [0, 0, 50]) for m in (0.0, 40.0, 80.0)]
    train = sessions_at(nominal, true, cases, 4)
    fit = calibrate(nominal, train, leg_model="compliance").geometry
    held = sessions_at(nominal, true, [payload_cases(50, [120.0], [0, 0, 50])], 5)[0]
    targets = payload_cases(40, [120.0], [0, 0, 50])
    legs, worst = held_out(nominal, true, fit, held, targets, 6)
    reference, _ = held_out(nominal, true, true, held, targets, 6)
    assert legs <= 1.3 * reference
    assert worst <= 0.01


def test_compliances_are_not_biased_by_a_nominal_machine_millimetres_off():
    """The axial forces are taken at a first fit's joints, not the nominal machine's: from the
    seed paper's nominal machine to its true one (joints and l0 several mm apart) the
    compliances came out biased by up to 6 standard errors (kc_2 3.6e-5 for 3.0e-5 mm/N) and
    120 kg was predicted at 3x the true model's error. Now each kc is within 4 of its standard
    errors (a two-sided 4σ bound: six of them fail by chance with probability 4e-4) and the
    held-out legs within the issue's 1.3x of the true machine's."""
    model = CovariateLegs(compliance=True, platform_mass=30.0)
    nominal = with_leg_model(preset("paper-hmt"), model)
    true = with_leg_model(preset("paper-hmt-true"), model).replace(leg_terms=KC[:, None])
    cases = [payload_cases(30, [m], [0, 0, 50]) for m in (0.0, 40.0, 80.0)]
    cal = calibrate(nominal, sessions_at(nominal, true, cases, 7), leg_model="compliance")
    names = [f"kc_{i}" for i in range(1, 7)]
    index = [cal.result.names.index(n) for n in names]
    error = cal.result.values[index] - KC
    assert np.all(np.abs(error) <= 4 * cal.result.stderr[index]), error / cal.result.stderr[index]
    held = sessions_at(nominal, true, [payload_cases(30, [120.0], [0, 0, 50])], 8)[0]
    targets = payload_cases(20, [120.0], [0, 0, 50])
    legs, _ = held_out(nominal, true, cal.geometry, held, targets, 9)
    reference, _ = held_out(nominal, true, true, held, targets, 9)
    assert legs <= 1.3 * reference


@pytest.mark.slow
def test_linear_legs_miss_what_the_covariate_models_reach():
    """The linear model's figures beside (benchmarks/covariate_legs.py prints them): it cannot
    follow 9 K beyond its sessions' mean (about 0.07 mm of leg)."""
    nominal, true = true_machine(CovariateLegs(thermal=True), KT)
    train = sessions_at(nominal, true, [constant_temperature(50, t) for t in (17.0, 21.0, 25.0)], 2)
    fit = calibrate(nominal, train, leg_model="linear").geometry
    held = sessions_at(nominal, true, [constant_temperature(50, 30.0)], 3)[0]
    legs, worst = held_out(nominal, true, fit, held, constant_temperature(40, 30.0), 4)
    reference, _ = held_out(nominal, true, true, held, constant_temperature(40, 30.0), 4)
    assert legs > 10 * reference and worst > 0.05


def test_a_warm_up_calibrated_with_its_temperatures_passes():
    """One session of 80 poses whose legs warm from 20 °C by about 6 K (each leg its share):
    with its temperatures (thermal) the verdict passes; with linear legs, the growth is a drift
    in acquisition order, and the verdict names it (the benchmark: fail, drift)."""
    nominal, true = true_machine(CovariateLegs(thermal=True), KT)
    cov = warm_up(80, 20.0, 6.0, legs=[1.0, 0.8, 1.2, 0.9, 1.1, 1.0])
    session = sessions_at(nominal, true, [cov], 6)
    warm = calibrate(nominal, session, leg_model="thermal").result.verdict
    assert warm.status == "pass", warm.codes()
    cold = calibrate(nominal, session, leg_model="linear").result.verdict
    assert "drift" in cold.codes("fail") + cold.codes("warn")
