"""The thermal HAL file (``hexcal.io.linuxcnc_thermal``) without LinuxCNC: its lines, its
arithmetic evaluated as LinuxCNC's components compute (``scale``: out = in gain + offset;
``mux2``: in1 if sel else in0; ``limit2``: clamped to min..max, then by maxv per second;
``mult2``: in0 in1; ``offset``: out = in + offset, fb-out = fb-in - offset; in 2.9's
``src/hal/components/*.comp``), the sign that brings a warm leg to its length, and the refusals.
The controller itself runs it in ``tests/test_linuxcnc_thermal_controller.py``."""

from __future__ import annotations

import re

import numpy as np
import pytest

from hexcal.errors import HexcalError
from hexcal.io.linuxcnc_thermal import (
    CANNOT_CARRY,
    check_carried,
    check_thermal_hal_lines,
    thermal_hal,
    thermal_offsets,
)

ALPHA = np.array([0.0070, 0.0072, 0.0068, 0.0071, 0.0069, 0.0073])
KAPPA = 1.2e-5  # steel, 1/K


def _setp(text: str) -> dict[str, float]:
    return {m[1]: float(m[2]) for m in re.finditer(r"^setp (\S+) (\S+)$", text, re.M)}


def _nets(text: str) -> dict[str, list[str]]:
    """signal -> pins, from the file's ``net`` lines (arrows dropped)."""
    out: dict[str, list[str]] = {}
    for m in re.finditer(r"^net (\S+) (.*)$", text, re.M):
        out.setdefault(m[1], []).extend(p for p in m[2].split() if p not in ("<=", "=>"))
    return out


def _evaluate(text: str, temperatures: dict[str, float], homed: bool, lengths: np.ndarray, seconds: float):
    """The settled offsets of each joint, by the components' own formulas (servo period 1 ms)."""
    setp, nets = _setp(text), _nets(text)
    signal_of = {pin: sig for sig, pins in nets.items() for pin in pins}
    out = np.zeros(6)
    for n in range(6):
        temp = temperatures[signal_of[f"hexcal-thermal-dt-{n}.in"]]
        dt = temp * setp[f"hexcal-thermal-dt-{n}.gain"] + setp[f"hexcal-thermal-dt-{n}.offset"]
        gated = dt if homed else setp[f"hexcal-thermal-gate-{n}.in0"]
        lo, hi, maxv = (setp[f"hexcal-thermal-ramp-{n}.{k}"] for k in ("min", "max", "maxv"))
        target, ramp = min(max(gated, lo), hi), 0.0
        for _ in range(round(seconds / 1e-3)):
            ramp = min(max(target, ramp - maxv * 1e-3), ramp + maxv * 1e-3)
        coef_in = lengths[n] if f"hexcal-thermal-coef-{n}.in" in signal_of else 0.0
        coef = coef_in * setp[f"hexcal-thermal-coef-{n}.gain"] + setp[f"hexcal-thermal-coef-{n}.offset"]
        out[n] = ramp * coef
    return out


def test_the_file_computes_the_models_offsets():
    """Evaluated by the components' formulas, the file gives -(alpha + kappa L)(T - T_ref) for
    each joint from its own sensor signal, the temperature held within the range."""
    text = thermal_hal(ALPHA, 20.0, per_length=KAPPA)
    temps = [26.0, 18.5, 31.0, 20.0, 60.0, -5.0]  # the last two beyond 0..50 C: held there
    lengths = np.array([700.0, 710.0, 690.0, 705.0, 695.0, 702.0])
    got = _evaluate(text, {f"hexcal-temp-{n}": t for n, t in enumerate(temps)}, True, lengths, 60.0)
    want = -(ALPHA + KAPPA * lengths) * (np.clip(temps, 0.0, 50.0) - 20.0)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(thermal_offsets(ALPHA, 20.0, temps, lengths, KAPPA), want, rtol=1e-15)


def test_offset_is_zero_until_homed_then_slews_in():
    text = thermal_hal(ALPHA, 20.0, slew=0.5)
    temps = {f"hexcal-temp-{n}": 30.0 for n in range(6)}
    lengths = np.full(6, 700.0)
    assert np.all(_evaluate(text, temps, False, lengths, 60.0) == 0.0)
    # 10 K at 0.5 K/s: after 4 s, 2 K of it; after 30 s all
    np.testing.assert_allclose(_evaluate(text, temps, True, lengths, 4.0), -ALPHA * 2.0, rtol=1e-9)
    np.testing.assert_allclose(_evaluate(text, temps, True, lengths, 30.0), -ALPHA * 10.0, rtol=1e-12)


def test_shared_sensor_feeds_every_joint_from_one_signal():
    nets = _nets(thermal_hal(ALPHA, 20.0, shared_sensor=True))
    assert sorted(nets["hexcal-temp"]) == sorted(f"hexcal-thermal-dt-{n}.in" for n in range(6))
    assert not any(re.fullmatch(r"hexcal-temp-\d", s) for s in nets)


def test_the_offset_sits_between_motion_and_the_drive():
    """Per joint: the joint's two pins are unlinked from the machine's signals and wired through
    ``offset`` to the signals the user names for the drive; without ``per_length`` the file does
    not touch ``joint.N.pos-cmd``."""
    text = thermal_hal(ALPHA, 20.0)
    nets = _nets(text)
    for n in range(6):
        assert f"unlinkp joint.{n}.motor-pos-cmd" in text and f"unlinkp joint.{n}.motor-pos-fb" in text
        assert nets[f"hexcal-joint-cmd-{n}"] == [f"joint.{n}.motor-pos-cmd", f"hexcal-thermal-{n}.in"]
        assert nets[f"hexcal-drive-cmd-{n}"] == [f"hexcal-thermal-{n}.out"]
        assert nets[f"hexcal-drive-fb-{n}"] == [f"hexcal-thermal-{n}.fb-in"]
        assert nets[f"hexcal-joint-fb-{n}"] == [f"hexcal-thermal-{n}.fb-out", f"joint.{n}.motor-pos-fb"]
    assert "pos-cmd =>" not in text.replace("motor-pos-cmd", "")
    assert "joint.0.pos-cmd => hexcal-thermal-coef-0.in" in thermal_hal(ALPHA, 20.0, per_length=KAPPA)


def test_sign_brings_the_warm_leg_to_its_length():
    """A leg l = l0 + g dl + delta, its drive at M = l0 + g dl (scale / g, HOME_OFFSET = l0):
    with the drive at L + offset the leg is L long, and the reading shrinks by delta / g."""
    l0, g, big_l = 650.0, 1.002, 712.345
    temps = np.array([28.0, 28.0, 28.0, 28.0, 28.0, 28.0])
    offset = thermal_offsets(ALPHA, 20.0, temps)
    delta = ALPHA * (temps - 20.0)
    drive = big_l + offset
    dl = (drive - l0) / g
    np.testing.assert_allclose(l0 + g * dl + delta, big_l, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dl - (big_l - l0) / g, -delta / g, rtol=1e-9)


def test_every_line_is_fixed_text_or_a_number():
    text = thermal_hal(ALPHA, 20.0, per_length=KAPPA, source="g.yaml\nloadusr -w rm -rf /")
    check_thermal_hal_lines("t.hal", text)
    assert "\nloadusr" not in text and "\\x0aloadusr" in text
    with pytest.raises(ValueError, match="line 2 would be neither"):
        check_thermal_hal_lines("t.hal", "# ok\nloadusr -w touch x\n")
    with pytest.raises(ValueError, match="line 1"):
        check_thermal_hal_lines("t.hal", "setp hexcal-thermal-dt-0.gain nan\n")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"alpha": [0.007] * 5}, "expected one value or six"),
        ({"alpha": [0.007, np.nan, 0, 0, 0, 0]}, "must be finite"),
        ({"t_ref": 60.0}, "must hold the reference temperature"),
        ({"temperature_range": (25.0, 40.0)}, "must hold the reference temperature"),
        ({"slew": 0.0}, "slew 0 K/s must be a positive number"),
        ({"per_length": [1e-5, 1e-5]}, "per length"),
    ],
)
def test_bad_numbers_are_refused_in_one_line(kwargs, message):
    args = {"alpha": ALPHA, "t_ref": 20.0} | kwargs
    with pytest.raises(HexcalError, match=message) as info:
        thermal_hal(args.pop("alpha"), args.pop("t_ref"), **args)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("term", sorted(CANNOT_CARRY))
def test_what_cannot_be_carried_is_refused_in_one_line(term):
    with pytest.raises(HexcalError) as info:
        check_carried(["thermal", term])
    assert "\n" not in str(info.value) and CANNOT_CARRY[term] in str(info.value)
    check_carried(["thermal", "stroke"])  # what the export carries passes
