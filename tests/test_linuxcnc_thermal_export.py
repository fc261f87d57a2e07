"""``hexcal export linuxcnc`` of a geometry with a thermal leg model (issue 30): the run-time file
``hexcal-thermal.hal`` beside the others, its offsets the model's growth; a stroke+thermal model
writes the tables and the thermal file; a compliance term is refused in one line, nothing written."""

from __future__ import annotations

import re

import numpy as np
import pytest

from hexcal.cli import main
from hexcal.cli.linuxcnc import THERMAL_FILE
from hexcal.core import preset
from hexcal.core.covariate_legs import CovariateLegs
from hexcal.core.kinematics import leg_lengths
from hexcal.core.stroke_legs import StrokeLegs, with_leg_model
from hexcal.instruments import Covariates
from hexcal.io import save_geometry
from hexcal.io.linuxcnc import export_linuxcnc
from hexcal.io.linuxcnc_comp import COMP_FILES
from hexcal.io.linuxcnc_thermal import CANNOT_CARRY, THERMAL_HAL_FILE, thermal_offsets

KT = np.array([0.006, 0.0066, 0.0072, 0.0078, 0.0084, 0.009])
STROKE = np.random.default_rng(3).uniform(-0.2, 0.2, (6, 3))
READINGS = np.array([[0.0] * 6, [120.0, 90.0, 200.0, 10.0, 300.0, 250.0]])


def run(capsys, *argv):
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def thermal(reference: float = 20.0, stroke: bool = False, per_length: bool = False, compliance=False):
    nominal = preset("paper-hmt").replace(euler="xyz", name="warm")
    base = StrokeLegs(4, [20.0] * 6, [495.0] * 6) if stroke else None
    model = CovariateLegs(base, True, compliance, reference, per_length, platform_mass=20.0)
    coef = KT / 600.0 if per_length else KT
    rows = ([STROKE] if stroke else []) + [coef[:, None]] + ([np.full((6, 1), 3e-5)] if compliance else [])
    return with_leg_model(nominal, model).replace(leg_terms=np.hstack(rows))


def _file_coefficients(text: str):
    """alpha, kappa, T_ref of the thermal HAL file's setp lines (its ``scale`` components)."""
    setp = {m[1]: float(m[2]) for m in re.finditer(r"^setp (\S+) (\S+)$", text, re.M)}
    alpha = -np.array([setp[f"hexcal-thermal-coef-{n}.offset"] for n in range(6)])
    kappa = -np.array([setp[f"hexcal-thermal-coef-{n}.gain"] for n in range(6)])
    t_ref = {-setp[f"hexcal-thermal-dt-{n}.offset"] for n in range(6)}
    assert len(t_ref) == 1
    return alpha, kappa, t_ref.pop()


def _growth(geometry, temperature: float):
    """Each leg's growth (mm) at ``temperature`` over its length at the reference, by the model."""
    model = geometry.leg_model
    at = model.leg_inputs(Covariates(temperatures=np.full(len(READINGS), temperature)))
    ref = model.leg_inputs(Covariates(temperatures=np.full(len(READINGS), model.reference)))
    return leg_lengths(geometry, READINGS, at) - leg_lengths(geometry, READINGS, ref)


@pytest.mark.parametrize(("reference", "stroke"), [(20.0, False), (22.5, True)])
def test_the_files_offsets_are_the_models_growth(reference, stroke):
    """The file's coefficients, evaluated as the controller settles (thermal_offsets), take off
    each leg's growth by the model at 12, 27 and 41 °C (-growth: the drive goes shorter)."""
    geometry = thermal(reference, stroke)
    files = export_linuxcnc(geometry)
    alpha, kappa, t_ref = _file_coefficients(files[THERMAL_HAL_FILE])
    assert t_ref == reference and np.all(kappa == 0.0)
    for temperature in (12.0, 27.0, 41.0):
        offsets = thermal_offsets(alpha, t_ref, np.full((len(READINGS), 6), temperature))
        np.testing.assert_allclose(offsets, -_growth(geometry, temperature), rtol=0, atol=1e-12)


def test_growth_per_length_goes_through_the_joints_position():
    """``cte``: the file's kappa times the strut's commanded length is the model's growth times
    ``1 + cte ΔT`` (the commanded length includes the growth: the file is first order in
    ``cte ΔT``, 2e-4 here, a few 1e-5 mm on these legs)."""
    geometry = thermal(per_length=True)
    alpha, kappa, t_ref = _file_coefficients(export_linuxcnc(geometry)[THERMAL_HAL_FILE])
    assert np.all(alpha == 0.0)
    for temperature in (5.0, 35.0):
        grown = leg_lengths(geometry, READINGS, geometry.leg_model.leg_inputs(
            Covariates(temperatures=np.full(len(READINGS), temperature))))  # fmt: skip
        offsets = thermal_offsets(alpha, t_ref, np.full(grown.shape, temperature), grown, kappa)
        second = 1.0 + KT / 600.0 * (temperature - t_ref)
        np.testing.assert_allclose(offsets, -_growth(geometry, temperature) * second, rtol=1e-9, atol=1e-12)


def test_stroke_and_thermal_write_the_tables_of_the_reference_model_and_the_thermal_file():
    geometry = thermal(stroke=True)
    files = export_linuxcnc(geometry)
    assert set(files) >= {*COMP_FILES, THERMAL_HAL_FILE}
    stroke_only = geometry.replace(leg_model=geometry.leg_model.base, leg_terms=STROKE)
    plain = export_linuxcnc(stroke_only)
    assert all(files[name] == plain[name] for name in COMP_FILES)
    # the INI's joint values are the stroke model's (the thermal term is 0 at the reference)
    joints = re.findall(r"^(HOME_OFFSET|HOME) = .*$", files["hexcal-joints.ini"], re.M)
    assert joints and re.findall(r"^HOME_OFFSET = .*$", files["hexcal-joints.ini"], re.M) == re.findall(
        r"^HOME_OFFSET = .*$", plain["hexcal-joints.ini"], re.M
    )
    assert "reference temperature, 20.0 C" in files["hexcal-joints.ini"]


def test_command_writes_the_thermal_file_and_says_so(capsys, tmp_path):
    assert THERMAL_FILE == THERMAL_HAL_FILE
    save_geometry(thermal(stroke=True), tmp_path / "warm.yaml")
    status, out, _ = run(capsys, "export", "linuxcnc", "--geometry", tmp_path / "warm.yaml",
                         "--out", tmp_path / "per-leg")  # fmt: skip
    assert status == 0 and f"load {THERMAL_FILE}" in out and "hexcal-temp-0 .. hexcal-temp-5" in out
    written = sorted(p.name for p in (tmp_path / "per-leg").iterdir())
    assert written == sorted(["hexcal-kins.hal", "hexcal-joints.ini", *COMP_FILES, THERMAL_FILE])
    assert "net hexcal-temp-3 => hexcal-thermal-dt-3.in" in (tmp_path / "per-leg" / THERMAL_FILE).read_text()
    status, out, _ = run(capsys, "export", "linuxcnc", "--geometry", tmp_path / "warm.yaml",
                         "--out", tmp_path / "shared", "--shared-sensor")  # fmt: skip
    text = (tmp_path / "shared" / THERMAL_FILE).read_text()
    assert status == 0 and "drive hexcal-temp from" in out
    assert text.count("net hexcal-temp => hexcal-thermal-dt-") == 6 and "hexcal-temp-" not in text


def test_compliance_is_refused_in_one_line_and_nothing_is_written(capsys, tmp_path):
    save_geometry(thermal(stroke=True, compliance=True), tmp_path / "load.yaml")
    status, _, err = run(capsys, "export", "linuxcnc", "--geometry", tmp_path / "load.yaml",
                         "--out", tmp_path / "out")  # fmt: skip
    assert status == 1 and len(err.strip().splitlines()) == 1
    assert CANNOT_CARRY["compliance"] in err and "nothing was written" in err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
