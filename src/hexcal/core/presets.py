"""Built-in geometries.

``paper-hmt`` and ``paper-hmt-true`` are the seed paper's hexapod machine tool:
nominal and simulated real values from Nategh & Agheli's companion paper
(Tables 1 and 2), with the leg limits, home pose and workspace box of
``shared/reference/paper-hmt.md``.
"""

from __future__ import annotations

import numpy as np

from hexcal.core.geometry import Geometry

# Rows: s_i (x, y, z), u_i (x, y, z), l0_i; mm.
_PAPER_NOMINAL = np.array(
    [
        [92.1597, 84.4488, 0, 305.4001, 111.1565, 0, 604.8652],
        [27.0550, 122.0370, 0, -56.4357, 320.0625, 0, 604.8652],
        [-119.2146, 37.5882, 0, -248.9644, 208.9060, 0, 604.8652],
        [-119.2146, -37.5882, 0, -248.9644, -208.9060, 0, 604.8652],
        [27.0550, -122.0370, 0, -56.4357, -320.0625, 0, 604.8652],
        [92.1597, -84.4488, 0, 305.4001, -111.1565, 0, 604.8652],
    ]
)
_PAPER_TRUE = np.array(
    [
        [96.6610, 81.7602, 1.0684, 305.2599, 115.0695, 2.6210, 604.4299],
        [22.2476, 125.2511, -0.5530, -55.2814, 322.9819, 4.2181, 607.2473],
        [-122.4519, 36.6453, 4.3547, -244.7954, 208.0087, 3.9365, 600.4441],
        [-120.6859, -34.4565, -4.9014, -252.5755, -211.8783, -3.0128, 605.9031],
        [24.7769, -125.0489, -4.8473, -53.9678, -320.6115, 4.3181, 604.5251],
        [91.3462, -80.9866, 0.2515, 302.4266, -109.4351, 3.3812, 600.0616],
    ]
)
_PAPER_LIMITS = (604.8652, 1100.0)
_PAPER_HOME = (0.0, 0.0, 800.0, 0.0, 0.0, 0.0)
_TEN_DEG = np.deg2rad(10.0)
_PAPER_WORKSPACE = (
    (-250.0, 250.0),
    (-250.0, 250.0),
    (700.0, 900.0),
    (-_TEN_DEG, _TEN_DEG),
    (-_TEN_DEG, _TEN_DEG),
    (-_TEN_DEG, _TEN_DEG),
)


def _paper(table: np.ndarray, name: str) -> Geometry:
    return Geometry(
        base_joints=table[:, 3:6],
        platform_joints=table[:, 0:3],
        initial_leg_lengths=table[:, 6],
        leg_length_limits=_PAPER_LIMITS,
        home_pose=_PAPER_HOME,
        workspace=_PAPER_WORKSPACE,
        name=name,
    )


PRESETS = {
    "paper-hmt": lambda: _paper(_PAPER_NOMINAL, "paper-hmt"),
    "paper-hmt-true": lambda: _paper(_PAPER_TRUE, "paper-hmt-true"),
}


def preset(name: str) -> Geometry:
    """A built-in geometry by name (see :data:`PRESETS`)."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise ValueError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}") from None
