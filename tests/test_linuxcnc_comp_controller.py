"""A stroke leg model in LinuxCNC itself: its joint compensation tables bring a machine with
ball-screw pitch errors to its targets (issue 20, item 2).

The simulated real machine is the seed paper's, whose legs carry pitch errors no gain describes:
per leg a slow trend (a bow of 0.1-0.25 mm over the stroke), a long periodic error (30-50 µm,
period 400 mm) and a short cyclic error of 2 µm at the 5 mm screw lead (which no smooth model
follows). 90 poses are measured with a tracker-like noise (legs 2 µm, positions 5 µm, angles
2e-5 rad, normal) and identified with the stroke model of degree 6; ``hexcal export linuxcnc``
writes its genhexkins HAL, the INI keys and six ``COMP_FILE`` tables. One headless LinuxCNC run
with the tables and one with the same export less its ``COMP_FILE`` lines move to 16 targets in
the workspace and 4 below it by MDI ``G0``; the 4 take legs beyond the calibrated stroke (by up
to 14 % of it), hence beyond the tables (issue 32). From the run:

- LinuxCNC's compensation (``joint.N.backlash-filt``) is the table's trim at the commanded joint
  position, and the motor command is the joint position plus it: the table's sign and meaning as
  LinuxCNC applies them;
- the machine's readings are the motor's travel from the home switch over the gain, with the
  trim LinuxCNC had at the switch when it homed (``HOME_OFFSET`` is the model's length at reading
  0); the simulated real machine's legs then have their true lengths, and its forward kinematics
  gives the pose it reaches.
- beyond the tables LinuxCNC holds their end trims, and the motor goes where hexcal's own
  inverse of the model (its curve held beyond the stroke) puts it: the same continuation.

Skipped, with the reason, where LinuxCNC is not installed.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

import linuxcnc_sim
from hexcal.calibration import estimate
from hexcal.core import NoiseModel, preset, random_poses, workspace_corners
from hexcal.core.kinematics import (
    forward_kinematics,
    inverse_kinematics,
    leg_lengths,
    leg_readings,
    pose_jacobian,
)
from hexcal.core.legs import LegModel
from hexcal.core.stroke_legs import StrokeLegs, with_leg_model
from hexcal.io.linuxcnc import HAL_FILE, INI_FILE, export_linuxcnc
from hexcal.io.linuxcnc_comp import COMP_FILES, TABLE_TOLERANCE
from hexcal.io.linuxcnc_import import parse_ini
from hexcal.simulation import simulate_measurements

NOISE = NoiseModel(leg=0.002, position=0.005, orientation=2e-5, distribution="normal")
DEGREE = 6
#: Per leg: the trend's bow (mm), the long periodic error's amplitude (mm) and phase.
BOW = np.array([0.10, -0.15, 0.25, -0.20, 0.12, 0.18])
WAVE = np.array([0.03, 0.05, 0.04, 0.035, 0.045, 0.03])
PHASE = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
CYCLIC = 0.002  # mm at the 5 mm lead
#: Targets below the workspace box (z 615-630 mm, readings 43-80 mm): legs beyond the stroke
#: of readings 81-97 to 476-490 mm that the measured poses and the other targets span.
BELOW = np.array(
    [
        [0.0, 0.0, 615.0, 0.0, 0.0, 0.0],
        [40.0, -30.0, 625.0, 0.05, -0.04, 0.03],
        [-50.0, 20.0, 630.0, -0.03, 0.05, -0.05],
        [20.0, 50.0, 620.0, 0.04, 0.03, 0.06],
    ]
)
INSIDE = slice(0, 16)  # the targets in the workspace box


class PitchLegs(LegModel):
    """The simulated machine's legs: ``l0 + g dl + e(dl)``, ``e`` the pitch error (no terms)."""

    name = "pitch-test"

    def _error(self, dl):
        x = dl / 250.0 - 1.0  # about -1 .. 1 over the stroke
        wave = WAVE * np.sin(2 * np.pi * dl / 400.0 + PHASE) + CYCLIC * np.sin(2 * np.pi * dl / 5.0)
        return BOW * (x**2 - 1.0 / 3.0) + wave, BOW * 2 * x / 250.0 + WAVE * 2 * np.pi / 400.0 * np.cos(
            2 * np.pi * dl / 400.0 + PHASE
        ) + CYCLIC * 2 * np.pi / 5.0 * np.cos(2 * np.pi * dl / 5.0)

    def length(self, theta, reading):
        return theta[..., 0] + theta[..., 1] * reading + self._error(reading)[0]

    def length_jacobian(self, theta, reading):
        one = np.ones(np.broadcast_shapes(theta.shape[:-1], np.shape(reading)))
        return np.stack([one, one * reading], axis=-1)

    def slope(self, theta, reading):
        return theta[..., 1] + self._error(reading)[1]


def _joint_ini(ini_text: str, with_tables: bool) -> dict[str, str]:
    ini = parse_ini(ini_text)
    out = {"TRAJ_HOME": ini.get("TRAJ", "HOME")[0]}
    for n in range(6):
        out[f"HOME_OFFSET_{n}"] = ini.get(f"JOINT_{n}", "HOME_OFFSET")[0]
        out[f"HOME_{n}"] = ini.get(f"JOINT_{n}", "HOME")[0]
        if with_tables:
            kind = ini.get(f"JOINT_{n}", "COMP_FILE_TYPE")[0]
            out[f"EXTRA_{n}"] = (
                f"COMP_FILE = {ini.get(f'JOINT_{n}', 'COMP_FILE')[0]}\nCOMP_FILE_TYPE = {kind}\n"
            )
    return out


@pytest.fixture(scope="module")
def scenario():
    reason = linuxcnc_sim.unavailable_reason()
    if reason:
        pytest.skip(reason)
    rng = np.random.default_rng(20)
    nominal = preset("paper-hmt").replace(euler="xyz")
    true = preset("paper-hmt-true").replace(euler="xyz", leg_model=PitchLegs())
    measured = np.vstack([workspace_corners(nominal), random_poses(nominal, 26, rng)])
    inside = np.vstack([random_poses(nominal, 12, rng), workspace_corners(nominal)[[0, 21, 42, 63]]])
    data = simulate_measurements(nominal, true, measured, NOISE, rng)
    every = np.vstack([data.readings, leg_readings(nominal, inverse_kinematics(nominal, inside))])
    targets = np.vstack([inside, BELOW])
    start = with_leg_model(nominal, StrokeLegs(DEGREE, every.min(axis=0), every.max(axis=0)))
    result = estimate(start, data, "ml", noise=NOISE, fit="joints,l0,gains,stroke", with_bound=False)
    calibrated = result.geometry.replace(name="calibrated", calibration=result.calibration_metadata())
    files = export_linuxcnc(calibrated)
    linear = estimate(nominal, data, "ml", noise=NOISE, fit="joints,l0,gains", with_bound=False).geometry
    linear_files = export_linuxcnc(linear)
    words = targets.copy()
    words[:, 3:] = np.rad2deg(words[:, 3:])
    runs = {}
    for with_tables in (True, False):
        workdir = Path(tempfile.mkdtemp(prefix="hexcal-linuxcnc-comp-"))
        try:
            run = linuxcnc_sim.run(
                workdir,
                [(files[HAL_FILE], words.tolist())],
                _joint_ini(files[INI_FILE], with_tables),
                timeout=90.0,
                files={name: files[name] for name in COMP_FILES} if with_tables else None,
            )
        finally:
            shutil.rmtree(workdir, ignore_errors=True)
        runs[with_tables] = run["batches"][0]
    workdir = Path(tempfile.mkdtemp(prefix="hexcal-linuxcnc-comp-"))
    try:  # the 48-parameter calibration of the same data: linear legs, no tables
        run = linuxcnc_sim.run(
            workdir, [(linear_files[HAL_FILE], words.tolist())], _joint_ini(linear_files[INI_FILE], False)
        )
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    runs["linear"] = run["batches"][0]
    return {
        "true": true,
        "calibrated": calibrated,
        "linear": linear,
        "targets": targets,
        "files": files,
        "runs": runs,
    }


def _table(files, n):
    rows = np.array([[float(v) for v in line.split()] for line in files[COMP_FILES[n]].splitlines()])
    return rows[:, 0], rows[:, 1]


def _reached(s, with_tables):
    """Poses the real machine reaches: readings from the motor's travel since homing."""
    rows = s["runs"][with_tables]
    cmd = np.array([r["joints_cmd"] for r in rows])
    comp = np.array([r["comp"] for r in rows])
    cal = s["calibrated"]
    home = leg_lengths(cal, np.zeros(6))  # HOME_OFFSET: the joint position at the switch
    trim_home = (
        np.array([np.interp(home[n], *_table(s["files"], n)) for n in range(6)]) if with_tables else 0.0
    )
    readings = (cmd + comp - home - trim_home) / cal.leg_gains
    result = forward_kinematics(s["true"], leg_lengths(s["true"], readings), guess=s["targets"])
    assert result.all_converged
    return result.poses


def test_linuxcnc_applies_the_table_with_its_sign(scenario):
    rows = scenario["runs"][True]
    cmd = np.array([r["joints_cmd"] for r in rows])
    comp = np.array([r["comp"] for r in rows])
    motor = np.array([r["motor_cmd"] for r in rows])
    expected = np.column_stack([np.interp(cmd[:, n], *_table(scenario["files"], n)) for n in range(6)])
    target = np.array([r["comp_target"] for r in rows])
    np.testing.assert_allclose(comp, target, rtol=0, atol=1e-9)  # the ramp has settled
    # the table's trim at the joint position: LinuxCNC keeps the trim of the last servo cycle in
    # motion, at most one cycle's travel before the target (a few mm at this test machine's speed),
    # where the tables' slopes (below 1e-3) make at most a few 1e-4 mm
    np.testing.assert_allclose(comp, expected, rtol=0, atol=5e-4)
    assert np.median(np.abs(comp - expected)) < 1e-5
    assert np.abs(comp).max() > 0.05  # tenths of a mm: the tables act
    offset = motor - cmd - comp  # LinuxCNC's motor offset of homing, the same at every target
    np.testing.assert_allclose(offset, offset[:1].repeat(len(offset), axis=0), rtol=0, atol=1e-9)
    assert np.all(np.array([r["comp"] for r in scenario["runs"][False]]) == 0)


def _hexcal_readings(s):
    """The readings hexcal's own inverse of the calibrated model gives the targets."""
    cal = s["calibrated"]
    return leg_readings(cal, inverse_kinematics(cal, s["targets"]))


def _linuxcnc_readings(s):
    """The readings the motors of the run with tables travelled to since homing."""
    rows = s["runs"][True]
    cmd = np.array([r["joints_cmd"] for r in rows])
    comp = np.array([r["comp"] for r in rows])
    cal = s["calibrated"]
    home = leg_lengths(cal, np.zeros(6))
    trim_home = np.array([np.interp(home[n], *_table(s["files"], n)) for n in range(6)])
    return (cmd + comp - home - trim_home) / cal.leg_gains


def test_beyond_its_tables_linuxcnc_continues_as_hexcal(scenario):
    """Issue 32: the joint positions of the 4 targets below the workspace lie before the tables'
    first entries, where LinuxCNC holds the first trim; hexcal's model holds its curve there, so
    the motors go where hexcal's inverse of the model puts them (no interpolation, no servo lag:
    the trim is constant there)."""
    s = scenario
    cal = s["calibrated"]
    rows = s["runs"][True]
    cmd = np.array([r["joints_cmd"] for r in rows])
    comp = np.array([r["comp"] for r in rows])
    first = np.array([_table(s["files"], n)[0][0] for n in range(6)])
    trims = np.array([_table(s["files"], n)[1][0] for n in range(6)])
    before = cmd < first  # (targets, legs) beyond the tables' low ends
    assert before[16:].all() and not before[INSIDE].any()
    readings = _hexcal_readings(s)
    low = cal.leg_model.stroke_range()[0]
    assert np.all((readings < low)[before])  # beyond the calibrated stroke, by up to:
    assert 0.08 < np.max((low - readings) / np.ptp(np.array(cal.leg_model.stroke_range()), axis=0)) < 0.2
    # to 1e-7 mm: the HAL pin of the trim reads with single precision here (5e-9 mm seen at trims
    # of 0.14 mm, 2^-24 relative)
    np.testing.assert_allclose(comp[before], np.broadcast_to(trims, comp.shape)[before], rtol=0, atol=1e-7)
    difference = (_linuxcnc_readings(s) - readings) * cal.leg_gains  # mm of leg
    np.testing.assert_allclose(difference[before], 0.0, rtol=0, atol=1e-7)


def test_tables_bring_the_real_machine_to_its_targets(scenario):
    s = scenario
    cal = s["calibrated"]
    # the legs: the motors' travel is hexcal's readings within the tables' interpolation error
    # (TABLE_TOLERANCE) and the trim of the last servo cycle in motion (below 5e-4 mm, above)
    difference = np.abs(_linuxcnc_readings(s) - _hexcal_readings(s)) * cal.leg_gains
    assert difference.max() <= TABLE_TOLERANCE + 5e-4
    reached = _reached(s, True)
    error = np.linalg.norm(reached[:, :3] - s["targets"][:, :3], axis=1)
    # hexcal's own commands for the calibrated model (its inverse, no table): the calibration's accuracy
    alone = forward_kinematics(
        s["true"], leg_lengths(s["true"], _hexcal_readings(s)), guess=s["targets"]
    ).poses
    alone_error = np.linalg.norm(alone[:, :3] - s["targets"][:, :3], axis=1)
    without = np.linalg.norm(_reached(s, False)[:, :3] - s["targets"][:, :3], axis=1)
    inside, below = error[INSIDE], error[16:]
    print(
        f"position error at 16 targets, max / rms (mm): LinuxCNC with tables {inside.max():.4f} / "
        f"{np.sqrt(np.mean(inside**2)):.4f}; hexcal alone {alone_error[INSIDE].max():.4f} / "
        f"{np.sqrt(np.mean(alone_error[INSIDE] ** 2)):.4f}; without tables {without[INSIDE].max():.4f} / "
        f"{np.sqrt(np.mean(without[INSIDE] ** 2)):.4f}; at the 4 below the workspace, with tables "
        f"{below.max():.4f}, hexcal alone {alone_error[16:].max():.4f}, without {without[16:].max():.4f}"
    )
    rows = s["runs"]["linear"]
    lin = s["linear"]
    joints = np.array([r["joints_cmd"] for r in rows])
    reached_linear = forward_kinematics(
        s["true"], leg_lengths(s["true"], leg_readings(lin, joints)), guess=s["targets"]
    ).poses
    linear = np.linalg.norm(reached_linear[:, :3] - s["targets"][:, :3], axis=1)
    print(
        f"48-parameter calibration (linear legs) in LinuxCNC: {linear[INSIDE].max():.4f} / "
        f"{np.sqrt(np.mean(linear[INSIDE] ** 2)):.4f}; below the workspace {linear[16:].max():.4f}"
    )
    # the poses: the leg differences through the inverse pose Jacobian (first order, exact enough
    # at a few µm)
    bound = np.linalg.norm(np.linalg.inv(pose_jacobian(cal, s["targets"]))[:, :3], ord=2, axis=(1, 2))
    assert np.all(np.abs(error - alone_error) <= bound * np.linalg.norm(difference, axis=1) + 1e-6)
    assert without[INSIDE].max() > 5 * inside.max()
    assert linear[INSIDE].max() > 3 * inside.max()
