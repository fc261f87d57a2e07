"""The one linear-algebra rule of hexcal: scaled SVD, numerical rank, pseudo-inverse, whitening.

Identifiability, covariances and Cramér–Rao bounds all judge a Jacobian the same way:
its columns are normalised to unit length (so the judgement does not depend on parameter
units), and a singular value below :data:`RANK_RTOL` times the largest counts as zero.
Covariances are pseudo-inverses built from that SVD, as ``scipy.optimize.curve_fit`` does,
never ``inv(JᵀJ)``.

Imports numpy only.

>>> import numpy as np
>>> jac = np.array([[1.0, 2.0], [2.0, 4.0], [0.0, 0.0]])  # the second column is twice the first
>>> numerical_rank(scaled_svd(jac).singular_values)
1
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Singular values of the column-normalised Jacobian below this fraction of the largest
#: count as zero (the parameter combination is not determined by the data).
RANK_RTOL = 1e-8


@dataclass(frozen=True)
class ScaledSVD:
    """SVD of ``A diag(1/norms)``: ``A`` with every column scaled to unit length.

    Attributes
    ----------
    norms : ndarray, shape (..., n)
        Column norms of ``A`` (1 where a column is zero).
    singular_values : ndarray, shape (..., k)
        Descending.
    vt : ndarray, shape (..., k, n)
        Row ``i`` is the (normalised-parameter) direction of ``singular_values[i]``.
    """

    norms: NDArray[np.float64]
    singular_values: NDArray[np.float64]
    vt: NDArray[np.float64]


def column_norms(a: ArrayLike) -> NDArray[np.float64]:
    """Column norms of ``a`` (shape ``(..., r, n)``), with 1 in place of 0."""
    norms = np.linalg.norm(np.asarray(a, dtype=float), axis=-2)
    return np.where(norms > 0, norms, 1.0)


def scaled_svd(a: ArrayLike, full_matrices: bool = False) -> ScaledSVD:
    """SVD of the column-normalised matrix (batched over leading axes)."""
    a = np.asarray(a, dtype=float)
    norms = column_norms(a)
    _, sv, vt = np.linalg.svd(a / norms[..., None, :], full_matrices=full_matrices)
    return ScaledSVD(norms, sv, vt)


def numerical_rank(singular_values: ArrayLike, rtol: float = RANK_RTOL) -> int:
    """Number of singular values above ``rtol`` times the largest (0 for an empty or zero set)."""
    sv = np.asarray(singular_values, dtype=float)
    if sv.size == 0 or not sv[0] > 0:
        return 0
    return int(np.sum(sv > rtol * sv[0]))


def gram_pinv(svd: ScaledSVD, rtol: float = RANK_RTOL) -> NDArray[np.float64]:
    """``(AᵀA)⁺`` in the units of ``A``'s columns, from :func:`scaled_svd` (batched).

    Directions whose singular value is below ``rtol`` times the largest are left out
    (their variance is not determined); with full rank this is ``inv(AᵀA)``.
    """
    sv = svd.singular_values
    keep = sv > rtol * sv[..., :1]
    inv_sv = np.where(keep, 1.0 / np.where(keep, sv, 1.0), 0.0)
    vs = np.swapaxes(svd.vt, -1, -2) * inv_sv[..., None, :]
    cov = vs @ np.swapaxes(vs, -1, -2)
    return cov / (svd.norms[..., :, None] * svd.norms[..., None, :])


def gram_pinv_diagonal(svd: ScaledSVD, rtol: float = RANK_RTOL) -> NDArray[np.float64]:
    """The diagonal of :func:`gram_pinv` without forming the matrix, shape ``(..., n)``."""
    sv = svd.singular_values
    keep = sv > rtol * sv[..., :1]
    inv_sv2 = np.where(keep, 1.0 / np.where(keep, sv, 1.0) ** 2, 0.0)
    return np.einsum("...kp,...k->...p", svd.vt**2, inv_sv2) / svd.norms**2


def whitening(covariances: ArrayLike) -> NDArray[np.float64]:
    """Matrices ``W`` with ``Wᵀ W = C⁻¹`` (inverse Cholesky factors), batched ``(..., k, k)``."""
    chol = np.linalg.cholesky(np.asarray(covariances, dtype=float))
    return np.linalg.inv(chol)


def null_space(a: ArrayLike, rtol: float = RANK_RTOL) -> NDArray[np.float64]:
    """Orthonormal basis (rows, in normalised-column units) of the directions ``A`` cannot see,
    and the column norms to map them back: ``(basis (n - rank, n), norms (n,))``."""
    svd = scaled_svd(a, full_matrices=True)
    sv = np.concatenate([svd.singular_values, np.zeros(svd.vt.shape[-1] - svd.singular_values.size)])
    rank = numerical_rank(sv, rtol)
    return svd.vt[rank:], svd.norms


def floored_whitener(covariance: ArrayLike, floor: float) -> NDArray[np.float64]:
    """``W`` with ``W C Wᵀ = I`` from the eigen-decomposition of ``C`` (k, k), eigenvalues
    floored at ``floor`` so that a zero variance (an exact measurement) stays finite."""
    vals, vecs = np.linalg.eigh(np.asarray(covariance, dtype=float))
    return (vecs / np.sqrt(np.maximum(vals, floor))).T
