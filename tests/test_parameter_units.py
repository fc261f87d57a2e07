"""Every parameter carries its unit from where it is made, and the reports and the verdict use it.

The machine's blocks (:mod:`hexcal.core.parameters`, a leg model's :meth:`term_units`), an
instrument's setup (its frame's angles in rad) and a leg model from outside (the toy quadratic
model of ``toy_extensions``, its term in 1/mm) each set their parameters' units; a calibration
reports in them (``Calibration.units``, the ``units`` of its dictionary), and the text and HTML
renderers read the unit from that dictionary, never from the name: a parameter named
``toy.tilt`` held in rad is shown in degrees, one held in ``mm/K`` passes through as it is.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from hexcal import calibrate
from hexcal.calibration.verdict import change_limits, parameter_limits
from hexcal.core import NoiseModel, preset, random_poses
from hexcal.instruments import BallbarSetup, Session, Setup, instrument_for
from hexcal.report import identification_text
from hexcal.report.calibration_pages import identification_page, parameter_rows
from hexcal.simulation import simulate_session
from toy_extensions import QuadraticLegs, registered

NOISE = NoiseModel(leg=0.001, position=0.001, orientation=1e-5, distribution="normal")
FRAME = {"x": 5.0, "y": -3.0, "z": 2.0, "a": 0.02, "b": -0.01, "c": 0.03}
TOOL = {"x": 0.0, "y": 0.0, "z": 40.0, "a": 0.0, "b": 0.0, "c": 0.0}


def test_units_are_set_where_the_parameters_are_made():
    machine = preset("paper-hmt").machine_parameters("joints,l0,gains")
    assert machine["u1.x"].unit == "mm" and machine["l0_1"].unit == "mm" and machine["g1"].unit == "1"
    tool = Setup.from_dict({"units": "mm", "instrument_frame": FRAME, "tool": TOOL}).parameters()
    assert tool.unit_of()["frame.a"] == "rad" and tool.unit_of()["frame.x"] == "mm"
    assert tool.unit_of()["tool.c"] == "rad" and tool.unit_of()["tool.z"] == "mm"
    bar = BallbarSetup.from_dict(
        {"units": "mm", "ballbar": {"pivot": [0, 0, 700], "ball": [0, 0, -50], "length": 150.0}}
    )
    assert set(bar.parameters().units) == {"mm"}
    with registered():  # a leg model from outside says its own term's unit
        legs = preset("paper-hmt").replace(leg_model=QuadraticLegs(), leg_terms=np.zeros((6, 1)))
        own = legs.machine_parameters("joints,l0,quadratic")
    assert own.unit_of()["q_3"] == "1/mm" and own.unit_of()["g3"] == "1"
    # units follow every copy: selection, sum, new values, a session's prefix, the dictionary
    both = own.select("l0,quadratic") + tool.renamed("session2.")
    assert both.unit_of()["session2.frame.b"] == "rad" and both.with_values(both.values)["q_1"].unit == "1/mm"
    assert both.free_units[-1] == "rad" and both.to_dict()["q_6"]["unit"] == "1/mm"


@pytest.fixture(scope="module")
def calibration():
    """A calibration of the quadratic legs from one session of a tool on a frame (all varied)."""
    with registered():
        nominal = preset("paper-hmt").replace(leg_model=QuadraticLegs(), leg_terms=np.zeros((6, 1)))
        vector = nominal.machine_vector()
        vector[:42] += np.random.default_rng(3).uniform(-0.5, 0.5, 42)
        true = nominal.with_machine_vector(vector)
        setup = Setup.from_dict({"units": "mm", "instrument_frame": FRAME, "tool": TOOL})
        poses = random_poses(nominal, 60, 11)
        sim = simulate_session(nominal, true, instrument_for(setup), poses, NOISE, 12)
        start = Setup.from_dict({"units": "mm", "instrument_frame": "auto", "tool": TOOL})
        session = Session(sim.data, instrument_for(start), "tool")
        yield calibrate(nominal, session, noise=NOISE, fit="joints,l0,quadratic")


def test_a_calibration_reports_each_parameter_in_its_makers_unit(calibration):
    units = calibration.units
    assert units["frame.a"] == "rad" and units["tool.z"] == "mm" and units["q_2"] == "1/mm"
    assert units["u1.x"] == "mm"
    data = calibration.to_dict()
    assert {n: data["units"][n] for n in data["names"]} == units
    text = _parameter_table(identification_text(data))
    frame_a = next(line for line in text if line.split()[:1] == ["frame.a"])
    shown = [float(v) for v in frame_a.split()[1:3]]  # nominal and identified, in degrees
    assert frame_a.endswith("deg")
    assert shown[1] == pytest.approx(math.degrees(data["parameters"]["frame.a"]), abs=1e-6)
    q = next(line for line in text if line.split()[:1] == ["q_2"])
    assert q.endswith("1/mm") and float(q.split()[2]) == pytest.approx(data["parameters"]["q_2"], abs=1e-6)


def _parameter_table(text: str) -> list[str]:
    """The lines of the text report's parameter table (the setup's own section comes before)."""
    lines = text.splitlines()
    return lines[lines.index("[[Parameters]]") :]


def _with_toy_parameters(data: dict) -> dict:
    """The dictionary with two parameters whose names say nothing of their units: ``toy.tilt``
    held in rad (0.01) and ``toy.k`` held in mm/K (0.0115, a steel leg's expansion per kelvin)."""
    out = copy.deepcopy(data)
    out["names"] = [*out["names"], "toy.tilt", "toy.k"]
    for key, tilt, k in (("start", 0.0, 0.0), ("parameters", 0.01, 0.0115), ("stderr", 1e-4, 2e-4)):
        out[key] |= {"toy.tilt": tilt, "toy.k": k}
    if out.get("bound"):
        out["bound"] |= {"toy.tilt": 1e-4, "toy.k": 2e-4}
    out["units"] |= {"toy.tilt": "rad", "toy.k": "mm/K"}
    return out


def test_rad_is_shown_in_degrees_and_a_unit_of_its_own_passes_through(calibration):
    data = _with_toy_parameters(calibration.to_dict())
    lines = _parameter_table(identification_text(data))
    tilt = next(line for line in lines if line.split()[:1] == ["toy.tilt"])
    k = next(line for line in lines if line.split()[:1] == ["toy.k"])
    assert tilt.endswith("deg") and float(tilt.split()[2]) == pytest.approx(math.degrees(0.01), abs=1e-6)
    assert k.endswith("mm/K") and float(k.split()[2]) == pytest.approx(0.0115, abs=1e-9)
    rows = {r[0]: r for r in parameter_rows(data)}
    assert rows["toy.tilt"][1] == "deg" and float(rows["toy.tilt"][3]) == pytest.approx(0.573, abs=1e-3)
    assert rows["toy.k"][1] == "mm/K" and float(rows["toy.k"][3]) == pytest.approx(0.0115, abs=1e-4)
    page = identification_page({"result": data, "kind": "identification"})
    assert '<td class="text">toy.k</td><td class="text">mm/K</td><td data-value="0.0">0</td>' in page
    assert '<td data-value="0.0115">0.01150</td>' in page  # identified, as held
    assert '<td class="text">toy.tilt</td><td class="text">deg</td>' in page
    assert f'<td data-value="{math.degrees(0.01)}">0.5730</td>' in page  # identified, in degrees
    assert "angles in degrees, 1/mm as held, mm/K as held." in page  # the note under the table


def test_the_verdict_judges_a_unit_of_its_own_in_its_scale():
    """Known units have their limits (1 mm, 1e-3 rad, 1e-3 of a ratio); another unit is judged in
    the parameter's characteristic scale, and no change limit applies to it."""
    units = ("mm", "rad", "1", "mm/K")
    limits = parameter_limits(units, 1.0, np.array([0, 0, 2.0, 0]), np.array([1, 1, 1, 5e-3]))
    np.testing.assert_allclose(limits, [1.0, 1e-3, 2e-3, 5e-3])
    geometry = preset("paper-hmt")
    change = change_limits(geometry, ("u1.x", "toy.tilt", "g1", "toy.k"), units, 0.1, np.ones(4))
    assert np.isfinite(change[0]) and change[2] == pytest.approx(0.1)
    assert np.isinf(change[1]) and np.isinf(change[3])
