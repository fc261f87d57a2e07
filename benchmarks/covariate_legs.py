"""Legs that grow with temperature and give under load: the figures of issue 30.

Run ``python benchmarks/covariate_legs.py`` (a few minutes). Simulated on the seed paper's
machine (``paper-hmt``): a true machine whose joints and initial lengths are off the nominal by
up to 1 mm (uniform, seeded), measured by a precise full-pose instrument (legs 1 µm, positions
2 µm, angles 1e-5 rad, uniform), 50 random poses a session.

- **thermal**: each true leg grows by ``kt_i`` (mm/K; 0.006 to 0.009, steel struts of about
  600 mm) above 20 °C. Three sessions at 17, 21 and 25 °C are calibrated with linear legs and
  with the thermal model (``joints,l0,thermal``), and each predicts 50 held-out poses at 30 °C
  (:func:`hexcal.calibration.validate`); the reference is the true machine itself, whose
  held-out error is the measurement noise alone. Then each compensates 40 targets at 30 °C
  (:func:`hexcal.core.compensate` with the targets' temperature) and the true machine at
  30 °C goes where its legs take it: the largest position error.
- **payload**: each true leg gives ``kc_i`` (mm/N; 2e-5 to 4e-5) under its axial force, the
  weight of a 30 kg platform and of payloads of 0, 40 and 80 kg; held out at 120 kg.
- **warm-up**: one session whose legs warm from 20 °C by 6 K (each leg its own share)
  calibrated with its temperatures (``thermal``) and without (linear legs): the verdict.
"""

from __future__ import annotations

import time

import numpy as np

from hexcal.calibration import validate
from hexcal.core import NoiseModel, compensate, pose_errors, preset, random_poses
from hexcal.core.covariate_legs import CovariateLegs
from hexcal.core.kinematics import forward_with_covariates
from hexcal.core.stroke_legs import with_leg_model
from hexcal.simulation import constant_temperature, payload_cases, simulate_session, warm_up
from hexcal.workflow import calibrate

NOISE = NoiseModel(leg=0.001, position=0.002, orientation=1e-5)
POSES = 50
PLATFORM_KG = 30.0


def true_machine(model: CovariateLegs, terms: np.ndarray, seed: int = 1):
    """The nominal and the true machine (joints and l0 off by up to 1 mm, the model's terms)."""
    nominal = preset("paper-hmt")
    rng = np.random.default_rng(seed)
    true = nominal.with_vector(nominal.to_vector() + rng.uniform(-1.0, 1.0, 42))
    return nominal, with_leg_model(true, model).replace(leg_terms=terms[:, None])


def sessions_at(nominal, true, conditions, seed: int):
    """One simulated session per covariates of ``conditions``."""
    rng = np.random.default_rng(seed)
    out = []
    for k, cov in enumerate(conditions):
        poses = random_poses(nominal, len(cov), rng)
        ids = tuple(f"{k + 1}-{i + 1}" for i in range(len(cov)))
        out.append(
            simulate_session(nominal, true, None, poses, NOISE, rng, ids, cov).replace(label=f"s{k + 1}")
        )
    return out


def held_out_figures(nominal, true, geometries: dict, held_cov, targets_cov, seed: int) -> None:
    """Held-out leg and position RMS of each geometry, and its compensation's largest error."""
    held = sessions_at(nominal, true, [held_cov], seed)[0]
    targets = random_poses(nominal, len(targets_cov), np.random.default_rng(seed + 1))
    for name, geometry in geometries.items():
        v = validate(geometry, held)
        comp = compensate(geometry, targets, covariates=targets_cov)
        fk, _ = forward_with_covariates(true, comp.readings, targets_cov, targets, "targets")
        position, _ = pose_errors(targets, fk.poses, nominal.euler)
        print(
            f"  {name:<10} held-out leg RMS {np.sqrt(np.mean(v.leg_residuals**2)):.4f} mm, position RMS "
            f"{np.sqrt(np.mean(v.position_error**2)):.4f} mm; compensation: largest position error "
            f"{position.max():.4f} mm (RMS {np.sqrt(np.mean(position**2)):.4f})"
        )


def thermal() -> None:
    kt = np.linspace(0.006, 0.009, 6)
    nominal, true = true_machine(CovariateLegs(thermal=True), kt)
    train = sessions_at(nominal, true, [constant_temperature(POSES, t) for t in (17.0, 21.0, 25.0)], 2)
    fits = {}
    for spec, fit in (("linear", "joints,l0"), ("thermal", "joints,l0,thermal")):
        t = time.time()
        fits[spec] = calibrate(nominal, train, leg_model=spec, fit=fit).geometry
        print(f"thermal: {spec} fitted at 17, 21, 25 °C ({time.time() - t:.0f} s)")
    fits["true"] = true
    print(f"  kt fitted {np.round(fits['thermal'].leg_terms[:, 0], 5).tolist()}, true {kt.round(5).tolist()}")
    print("held out at 30 °C:")
    held_out_figures(
        nominal, true, fits, constant_temperature(POSES, 30.0), constant_temperature(40, 30.0), 3
    )


def payload() -> None:
    kc = np.linspace(2e-5, 4e-5, 6)
    model = CovariateLegs(compliance=True, platform_mass=PLATFORM_KG)
    nominal, true = true_machine(model, kc)
    nominal = with_leg_model(nominal, model)
    train = sessions_at(nominal, true, [payload_cases(POSES, [m], [0, 0, 50]) for m in (0.0, 40.0, 80.0)], 4)
    fits = {}
    for spec, fit in (("linear", "joints,l0"), ("compliance", "joints,l0,compliance")):
        t = time.time()
        fits[spec] = calibrate(nominal, train, leg_model=spec, fit=fit).geometry
        print(f"payload: {spec} fitted at 0, 40, 80 kg ({time.time() - t:.0f} s)")
    fits["true"] = true
    print(
        f"  kc fitted {np.round(fits['compliance'].leg_terms[:, 0], 7).tolist()}, true {kc.round(7).tolist()}"
    )
    print("held out at 120 kg:")
    held_out_figures(
        nominal,
        true,
        fits,
        payload_cases(POSES, [120.0], [0, 0, 50]),
        payload_cases(40, [120.0], [0, 0, 50]),
        5,
    )


def warming() -> None:
    kt = np.linspace(0.006, 0.009, 6)
    nominal, true = true_machine(CovariateLegs(thermal=True), kt)
    cov = warm_up(80, 20.0, 6.0, legs=[1.0, 0.8, 1.2, 0.9, 1.1, 1.0])
    session = sessions_at(nominal, true, [cov], 6)
    for spec, fit in (("linear", "joints,l0"), ("thermal", "joints,l0,thermal")):
        cal = calibrate(nominal, session, leg_model=spec, fit=fit)
        reasons = [f"{r.code} ({r.severity})" for r in cal.result.verdict.reasons if r.severity != "info"]
        said = ", ".join(reasons) or "no warning"
        print(f"warm-up 20 -> 26 °C, {spec}: verdict {cal.result.verdict.status}; {said}")


def main() -> None:
    thermal()
    payload()
    warming()


if __name__ == "__main__":
    main()
