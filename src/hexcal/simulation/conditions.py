"""The conditions of simulated campaigns: a warm-up, constant temperatures, payload cases.

Each function returns the :class:`~hexcal.instruments.Covariates` of a campaign's poses, in
order, for :func:`hexcal.simulation.simulate_session` (``covariates=``), whose true machine
then reaches its poses under them when its leg model reads them
(:mod:`hexcal.core.covariate_legs`: its legs warm and give).

>>> warm_up(4, 20.0, 5.0, duration=3600.0).temperatures[:, 0].round(2).tolist()
[20.0, 22.64, 23.88, 24.47]
>>> payload_cases(4, [0.0, 50.0]).payload_kg.tolist()
[0.0, 50.0, 0.0, 50.0]
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from hexcal.instruments.covariates import Covariates

#: Time constant of a warm-up as a share of its duration (the legs settle within the session).
WARM_UP_TIME_CONSTANT = 1.0 / 3.0


def warm_up(
    poses: int,
    start: float,
    rise: float,
    *,
    duration: float = 3600.0,
    legs: ArrayLike = 1.0,
    time_constant: float | None = None,
) -> Covariates:
    """The legs' temperatures of a session measured while the machine warms up.

    Each leg goes from ``start`` °C towards ``start + rise * legs_i`` along a first-order
    response ``1 - exp(-t / τ)`` over ``duration`` s (``τ`` default a third of it), one pose
    every ``duration / poses`` s from ``t = 0``.

    Parameters
    ----------
    poses : int
    start, rise : float
        °C and K.
    duration : float
        s.
    legs : array_like, shape (6,) or ()
        Each leg's share of the rise (its motor and screw warm it more or less).
    time_constant : float, optional
        s.
    """
    t = np.arange(poses) * (duration / poses)
    tau = duration * WARM_UP_TIME_CONSTANT if time_constant is None else float(time_constant)
    share = np.broadcast_to(np.asarray(legs, dtype=float), (6,))
    temps = start + rise * (1.0 - np.exp(-t / tau))[:, None] * share
    one = bool(np.all(share == share[0]))
    return Covariates(time=t, temperatures=temps[:, 0] if one else temps)


def constant_temperature(poses: int, temperature: float) -> Covariates:
    """One temperature (°C) for every leg at every pose (a session at a settled temperature)."""
    return Covariates(temperatures=np.full(poses, float(temperature)))


def payload_cases(
    poses: int, masses: Sequence[float], centre: ArrayLike | None = None, temperature: float | None = None
) -> Covariates:
    """Payloads of ``masses`` kg taken in turn, pose after pose (their centre of mass ``centre``
    mm in the platform frame, default none given: the platform's origin), optionally at one
    ``temperature``."""
    mass = np.resize(np.asarray(masses, dtype=float), poses)
    com = None if centre is None else np.broadcast_to(np.asarray(centre, dtype=float), (poses, 3))
    temps = None if temperature is None else np.full(poses, float(temperature))
    return Covariates(temperatures=temps, payload_kg=mass, payload_com=com)


__all__ = ["constant_temperature", "payload_cases", "warm_up"]
