"""LinuxCNC at run time: a HAL file that trims each joint by its leg's thermal growth.

A thermal leg model says that leg ``i`` is ``delta_i = (alpha_i + kappa_i l_i) (T_i - T_ref)``
longer than its linear model at the same reading (``alpha`` mm/K; ``kappa`` 1/K for growth
proportional to the leg's length ``l_i``, optional), ``T_i`` its temperature. LinuxCNC cannot
read that from the geometry: ``genhexkins`` struts are ``l0 + g dl`` and a ``COMP_FILE`` table
is a fixed function of the joint position, read once at start-up. What it can do at run time
is add a HAL signal to a joint's motor command between the motion controller and the drive,
with LinuxCNC's own ``offset`` component; this module writes the HAL file that does it.

Sign. With the joint's scale divided by the gain and ``HOME_OFFSET = l0``
(:mod:`hexcal.io.linuxcnc`) the drive's position ``M`` (joint units, mm) is ``l0 + g dl``, and
the leg is ``l0 + g dl + delta = M + delta`` long. To make it ``L`` (genhexkins' joint
position) the drive must go to ``M = L - delta``: the offset added to the motor command is
``-delta`` (the reading ``dl`` shrinks by ``delta / g``). ``offset`` adds it to the command
(``out = in + offset``) and subtracts it from the feedback (``fb-out = fb-in - offset``), so
motion sees the joint at ``L`` while the drive stands at ``L - delta``.

Homing. Homing sets the joint position to ``HOME_OFFSET = l0`` where the switch is (reading
0), from the feedback motion sees. If the offset were applied then, motion would take the
switch for ``l0`` with the drive's feedback raised by ``delta_home``, and every later position
would be ``delta_home`` out. So the offset is gated by ``joint.N.homed`` (0 until the joint is
homed, through a ``mux2``) and brought in by a ``limit2`` at :data:`DEFAULT_SLEW` K/s, which
also holds the temperature difference within a range (a failed sensor reading −273 °C moves no
leg by metres). Per joint ``N`` (hexcal's leg ``N + 1``)::

    hexcal-temp-N ─ scale dT = T - T_ref ─ mux2 (joint.N.homed) ─ limit2 (range, slew)
        ─ mult2 × coef ─ offset.offset;   coef = scale (joint.N.pos-cmd): -(alpha + kappa L)
    joint.N.motor-pos-cmd ─ offset.in,  offset.out ─ hexcal-drive-cmd-N ─ the drive
    the drive ─ hexcal-drive-fb-N ─ offset.fb-in,  offset.fb-out ─ joint.N.motor-pos-fb

The user renames, in the machine's own HAL file, the signal that carries joint ``N``'s motor
command to the drive ``hexcal-drive-cmd-N`` and the one that carries its feedback
``hexcal-drive-fb-N``; this file, loaded after it, unlinks the joint's two pins from them and
puts the ``offset`` in between. The temperatures are signals ``hexcal-temp-N`` (one per leg) or
``hexcal-temp`` (one shared sensor) that the user drives from a sensor pin (e.g.
``net hexcal-temp-0 <= thermistor.0.temperature-c``).

What the HAL file cannot carry is :data:`CANNOT_CARRY`; :func:`check_carried` refuses it in
one line. :func:`thermal_offsets` is the file's arithmetic in numpy (the offsets once settled
on a homed machine), for tests and for stating what the controller will apply.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hexcal.errors import UsageError
from hexcal.io.hal_text import NUMBER, comment_line, comment_ok, printable

#: The file :func:`thermal_hal` writes.
THERMAL_HAL_FILE = "hexcal-thermal.hal"

#: Temperatures (°C) the offsets are held within by default: a workshop's, wide of any
#: calibration; outside it a sensor has failed rather than the machine warmed.
DEFAULT_TEMPERATURE_RANGE = (0.0, 50.0)

#: Largest rate (K/s) at which the temperature difference, hence the offset, changes by default:
#: machines warm by kelvins an hour; after homing the offset comes in over a few seconds.
DEFAULT_SLEW = 1.0

#: The HAL thread (motmod's) the functions are added to.
THREAD = "servo-thread"

#: The HAL modules the file loads (one ``loadrt`` each: LinuxCNC loads a module once).
MODULES = ("scale", "mux2", "limit2", "mult2", "offset")

#: What a leg model may have that a joint-level HAL file cannot apply, each in one line.
CANNOT_CARRY = {
    "compliance": (
        "a compliance term needs each leg's axial force, which comes from the static equilibrium "
        "at the pose (the platform's Jacobian and the payload); no stock HAL component computes it "
        "at run time and genhexkins exports no Jacobian, so LinuxCNC cannot apply it"
    ),
    "payload": (
        "a payload is a per-pose covariate that LinuxCNC does not know at run time (no pin carries "
        "the mass or its centre); compensate the program for it instead (hexcal compensate --payload)"
    ),
}


def _array6(value: ArrayLike, what: str) -> NDArray[np.float64]:
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = np.full(6, float(array))
    if array.shape != (6,):
        raise UsageError(f"{what}: expected one value or six (one per leg), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise UsageError(f"{what}: every value must be finite")
    return array


def _checked(
    alpha: ArrayLike, t_ref: float, per_length: ArrayLike | None, temperature_range: tuple[float, float]
) -> tuple[NDArray[np.float64], float, NDArray[np.float64], float, float]:
    a = _array6(alpha, "thermal coefficients alpha (mm/K)")
    k = np.zeros(6) if per_length is None else _array6(per_length, "thermal coefficients per length (1/K)")
    t_ref = float(t_ref)
    low, high = (float(t) for t in temperature_range)
    if not np.isfinite(t_ref) or not -273.15 < t_ref < 1000.0:
        raise UsageError(f"reference temperature {t_ref:g} °C is not a temperature")
    if not (np.isfinite(low) and np.isfinite(high) and -273.15 <= low <= t_ref <= high):
        raise UsageError(
            f"temperature range {low:g} .. {high:g} °C must hold the reference temperature {t_ref:g} °C "
            "(the offset is 0 there, and until the joint is homed)"
        )
    return a, t_ref, k, low, high


def check_carried(terms: Iterable[str]) -> None:
    """Refuse, in one line (:class:`~hexcal.errors.UsageError`), a term of
    :data:`CANNOT_CARRY` among ``terms`` (the leg model's terms asked for)."""
    for term in terms:
        if term in CANNOT_CARRY:
            raise UsageError(f"LinuxCNC at run time: {CANNOT_CARRY[term]}; nothing was written")


def thermal_offsets(
    alpha: ArrayLike,
    t_ref: float,
    temperatures: ArrayLike,
    lengths: ArrayLike | None = None,
    per_length: ArrayLike | None = None,
    temperature_range: tuple[float, float] = DEFAULT_TEMPERATURE_RANGE,
) -> NDArray[np.float64]:
    """The offsets (mm) the HAL file adds to the joints' motor commands, once settled on a
    homed machine: ``-(alpha + kappa L) (clip(T) - T_ref)``.

    Parameters
    ----------
    alpha : array_like, (6,) or scalar
        Each leg's growth, mm/K.
    t_ref : float
        Temperature (°C) at which the legs are their geometry's length.
    temperatures : array_like, (..., 6) or (...,)
        Each leg's temperature (°C), or one shared temperature per row.
    lengths : array_like, (..., 6), optional
        The joints' commanded positions (strut lengths, mm); needed with ``per_length``.
    per_length : array_like, (6,) or scalar, optional
        Growth proportional to the leg's length, 1/K.
    temperature_range : (float, float)
        Temperatures the HAL file holds the sensors' readings within (°C).

    Returns
    -------
    ndarray, (..., 6)
    """
    a, t_ref, k, low, high = _checked(alpha, t_ref, per_length, temperature_range)
    t = np.asarray(temperatures, dtype=float)
    if t.ndim == 0 or t.shape[-1] != 6:
        t = t[..., None] * np.ones(6)
    coef = a + (k * np.asarray(lengths, dtype=float) if per_length is not None else 0.0)
    return -coef * (np.clip(t, low, high) - t_ref)


def _num(value: float) -> str:
    return repr(float(value))


def thermal_hal(
    alpha: ArrayLike,
    t_ref: float,
    *,
    per_length: ArrayLike | None = None,
    shared_sensor: bool = False,
    temperature_range: tuple[float, float] = DEFAULT_TEMPERATURE_RANGE,
    slew: float = DEFAULT_SLEW,
    source: str = "(in memory)",
) -> str:
    """The text of ``hexcal-thermal.hal`` (see the module's notes for what it does).

    Parameters
    ----------
    alpha : array_like, (6,) or scalar
        Each leg's growth, mm/K (LinuxCNC joint ``N`` is leg ``N + 1``).
    t_ref : float
        Reference temperature, °C.
    per_length : array_like, (6,) or scalar, optional
        Growth proportional to the leg's length, 1/K: the file multiplies it by the joint's
        commanded position (``joint.N.pos-cmd``, the strut length).
    shared_sensor : bool
        One temperature for every leg (signal ``hexcal-temp``) instead of one per leg
        (``hexcal-temp-0`` .. ``hexcal-temp-5``).
    temperature_range : (float, float)
        Temperatures (°C) the readings are held within; must hold ``t_ref``.
    slew : float
        Largest rate of change of the temperature difference the offset follows, K/s.
    source : str
        What the coefficients came from (a geometry file), for the header.

    Returns
    -------
    str
        The HAL file's text: numbers and fixed names only, checked by
        :func:`check_thermal_hal_lines`.
    """
    a, t_ref, k, low, high = _checked(alpha, t_ref, per_length, temperature_range)
    slew = float(slew)
    if not (np.isfinite(slew) and slew > 0):
        raise UsageError(f"slew {slew:g} K/s must be a positive number")
    lines = [
        comment_line(f"{THERMAL_HAL_FILE} -- written by hexcal: each joint trimmed by its leg's growth"),
        comment_line(f"source: {printable(source)}"),
        "# leg i = joint N + 1 grows by delta = (alpha + kappa L) (T - T_ref) mm; the drive goes to",
        "# L - delta (the offset -delta is added to joint.N.motor-pos-cmd and taken off its feedback),",
        "# so the warm leg is L long. 0 until the joint is homed (homing sets HOME_OFFSET from the",
        f"# feedback), then brought in at {_num(slew)} K/s; temperatures held in {_num(low)}..{_num(high)} C",
        "# use: load after the machine's HAL file ([HAL] HALFILE = hexcal-thermal.hal). In that file,",
        "#   name the signal joint N's motor command goes to the drive on hexcal-drive-cmd-N and the",
        "#   one its feedback comes back on hexcal-drive-fb-N (N = 0..5); this file unlinks the",
        "#   joint's two pins and puts the offset between. Drive the temperature signal(s) from your",
        f"#   sensor, e.g. net {'hexcal-temp' if shared_sensor else 'hexcal-temp-0'} "
        "<= thermistor.0.temperature-c",
        "# if the machine's HAL already loads one of scale, mux2, limit2, mult2, offset: add these",
        "#   names= to its loadrt line instead (LinuxCNC loads a module once); if it already nets",
        "#   joint.N.homed (or joint.N.pos-cmd), net that signal to the pins below instead",
        "# thread order: update-output must run after motion-controller and before the drive's write,",
        "#   update-feedback after the drive's read and before motion-command-handler; appended at the",
        "#   end of the thread (below) each side lags one servo period: move them with addf's position",
        "",
    ]
    per_joint = {
        "scale": [f"hexcal-thermal-{part}-{n}" for part in ("dt", "coef") for n in range(6)],
        "mux2": [f"hexcal-thermal-gate-{n}" for n in range(6)],
        "limit2": [f"hexcal-thermal-ramp-{n}" for n in range(6)],
        "mult2": [f"hexcal-thermal-mult-{n}" for n in range(6)],
        "offset": [f"hexcal-thermal-{n}" for n in range(6)],
    }
    lines += [f"loadrt {module} names={','.join(per_joint[module])}" for module in MODULES]
    for n in range(6):
        temp = "hexcal-temp" if shared_sensor else f"hexcal-temp-{n}"
        lines += [
            "",
            f"# joint {n} (hexcal leg {n + 1}): alpha {_num(a[n])} mm/K, kappa {_num(k[n])} 1/K",
            f"addf hexcal-thermal-dt-{n} {THREAD}",
            f"addf hexcal-thermal-gate-{n} {THREAD}",
            f"addf hexcal-thermal-ramp-{n} {THREAD}",
            f"addf hexcal-thermal-coef-{n} {THREAD}",
            f"addf hexcal-thermal-mult-{n} {THREAD}",
            f"addf hexcal-thermal-{n}.update-output {THREAD}",
            f"addf hexcal-thermal-{n}.update-feedback {THREAD}",
            f"setp hexcal-thermal-dt-{n}.gain 1.0",
            f"setp hexcal-thermal-dt-{n}.offset {_num(-t_ref)}",
            f"net {temp} => hexcal-thermal-dt-{n}.in",
            f"net hexcal-thermal-dt-{n} hexcal-thermal-dt-{n}.out => hexcal-thermal-gate-{n}.in1",
            f"setp hexcal-thermal-gate-{n}.in0 0.0",
            f"net hexcal-thermal-homed-{n} joint.{n}.homed => hexcal-thermal-gate-{n}.sel",
            f"net hexcal-thermal-gated-{n} hexcal-thermal-gate-{n}.out => hexcal-thermal-ramp-{n}.in",
            f"setp hexcal-thermal-ramp-{n}.min {_num(low - t_ref)}",
            f"setp hexcal-thermal-ramp-{n}.max {_num(high - t_ref)}",
            f"setp hexcal-thermal-ramp-{n}.maxv {_num(slew)}",
            f"net hexcal-thermal-ramp-{n} hexcal-thermal-ramp-{n}.out => hexcal-thermal-mult-{n}.in0",
            f"setp hexcal-thermal-coef-{n}.gain {_num(0.0 - k[n])}",
            f"setp hexcal-thermal-coef-{n}.offset {_num(0.0 - a[n])}",
        ]
        if per_length is not None:
            lines.append(f"net hexcal-thermal-length-{n} joint.{n}.pos-cmd => hexcal-thermal-coef-{n}.in")
        lines += [
            f"net hexcal-thermal-coef-{n} hexcal-thermal-coef-{n}.out => hexcal-thermal-mult-{n}.in1",
            f"net hexcal-thermal-offset-{n} hexcal-thermal-mult-{n}.out => hexcal-thermal-{n}.offset",
            f"unlinkp joint.{n}.motor-pos-cmd",
            f"unlinkp joint.{n}.motor-pos-fb",
            f"net hexcal-joint-cmd-{n} joint.{n}.motor-pos-cmd => hexcal-thermal-{n}.in",
            f"net hexcal-drive-cmd-{n} <= hexcal-thermal-{n}.out",
            f"net hexcal-drive-fb-{n} => hexcal-thermal-{n}.fb-in",
            f"net hexcal-joint-fb-{n} hexcal-thermal-{n}.fb-out => joint.{n}.motor-pos-fb",
        ]
    text = "\n".join(lines) + "\n"
    check_thermal_hal_lines(THERMAL_HAL_FILE, text)
    return text


_NAME = r"hexcal-(thermal|joint|drive|temp)(-[a-z]+)?(-[0-5])?"
_PIN = rf"({_NAME}\.[a-z0-9-]+|joint\.[0-5]\.(homed|pos-cmd|motor-pos-cmd|motor-pos-fb))"
_HAL_LINES = [
    re.compile(rf"loadrt ({'|'.join(MODULES)}) names={_NAME}(,{_NAME})*"),
    re.compile(rf"addf {_NAME}(\.update-(output|feedback))? {THREAD}"),
    re.compile(rf"setp {_PIN} (?P<v>\S+)"),
    re.compile(rf"net {_NAME} ((<=|=>) )?{_PIN}( (<=|=>) {_PIN})?"),
    re.compile(r"unlinkp joint\.[0-5]\.motor-pos-(cmd|fb)"),
]


def check_thermal_hal_lines(name: str, text: str) -> None:
    """Refuse (ValueError) a thermal HAL text with a line that is not a comment or one of the
    file's fixed commands with numbers: no text from an input reaches a file ``halcmd`` runs."""
    for number, line in enumerate(text.rstrip("\n").split("\n"), 1):
        if not line or comment_ok(line):
            continue
        match = next((m for m in (p.fullmatch(line) for p in _HAL_LINES) if m), None)
        value = match.groupdict().get("v") if match else None
        if match is None or (value is not None and not NUMBER.fullmatch(value)):
            raise ValueError(
                f"{name}: line {number} would be neither a comment nor a fixed command with numbers "
                f"({printable(line, 60)!r}); nothing was written"
            )


def thermal_export(
    geometry: Any, *, shared_sensor: bool = False, source: str = "(in memory)"
) -> tuple[Any, str]:
    """A geometry with a thermal leg model as LinuxCNC carries it: ``(base, text)``, the
    geometry at the model's reference temperature (its base model, linear or stroke: what
    ``genhexkins`` and the compensation tables hold) and the text of ``hexcal-thermal.hal``
    (:func:`thermal_hal`) with the model's coefficients: ``kt`` as ``alpha`` (mm/K), or ``cte``
    as the growth per length (1/K).

    A term the file cannot apply (:data:`CANNOT_CARRY`: compliance) is refused in one line by
    :func:`check_carried`. The temperature range holds the reference temperature (the default
    range, widened to it if need be).
    """
    from hexcal.core.covariate_legs import CovariateLegs, at_conditions
    from hexcal.instruments import Covariates

    model = geometry.leg_model
    if not isinstance(model, CovariateLegs):
        raise UsageError(f"{printable(source)}: the {model.name} leg model has no thermal term to export")
    check_carried(model.groups())
    theta = model.thetas(geometry.leg_block())  # (6, per_leg): the thermal coefficient after the base's
    coefficient = theta[:, model.base.per_leg]
    base = at_conditions(geometry, Covariates(temperatures=[model.reference]), source)
    low, high = DEFAULT_TEMPERATURE_RANGE
    text = thermal_hal(
        0.0 if model.per_length else coefficient,
        model.reference,
        per_length=coefficient if model.per_length else None,
        shared_sensor=shared_sensor,
        temperature_range=(min(low, model.reference), max(high, model.reference)),
        source=source,
    )
    return base, text
