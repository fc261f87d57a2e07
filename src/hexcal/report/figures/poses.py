"""Figures over poses: residuals per measured pose, poses in the workspace, pose errors
of held-out poses (the validate page and the paper's Fig. 11 are one figure) and their
distributions.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.ticker import FuncFormatter, MaxNLocator

from hexcal.report.figures.render import (
    RASTER_POINTS,
    legend_outside,
    log_ticks,
    note,
    one_trial,
    plain,
    plt,
    save_png,
)

#: Marker size of a pose alone at its place (points²).
POSE_MARKER = 30.0

#: Colours of the third coordinate: viridis without its palest yellow (rings on white).
POSE_COLOURS = ListedColormap(plt.get_cmap("viridis")(np.linspace(0.0, 0.85, 256)), "viridis-dark")

#: Above this many poses a projection is a cloud of small dots (poses of a large set rarely
#: coincide, and rings would hide the cloud).
RING_LIMIT = 200

#: Rings drawn at one place at most (the count beside says how many poses are there).
MAX_RINGS = 8


#: Most pose ids written under an axis (more poses: ids at evenly spread ticks).
MAX_ID_TICKS = 24


def id_axis(ax: Any, ids: Sequence[str]) -> None:
    """Label the x positions ``0 .. n-1`` of ``ax`` by the poses' ids (every one for a few
    poses, else at evenly spread integer ticks), as the tables and reports name the poses."""
    names = [str(i) for i in ids]
    ax.xaxis.set_major_locator(MaxNLocator(nbins=MAX_ID_TICKS, integer=True, min_n_ticks=1))

    def name(x: float, _: Any) -> str:
        k = round(x)
        return names[k] if abs(x - k) < 1e-6 and 0 <= k < len(names) else ""

    ax.xaxis.set_major_formatter(FuncFormatter(name))
    if max((len(n) for n in names), default=0) > 4:
        ax.tick_params(axis="x", labelrotation=45)


def pose_residuals(
    ids: Sequence[str],
    before: Any,
    after: Any,
    marked: Mapping[str, Sequence[str]] | None = None,
) -> Any:
    """RMS leg residual per pose with the nominal and the identified parameters (log scale);
    ``marked`` labels sets of pose ids (outliers, flagged poses) drawn over them."""
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
                k[sel], np.maximum(after[sel], 1e-12), style, ms=9, mfc="none", color="C3", label=plain(label)
            )
    ax.set_xlabel("measured pose (id)")
    ax.set_ylabel("RMS leg residual (mm)")
    log_ticks(ax)
    id_axis(ax, ids)
    ax.grid(True, which="both", alpha=0.3)
    legend_outside(ax)
    ax.set_title(f"Leg residuals per pose ({len(ids)} poses)")
    return fig


def stacked(u: Any, v: Any, span: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """For each point, how many earlier points lie on it (within 1 % of the axis span) and
    how many lie there in all: the depth of its ring and the count written beside it.

    >>> depth, count = stacked([0, 0, 1, 0], [0, 0, 0, 0], (10.0, 10.0))
    >>> depth.tolist(), count.tolist()
    ([0, 1, 0, 2], [3, 3, 1, 3])
    """
    cells = list(
        zip(
            np.round(np.asarray(u, dtype=float) / max(span[0] * 0.01, 1e-12)).tolist(),
            np.round(np.asarray(v, dtype=float) / max(span[1] * 0.01, 1e-12)).tolist(),
            strict=True,
        )
    )
    depth = np.zeros(len(cells), dtype=int)
    seen: dict[tuple[float, float], int] = {}
    for k, cell in enumerate(cells):
        depth[k] = seen.get(cell, 0)
        seen[cell] = depth[k] + 1
    return depth, np.array([seen[cell] for cell in cells], dtype=int)


def workspace_poses(
    poses: Any, box: Any | None = None, title: str = "Measured poses in the workspace"
) -> Any:
    """Every pose visible: positions x–y (colour z) and angles a–b (colour c), in mm and
    degrees. Poses that fall on one place of a projection are drawn as concentric rings, one
    ring per pose (up to :data:`MAX_RINGS`), with their count beside: never one dot for seven
    (sets of more than :data:`RING_LIMIT` poses: a cloud of small dots)."""
    p = np.asarray(poses, dtype=float).reshape(-1, 6)
    raster = len(p) > RASTER_POINTS
    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.4), constrained_layout=True)
    values = np.column_stack([p[:, :3], np.rad2deg(p[:, 3:])])
    b = None if box is None else np.asarray(box, dtype=float).copy()
    if b is not None:
        b[3:] = np.rad2deg(b[3:])
    shared = []  # (places, projection, rings drawn) of each panel
    panels = (((0, 1, 2), ("x (mm)", "y (mm)", "z (mm)")), ((3, 4, 5), ("a (deg)", "b (deg)", "c (deg)")))
    for ax, ((i, j, w), labels) in zip(axes, panels, strict=True):
        u, v, c = values[:, i], values[:, j], values[:, w]
        span = (float(np.ptp(u)) or 1.0, float(np.ptp(v)) or 1.0)
        if b is not None:
            span = (max(span[0], b[i, 1] - b[i, 0]), max(span[1], b[j, 1] - b[j, 0]))
        depth, count = stacked(u, v, span)
        rings = count.max() > 1 and len(p) <= RING_LIMIT
        shared.append((int(np.sum(depth == 0)), labels[0][0] + "–" + labels[1][0], rings))
        lo, hi = float(np.min(c)), float(np.max(c))
        mappable = ScalarMappable(Normalize(lo, hi if hi > lo else lo + 1), POSE_COLOURS)
        if rings:
            # rings: the radius grows by a marker's radius per pose at one place
            radius = 1 + 0.75 * np.minimum(depth, MAX_RINGS)
            order = np.argsort(-depth, kind="stable")
            ax.scatter(
                u[order],
                v[order],
                s=POSE_MARKER * radius[order] ** 2,
                facecolors="none",
                edgecolors=mappable.to_rgba(c[order]),
                linewidths=1.2,
                rasterized=raster,
            )
            for k in np.flatnonzero((depth == 0) & (count > 1)):
                ax.annotate(
                    f"×{count[k]}", (u[k], v[k]), xytext=(8, 8), textcoords="offset points", fontsize=7
                )
        else:
            small = len(p) > RING_LIMIT
            ax.scatter(
                u,
                v,
                s=POSE_MARKER * (0.2 if small else 0.5),
                c=mappable.to_rgba(c),
                alpha=0.6 if small else 1.0,
                rasterized=raster,
            )
        if b is not None:
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
            ax.margins(0.1)
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        fig.colorbar(mappable, ax=ax, label=labels[2])
        ax.grid(True, alpha=0.3)
    where = ""
    if any(r for _, _, r in shared):
        places = " and ".join(f"{n} {what}" for n, what, _ in shared)
        where = f" at {places} places; one ring per pose"
    fig.suptitle(f"{plain(title)} ({len(p)} poses{where})")
    return fig


def pose_errors(
    series: Mapping[str, Mapping[str, Any]],
    xlabel: str = "held-out pose (file order)",
    title: str = "",
    numbers: Sequence[int] | None = None,
    text: str = "",
    ids: Sequence[str] | None = None,
) -> Any:
    """Position (mm) and orientation (mrad) error of every pose, one marker and line style
    per series (``{label: {"position": mm, "orientation": rad}}``), log scale; ``numbers``
    labels the x positions (default 0, 1, ...), or ``ids`` names the poses under the axis;
    ``text`` is the conditions line below."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.9), constrained_layout=True)
    styles = (("s", "-", "C0"), ("o", "--", "C1"), ("^", ":", "C2"))
    first = next(iter(series.values()))
    n = len(first["position"])
    k = np.arange(n) if numbers is None else np.asarray(numbers)
    raster = n > RASTER_POINTS
    line = n <= 40
    for (label, err), (marker, ls, color) in zip(series.items(), styles, strict=False):
        for ax, key, scale in ((axes[0], "position", 1.0), (axes[1], "orientation", 1e3)):
            ax.semilogy(
                k,
                np.asarray(err[key], dtype=float) * scale,
                marker,
                ls=ls if line else "none",
                ms=4 if line else 3,
                color=color,
                label=plain(label),
                rasterized=raster,
            )
    for ax, ylabel in zip(axes, ("position error (mm)", "orientation error (mrad)"), strict=True):
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        log_ticks(ax)
        if ids is not None:
            id_axis(ax, ids)
        elif n <= 20 and numbers is not None:
            ax.set_xticks(k)
        else:
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(True, which="both", alpha=0.3)
    legend_outside(axes[1])
    fig.suptitle(title or f"Pose errors of {n} held-out poses")
    note(fig, text)
    return fig


def validation_errors(ids: Sequence[str], errors: Mapping[str, Mapping[str, Any]]) -> Any:
    """The validate page's pose errors: :func:`pose_errors` of each geometry's
    ``ValidationResult.to_dict()``."""
    series = {
        name: {"position": e["position_error"], "orientation": e["orientation_error"]}
        for name, e in errors.items()
    }
    title = f"Pose errors of {len(ids)} held-out poses"
    return pose_errors(series, "held-out pose (id)", title=title, ids=ids)


def validation_errors_figure(data: Mapping[str, Any]) -> Any:
    """Like the paper's Fig. 11: :func:`pose_errors` at the validation corners of the first
    trial, nominal and identified parameters; the conditions line says it is one trial."""
    before, after = data["validation_before"], data["validation_after"]
    series = {"identified parameters (15 corners)": after, "nominal parameters": before}
    numbers = np.arange(1, len(before["position"]) + 1)
    trials = int(data.get("trials", 1))
    title = (
        "Pose errors at the validation corners (first trial)"
        if trials > 1
        else ("Pose errors at the validation corners (one trial)")
    )
    return pose_errors(
        series, "validation pose (corner number)", title, numbers, one_trial(data.get("note", ""), trials)
    )


def plot_validation_errors(data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """:func:`validation_errors_figure` written as a PNG file."""
    save_png(validation_errors_figure(data), path)


def validation_distributions(errors: Mapping[str, Mapping[str, Any]]) -> Any:
    """Histograms of the held-out position and orientation errors, every geometry's shape
    visible: when the geometries' errors are a decade or more apart (millimetres before
    calibration, micrometres after), a logarithmic axis with each geometry's own logarithmic
    bins, where shared linear bins would put the calibrated errors into one bar."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.9), constrained_layout=True)
    for ax, key, scale, label in (
        (axes[0], "position_error", 1.0, "position error (mm)"),
        (axes[1], "orientation_error", 1e3, "orientation error (mrad)"),
    ):
        data = [np.asarray(e[key], dtype=float) * scale for e in errors.values()]
        data = [d[np.isfinite(d)] for d in data]
        finite = np.concatenate(data) if data else np.zeros(0)
        positive = finite[finite > 0]
        medians = [float(np.median(d[d > 0])) for d in data if (d > 0).any()]
        # geometries a decade or more apart (before and after calibration): log axis
        logarithmic = len(medians) > 1 and max(medians) > 10 * min(medians)
        if logarithmic:
            ax.set_xscale("log")
            log_ticks(ax, "x")
        else:
            top = float(finite.max()) if finite.size else 1.0
            shared = np.linspace(0, top * 1.02 if top > 0 else 1.0, 30)
        for name, values, style in zip(errors, data, ("-", "--", ":"), strict=False):
            if logarithmic:
                values = np.maximum(values, positive.min())  # an exact 0 at the smallest error shown
                count = int(np.clip(2 * np.sqrt(values.size), 6, 30)) if values.size else 1
                lo, hi = (float(values.min()), float(values.max())) if values.size else (1.0, 1.0)
                bins = np.geomspace(lo * 0.97, hi * 1.03, count + 1)
            else:
                bins = shared
            ax.hist(values, bins=bins, histtype="step", ls=style, lw=1.5, label=plain(name))
        ax.set_xlabel(label + (", logarithmic bins" if logarithmic else ""))
        ax.set_ylabel("poses")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    legend_outside(axes[1])
    fig.suptitle("Distribution of the held-out pose errors")
    return fig
