"""Observability indices O1–O5 of an identification Jacobian, and its column scaling.

The SVD of the column-scaled identification Jacobian and the indices of the calibration
literature (:func:`observability_indices`): larger is better for all five. The rank
reported beside them follows :mod:`hexcal.core.linalg` whatever the scaling
(:func:`hexcal.design.identifiability.numerical_rank`). Imports :mod:`hexcal.core`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.core import PARAMETER_SCALE, column_norms
from hexcal.design.identifiability import numerical_rank

SCALINGS = ("norm", "parameter", "none")


@dataclass(frozen=True)
class ObservabilityIndices:
    """Singular values and observability indices of a (column-scaled) Jacobian.

    Attributes
    ----------
    singular_values : ndarray, shape (n,)
        Descending; zeros appended when the Jacobian has fewer rows than columns.
    O1, O2, O3, O4, O5 : float
        See :func:`observability_indices`.
    condition_number : float
        ``σ1 / σn`` (inf when ``σn = 0``).
    rank : int
        Numerical rank (judged on the column-normalised Jacobian, whatever the scaling).
    scaling : str
    """

    singular_values: NDArray[np.float64]
    O1: float
    O2: float
    O3: float
    O4: float
    O5: float
    condition_number: float
    rank: int
    scaling: str

    def to_dict(self) -> dict[str, float | int | str | list[float]]:
        """Plain-Python form (for JSON); an infinite condition number stays ``inf``.

        >>> ind = observability_indices(np.eye(2))
        >>> ind.to_dict()["rank"], ind.to_dict()["singular_values"]
        (2, [1.0, 1.0])
        """
        return {
            "scaling": self.scaling,
            "rank": self.rank,
            "singular_values": self.singular_values.tolist(),
            "O1": self.O1,
            "O2": self.O2,
            "O3": self.O3,
            "O4": self.O4,
            "O5": self.O5,
            "condition_number": self.condition_number,
        }

    #: The former name of :meth:`to_dict` (``hexcal observability --json`` still calls it).


def column_scales(
    jacobian: ArrayLike, scaling: str = "norm", parameter_scale: ArrayLike | None = None
) -> NDArray[np.float64]:
    """Factors ``d`` (n,) by which the columns of a Jacobian are multiplied before its SVD.

    Parameters
    ----------
    jacobian : array_like, shape (r, n)
    scaling : {"norm", "parameter", "none"}
        ``norm``: ``d_k = 1 / ||J[:, k]||`` (every column of unit length: the indices no
        longer depend on parameter units or on any prior column scaling);
        ``parameter``: ``d_k`` the characteristic scale of parameter ``k`` (1 mm for joints
        and ``l0``, 1e-3 for gains; a column then reads "residual per characteristic
        parameter error", after Hollerbach & Wampler 1996);
        ``none``: ``d_k = 1`` (parameters in their own units).
    parameter_scale : array_like, shape (n,), optional
        Scales for ``parameter`` (default: :data:`hexcal.core.PARAMETER_SCALE` of the 42 joints
        and ``l0``, which requires ``n == 42``).

    >>> column_scales([[3.0, 0.0], [4.0, 2.0]])
    array([0.2, 0.5])
    """
    jac = np.asarray(jacobian, dtype=float)
    if jac.ndim != 2:
        raise ValueError(f"jacobian must have shape (r, n), got {jac.shape}")
    n = jac.shape[1]
    if scaling == "norm":
        return 1.0 / column_norms(jac)
    if scaling == "parameter":
        scale = PARAMETER_SCALE[:42] if parameter_scale is None else np.asarray(parameter_scale, dtype=float)
        if scale.shape != (n,):
            raise ValueError(f"parameter_scale must have shape ({n},), got {scale.shape}")
        return scale
    if scaling == "none":
        return np.ones(n)
    raise ValueError(f"unknown scaling {scaling!r}; choose from {', '.join(SCALINGS)}")


def indices_from_singular_values(singular_values: ArrayLike) -> dict[str, float]:
    """O1–O5 and the condition number of singular values ``σ1 >= ... >= σn`` (see
    :func:`observability_indices`).

    >>> indices_from_singular_values([4.0, 1.0])
    {'O1': 2.0, 'O2': 0.25, 'O3': 1.0, 'O4': 0.25, 'O5': 0.8, 'condition_number': 4.0}
    """
    sv = np.sort(np.asarray(singular_values, dtype=float))[::-1]
    smax, smin = float(sv[0]), float(sv[-1])
    positive = smin > 0
    with np.errstate(divide="ignore"):
        o1 = float(np.exp(np.mean(np.log(sv)))) if positive else 0.0
        o5 = float(1.0 / np.sum(1.0 / sv)) if positive else 0.0
    return {
        "O1": o1,
        "O2": smin / smax if smax > 0 else 0.0,
        "O3": smin,
        "O4": smin**2 / smax if smax > 0 else 0.0,
        "O5": o5,
        "condition_number": smax / smin if positive else float("inf"),
    }


def observability_indices(
    jacobian: ArrayLike,
    scaling: str = "norm",
    parameter_scale: ArrayLike | None = None,
) -> ObservabilityIndices:
    """Observability indices O1–O5 of an identification Jacobian.

    Parameters
    ----------
    jacobian : array_like, shape (r, n)
        Rows are measurement equations, columns parameters.
    scaling : {"norm", "parameter", "none"}
        Column scaling before the SVD (:func:`column_scales`).
    parameter_scale : array_like, shape (n,), optional
        For ``scaling="parameter"``.

    Returns
    -------
    ObservabilityIndices

    Examples
    --------
    >>> ind = observability_indices(np.diag([2.0, 0.5]), scaling="none")
    >>> ind.O1, ind.O2, ind.O3, ind.O4, ind.rank
    (1.0, 0.25, 0.5, 0.125, 2)

    Notes
    -----
    With ``σ1 >= ... >= σn`` the singular values of ``J D`` (``D`` the column scaling;
    zeros are appended when ``r < n``):

    - ``O1 = (σ1 σ2 ... σn)^(1/n)``, the geometric mean of the singular values (the
      ``n``-th root of the product, i.e. ``det(Dᵀ JᵀJ D)^(1/2n)``): D-optimality, after
      Borm & Menq (1991), who also divide by ``√r``; hexcal does not, so that O1 of a pose
      set grows with the number of poses as the information does;
    - ``O2 = σn / σ1``, the inverse condition number (Driels & Pathre 1990);
    - ``O3 = σn``, the minimum singular value: E-optimality (Nahvi, Hollerbach & Hayward
      1994);
    - ``O4 = σn² / σ1``, the noise amplification index (Nahvi & Hollerbach 1996);
    - ``O5 = 1 / (1/σ1 + ... + 1/σn)``, related to A-optimality (Sun & Hollerbach 2008).

    Larger is better for all five. Under column scaling ``J -> J S`` (``S`` diagonal):
    with ``scaling="norm"`` every index is invariant; otherwise O1 is multiplied by
    ``|det S|^(1/n)`` (so O1 ranks pose sets the same under any units) while O2–O5
    change in general. Multiplying every row by ``c`` multiplies O1, O3, O4 and O5 by
    ``|c|`` and leaves O2 unchanged.

    References
    ----------
    .. [1] J. H. Borm and C. H. Menq, "Determination of optimal measurement
       configurations for robot calibration based on observability measure," Int. J.
       Robotics Research 10(1), 51-63, 1991. doi:10.1177/027836499101000104
    .. [2] M. R. Driels and U. S. Pathre, "Significance of observation strategy on the
       design of robot calibration experiments," J. Robotic Systems 7(2), 197-223, 1990.
       doi:10.1002/rob.4620070204
    .. [3] A. Nahvi, J. M. Hollerbach and V. Hayward, "Calibration of a parallel robot
       using multiple kinematic closed loops," IEEE ICRA 1994, 407-412.
       doi:10.1109/ROBOT.1994.351272
    .. [4] A. Nahvi and J. M. Hollerbach, "The noise amplification index for optimal
       pose selection in robot calibration," IEEE ICRA 1996, 647-654.
       doi:10.1109/ROBOT.1996.503848
    .. [5] Y. Sun and J. M. Hollerbach, "Observability index selection for robot
       calibration," IEEE ICRA 2008, 831-836. doi:10.1109/ROBOT.2008.4543242
    """
    jac = np.asarray(jacobian, dtype=float)
    scales = column_scales(jac, scaling, parameter_scale)
    sv = np.linalg.svd(jac * scales, compute_uv=False)
    sv = np.concatenate([sv, np.zeros(jac.shape[1] - sv.size)])
    values = indices_from_singular_values(sv)
    return ObservabilityIndices(singular_values=sv, rank=numerical_rank(jac), scaling=scaling, **values)
