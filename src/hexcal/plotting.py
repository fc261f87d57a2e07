"""Figures (the only module that imports matplotlib)."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hexcal.geometry import PARAMETER_NAMES
from hexcal.simulation import PaperExperiment


def _save(fig: plt.Figure, path: str | os.PathLike[str]) -> None:
    tmp = f"{path}.tmp.png"
    fig.savefig(tmp, dpi=120, bbox_inches="tight")
    plt.close(fig)
    os.replace(tmp, path)


def plot_parameter_errors(experiment: PaperExperiment, path: str | os.PathLike[str]) -> None:
    """Like the paper's Fig. 10: error of each parameter before and after calibration.

    Bars are the mean absolute error over trials of each of the 42 parameters.
    """
    names = PARAMETER_NAMES[:42]
    before = np.abs(experiment.nominal_vector - experiment.true_vectors).mean(axis=0)
    interior = np.nanmean(np.abs(experiment.interior_vectors - experiment.true_vectors), axis=0)
    boundary = np.nanmean(np.abs(experiment.boundary_vectors - experiment.true_vectors), axis=0)
    x = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(13, 4.5))
    ax.bar(x - 0.27, before, 0.27, label="before calibration")
    ax.bar(x, interior, 0.27, label="after: 15 interior poses")
    ax.bar(x + 0.27, boundary, 0.27, label="after: 15 corners")
    ax.set_xticks(x, names, rotation=90, fontsize=7)
    ax.set_ylabel("mean absolute error (mm)")
    ax.set_yscale("log")
    ax.set_title(f"Identified parameter errors ({experiment.trials} trials)")
    ax.legend()
    _save(fig, path)


def plot_validation_errors(experiment: PaperExperiment, path: str | os.PathLike[str]) -> None:
    """Like the paper's Fig. 11: position and orientation error of the validation poses.

    Shows the first trial's validation poses, before and after calibration.
    """
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    k = np.arange(1, experiment.validation_targets.shape[1] + 1)
    for ax, key, unit in zip(axes, ("position", "orientation"), ("mm", "rad"), strict=True):
        ax.semilogy(k, experiment.validation_before[key][0], "o-", label="nominal parameters")
        ax.semilogy(k, experiment.validation_after[key][0], "s-", label="identified parameters")
        ax.set_xlabel("validation pose")
        ax.set_ylabel(f"{key} error ({unit})")
        ax.set_xticks(k)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend()
    fig.suptitle("Pose errors at the validation corners (first trial)")
    _save(fig, path)


def plot_study(cells: list, path: str | os.PathLike[str]) -> None:
    """Mean absolute parameter error against the number of poses, per strategy and method.

    Dashed lines are the Cramér–Rao bounds of the same pose strategies (one per strategy
    and noise level). ``cells`` are :class:`hexcal.study.StudyCell` objects.
    """
    rows = [c.row() for c in cells]
    fig, ax = plt.subplots(figsize=(8, 5))
    keys = sorted({(r["strategy"], r["noise"], r["method"]) for r in rows})
    for strategy, noise, method in keys:
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"], r["method"]) == (strategy, noise, method)),
            key=lambda r: r["poses"],
        )
        ax.plot(
            [r["poses"] for r in sel],
            [r["error_mean"] for r in sel],
            "o-",
            label=f"{strategy}, {method}, noise {noise}",
        )
    for strategy, noise in sorted({(r["strategy"], r["noise"]) for r in rows}):
        sel = sorted(
            (r for r in rows if (r["strategy"], r["noise"]) == (strategy, noise)), key=lambda r: r["poses"]
        )
        ax.plot([r["poses"] for r in sel], [r["bound"] for r in sel], "k--", lw=0.8, alpha=0.6)
    ax.set_xlabel("number of measurement poses")
    ax.set_ylabel("mean absolute parameter error (mm)")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title("Calibration campaigns (dashed: Cramér–Rao bounds)")
    ax.legend(fontsize=7)
    _save(fig, path)
