"""The thermal HAL file in LinuxCNC itself (issue 30, item 5): warm legs reach their lengths.

One headless LinuxCNC run (``tests/linuxcnc_sim.py``) of the seed paper's machine exported by
``hexcal export linuxcnc``, its simulated hardware a drive per joint whose command comes back
as its feedback on the signals ``hexcal-drive-cmd-N`` / ``hexcal-drive-fb-N`` (as the thermal
file asks a machine's HAL to name them), and ``hexcal-thermal.hal`` (alpha 1 µm/K per leg plus
12e-6/K of the leg's length: about 9 µm/K on a 700 mm strut) loaded after it. The legs'
temperatures are set (``sets hexcal-temp-N``) before homing, and changed between two batches
of MDI ``G0`` moves; a third batch has a sensor beyond the temperature range. From the run:

- LinuxCNC's offsets are hexcal's :func:`thermal_offsets` at the commanded strut lengths;
- the drive stands at the joint's motor command plus the offset, and motion still sees the joint
  at hexcal's inverse kinematics (the offset is taken off the feedback);
- the simulated warm machine (leg = ``l0 + g dl + delta``, ``dl`` the drive's travel from where
  it homed) has legs of exactly the inverse kinematics' lengths: the sign is right, and the offset
  was 0 while homing (otherwise every leg would be off by its growth at homing).

Also ``halrun`` loads the file after motion (``motmod``), and the offsets stay 0 while the
joints are not homed. Skipped, with the reason, where LinuxCNC is missing or already running.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

import linuxcnc_sim
from hexcal.core import preset, random_poses
from hexcal.core.kinematics import inverse_kinematics
from hexcal.io.linuxcnc import HAL_FILE, INI_FILE, export_linuxcnc
from hexcal.io.linuxcnc_import import parse_ini
from hexcal.io.linuxcnc_thermal import thermal_hal, thermal_offsets

ALPHA = np.full(6, 0.001)  # mm/K: a joint's own growth
KAPPA = np.array([12.0, 11.5, 12.5, 11.8, 12.2, 12.0]) * 1e-6  # 1/K of the strut's length
T_REF = 20.0
#: Per batch, each leg's temperature (°C): set before homing, then changed; the third has a
#: sensor reading 80 °C, beyond the default range 0..50 °C (held at 50).
TEMPERATURES = np.array(
    [
        [26.0, 27.5, 25.0, 28.0, 24.5, 26.5],
        [31.0, 18.0, 35.0, 22.0, 29.0, 40.0],
        [31.0, 18.0, 35.0, 22.0, 29.0, 80.0],
    ]
)
#: Offsets agree with hexcal's arithmetic to this, mm (both double precision: ~1e-15).
TOLERANCE = 1e-9

RECORD = [f"hexcal-thermal-{n}.{pin}" for n in range(6) for pin in ("offset", "out")] + [
    f"joint.{n}.{pin}" for n in range(6) for pin in ("motor-offset", "pos-cmd", "motor-pos-cmd")
]


def _machine_hal() -> str:
    """Simulated drives: command in on ``hexcal-drive-cmd-N``, the same out as feedback."""
    lines = [
        "loadrt [KINS]KINEMATICS",
        "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
        "loadrt limit1 names=" + ",".join(f"sim-drive-{n}" for n in range(6)),
        "addf motion-command-handler servo-thread",
        "addf motion-controller servo-thread",
    ]
    for n in range(6):
        lines += [
            f"addf sim-drive-{n} servo-thread",
            f"net hexcal-drive-cmd-{n} joint.{n}.motor-pos-cmd => sim-drive-{n}.in",
            f"net hexcal-drive-fb-{n} sim-drive-{n}.out => joint.{n}.motor-pos-fb",
        ]
    lines += [
        "net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in",
        "net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared",
        "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed",
    ]
    return "\n".join(lines) + "\n"


def _sets(temperatures: np.ndarray) -> str:
    return "".join(f"sets hexcal-temp-{n} {float(t)!r}\n" for n, t in enumerate(temperatures))


def _busy_reason() -> str | None:
    reason = linuxcnc_sim.unavailable_reason()
    if reason:
        return reason
    status = subprocess.run(["/usr/lib/linuxcnc/realtime", "status"], capture_output=True, check=False)
    return "a LinuxCNC realtime session is already running here" if status.returncode == 0 else None


@pytest.fixture(scope="module")
def scenario():
    reason = _busy_reason()
    if reason:
        pytest.skip(reason)
    geometry = preset("paper-hmt").replace(euler="xyz")
    files = export_linuxcnc(geometry)
    ini = parse_ini(files[INI_FILE])
    joints_ini = {"TRAJ_HOME": ini.get("TRAJ", "HOME")[0]}
    for n in range(6):
        joints_ini[f"HOME_OFFSET_{n}"] = ini.get(f"JOINT_{n}", "HOME_OFFSET")[0]
        joints_ini[f"HOME_{n}"] = ini.get(f"JOINT_{n}", "HOME")[0]
    rng = np.random.default_rng(30)
    targets = random_poses(geometry, 6, rng)
    words = targets.copy()
    words[:, 3:] = np.rad2deg(words[:, 3:])
    thermal = thermal_hal(ALPHA, T_REF, per_length=KAPPA, slew=1e4)  # settled within a servo cycle
    batches = [(files[HAL_FILE] + thermal + _sets(TEMPERATURES[0]), words.tolist())]
    batches += [(_sets(t), words.tolist()) for t in TEMPERATURES[1:]]
    workdir = Path(tempfile.mkdtemp(prefix="hexcal-linuxcnc-thermal-"))
    try:
        run = linuxcnc_sim.run(
            workdir, batches, joints_ini, timeout=90.0, machine_hal=_machine_hal(), record=RECORD
        )
    finally:
        shutil.rmtree(workdir, ignore_errors=True)

    def pins(batch: int, pin: str) -> np.ndarray:
        rows = run["batches"][batch]
        return np.array([[row["record"][pin.format(n=n)] for n in range(6)] for row in rows])

    return {"geometry": geometry, "targets": targets, "run": run, "pins": pins}


@pytest.mark.parametrize("batch", [0, 1, 2])
def test_offsets_are_hexcals_at_the_commanded_lengths(scenario, batch):
    pins = scenario["pins"]
    lengths = pins(batch, "joint.{n}.pos-cmd")
    want = thermal_offsets(ALPHA, T_REF, TEMPERATURES[batch], lengths, KAPPA)
    np.testing.assert_allclose(pins(batch, "hexcal-thermal-{n}.offset"), want, rtol=0, atol=TOLERANCE)
    assert np.all(np.abs(want) > 1e-3)  # the test means something: microns to tenths of mm


@pytest.mark.parametrize("batch", [0, 1])
def test_the_warm_machine_has_the_inverse_kinematics_lengths(scenario, batch):
    """The drive is at motor command + offset; the simulated warm legs, from the drive's travel
    since homing, are the lengths hexcal's inverse kinematics asks for; motion's joints are."""
    pins, geometry = scenario["pins"], scenario["geometry"]
    want = inverse_kinematics(geometry, scenario["targets"])
    joints = np.array([row["joints"] for row in scenario["run"]["batches"][batch]])
    np.testing.assert_allclose(joints, want, rtol=0, atol=1e-6)
    drive = pins(batch, "hexcal-thermal-{n}.out")
    offset = pins(batch, "hexcal-thermal-{n}.offset")
    np.testing.assert_allclose(drive, pins(batch, "joint.{n}.motor-pos-cmd") + offset, rtol=0, atol=TOLERANCE)
    # homing set the joint to HOME_OFFSET = l0 with the drive at P_sw, the offset 0:
    # motor-offset = P_sw - l0; the leg is l0 + g dl + delta = drive - motor-offset + delta (g = 1)
    delta = (ALPHA + KAPPA * want) * (TEMPERATURES[batch] - T_REF)
    legs = drive - pins(batch, "joint.{n}.motor-offset") + delta
    np.testing.assert_allclose(legs, want, rtol=0, atol=1e-6)
    # without the file the legs would be off by their growth: tens of microns
    assert np.min(np.abs(delta)) > 0.03 if batch == 0 else np.max(np.abs(delta)) > 0.1


def test_a_failed_sensor_is_held_at_the_range(scenario):
    offset = scenario["pins"](2, "hexcal-thermal-{n}.offset")[:, 5]
    lengths = scenario["pins"](2, "joint.{n}.pos-cmd")[:, 5]
    np.testing.assert_allclose(offset, -(ALPHA[5] + KAPPA[5] * lengths) * (50.0 - T_REF), atol=TOLERANCE)


def test_halrun_loads_it_after_motion_and_holds_zero_until_homed():
    reason = _busy_reason()
    if reason:
        pytest.skip(reason)
    hal = (
        "loadrt genhexkins\nloadrt homemod\nloadrt tpmod\n"
        "loadrt motmod servo_period_nsec=1000000 num_joints=6\n"
        + "\n".join(_machine_hal().splitlines()[2:-3])
        + "\n"
        + thermal_hal(ALPHA, T_REF, per_length=KAPPA)
        + _sets(TEMPERATURES[1])
        + "start\nloadusr -w sleep 0.3\n"
        + "".join(f"getp hexcal-thermal-{n}.offset\n" for n in range(6))
        + "show sig hexcal-drive-cmd-0\n"
    )
    workdir = Path(tempfile.mkdtemp(prefix="hexcal-halrun-thermal-"))  # RTAPI's uid must reach it
    try:
        workdir.chmod(0o755)
        script = workdir / "probe.hal"
        script.write_text(hal)
        done = subprocess.run(
            ["halrun", "-f", str(script)],
            cwd=workdir,
            env=linuxcnc_sim.environment(workdir),
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
            start_new_session=True,
        )
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    values = [float(v) for v in re.findall(r"^(-?\d\S*)$", done.stdout, re.M)]
    assert values == [0.0] * 6  # not homed: no offset, whatever the temperature
    wiring = r"hexcal-drive-cmd-0\s*\n\s*<== hexcal-thermal-0\.out\s*\n\s*==> sim-drive-0\.in"
    assert re.search(wiring, done.stdout)
