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
