"""Run LinuxCNC headless on a simulated hexapod, for the controller tests.

One run of LinuxCNC (``linuxcnc CONFIG.ini``) with a configuration made here:

- ``[KINS] KINEMATICS = genhexkins``, six joints whose ``motor-pos-cmd`` is looped back
  to ``motor-pos-fb`` (simulated hardware, as LinuxCNC's sim configurations do);
- ``[DISPLAY] DISPLAY`` is :data:`DRIVER`, a Python script run by ``/usr/bin/python3``
  with LinuxCNC's ``linuxcnc`` module (as LinuxCNC's own ``tests/`` do): it homes the
  machine and, for each batch, loads a ``hexcal-kins.hal`` with ``halcmd -f`` (in joint
  mode, so that no joint jumps), commands each target pose by MDI ``G0`` and records the
  joint positions. When it exits, the ``linuxcnc`` script shuts LinuxCNC down.

Every wait has a timeout; :func:`run` kills the whole process group if LinuxCNC does not
end in time and raises :class:`LinuxCNCRunError` with the tail of its output.
"""

from __future__ import annotations

import ctypes
import json
import os
import shutil
import signal
import subprocess
import textwrap
import time
from pathlib import Path
from typing import Any

LINUXCNC = "/usr/bin/linuxcnc"
SYSTEM_PYTHON = "/usr/bin/python3"
LOCKFILE = Path("/tmp/linuxcnc.lock")  # fixed by the linuxcnc script
PACKAGE = "linuxcnc-uspace"


class LinuxCNCRunError(RuntimeError):
    """LinuxCNC did not run the job to the end."""


def unavailable_reason() -> str | None:
    """Why LinuxCNC cannot run here, or None when it can."""
    if not (os.access(LINUXCNC, os.X_OK) and shutil.which("halcmd")):
        return f"LinuxCNC is not installed: apt-get install {PACKAGE} (Debian) to run these tests"
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import linuxcnc"], capture_output=True, text=True, timeout=30, check=False
    )
    if probe.returncode != 0:
        return f"{SYSTEM_PYTHON} cannot import the linuxcnc module: apt-get install {PACKAGE}"
    if LOCKFILE.exists():
        return f"another LinuxCNC seems to run ({LOCKFILE} exists); stop it or remove the stale file"
    return None


DRIVER = textwrap.dedent(
    '''\
    #!/usr/bin/python3
    """hexcal test driver: home, then per batch load a kins HAL file and MDI the poses."""
    import json, os, subprocess, sys, time, traceback
    import hal, linuxcnc

    job = json.load(open(os.environ["HEXCAL_LCNC_JOB"]))
    out = {"batches": [], "error": None}
    s, c, e = linuxcnc.stat(), linuxcnc.command(), linuxcnc.error_channel()
    TIMEOUT = float(job["timeout"])

    def fail(msg):
        raise RuntimeError(msg)

    def errors():
        while True:
            m = e.poll()
            if not m:
                return
            out.setdefault("messages", []).append(m[1])
            if m[0] in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
                fail("LinuxCNC error: " + m[1])

    def wait(what, pred):
        end = time.monotonic() + TIMEOUT
        while time.monotonic() < end:
            s.poll()
            errors()
            if pred():
                return
            time.sleep(0.005)
        fail("timed out waiting for " + what)

    def mode(m):
        c.mode(m)
        c.wait_complete(TIMEOUT)
        wait("task mode %d" % m, lambda: s.task_mode == m)

    probe = None
    try:
        probe = hal.component("hexcal-probe")  # hal.get_value needs a component of its own
        probe.ready()
        wait("task to start", lambda: s.task_state != 0)
        c.state(linuxcnc.STATE_ESTOP_RESET)
        c.wait_complete(TIMEOUT)
        c.state(linuxcnc.STATE_ON)
        c.wait_complete(TIMEOUT)
        wait("machine on", lambda: s.task_state == linuxcnc.STATE_ON)
        mode(linuxcnc.MODE_MANUAL)
        c.home(-1)
        c.wait_complete(TIMEOUT)
        wait("homing", lambda: all(s.homed[:6]))
        for batch in job["batches"]:
            mode(linuxcnc.MODE_MANUAL)
            c.teleop_enable(0)
            c.wait_complete(TIMEOUT)
            if batch["hal"]:
                subprocess.run(["halcmd", "-f", batch["hal"]], check=True, timeout=TIMEOUT)
            mode(linuxcnc.MODE_MDI)
            rows = []
            for pose in batch["poses"]:
                c.mdi("G0 " + " ".join(w + repr(v) for w, v in zip("XYZABC", pose)))
                c.wait_complete(TIMEOUT)
                wait("the move to %r" % (pose,), lambda: s.interp_state == linuxcnc.INTERP_IDLE
                     and s.queue == 0 and s.inpos and s.state == linuxcnc.RCS_DONE
                     and max(abs(p - q) for p, q in zip(s.position[:6], pose)) < 1e-6)
                time.sleep(0.01)  # a few servo cycles: feedback = command
                s.poll()
                rows.append({"joints": list(s.joint_actual_position[:6]),
                             "joints_cmd": list(s.joint_position[:6]),
                             "position": list(s.position[:6]),
                             "motor_cmd": [hal.get_value("joint.%d.motor-pos-cmd" % n) for n in range(6)],
                             "comp": [hal.get_value("joint.%d.backlash-filt" % n) for n in range(6)],
                             "comp_target": [hal.get_value("joint.%d.backlash-corr" % n) for n in range(6)],
                             "record": {p: hal.get_value(p) for p in job.get("record", [])}})
            out["batches"].append(rows)
    except Exception:
        out["error"] = traceback.format_exc()
    finally:
        with open(job["result"], "w") as fh:
            json.dump(out, fh)
        try:
            c.state(linuxcnc.STATE_ESTOP)
        except Exception:
            pass
        if probe is not None:
            probe.exit()
    '''
)


def _config(joints_ini: dict[str, str], first_hal: str, workdir: Path) -> str:
    """The test machine's INI text; ``joints_ini`` holds per-joint HOME_OFFSET/HOME."""
    joints = []
    for n in range(6):
        joints.append(
            textwrap.dedent(
                f"""\
                [JOINT_{n}]
                TYPE = LINEAR
                MAX_VELOCITY = 100000
                MAX_ACCELERATION = 5000000
                MIN_LIMIT = 0
                MAX_LIMIT = 5000
                FERROR = 1000
                MIN_FERROR = 1000
                HOME_OFFSET = {joints_ini[f"HOME_OFFSET_{n}"]}
                HOME = {joints_ini[f"HOME_{n}"]}
                HOME_SEQUENCE = 0
                """
            )
            + joints_ini.get(f"EXTRA_{n}", "")
        )
    axes = []
    for axis in "XYZABC":
        axes.append(
            textwrap.dedent(
                f"""\
                [AXIS_{axis}]
                MIN_LIMIT = -5000
                MAX_LIMIT = 5000
                MAX_VELOCITY = 100000
                MAX_ACCELERATION = 5000000
                """
            )
        )
    return (
        textwrap.dedent(
            f"""\
            [EMC]
            VERSION = 1.1
            MACHINE = hexcal-test-hexapod
            DEBUG = 0

            [DISPLAY]
            DISPLAY = {workdir / "driver.py"}

            [TASK]
            TASK = milltask
            CYCLE_TIME = 0.001

            [RS274NGC]
            PARAMETER_FILE = {workdir / "sim.var"}
            RS274NGC_STARTUP_CODE = G21 G90 G49 G40 G17 G54 G94

            [EMCMOT]
            EMCMOT = motmod
            COMM_TIMEOUT = 1.0
            SERVO_PERIOD = 1000000

            [HAL]
            HALFILE = {workdir / "machine.hal"}
            HALFILE = {first_hal}

            [TRAJ]
            COORDINATES = X Y Z A B C
            LINEAR_UNITS = mm
            ANGULAR_UNITS = degree
            HOME = {joints_ini["TRAJ_HOME"]}
            DEFAULT_LINEAR_VELOCITY = 100000
            MAX_LINEAR_VELOCITY = 100000
            DEFAULT_LINEAR_ACCELERATION = 5000000
            MAX_LINEAR_ACCELERATION = 5000000
            DEFAULT_ANGULAR_VELOCITY = 100000
            MAX_ANGULAR_VELOCITY = 100000

            [EMCIO]
            EMCIO = io
            CYCLE_TIME = 0.100
            TOOL_TABLE = {workdir / "sim.tbl"}

            [KINS]
            KINEMATICS = genhexkins
            JOINTS = 6

            """
        )
        + "\n".join(joints)
        + "\n"
        + "\n".join(axes)
    )


MACHINE_HAL = textwrap.dedent(
    """\
    # simulated hexapod: genhexkins, motion, each joint's command looped back to its feedback
    loadrt [KINS]KINEMATICS
    loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
    addf motion-command-handler servo-thread
    addf motion-controller servo-thread
    net j0 joint.0.motor-pos-cmd => joint.0.motor-pos-fb
    net j1 joint.1.motor-pos-cmd => joint.1.motor-pos-fb
    net j2 joint.2.motor-pos-cmd => joint.2.motor-pos-fb
    net j3 joint.3.motor-pos-cmd => joint.3.motor-pos-fb
    net j4 joint.4.motor-pos-cmd => joint.4.motor-pos-fb
    net j5 joint.5.motor-pos-cmd => joint.5.motor-pos-fb
    net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in
    net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared
    net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed
    """
)


def environment(workdir: Path) -> dict[str, str]:
    """Environment for LinuxCNC: as root, RTAPI needs an unprivileged uid and a socket it can write."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON") and k != "VIRTUAL_ENV"}
    env["PATH"] = "/usr/bin:/bin:/usr/sbin:/sbin"
    env.pop("DISPLAY", None)  # headless: the linuxcnc script must not ask questions on X
    if os.geteuid() == 0:
        env.setdefault("RTAPI_UID", "65534")
        fifo_dir = workdir / "rtapi"
        fifo_dir.mkdir(exist_ok=True)
        fifo_dir.chmod(0o1777)
        env["RTAPI_FIFO_PATH"] = str(fifo_dir / "rtapi_fifo")
    return env


def run(
    workdir: Path,
    batches: list[tuple[str, list[list[float]]]],
    joints_ini: dict[str, str],
    timeout: float = 60.0,
    wait_timeout: float = 10.0,
    files: dict[str, str] | None = None,
    machine_hal: str | None = None,
    record: list[str] | None = None,
) -> dict[str, Any]:
    """Run LinuxCNC once over ``batches`` of ``(kins HAL text, poses X Y Z A B C)``.

    ``joints_ini`` may add lines to a joint's section (``EXTRA_N``, e.g. its ``COMP_FILE``),
    and ``files`` are written into the configuration's folder beside the INI (the tables).
    Each pose's row also has the joints' ``motor_cmd`` (``joint.N.motor-pos-cmd``), the
    compensation applied (``comp``, ``joint.N.backlash-filt``) and its target (``comp_target``,
    ``joint.N.backlash-corr``). ``machine_hal`` replaces :data:`MACHINE_HAL` (the simulated
    hardware), and each row's ``record`` holds the values of the HAL pins named in ``record``.

    Returns the driver's result: ``{"batches": [[{"joints", "joints_cmd", "position"}, ...]],
    "seconds": wall time}``. Raises :class:`LinuxCNCRunError` when the run fails.
    """
    workdir.mkdir(parents=True, exist_ok=True)
    workdir.chmod(0o755)
    hal_paths = []
    for k, (hal_text, _) in enumerate(batches):
        path = workdir / f"kins{k}.hal"
        path.write_text(hal_text)
        hal_paths.append(str(path))
    driver = workdir / "driver.py"
    driver.write_text(DRIVER)
    driver.chmod(0o755)
    (workdir / "machine.hal").write_text(MACHINE_HAL if machine_hal is None else machine_hal)
    for name, text in (files or {}).items():
        (workdir / name).write_text(text)
    (workdir / "sim.tbl").write_text("T1 P1 Z0 ;\n")
    (workdir / "sim.var").write_text("")
    ini = workdir / "hexapod.ini"
    ini.write_text(_config(joints_ini, hal_paths[0], workdir))
    result_path = workdir / "result.json"
    job = {
        "timeout": wait_timeout,
        "result": str(result_path),
        "record": list(record or []),
        # the first batch's file is loaded by the INI already
        "batches": [
            {"hal": None if k == 0 else hal_paths[k], "poses": p} for k, (_, p) in enumerate(batches)
        ],
    }
    job_path = workdir / "job.json"
    job_path.write_text(json.dumps(job))
    env = environment(workdir)
    env["HEXCAL_LCNC_JOB"] = str(job_path)
    log = workdir / "linuxcnc.log"
    start = time.monotonic()
    with open(log, "w") as out, _Subreaper() as reaper:
        proc = subprocess.Popen(
            [LINUXCNC, str(ini)],
            cwd=workdir,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            _stop(proc)
            raise LinuxCNCRunError(f"LinuxCNC did not finish in {timeout} s; log:\n{_tail(log)}") from None
        finally:
            if proc.poll() is None:
                _stop(proc)
    seconds = time.monotonic() - start
    if reaper.killed:
        killed = reaper.killed
        raise LinuxCNCRunError(f"LinuxCNC left processes running (killed: {killed}); log:\n{_tail(log)}")
    if not result_path.exists():
        raise LinuxCNCRunError(
            f"LinuxCNC ended (status {proc.returncode}) without a result; log:\n{_tail(log)}"
        )
    result = json.loads(result_path.read_text())
    if result["error"]:
        raise LinuxCNCRunError(f"the driver failed:\n{result['error']}\nlog:\n{_tail(log)}")
    result["seconds"] = seconds
    return result


def genhexkins_pins(workdir: Path, timeout: float = 30.0) -> dict[str, float]:
    """Values of the base and platform pins of a freshly loaded genhexkins (``halrun``)."""
    workdir.mkdir(parents=True, exist_ok=True)
    workdir.chmod(0o755)
    script = workdir / "pins.hal"
    script.write_text("loadrt genhexkins\nshow pin genhexkins.base.\nshow pin genhexkins.platform.\n")
    try:
        with _Subreaper() as reaper:
            done = subprocess.run(
                ["halrun", "-f", str(script)],
                cwd=workdir,
                env=environment(workdir),
                capture_output=True,
                text=True,
                timeout=timeout,
                check=False,
                start_new_session=True,
            )
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    if done.returncode != 0 or reaper.killed:
        output = done.stdout[-2000:] + done.stderr[-2000:]
        raise LinuxCNCRunError(f"halrun failed (status {done.returncode}): {output}")
    values = {}
    for line in done.stdout.splitlines():
        fields = line.split()
        if len(fields) == 5 and fields[1] == "float" and fields[4].startswith("genhexkins."):
            values[fields[4]] = float(fields[3])
    return values


def _children() -> dict[int, str]:
    """This process's children: pid -> state letter (from /proc)."""
    me, out = os.getpid(), {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                stat = fh.read()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == me:
            out[int(entry)] = fields[0]
    return out


class _Subreaper:
    """Adopt the processes LinuxCNC daemonises, and reap them when it has ended.

    LinuxCNC's ``rtapi_app``, ``linuxcncsvr`` and ``milltask`` outlive their parents; as a
    child subreaper (Linux ``prctl``) this process becomes their parent, so that on exit
    they are reaped here instead of staying zombies, and any still running after a grace
    period are killed (listed in ``killed``: a test fails on them).
    """

    PR_SET_CHILD_SUBREAPER = 36

    def __init__(self, grace: float = 20.0) -> None:
        self.grace = grace
        self.killed: list[int] = []
        self.before: set[int] = set()
        self.libc = ctypes.CDLL(None, use_errno=True)

    def __enter__(self) -> _Subreaper:
        self.before = set(_children())
        self.libc.prctl(self.PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            deadline = time.monotonic() + self.grace
            while True:
                adopted = {p: s for p, s in _children().items() if p not in self.before}
                for pid, state in adopted.items():
                    if state == "Z":
                        _reap(pid)
                running = [p for p, s in adopted.items() if s != "Z"]
                if not running:
                    return
                if time.monotonic() > deadline:
                    for pid in running:
                        try:
                            os.kill(pid, signal.SIGKILL)
                        except ProcessLookupError:
                            continue
                        self.killed.append(pid)
                        _reap(pid, block=True)
                    return
                time.sleep(0.05)
        finally:
            self.libc.prctl(self.PR_SET_CHILD_SUBREAPER, 0, 0, 0, 0)


def _reap(pid: int, block: bool = False) -> None:
    try:
        os.waitpid(pid, 0 if block else os.WNOHANG)
    except ChildProcessError:
        pass


def _stop(proc: subprocess.Popen[Any]) -> None:
    """End the linuxcnc script (its trap runs LinuxCNC's cleanup), then its whole group."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=20)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        pass
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=10)


def _tail(path: Path, lines: int = 40) -> str:
    try:
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])
    except OSError:
        return "(no log)"
