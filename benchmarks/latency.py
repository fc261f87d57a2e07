"""Latency of a real campaign (issue 29, item 6): ``identify`` as a ratio to a plain scipy fit.

Run ``python benchmarks/latency.py`` (``--quick`` for one repeat, ``--only real|auto|ballbar``,
``--profile`` for where the time goes). For each campaign it times, in the same run:

- **baseline**: a plain ``scipy.optimize.least_squares`` fit of the same campaign, written with
  numpy and scipy alone (trust-region reflective, finite-difference Jacobian, the leg length
  residual of every pose): the two real sessions' leg lengths at the measured poses with the
  machine, each session's motion-capture frame and tool free (the independent fit of
  ``tests/test_real_sessions.py``); for the ballbar, which gives no pose, the bar's readings
  with the machine and the bars free and each pose from its legs (Newton's method);
- **library**: the library call in this process (``hexcal.calibrate`` where it exists, else
  what ``hexcal identify`` calls: the leg model's choice for ``auto``, then
  :func:`hexcal.calibration.estimate` with the command's defaults), the inputs already read;
- **command**: the whole ``hexcal identify ... --out FILE`` as a subprocess (start-up, reading,
  reports and writing included).

It prints each as CPU seconds (the best of ``--repeats``) and as a ratio to the baseline, with
the target and PASS/MISS: the two real sessions (``tests/data/jugglebot``, ``--fit
joints,l0,gains``) <= 8x with linear legs and <= 20x with ``--leg-model auto``; the ballbar
walkthrough's 288-pose identify (``docs/ballbar.md``, made here by its own commands) <= 8x.
BLAS is pinned to one thread in this process (set below, before numpy is imported); the
``hexcal`` subprocesses pin it themselves.

``--profile`` runs each command once in this process under cProfile and prints the time of its
stages (inclusive, with call counts; they nest) and the time of each hexcal package (own time,
numpy's and scipy's given to the hexcal function that called them).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import contextlib
import cProfile
import csv
import gc
import io
import pstats
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "jugglebot"
REAL = ("session1_108_poses.csv", "session2_60_poses.csv")
TARGETS = {"real": 8.0, "auto": 20.0, "ballbar": 8.0}

#: The walkthrough's files (docs/ballbar.md, "A campaign, step by step"), made by its commands.
BALLBAR_STEPS = r"""
cat > bar.yaml <<'EOF'
units: mm
ballbar: {pivot: [0, 0, 750], ball: [0, 0, -50], length: 150.0}
EOF
HEXCAL candidates --geometry paper-hmt --ballbar bar.yaml --out circles.csv > /dev/null
HEXCAL select --geometry paper-hmt --ballbar bar.yaml --circles 24 \
    --noise leg=0.002,pos=0.001,ang=0 --noise-dist normal --out plan.csv > /dev/null
grep -E '^(#|id,|p5\.)' plan.csv > poses-p5.csv
grep -E '^(#|id,|p7\.)' plan.csv > poses-p7.csv
for bar in "p5 0.8, -125.6, 750.5" "p7 -0.7, 0.5, 700.6" "true-p5 0, -125, 750" "true-p7 0, 0, 700"; do
    printf 'units: mm\nballbar: {pivot: [%s], ball: [0, 0, -50], length: 150.0}\n' "${bar#* }" \
        > "${bar%% *}.yaml"
done
HEXCAL synthesize --nominal paper-hmt --true paper-hmt-true --poses poses-p5.csv --setup true-p5.yaml \
    --noise leg=0.002,pos=0.001,ang=0 --noise-dist normal --seed 5 --out bar-p5.csv > /dev/null
HEXCAL synthesize --nominal paper-hmt --true paper-hmt-true --poses poses-p7.csv --setup true-p7.yaml \
    --noise leg=0.002,pos=0.001,ang=0 --noise-dist normal --seed 7 --out bar-p7.csv > /dev/null
"""


def hexcal_command() -> list[str]:
    """The ``hexcal`` console script next to this interpreter, else ``python -m hexcal``."""
    script = Path(sys.executable).with_name("hexcal")
    return [str(script)] if script.exists() else [sys.executable, "-m", "hexcal"]


def cpu_of(fn: Callable[[], Any], repeats: int) -> tuple[Any, float]:
    """``(result, best CPU seconds)`` of ``repeats`` calls, the garbage collector off."""
    best, out = float("inf"), None
    for _ in range(repeats):
        gc.collect()
        gc.disable()
        try:
            start = time.process_time()
            out = fn()
            best = min(best, time.process_time() - start)
        finally:
            gc.enable()
    return out, best


def command_cpu(argv: list[str], cwd: Path, repeats: int) -> tuple[float, float]:
    """Best CPU and wall seconds of a subprocess (its children's rusage)."""
    best_cpu = best_wall = float("inf")
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        done = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(argv)} failed:\n{done.stderr}")
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        best_cpu, best_wall = min(best_cpu, cpu), min(best_wall, wall)
    return best_cpu, best_wall


# -- the plain baselines (numpy and scipy only) --------------------------------------------
def _rotations(angles: np.ndarray) -> np.ndarray:
    """``Rx(a) Ry(b) Rz(c)`` (intrinsic XYZ, the geometries' sequence) of angles ``(..., 3)``."""
    (ca, cb, cc), (sa, sb, sc) = np.cos(np.moveaxis(angles, -1, 0)), np.sin(np.moveaxis(angles, -1, 0))
    rows = [
        [cb * cc, -cb * sc, sb],
        [sa * sb * cc + ca * sc, -sa * sb * sc + ca * cc, -sa * cb],
        [-ca * sb * cc + sa * sc, ca * sb * sc + sa * cc, ca * cb],
    ]
    return np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def _read_real(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Readings (revolutions), positions (mm) and rotation matrices of a Jugglebot session, by
    the csv module and scipy (not hexcal)."""
    from scipy.spatial.transform import Rotation

    with open(DATA / name, newline="") as fh:
        rows = list(csv.DictReader(fh))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    readings = np.column_stack([col[f"leg_length_{i}"] for i in range(1, 7)])
    position = np.column_stack([col[f"position_{c}"] for c in "xyz"])
    quat = np.column_stack([col[f"orientation_{c}"] for c in "xyzw"])
    return readings, position, Rotation.from_quat(quat).as_matrix()


def real_baseline(sessions: list[Any], nominal: Any) -> Callable[[], float]:
    """The plain fit of the real sessions: machine (joints, l0, gains) and each session's frame
    and tool, from hexcal's registered start (computed before, not timed); returns a function
    that fits and gives the leg RMS (mm)."""
    from scipy.optimize import least_squares

    data = [_read_real(name) for name in REAL]
    machine0 = np.concatenate([nominal.base_joints.ravel(), nominal.platform_joints.ravel()])
    legs0 = np.concatenate([nominal.initial_leg_lengths, nominal.leg_gains])
    setups0 = [s.instrument.parameters().values for s in sessions]  # frame, tool (x, y, z, a, b, c)
    x0 = np.concatenate([machine0, legs0, *setups0])

    def residuals(x: np.ndarray) -> np.ndarray:
        u, s = x[:18].reshape(6, 3), x[18:36].reshape(6, 3)
        l0, g = x[36:42], x[42:48]
        out = []
        for k, (readings, position, rot_m) in enumerate(data):
            frame, tool = x[48 + 12 * k : 54 + 12 * k], x[54 + 12 * k : 60 + 12 * k]
            rot_f, rot_t = _rotations(frame[3:]), _rotations(tool[3:])
            rot_p = rot_f.T @ rot_m @ rot_t.T  # platform orientation: F⁻¹ M T⁻¹
            origin = (position - frame[:3]) @ rot_f - rot_p @ tool[:3]
            v = origin[:, None, :] + np.einsum("mij,kj->mki", rot_p, s) - u
            out.append(np.linalg.norm(v, axis=2) - (l0 + g * readings))
        return np.concatenate(out).ravel()

    def fit() -> float:
        sol = least_squares(residuals, x0)
        return float(np.sqrt(np.mean(sol.fun**2)))

    return fit


def ballbar_baseline(sessions: list[Any], nominal: Any) -> Callable[[], float]:
    """The plain fit of the ballbar sessions: machine (joints, l0) and each bar (pivot, ball,
    length) from the nominal machine and the setups as given; each pose from its leg readings by
    Newton's method (a finite-difference Jacobian, warm-started at the last poses), the bar
    residual ``|o + R b - c| - length - d``; returns a function that fits and gives the bar RMS
    (mm)."""
    from scipy.optimize import least_squares

    from hexcal.instruments.framed import fk_start_poses

    readings = np.concatenate([s.data.readings for s in sessions])
    d = np.concatenate([s.data.d for s in sessions])
    session = np.repeat(np.arange(len(sessions)), [len(s.data.d) for s in sessions])
    poses0 = fk_start_poses(nominal, readings)  # a start for Newton's method (not timed)
    machine0 = np.concatenate([nominal.base_joints.ravel(), nominal.platform_joints.ravel()])
    setups0 = [s.instrument.parameters().values for s in sessions]  # pivot, ball, length
    x0 = np.concatenate([machine0, nominal.initial_leg_lengths, *setups0])
    gains = nominal.leg_gains
    last = [poses0]

    def legs(poses: np.ndarray, u: np.ndarray, s: np.ndarray) -> np.ndarray:
        v = poses[:, None, :3] + np.einsum("mij,kj->mki", _rotations(poses[:, 3:]), s) - u
        return np.linalg.norm(v, axis=2)

    def residuals(x: np.ndarray) -> np.ndarray:
        u, s, l0 = x[:18].reshape(6, 3), x[18:36].reshape(6, 3), x[36:42]
        target = l0 + gains * readings
        poses = last[0].copy()
        for _ in range(20):  # Newton's method on the six leg lengths of every pose
            error = legs(poses, u, s) - target
            jac = np.stack(
                [(legs(poses + h, u, s) - legs(poses - h, u, s)) / 2e-6 for h in 1e-6 * np.eye(6)], -1
            )
            try:
                step = np.linalg.solve(jac, error[..., None])[..., 0]
            except np.linalg.LinAlgError:  # a wild trial step: no pose (the solver steps back)
                return np.full(len(d), np.nan)
            poses -= step
            if np.max(np.abs(step)) < 1e-10:
                break
        if not np.all(np.isfinite(poses)):
            return np.full(len(d), np.nan)
        last[0] = poses
        bar = x[42:].reshape(len(sessions), 7)[session]
        ball = np.einsum("mij,mj->mi", _rotations(poses[:, 3:]), bar[:, 3:6])
        return np.linalg.norm(poses[:, :3] + ball - bar[:, :3], axis=1) - bar[:, 6] - d

    def fit() -> float:
        last[0] = poses0
        sol = least_squares(residuals, x0)
        return float(np.sqrt(np.mean(sol.fun**2)))

    return fit


# -- the campaigns ---------------------------------------------------------------------------
def library_call(nominal: Any, sessions: list[Any], fit: str | None, leg_model: str) -> Callable[[], Any]:
    """The library call of ``hexcal identify`` with its defaults (noise learned, ml)."""
    import hexcal

    if hasattr(hexcal, "calibrate"):
        return lambda: hexcal.calibrate(nominal, sessions, fit=fit, leg_model=leg_model)
    from hexcal.calibration import estimate
    from hexcal.calibration.leg_model_choice import choose_leg_model, fit_for, start_for

    radius = float(np.max(np.linalg.norm(nominal.platform_joints[:, :2], axis=1)))

    def call() -> Any:
        start, groups = nominal, fit
        if leg_model != "linear":
            spec = leg_model
            if leg_model == "auto":
                spec = choose_leg_model(nominal, sessions, method="ml", fit=fit, fix=(), noise="auto").choice
            start = start_for(spec, nominal, sessions)
            groups = fit_for(fit, start.leg_model)
        return estimate(
            start, sessions, "ml", noise="auto", fit=groups, sigma_limit=0.2 * radius, max_change=0.25
        )

    return call


def campaigns(only: set[str], folder: Path) -> list[dict[str, Any]]:
    """The campaigns to time: name, command arguments, working folder, library call, baseline."""
    from hexcal.io import load_geometry, read_sessions

    out = []
    if only & {"real", "auto"}:
        nominal = load_geometry(DATA / "jugglebot.yaml")
        files = [str(DATA / n) for n in REAL]
        sessions = read_sessions(files, [str(DATA / "mocap.yaml")] * 2, nominal.euler)
        from hexcal.calibration import register_sessions

        registered, _ = register_sessions(nominal, sessions)
        baseline = real_baseline(registered, nominal)
        argv = ["identify", "--geometry", str(DATA / "jugglebot.yaml")]
        for f in files:
            argv += ["--data", f, "--setup", str(DATA / "mocap.yaml")]
        argv += ["--fit", "joints,l0,gains", "--out", str(folder / "real.yaml")]
        for name, leg_model in (("real", "linear"), ("auto", "auto")):
            if name in only:
                extra = ["--leg-model", "auto"] if leg_model == "auto" else []
                library = library_call(nominal, sessions, "joints,l0,gains", leg_model)
                out.append(
                    {
                        "name": name,
                        "argv": argv + extra,
                        "cwd": folder,
                        "library": library,
                        "baseline": baseline,
                    }
                )
    if "ballbar" in only:
        bar = folder / "ballbar"
        bar.mkdir(exist_ok=True)
        script = BALLBAR_STEPS.replace("HEXCAL", " ".join(hexcal_command()))
        subprocess.run(["bash", "-e", "-c", script], cwd=bar, check=True)
        nominal = load_geometry("paper-hmt")
        sessions = read_sessions(
            [str(bar / "bar-p5.csv"), str(bar / "bar-p7.csv")],
            [str(bar / "p5.yaml"), str(bar / "p7.yaml")],
            "XYZ",
        )
        argv = ["identify", "--geometry", "paper-hmt", "--data", "bar-p5.csv", "--setup", "p5.yaml"]
        argv += ["--data", "bar-p7.csv", "--setup", "p7.yaml", "--out", "cal.yaml"]
        out.append(
            {
                "name": "ballbar",
                "argv": argv,
                "cwd": bar,
                "library": library_call(nominal, sessions, None, "linear"),
                "baseline": ballbar_baseline(sessions, nominal),
            }
        )
    return out


# -- the profile -----------------------------------------------------------------------------
#: Stages of a command (inclusive time; they nest), by ``module:function`` suffix.
STAGES = (
    ("command", "cli/calibrate.py:cmd_identify"),
    ("  read the inputs", "io/sessions.py:read_sessions"),
    ("  leg-model choice", "calibration/leg_model_choice.py:choose_leg_model"),
    ("  estimate", "calibration/identify.py:estimate"),
    ("    registration", "calibration/identify.py:register_sessions"),
    ("    noise estimation (with its ml fits)", "estimation/noise_estimation.py:estimate_noise"),
    ("      of which ml fits", "estimation/likelihood.py:fit_ml"),
    ("      of which group statistics", "estimation/noise_estimation.py:_statistics"),
    ("    bound", "estimation/uncertainty.py:bound_stderr"),
    ("    outlier check", "calibration/identify.py:_flagged"),
    ("    verdict", "calibration/verdict.py:assess"),
    ("      screening refits", "estimation/robust.py:screen_poses"),
    ("      diagnosis refits", "calibration/diagnosis.py:diagnose"),
    ("      predicted accuracy", "calibration/accuracy.py:predicted_pose_accuracy"),
    ("      expected validation", "calibration/accuracy.py:expected_validation"),
    ("  report dict", "report/convert.py:identification_report_dict"),
    ("  result to_dict", "estimation/result.py:to_dict"),
    ("  write the geometry", "io/geometry_file.py:save_geometry"),
    ("all ml fits", "estimation/likelihood.py:fit_ml"),
    ("all pose solves", "estimation/likelihood.py:solve"),
    ("all observation equations", "estimation/equations.py:observation_equations"),
)


def _key(func: tuple[str, int, str]) -> str:
    path, _, name = func
    return f"{'/'.join(Path(path).parts[-2:])}:{name}"


def _package(func: tuple[str, int, str]) -> str | None:
    parts = Path(func[0]).parts
    if "hexcal" in parts and "site-packages" not in parts:
        rest = parts[parts.index("hexcal") + 1 :]
        return rest[0].removesuffix(".py") if len(rest) > 1 else "hexcal"
    return None


def by_package(stats: pstats.Stats) -> dict[str, float]:
    """Own time of each hexcal package, a library function's given to its callers in proportion
    to the time it spent for each (up to the first hexcal caller)."""
    raw = stats.stats  # type: ignore[attr-defined]
    out: dict[str, float] = {}

    def give(func: Any, seconds: float, depth: int = 0) -> None:
        pkg = _package(func)
        if pkg is not None:
            out[pkg] = out.get(pkg, 0.0) + seconds
            return
        callers = raw.get(func, (0, 0, 0, 0, {}))[4]
        total = sum(c[2] for c in callers.values()) or sum(c[3] for c in callers.values())
        if not callers or total <= 0 or depth > 30:
            out["(outside hexcal)"] = out.get("(outside hexcal)", 0.0) + seconds
            return
        for caller, c in callers.items():
            share = (c[2] if sum(x[2] for x in callers.values()) > 0 else c[3]) / total
            give(caller, seconds * share, depth + 1)

    for func, (_, _, tt, _, _) in raw.items():
        if tt > 0:
            give(func, tt)
    return out


def profile(case: dict[str, Any]) -> None:
    """The command once in this process under cProfile: its stages and its packages."""
    from hexcal.cli.main import main

    profiler = cProfile.Profile()
    cwd = os.getcwd()
    os.chdir(case["cwd"])
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            profiler.enable()
            main(case["argv"])
            profiler.disable()
    finally:
        os.chdir(cwd)
    stats = pstats.Stats(profiler)
    raw = stats.stats  # type: ignore[attr-defined]
    total = max(ct for (_, _, _, ct, _) in raw.values())
    print(f"  profile of `hexcal {case['argv'][0]} ...` in this process ({total:.2f} s under cProfile):")
    for label, suffix in STAGES:
        hits = [(v[1], v[3]) for f, v in raw.items() if _key(f).endswith(suffix)]
        if hits:
            calls, seconds = sum(h[0] for h in hits), max(h[1] for h in hits)
            print(f"    {label:44s} {seconds:7.2f} s {100 * seconds / total:5.1f} %  {calls} call(s)")
    print("    by package (own time, libraries' time given to their hexcal callers):")
    for pkg, seconds in sorted(by_package(stats).items(), key=lambda kv: -kv[1]):
        if seconds >= 0.005 * total:
            print(f"      {pkg:20s} {seconds:7.2f} s {100 * seconds / total:5.1f} %")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repeat of everything (a smoke run)")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs of each figure (best kept)")
    parser.add_argument("--only", action="append", choices=sorted(TARGETS), help="one campaign (repeatable)")
    parser.add_argument("--profile", action="store_true", help="where each command's time goes")
    args = parser.parse_args()
    repeats = 1 if args.quick else args.repeats
    only = set(args.only or TARGETS)
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average {load} on {os.cpu_count()} cores; BLAS threads pinned to 1; best of {repeats}")
    with tempfile.TemporaryDirectory(prefix="hexcal-latency-") as tmp:
        for case in campaigns(only, Path(tmp)):
            rms, base = cpu_of(case["baseline"], repeats)
            case["library"]()  # a warm-up: imports and caches, as the command's start-up is not the fit's
            result, library = cpu_of(case["library"], repeats)
            command, wall = command_cpu([*hexcal_command(), *case["argv"]], case["cwd"], repeats)
            target = TARGETS[case["name"]]
            leg = getattr(result, "leg_rms_after", float("nan"))
            print(
                f"latency.{case['name']}: baseline {base:.3f} s (plain scipy fit, RMS {rms:.3f} mm) | "
                f"library {library:.3f} s = {library / base:.1f}x (leg RMS {leg:.3f} mm) | "
                f"command {command:.3f} s cpu ({wall:.3f} s wall) = {command / base:.1f}x | "
                f"target <= {target:g}x: library {'PASS' if library / base <= target else 'MISS'}, "
                f"command {'PASS' if command / base <= target else 'MISS'}"
            )
            if args.profile:
                profile(case)
    load = ", ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average {load} at the end")


if __name__ == "__main__":
    main()
