"""Gauge freedoms of instrument setups: detect them, fix them by a convention, project.

With the instrument frame identified, the base frame is defined only up to a rigid motion:
moving the base joints, every pose and the instrument frame together changes no prediction.
With the targets (or the tool) identified, the platform frame is likewise free (moving the
platform joints and the targets together). That is up to 12 parameter combinations no data
can determine. hexcal

- **detects** them: the generators of the two rigid motions (derivatives of
  :func:`transform_parameters`), kept where they touch only varied parameters, checked to lie
  in the null space of the Jacobian;
- **removes** them by the convention: *the base frame is the one in which the identified base
  joints are closest (least squares) to their nominal positions, and the platform frame the
  one in which the platform joints are closest to theirs* (:func:`apply_convention`, a Kabsch
  fit after the solve);
- **projects** the covariance onto that convention: the linearised convention is
  ``Gᵀ M δ = 0`` (``M`` selects the joint coordinates), so the gauge-fixed estimate is
  ``P δ`` with the oblique projector ``P = I - G (Gᵀ M G)⁻¹ Gᵀ M``, and its covariance is
  ``P (JᵀJ)⁺ Pᵀ`` (:func:`gauge_projector`).

Combinations the data cannot determine beyond the gauges (too few targets or poses) are
named separately (:func:`unidentifiable`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexcal.core.linalg import scaled_svd
from hexcal.estimation.problem import Problem

#: The convention, as reports state it.
CONVENTION = (
    "gauge convention: base frame with the base joints closest to nominal, "
    "platform frame with the platform joints closest to nominal (least squares)"
)
GAUGE_LABELS = tuple(
    f"{frame} {kind} {axis}"
    for frame in ("base", "platform")
    for kind in ("translation", "rotation")
    for axis in "xyz"
)
_STEP = 1e-6
_TOUCH_TOL = 1e-9


def _rotation(rotvec: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrix of a rotation vector (Rodrigues)."""
    theta = float(np.linalg.norm(rotvec))
    k = np.array([[0, -rotvec[2], rotvec[1]], [rotvec[2], 0, -rotvec[0]], [-rotvec[1], rotvec[0], 0]])
    if theta < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + np.sin(theta) / theta * k + (1 - np.cos(theta)) / theta**2 * k @ k


def transform_parameters(
    problem: Problem,
    full: NDArray[np.float64],
    base: tuple[NDArray, NDArray] | None = None,
    platform: tuple[NDArray, NDArray] | None = None,
) -> NDArray[np.float64] | None:
    """All parameter values in new base (``p' = R_b p + t_b``) and platform coordinates, or
    None when an instrument is tied to the base frame (no such change exists).

    Predictions do not change (the poses move with the frames); the leg model stays.
    """
    eye = (np.eye(3), np.zeros(3))
    (rb, tb), (rp, tp) = base or eye, platform or eye
    out = np.array(full)
    joints = full[problem.joints]
    u = (joints[:18].reshape(6, 3) @ rb.T + tb).ravel()
    s = (joints[18:36].reshape(6, 3) @ rp.T + tp).ravel()
    out[problem.joints] = np.concatenate([u, s])
    for part in problem.parts:
        if part.block.stop > part.block.start:
            moved = part.instrument.transform_setup(full[part.block], (rb, tb), (rp, tp), problem.euler)
            if moved is None:
                return None
            out[part.block] = moved
    return out


def _motion(k: int, eps: float) -> tuple[NDArray, NDArray]:
    vec = np.zeros(6)
    vec[k % 6] = eps
    return _rotation(vec[3:]), vec[:3]


@dataclass(frozen=True)
class Gauge:
    """The gauge freedoms of a problem at some parameter values.

    Attributes
    ----------
    generators : ndarray, shape (n_free, g)
        Directions in solver units.
    labels : tuple of str
        ``base translation x`` ... ``platform rotation z``.
    metric : ndarray, shape (n_free,)
        1 on the joint coordinates the convention uses, else 0.
    """

    generators: NDArray[np.float64]
    labels: tuple[str, ...]
    metric: NDArray[np.float64]

    @property
    def size(self) -> int:
        return len(self.labels)

    @property
    def base(self) -> bool:
        return any(lab.startswith("base") for lab in self.labels)

    @property
    def platform(self) -> bool:
        return any(lab.startswith("platform") for lab in self.labels)


def gauge_freedoms(problem: Problem, full: NDArray[np.float64]) -> Gauge:
    """Detect the base and platform gauges of ``problem`` at ``full`` (none where an
    instrument is tied to the base frame, or a motion touches a parameter held fixed)."""
    mask, scale = problem.mask, problem.scale
    cols, labels = [], []
    # a frame is free only where an instrument's own quantities move with it
    moving = any(problem.free_in(part.block).any() for part in problem.parts)
    for k, label in enumerate(GAUGE_LABELS if moving else ()):
        plus, minus = _motion(k, _STEP), _motion(k, -_STEP)
        args = ({"base": plus}, {"base": minus}) if k < 6 else ({"platform": plus}, {"platform": minus})
        hi = transform_parameters(problem, full, **args[0])
        lo = transform_parameters(problem, full, **args[1])
        if hi is None or lo is None:
            break
        diff = (hi - lo) / (2 * _STEP)
        if np.linalg.norm(diff[~mask]) <= _TOUCH_TOL * np.linalg.norm(diff):
            cols.append(diff[mask] / scale)
            labels.append(label)
    metric = np.zeros(len(mask))
    metric[problem.joints] = 1.0
    gen = np.array(cols).T if cols else np.zeros((int(mask.sum()), 0))
    return Gauge(gen, tuple(labels), metric[mask] * scale**2)


def complement_basis(gauge: Gauge) -> NDArray[np.float64]:
    """Orthonormal basis ``(n_free, n_free - g)`` of the solver directions orthogonal to the gauges."""
    n, g = gauge.generators.shape
    if g == 0:
        return np.eye(n)
    u, _, _ = np.linalg.svd(gauge.generators, full_matrices=True)
    return u[:, g:]


def gauge_projector(gauge: Gauge) -> NDArray[np.float64]:
    """The oblique projector ``P = I - G (Gᵀ M G)⁻¹ Gᵀ M`` onto the convention (solver units)."""
    g, n = gauge.generators, gauge.generators.shape[0]
    if g.shape[1] == 0:
        return np.eye(n)
    mg = gauge.metric[:, None] * g
    return np.eye(n) - g @ np.linalg.solve(g.T @ mg, mg.T)


def _kabsch(points: NDArray[np.float64], nominal: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Rigid motion ``(R, t)`` with ``R points + t`` closest to ``nominal``."""
    from scipy.spatial.transform import Rotation  # deferred: slow to import

    cp, cn = points.mean(axis=0), nominal.mean(axis=0)
    rot = Rotation.align_vectors(nominal - cn, points - cp)[0].as_matrix()
    return rot, cn - rot @ cp


def apply_convention(problem: Problem, full: NDArray[np.float64], gauge: Gauge) -> NDArray[np.float64]:
    """Parameter values in the convention's base and platform frames (see module)."""
    joints, nominal = full[problem.joints], problem.full0[problem.joints]
    base = _kabsch(joints[:18].reshape(6, 3), nominal[:18].reshape(6, 3)) if gauge.base else None
    plat = _kabsch(joints[18:36].reshape(6, 3), nominal[18:36].reshape(6, 3)) if gauge.platform else None
    out = transform_parameters(problem, full, base, plat)
    return full if out is None else out


def unidentifiable(
    problem: Problem, jac: NDArray[np.float64], gauge: Gauge, rtol: float = 1e-8, top: int = 4
) -> list[str]:
    """Parameter combinations that the Jacobian (solver units) cannot determine beyond the gauges."""
    basis = complement_basis(gauge)
    reduced = jac @ basis
    svd = scaled_svd(reduced)
    sv = svd.singular_values
    weak = np.flatnonzero(sv <= rtol * sv[0]) if sv.size else []
    out = []
    for k in weak:
        vec = basis @ (svd.vt[k] / svd.norms)
        out.append(problem.combination(vec / np.max(np.abs(vec)), top))
    return out
