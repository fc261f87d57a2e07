"""Benchmarks of hexcal: the figures the issues name, each with its target.

Run ``python benchmarks/run.py`` (``--quick`` for a smoke run, ``--only NAME`` for
one group). Every figure is printed on its own line with its target and PASS/MISS.
The single-core figures run with BLAS/OpenMP pinned to one thread (set below,
before numpy is imported).
"""

from __future__ import annotations

import os

# Pin BLAS/OpenMP to one thread before numpy is imported, so the in-process
# figures are single-core. The caller's values are kept for the CLI runs.
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
CALLER_ENV = dict(os.environ)
for _var in THREAD_VARS:
    os.environ[_var] = "1"

import argparse
import gc
import platform
import re
import subprocess
import sys
import time
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path

import numpy as np
import scipy

from hexcal.calibration.identify import estimate
from hexcal.core.geometry import Geometry
from hexcal.core.kinematics import (
    FK_TOLERANCE,
    forward_kinematics,
    inverse_kinematics,
    leg_lengths,
    leg_readings,
)
from hexcal.core.noise import NoiseModel
from hexcal.core.presets import preset
from hexcal.core.workspace import random_poses, workspace_corners
from hexcal.errors import IdentificationError
from hexcal.instruments.pose import Measurements

BENCHMARKS = ("ik", "fk", "identify", "ml", "identify-cli", "cli")
SEED = 20240601

# Issue targets.
IK_TARGET = 3_000_000.0  # poses/s, one core
FK_TARGET = 1.0  # s for 100,000 poses
IDENTIFY_TARGET = 5e-3  # s per identification (15 poses, 42 parameters)
CLI_TARGET = 30.0  # s for `hexcal paper --trials 1000`
ML_TARGETS = {15: 20e-3, 1000: 1.0}  # s per maximum-likelihood identification (issue 5)
IDENTIFY_CLI_TARGETS = {100: 1.0, 10_000: 10.0}  # s wall for `hexcal identify` incl. start-up (issue 3)

IK_SIZES = (1, 10, 1000, 10_000, 1_000_000)
IK_SIZES_QUICK = (1, 10, 1000, 10_000, 100_000)


# -- reporting --------------------------------------------------------------------


class Report:
    """One line per figure: name, value, target, PASS/MISS (or a note), details."""

    def __init__(self) -> None:
        self.status: list[str] = []

    def line(self, name: str, value: str, target: str, ok: bool | None, detail: str = "") -> None:
        if ok is None:
            status = "-"
        else:
            status = "PASS" if ok else "MISS"
            self.status.append(status)
        print(f"{name:<34} {value:>16}   target {target:<14} {status:<5} {detail}".rstrip(), flush=True)

    def figure(
        self,
        name: str,
        value: str,
        target: str,
        ok: bool,
        detail: str = "",
        full_size: bool = True,
    ) -> None:
        """A figure with a target; in a quick run at a reduced size it is not judged."""
        if full_size:
            self.line(name, value, target, ok, detail)
        else:
            self.line(name, value, target, None, f"(quick run: not the issue's size) {detail}")

    def error(self, name: str, message: str) -> None:
        self.status.append("ERROR")
        print(f"{name:<34} {'ERROR':>16}   {message}", flush=True)


def header(title: str) -> None:
    print(f"\n== {title}", flush=True)


class CpuShare:
    """CPU seconds per wall second over a block (``with CpuShare() as c: ...; c.share``).

    About 1 for an unhindered single-threaded run, less when other processes took the
    core: the benchmark's own measure of how busy the shared machine was. With
    ``children=True`` it counts the CPU time of finished subprocesses instead.
    """

    def __init__(self, children: bool = False) -> None:
        self.children = children
        self.share = float("nan")

    def _cpu(self) -> float:
        if not self.children:
            return time.process_time()  # finer than os.times' clock ticks
        t = os.times()
        return t.children_user + t.children_system

    def __enter__(self) -> CpuShare:
        self._wall, self._cpu0 = time.perf_counter(), self._cpu()
        return self

    def __exit__(self, *exc: object) -> None:
        wall = time.perf_counter() - self._wall
        self.share = (self._cpu() - self._cpu0) / wall if wall > 0 else float("nan")


def time_calls(fn: Callable[[], object], repeats: int, min_time: float) -> tuple[list[float], float]:
    """Seconds per call of ``fn``: ``repeats`` samples, each of enough calls to last ``min_time``.

    One warm-up call first (which also sizes the loop, as ``timeit.autorange``
    does); the garbage collector is off while timing, as in :mod:`timeit`. Also
    returns the :class:`CpuShare` of the timed calls.
    """
    start = time.perf_counter()
    fn()
    first = time.perf_counter() - start
    number = max(1, int(np.ceil(min_time / max(first, 1e-9))))
    samples = []
    gc.collect()
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        with CpuShare() as cpu:
            for _ in range(repeats):
                start = time.perf_counter()
                for _ in range(number):
                    fn()
                samples.append((time.perf_counter() - start) / number)
    finally:
        if was_enabled:
            gc.enable()
    return samples, cpu.share


def fmt_time(seconds: float) -> str:
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6)):
        if seconds >= scale:
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds / 1e-9:.3g} ns"


# -- benchmarks -------------------------------------------------------------------


def bench_ik(report: Report, nominal: Geometry, quick: bool) -> None:
    """Inverse kinematics: time per call by problem size, and throughput at 1,000,000 poses."""
    header("inverse kinematics: inverse_kinematics(preset('paper-hmt'), poses), one core")
    sizes = IK_SIZES_QUICK if quick else IK_SIZES
    repeats = 7
    medians: dict[int, float] = {}
    columns = f"  {'poses':>9}  {'time per call':>14}  {'poses/s':>10}"
    print(f"{columns}  (median of {repeats}; min .. max; cpu/wall)")
    for n in sizes:
        poses = random_poses(nominal, n, SEED + n)
        samples, share = time_calls(lambda p=poses: inverse_kinematics(nominal, p), repeats, 0.2)
        med = float(np.median(samples))
        medians[n] = med
        print(
            f"  {n:>9,}  {fmt_time(med):>14}  {n / med:>10.3g}  "
            f"({fmt_time(min(samples))} .. {fmt_time(max(samples))}; {share:.2f})",
            flush=True,
        )
    n = sizes[-1]
    rate = n / medians[n]
    report.figure(
        "ik.throughput",
        f"{rate / 1e6:.2f} M poses/s",
        ">= 3.00 M/s",
        rate >= IK_TARGET,
        f"({n:,} random workspace poses, median of {repeats} after a warm-up; cpu/wall {share:.2f})",
        full_size=n == 1_000_000,
    )


def bench_fk(report: Report, nominal: Geometry, quick: bool) -> None:
    """Forward kinematics of 100,000 poses from the home pose."""
    header("forward kinematics: forward_kinematics(preset('paper-hmt'), lengths) from the home pose")
    n = 10_000 if quick else 100_000
    repeats = 5
    truth = random_poses(nominal, n, SEED)
    lengths = inverse_kinematics(nominal, truth)
    forward_kinematics(nominal, lengths[:1000])  # warm-up
    samples = []
    result = None
    with CpuShare() as cpu:
        for _ in range(repeats):
            gc.collect()
            start = time.perf_counter()
            result = forward_kinematics(nominal, lengths)
            samples.append(time.perf_counter() - start)
    assert result is not None
    med = float(np.median(samples))
    error = np.abs(result.poses - truth)
    report.figure(
        "fk.wall_time",
        fmt_time(med),
        "<= 1 s",
        med <= FK_TARGET,
        f"({n:,} poses, median of {repeats}; min {fmt_time(min(samples))}, max {fmt_time(max(samples))}; "
        f"cpu/wall {cpu.share:.2f})",
        full_size=n == 100_000,
    )
    n_conv = int(result.converged.sum())
    report.line(
        "fk.converged",
        f"{n_conv:,}/{n:,}",
        "all",
        bool(result.all_converged),
        f"(iterations: median {np.median(result.iterations):.0f}, max {result.iterations.max()})",
    )
    report.line(
        "fk.max_residual",
        f"{np.nanmax(result.residual):.2e} mm",
        f"<= {FK_TOLERANCE:.0e} mm",
        bool(np.nanmax(result.residual) <= FK_TOLERANCE),
        f"(the solver's tolerance; max pose error vs the IK input: {np.nanmax(error[:, :3]):.1e} mm, "
        f"{np.nanmax(error[:, 3:]):.1e} rad)",
    )


def simulated_corner_data(
    nominal: Geometry, true: Geometry, n_poses: int, rng: np.random.Generator, noise: NoiseModel
) -> Measurements:
    """One noisy data set from random workspace corners, following hexcal.simulation.

    Readings come from the nominal inverse kinematics; the true machine reaches the
    forward kinematics of ``l0 + g dl + e`` (leg sensor error ``e``); the measured
    pose is that pose plus measurement noise.
    """
    commanded = workspace_corners(nominal)[rng.permutation(64)[:n_poses]]
    readings = leg_readings(nominal, inverse_kinematics(nominal, commanded))
    lengths = leg_lengths(true, readings) + noise.leg_errors(rng, (n_poses,))
    reached = forward_kinematics(true, lengths, guess=commanded)
    if not reached.all_converged:
        raise RuntimeError("forward kinematics of the true machine did not converge")
    return Measurements(reached.poses + noise.pose_errors(rng, (n_poses,)), readings)


def bench_identify(report: Report, nominal: Geometry, quick: bool) -> None:
    """One identification from 15 noisy corner poses, 42 parameters."""
    header(
        "identification: estimate(paper-hmt, 15 noisy corners of paper-hmt-true, 'paper' | 'length'), "
        "42 parameters"
    )
    runs = 20 if quick else 100
    true = preset("paper-hmt-true")
    noise = NoiseModel()  # the paper's: U(±0.01 mm) legs, U(±0.025 mm), U(±0.001 rad) poses
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(SEED).spawn(runs)]
    datasets = [simulated_corner_data(nominal, true, 15, r, noise) for r in rngs]
    print(
        f"  {runs} data sets, one identification each (noise: legs ±{noise.leg} mm, "
        f"position ±{noise.position} mm, angles ±{noise.orientation} rad, uniform)"
    )
    for method in ("paper", "length"):
        estimate(nominal, datasets[0], method, with_bound=False)  # warm-up
        samples, nfev, failures = [], [], 0
        gc.collect()
        gc.disable()
        try:
            with CpuShare() as cpu:
                for data in datasets:
                    start = time.perf_counter()
                    try:
                        result = estimate(nominal, data, method, with_bound=False)
                    except IdentificationError:
                        failures += 1
                        continue
                    finally:
                        samples.append(time.perf_counter() - start)
                    nfev.append(result.nfev)
        finally:
            gc.enable()
        med = float(np.median(samples))
        report.figure(
            f"identify.{method}",
            fmt_time(med),
            "<= 5 ms",
            med <= IDENTIFY_TARGET,
            f"(median of {runs}; p10 {fmt_time(np.percentile(samples, 10))}, "
            f"p90 {fmt_time(np.percentile(samples, 90))}; nfev median {np.median(nfev):.0f}; "
            f"{failures} failed; cpu/wall {cpu.share:.2f})",
            full_size=runs >= 50,
        )


def bench_ml(report: Report, nominal: Geometry, quick: bool) -> None:
    """Maximum-likelihood identification (issue 5): 15 corners, and 1000 random workspace poses."""
    from hexcal.simulation import simulate_measurements

    header("maximum likelihood: estimate(paper-hmt, noisy data of paper-hmt-true, 'ml'), 42 parameters")
    true = preset("paper-hmt-true")
    noise = NoiseModel()
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(SEED + 1).spawn(30)]
    sets15 = [simulated_corner_data(nominal, true, 15, r, noise) for r in rngs[: 10 if quick else 30]]
    estimate(nominal, sets15[0], "ml", noise=noise, with_bound=False)
    samples = []
    with CpuShare() as cpu:
        for data in sets15:
            start = time.perf_counter()
            estimate(nominal, data, "ml", noise=noise, with_bound=False)
            samples.append(time.perf_counter() - start)
    med = float(np.median(samples))
    report.figure(
        "ml.15_poses",
        fmt_time(med),
        "<= 20 ms",
        med <= ML_TARGETS[15],
        f"(median of {len(samples)} data sets; cpu/wall {cpu.share:.2f})",
        full_size=len(samples) >= 30,
    )
    n = 200 if quick else 1000
    poses = random_poses(nominal, n, rngs[0])
    data = simulate_measurements(nominal, true, poses, noise, rngs[1])
    samples = []
    with CpuShare() as cpu:
        for _ in range(3):
            start = time.perf_counter()
            result = estimate(nominal, data, "ml", noise=noise, with_bound=False)
            samples.append(time.perf_counter() - start)
    med = float(np.median(samples))
    report.figure(
        "ml.1000_poses",
        fmt_time(med),
        "<= 1 s",
        med <= ML_TARGETS[1000],
        f"({n} poses, median of 3; {result.njev} iterations; cpu/wall {cpu.share:.2f})",
        full_size=not quick,
    )


def bench_identify_cli(report: Report, nominal: Geometry, quick: bool) -> None:
    """`hexcal identify` wall time including start-up (issue 3), on 100 and 10,000 poses."""
    import tempfile

    from hexcal.io import write_measurements
    from hexcal.simulation import simulate_measurements

    exe = hexcal_executable()
    header(f"command line: {exe} identify (default method) on simulated measurement files")
    true = preset("paper-hmt-true")
    rng = np.random.default_rng(SEED + 2)
    with tempfile.TemporaryDirectory() as tmp:
        for n in (100, 1000 if quick else 10_000):
            data = simulate_measurements(nominal, true, random_poses(nominal, n, rng), NoiseModel(), rng)
            path = Path(tmp) / f"m{n}.csv"
            write_measurements(path, data, nominal.euler)
            cmd = [
                str(exe),
                "identify",
                "--geometry",
                "paper-hmt",
                "--data",
                str(path),
                "--out",
                str(Path(tmp) / f"c{n}.yaml"),
            ]
            walls = []
            for _ in range(3 if n <= 1000 else 1):
                start = time.perf_counter()
                proc = subprocess.run(cmd, env=CALLER_ENV, capture_output=True, text=True, check=False)
                walls.append(time.perf_counter() - start)
                if proc.returncode != 0:
                    report.error(f"identify_cli.{n}", proc.stderr.strip().splitlines()[-1])
                    break
            else:
                wall = float(np.median(walls))
                target = IDENTIFY_CLI_TARGETS.get(n)
                report.figure(
                    f"identify_cli.{n}_poses",
                    f"{wall:.2f} s",
                    f"<= {target:g} s" if target else "-",
                    target is not None and wall <= target,
                    f"(median of {len(walls)} runs, start-up included)",
                    full_size=target is not None,
                )


def hexcal_executable() -> Path:
    # next to the interpreter (not resolved: .venv/bin/python is a symlink)
    return Path(sys.executable).with_name("hexcal")


def bench_cli(report: Report, quick: bool) -> None:
    """`hexcal paper --trials 1000 --quiet` as a subprocess: as named, and with --jobs 2 and 1."""
    trials = 100 if quick else 1000
    exe = hexcal_executable()
    header(f"command line: {exe} paper --trials {trials} --quiet [--jobs N]")
    caller = ", ".join(f"{v}={CALLER_ENV.get(v, 'unset')}" for v in THREAD_VARS)
    print(f"  subprocesses get the caller's environment ({caller}): the command's own thread defaults apply")
    if not exe.exists():
        report.error("cli", f"console script not found: {exe} (pip install -e . into this environment)")
        return
    variants = (("cli.paper", []), ("cli.paper.jobs2", ["--jobs", "2"]), ("cli.paper.jobs1", ["--jobs", "1"]))
    for name, extra in variants:
        cmd = [str(exe), "paper", "--trials", str(trials), "--quiet", *extra]
        start = time.perf_counter()
        with CpuShare(children=True) as cpu:
            proc = subprocess.run(cmd, env=CALLER_ENV, capture_output=True, text=True, check=False)
        wall = time.perf_counter() - start
        if proc.returncode != 0:
            last = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
            report.error(name, f"exit status {proc.returncode}: {last}")
            continue
        inner = re.findall(r"^\(([\d.]+) s\)$", proc.stdout, flags=re.MULTILINE)
        detail = (
            f"(`{' '.join(cmd[1:])}`; the command's own timer: {inner[-1] if inner else '?'} s; "
            f"cpu/wall {cpu.share:.2f}, all its processes)"
        )
        report.figure(name, f"{wall:.1f} s", "<= 30 s", wall <= CLI_TARGET, detail, full_size=trials == 1000)


# -- main -------------------------------------------------------------------------


def describe_machine() -> None:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            names = [ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")]
        cpu = names[0] if names else cpu
    except OSError:
        pass
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "n/a"
    print(
        f"hexcal {version('hexcal')} | Python {platform.python_version()} | numpy {np.__version__} | "
        f"scipy {scipy.__version__}"
    )
    print(f"{cpu}, {os.cpu_count()} CPUs, load average {load} (shared machines vary)")
    print(
        "threads: "
        + " ".join(f"{v}=1" for v in THREAD_VARS)
        + " set before importing numpy; the in-process figures are single-core"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes, for a smoke run")
    parser.add_argument(
        "--only",
        action="append",
        choices=BENCHMARKS,
        metavar="NAME",
        help=f"run only this group (repeatable): {', '.join(BENCHMARKS)}",
    )
    args = parser.parse_args(argv)
    selected = args.only or list(BENCHMARKS)
    describe_machine()
    if args.quick:
        print("quick run: reduced sizes; figures not at the issue's size are not judged")
    nominal = preset("paper-hmt")
    report = Report()
    start = time.perf_counter()
    if "ik" in selected:
        bench_ik(report, nominal, args.quick)
    if "fk" in selected:
        bench_fk(report, nominal, args.quick)
    if "identify" in selected:
        bench_identify(report, nominal, args.quick)
    if "ml" in selected:
        bench_ml(report, nominal, args.quick)
    if "identify-cli" in selected:
        bench_identify_cli(report, nominal, args.quick)
    if "cli" in selected:
        bench_cli(report, args.quick)
    counts = {s: report.status.count(s) for s in ("PASS", "MISS", "ERROR")}
    print(
        f"\n{counts['PASS']} PASS, {counts['MISS']} MISS, {counts['ERROR']} ERROR "
        f"({time.perf_counter() - start:.0f} s)"
    )
    return 1 if counts["ERROR"] else 0


if __name__ == "__main__":
    sys.exit(main())
