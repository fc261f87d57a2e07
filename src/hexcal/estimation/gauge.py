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
    """Rotation matrix of a rotation vector."""
    from scipy.spatial.transform import Rotation  # deferred: slow to import

    return Rotation.from_rotvec(rotvec).as_matrix()


def transform_parameters(
    problem: Problem,
    full: NDArray[np.float64],
    base: tuple[NDArray, NDArray] | None = None,
    platform: tuple[NDArray, NDArray] | None = None,
) -> NDArray[np.float64] | None:
    """All parameter values in new base (``p' = R_b p + t_b``) and platform coordinates, or
    None when an instrument is tied to the base frame (no such change exists).

    Batch-first: ``full`` ``(..., N)`` with rotations ``(..., 3, 3)`` and translations
    ``(..., 3)`` that broadcast. Predictions do not change (the poses move with the frames);
    the leg model stays.
    """
    eye = (np.eye(3), np.zeros(3))
    (rb, tb), (rp, tp) = base or eye, platform or eye
    full = np.asarray(full, dtype=float)
    out = np.array(full)
    joints = full[..., problem.joints]
    lead = joints.shape[:-1]
    u = joints[..., :18].reshape(*lead, 6, 3) @ np.swapaxes(rb, -1, -2) + np.asarray(tb)[..., None, :]
    s = joints[..., 18:36].reshape(*lead, 6, 3) @ np.swapaxes(rp, -1, -2) + np.asarray(tp)[..., None, :]
    out[..., problem.joints] = np.concatenate([u.reshape(*lead, 18), s.reshape(*lead, 18)], axis=-1)
    for part in problem.parts:
        if part.block.stop > part.block.start:
            moved = part.instrument.transform_setup(full[..., part.block], (rb, tb), (rp, tp), problem.euler)
            if moved is None:
                return None
            out[..., part.block] = moved
    return out


def _motions() -> tuple[tuple[NDArray, NDArray], tuple[NDArray, NDArray]]:
    """The base and platform motions of the central differences, stacked ``(24, 1, ...)``: the
    six base motions by ``+_STEP`` then by ``-_STEP`` (platform fixed), then the platform's."""
    vec = np.concatenate([np.eye(6), -np.eye(6)]) * _STEP  # (12, 6): +e_k, then -e_k
    rot, shift = _rotation(vec[:, 3:]), vec[:, :3]
    still = (np.broadcast_to(np.eye(3), rot.shape), np.zeros_like(shift))
    rb, tb = np.concatenate([rot, still[0]]), np.concatenate([shift, still[1]])
    rp, tp = np.concatenate([still[0], rot]), np.concatenate([still[1], shift])
    return (rb[:, None], tb[:, None]), (rp[:, None], tp[:, None])


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
    labels, generators = gauge_generators(problem, np.asarray(full, dtype=float)[None])
    metric = np.zeros(len(problem.mask))
    metric[problem.joints] = 1.0
    return Gauge(generators[0], labels, metric[problem.mask] * problem.scale**2)


def gauge_generators(
    problem: Problem, full: NDArray[np.float64]
) -> tuple[tuple[str, ...], NDArray[np.float64]]:
    """The gauge freedoms of ``problem``'s layout at the values of ``T`` trials ``(T, N)``: their
    labels and each trial's generators ``(T, n_free, g)`` in solver units (derivatives of
    :func:`transform_parameters`, kept where they touch only varied parameters)."""
    mask, scale = problem.mask, problem.scale
    t = len(full)
    cols, labels = [], []
    # a frame is free only where an instrument's own quantities move with it
    moving = any(problem.free_in(part.block).any() for part in problem.parts)
    # the 24 moved parameter sets in one batched call (24 calls cost a fifth of a registration)
    moved = None
    if moving:
        base, platform = _motions()
        moved = transform_parameters(problem, np.broadcast_to(full, (24, *full.shape)), base, platform)
    for k, label in enumerate(GAUGE_LABELS if moved is not None else ()):
        hi, lo = (moved[k], moved[k + 6]) if k < 6 else (moved[k + 6], moved[k + 12])
        diff = (hi - lo) / (2 * _STEP)
        touch = np.linalg.norm(diff[:, ~mask], axis=1) <= _TOUCH_TOL * np.linalg.norm(diff, axis=1)
        if touch.all():
            cols.append(diff[:, mask] / scale)
            labels.append(label)
    gen = np.stack(cols, axis=-1) if cols else np.zeros((t, int(mask.sum()), 0))
    return tuple(labels), gen


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


def kabsch(points: NDArray[np.float64], nominal: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Rigid motions ``(R, t)`` with ``R points + t`` closest to ``nominal`` (least squares),
    batch-first: points ``(..., k, 3)``, rotations ``(..., 3, 3)``, translations ``(..., 3)``
    (the orthogonal Procrustes solution from the SVD of the cross-covariance)."""
    cp, cn = points.mean(axis=-2), nominal.mean(axis=-2)
    cross = np.swapaxes(points - cp[..., None, :], -1, -2) @ (nominal - cn[..., None, :])
    u, _, vt = np.linalg.svd(cross)
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.ones((*d.shape, 3))
    fix[..., 2] = np.where(d == 0, 1.0, d)
    rot = np.swapaxes(vt, -1, -2) @ (fix[..., :, None] * np.swapaxes(u, -1, -2))
    return rot, cn - np.einsum("...ij,...j->...i", rot, cp)


def apply_convention(
    problem: Problem, full: NDArray[np.float64], gauge: Gauge | tuple[str, ...]
) -> NDArray[np.float64]:
    """Parameter values in the convention's base and platform frames (see module), batch-first:
    ``full`` ``(..., N)``; ``gauge`` the gauge freedoms (or their labels)."""
    labels = gauge.labels if isinstance(gauge, Gauge) else tuple(gauge)
    full = np.asarray(full, dtype=float)
    joints, nominal = full[..., problem.joints], problem.full0[problem.joints]
    lead = joints.shape[:-1]
    base = plat = None
    if any(label.startswith("base") for label in labels):
        base = kabsch(joints[..., :18].reshape(*lead, 6, 3), nominal[:18].reshape(6, 3))
    if any(label.startswith("platform") for label in labels):
        plat = kabsch(joints[..., 18:36].reshape(*lead, 6, 3), nominal[18:36].reshape(6, 3))
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
