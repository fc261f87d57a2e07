"""Figures of the HTML reports, as SVG text (matplotlib, like :mod:`hexcal.report.figures`).

Each function takes plain data (the ``to_dict()`` values) and returns a figure; :func:`svg`
turns it into inline SVG. Axis labels carry units, legends sit outside the data, panels
that are compared share one colour scale, and large point sets are rasterised inside the
SVG so that the report of a 10,000-pose calibration still opens quickly.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

#: Above this many points a scatter or line layer is rasterised inside the SVG.
RASTER_POINTS = 1500


def svg(fig: Any) -> str:
    """The figure as SVG text (closed afterwards)."""
    buffer = io.StringIO()
    # text stays text (the browser draws it): ten times faster and smaller than glyph paths
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        fig.savefig(buffer, format="svg", bbox_inches="tight")
    plt.close(fig)
    return buffer.getvalue()


def parameter_changes(result: Mapping[str, Any]) -> Any:
    """Change of every identified parameter with ±2 standard errors and ±2 Cramér–Rao σ."""
    names = list(result.get("names") or result["parameters"])
    change = np.array([result["parameters"][n] - result["start"][n] for n in names])
    err = np.array([result.get("stderr", {}).get(n, np.nan) for n in names], dtype=float)
    bound = result.get("bound") or {}
    crb = np.array([bound.get(n, np.nan) for n in names], dtype=float)
    gains = np.array([n.startswith("g") for n in names])
    panels = [("lengths", ~gains, 1.0, "change (mm)")]
    if gains.any():
        panels.append(("gains", gains, 1e3, "change (×1e-3)"))
    widths = [max(int(mask.sum()), 3) for _, mask, _, _ in panels]
    fig, axes = plt.subplots(
        1,
        len(panels),
        figsize=(min(4 + 0.2 * sum(widths), 16), 4),
        gridspec_kw={"width_ratios": widths},
        squeeze=False,
    )
    for ax, (_, mask, scale, label) in zip(axes[0], panels, strict=True):
        x = np.arange(int(mask.sum()))
        ax.axhline(0, color="0.6", lw=0.8)
        ax.errorbar(
            x,
            change[mask] * scale,
            yerr=2 * err[mask] * scale,
            fmt="o",
            ms=3,
            capsize=2,
            color="C0",
            label="identified change ± 2 std. errors",
        )
        if np.isfinite(crb[mask]).any():
            ax.errorbar(
                x,
                change[mask] * scale,
                yerr=2 * crb[mask] * scale,
                fmt="none",
                capsize=5,
                elinewidth=0,
                color="C3",
                label="± 2 Cramér–Rao σ",
            )
        ax.set_xticks(x, [n for n, keep in zip(names, mask, strict=True) if keep], rotation=90, fontsize=7)
        ax.set_ylabel(label)
        ax.grid(True, axis="y", alpha=0.3)
    axes[0][0].legend(loc="upper left", bbox_to_anchor=(0, -0.28), ncol=2, fontsize=8, frameon=False)
    fig.suptitle(
        f"Identified parameter changes ({result.get('method', '')}, {result.get('poses', '?')} poses)"
    )
    return fig


def pose_residuals(
    ids: Sequence[str],
    before: np.ndarray,
    after: np.ndarray,
    marked: Mapping[str, Sequence[str]] | None = None,
) -> Any:
    """RMS leg residual per pose with the nominal and the identified parameters (log scale)."""
    before, after = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    k = np.arange(len(ids))
    fig, ax = plt.subplots(figsize=(9, 3.8))
    raster = len(ids) > RASTER_POINTS
    ax.semilogy(k, before, ".", ms=4, color="C1", label="nominal parameters", rasterized=raster)
    ax.semilogy(k, after, ".", ms=4, color="C0", label="identified parameters", rasterized=raster)
    index = {pid: j for j, pid in enumerate(ids)}
    for (label, which), style in zip((marked or {}).items(), ("x", "s"), strict=False):
        sel = [index[p] for p in which if p in index]
        if sel:
            ax.semilogy(
                k[sel], np.maximum(after[sel], 1e-12), style, ms=9, mfc="none", color="C3", label=label
            )
    ax.set_xlabel("measured pose (file order)")
    ax.set_ylabel("RMS leg residual (mm)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.set_title(f"Leg residuals per pose ({len(ids)} poses)")
    return fig


def correlation(names: Sequence[str], matrix: Any) -> Any:
    """Correlation heat map on the fixed scale −1 to 1."""
    corr = np.asarray(matrix, dtype=float)
    n = len(names)
    size = min(3 + 0.16 * n, 11)
    fig, ax = plt.subplots(figsize=(size + 1, size))
    image = ax.imshow(corr, cmap="RdBu_r", vmin=-1, vmax=1, interpolation="nearest")
    step = max(1, n // 48)
    ax.set_xticks(range(0, n, step), list(names)[::step], rotation=90, fontsize=6)
    ax.set_yticks(range(0, n, step), list(names)[::step], fontsize=6)
    fig.colorbar(image, ax=ax, shrink=0.8, label="correlation")
    ax.set_title("Parameter correlations")
    return fig


def singular_values(values: Sequence[float], threshold: float) -> Any:
    """Singular values of the column-normalised Jacobian relative to the largest."""
    sv = np.asarray(values, dtype=float)
    rel = sv / sv[0]
    fig, ax = plt.subplots(figsize=(7, 3.6))
    ax.semilogy(np.arange(1, rel.size + 1), rel, "o-", ms=3)
    ax.axhline(threshold, ls="--", color="C3", lw=1, label=f"rank threshold {threshold:g}")
    ax.set_xlabel("index")
    ax.set_ylabel("σ / σmax (column-normalised)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    ax.set_title("Singular values of the identification Jacobian")
    return fig


def workspace_poses(
    poses: Any, box: Any | None = None, title: str = "Measured poses in the workspace"
) -> Any:
    """Measured poses: x–y position (colour z) and two angles (colour the third), in degrees."""
    p = np.asarray(poses, dtype=float).reshape(-1, 6)
    raster = len(p) > RASTER_POINTS
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2), constrained_layout=True)
    deg = np.rad2deg(p[:, 3:])
    layers = (
        (axes[0], p[:, 0], p[:, 1], p[:, 2], ("x (mm)", "y (mm)", "z (mm)"), (0, 1)),
        (axes[1], deg[:, 0], deg[:, 1], deg[:, 2], ("a (deg)", "b (deg)", "c (deg)"), (3, 4)),
    )
    for ax, u, v, w, labels, (i, j) in layers:
        dots = ax.scatter(u, v, c=w, s=12, cmap="viridis", rasterized=raster)
        if box is not None:
            b = np.asarray(box, dtype=float)
            if i >= 3:
                b = np.rad2deg(b)
            ax.add_patch(
                plt.Rectangle(
                    (b[i, 0], b[j, 0]),
                    b[i, 1] - b[i, 0],
                    b[j, 1] - b[j, 0],
                    fill=False,
                    ls="--",
                    color="0.5",
                    label="workspace box",
                )
            )
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        fig.colorbar(dots, ax=ax, label=labels[2])
        ax.grid(True, alpha=0.3)
    fig.suptitle(f"{title} ({len(p)} poses)")
    return fig


def validation_errors(ids: Sequence[str], errors: Mapping[str, Mapping[str, Any]]) -> Any:
    """Position and orientation error per held-out pose, one line style per geometry."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), constrained_layout=True)
    k = np.arange(len(ids))
    raster = len(ids) > RASTER_POINTS
    for (name, err), marker in zip(errors.items(), ("o", "s", "^"), strict=False):
        axes[0].semilogy(k, err["position_error"], marker, ms=3, label=name, rasterized=raster)
        axes[1].semilogy(
            k, np.asarray(err["orientation_error"]) * 1e3, marker, ms=3, label=name, rasterized=raster
        )
    for ax, label in zip(axes, ("position error (mm)", "orientation error (mrad)"), strict=True):
        ax.set_xlabel("held-out pose (file order)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.suptitle(f"Pose errors of {len(ids)} held-out poses")
    return fig


def validation_distributions(errors: Mapping[str, Mapping[str, Any]]) -> Any:
    """Histograms of the held-out position and orientation errors (shared bins per panel)."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), constrained_layout=True)
    for ax, key, scale, label in (
        (axes[0], "position_error", 1.0, "position error (mm)"),
        (axes[1], "orientation_error", 1e3, "orientation error (mrad)"),
    ):
        # NaN where the instrument gives no platform pose (one target): nothing to count
        data = [np.asarray(e[key], dtype=float) * scale for e in errors.values()]
        data = [d[np.isfinite(d)] for d in data]
        top = max((float(np.max(d)) for d in data if d.size), default=1.0)
        bins = np.linspace(0, top * 1.02 if top > 0 else 1.0, 30)
        for (name, _), values, style in zip(errors.items(), data, ("-", "--", ":"), strict=False):
            ax.hist(values, bins=bins, histtype="step", ls=style, lw=1.5, label=name)
        if not any(d.size for d in data):
            ax.text(0.5, 0.5, "no platform pose from this instrument", ha="center", transform=ax.transAxes)
        ax.set_xlabel(label)
        ax.set_ylabel("poses")
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    fig.suptitle("Distribution of the held-out pose errors")
    return fig
