"""What instruments are known to do: the noise each kind of instrument has, with its source.

A calibration that learns its noise from the data (``noise="auto"``) absorbs whatever the model
does not describe (a bumped tracker, legs that warm up) into a larger noise. The learned noise
is therefore held against what the instrument can plausibly do: the noise a setup file declares
(``noise:``, docs/formats.md), else the range of noise that instruments of its kind have
(:data:`DEVICES`; the legs against :data:`LEG_ENCODERS`). A learned σ several times beyond
that range says the model does not describe the data (:mod:`hexcal.calibration.noise_judgement`).
The same record gives the deterministic value a noise group is held at where the data cannot
determine it: the declared σ, else the kind's typical σ.

Each :class:`NoiseRange` is one standard deviation per coordinate (mm for lengths, rad for
angles): ``low`` what the best instruments of the kind reach, ``typical`` a careful
measurement, ``high`` the most that a working instrument of the kind shows (a larger one is
not the instrument). The figures and their sources are in docs/instruments.md ("What
instruments are known to do"); manufacturers state a maximum permissible error (MPE) at about
two standard deviations ("typical results are half of the MPE", Leica's AT500/AT960 manuals),
so σ ≈ MPE / 2.

Imports :mod:`hexcal.errors` only.

>>> DEVICES["laser-tracker"].ranges["position"].typical
0.015
>>> device_for("tool").name
'pose-instrument'
"""

from __future__ import annotations

from dataclasses import dataclass, field

from hexcal.errors import InputError


@dataclass(frozen=True)
class NoiseRange:
    """The noise (one σ per coordinate) of one group of an instrument kind.

    Attributes
    ----------
    low, typical, high : float
        The best such instruments reach, a careful measurement, the most a working one shows
        (mm for lengths, rad for angles).
    unit : str
    """

    low: float
    typical: float
    high: float
    unit: str = "mm"


@dataclass(frozen=True)
class Device:
    """A kind of instrument and the noise of its groups.

    Attributes
    ----------
    name : str
        The setup file's ``instrument:`` word (``laser-tracker``, ``motion-capture``, ...).
    label : str
        How the verdict names it ("a laser tracker").
    kinds : tuple of str
        The setup kinds it can be (``targets``, ``tool``, ``ballbar``; ``pose`` for the full pose
        in the base frame).
    ranges : mapping of str to NoiseRange
        By noise group (``position``, ``orientation``; a ballbar's reading is ``position``).
    source : str
        Where the figures come from (one line; the docs give the references).
    """

    name: str
    label: str
    kinds: tuple[str, ...]
    ranges: dict[str, NoiseRange] = field(default_factory=dict)
    source: str = ""


#: The legs' own measurement: encoders on screws or motors, or linear scales. σ of a leg
#: reading as a length, mm: linear scales reach about a micrometre (accuracy grade ±3 µm), a
#: rotary encoder on a ball screw a few micrometres with the screw's repeatability, belt and
#: hobby drives some tens of micrometres; 50 µm is the most a working leg sensor shows.
LEG_ENCODERS = NoiseRange(0.0005, 0.005, 0.05)

#: Instrument kinds by the setup file's ``instrument:`` word.
DEVICES: dict[str, Device] = {
    device.name: device
    for device in (
        Device(
            "laser-tracker",
            "a laser tracker",
            ("targets",),
            {"position": NoiseRange(0.003, 0.015, 0.05)},
            "MPE ±(15 µm + 6 µm/m) transverse, ±(10 µm + 0.3 µm/m) in distance (Leica AT960/AT500, "
            "ISO 10360-10); typical results half the MPE",
        ),
        Device(
            "6dof-tracker",
            "a 6-DOF laser tracker or probe",
            ("tool",),
            {"position": NoiseRange(0.003, 0.015, 0.05), "orientation": NoiseRange(1e-5, 5e-5, 3e-4, "rad")},
            "a laser tracker's position with a 6-DOF probe's orientation, MPE about ±0.01° (Leica "
            "T-Probe, T-Mac)",
        ),
        Device(
            "motion-capture",
            "a motion-capture system",
            ("tool", "pose"),
            {"position": NoiseRange(0.02, 0.2, 1.0), "orientation": NoiseRange(1e-4, 2e-3, 1e-2, "rad")},
            "static mean absolute error 0.15 mm, dynamic under 2 mm (Merriaux et al. 2017, Vicon); "
            "a rigid body of markers some 100 mm apart turns that into about 2 mrad",
        ),
        Device(
            "ballbar",
            "a telescoping ballbar",
            ("ballbar",),
            {"position": NoiseRange(0.0001, 0.001, 0.005)},
            "accuracy ±(0.7 µm + 0.3 % of the measured change), resolution 0.1 µm (Renishaw QC20-W, "
            "ISO 230-4)",
        ),
        Device(
            "pose-instrument",
            "a pose-measuring instrument (a 6-DOF tracker, a probe or motion capture)",
            ("tool", "pose"),
            {
                "position": NoiseRange(0.003, 0.0144, 1.0),
                "orientation": NoiseRange(1e-5, 5.8e-4, 1e-2, "rad"),
            },
            "the span of 6-DOF trackers, probes and motion capture; typical: the seed paper's noise "
            "(uniform ±0.025 mm, ±0.001 rad: σ 0.0144 mm, 0.58 mrad)",
        ),
    )
}

#: The instrument kind a setup kind is read as when the setup does not name one.
DEFAULT_DEVICES = {
    "targets": "laser-tracker",
    "tool": "pose-instrument",
    "pose": "pose-instrument",
    "ballbar": "ballbar",
}

#: The keys of a setup's ``noise:`` mapping and the noise group each gives (a ballbar's ``d``
#: is its one value, the group ``position``); ``orientation_deg`` in degrees.
NOISE_KEYS = {
    "position": "position",
    "orientation": "orientation",
    "orientation_deg": "orientation",
    "d": "position",
}


#: A declared σ more than this factor beyond the range of its instrument kind (above the most
#: such instruments show, below the best) is refused: it is no such instrument (the verdict's
#: fail for a learned σ, :mod:`hexcal.calibration.noise_judgement`, is the same factor).
PLAUSIBLE_FACTOR = 10.0


def device_for(kind: str, name: str | None = None) -> Device:
    """The instrument kind of a setup (``kind``: targets, tool, ballbar or pose) named ``name``
    (the setup's ``instrument:``; default :data:`DEFAULT_DEVICES`); :class:`InputError` naming
    the choices when the name is unknown or does not fit the setup."""
    if name is None:
        return DEVICES[DEFAULT_DEVICES.get(kind, "pose-instrument")]
    device = DEVICES.get(name)
    if device is None:
        raise InputError(f"instrument: unknown kind {name!r}; choose from {', '.join(DEVICES)}")
    if kind not in device.kinds:
        fits = [d for d, dev in DEVICES.items() if kind in dev.kinds]
        raise InputError(
            f"instrument: {name} does not measure a setup with {kind} (for this setup: {', '.join(fits)})"
        )
    return device


def declared_noise(value: object, kind: str, instrument: str | None = None) -> dict[str, float]:
    """A setup's ``noise:`` mapping as σ by noise group (mm, rad); :class:`InputError` naming
    the problem (a key the setup's kind has no use for, a value that is not a positive number,
    a σ that no instrument of its kind (``instrument``, default by ``kind``) has:
    :data:`PLAUSIBLE_FACTOR` times beyond its range)."""
    import math

    if not isinstance(value, dict) or not value:
        raise InputError("noise: must be a mapping like {position: 0.015} (one σ, mm; orientation in rad)")
    allowed = {"ballbar": ("d",), "targets": ("position",)}.get(
        kind, ("position", "orientation", "orientation_deg")
    )
    out: dict[str, float] = {}
    for key, number in value.items():
        if key not in allowed:
            raise InputError(f"noise: {key!r} is not a noise of this setup; give {', '.join(allowed)}")
        if (
            isinstance(number, bool)
            or not isinstance(number, int | float)
            or not math.isfinite(number)
            or number <= 0
        ):
            raise InputError(f"noise.{key}: must be a number > 0 (one σ), got {number!r}")
        group = NOISE_KEYS[key]
        if group in out:
            raise InputError("noise: give orientation or orientation_deg, not both")
        out[group] = math.radians(number) if key.endswith("_deg") else float(number)
        span = device_for(kind, instrument).ranges.get(group)
        if span is not None and not span.low / PLAUSIBLE_FACTOR <= out[group] <= span.high * PLAUSIBLE_FACTOR:
            device = device_for(kind, instrument)
            raise InputError(
                f"noise.{key}: {number:g} {'deg' if key.endswith('_deg') else span.unit} is no noise of "
                f"{device.label} (they show {span.low:g} ... {span.high:g} {span.unit}, one σ): "
                f"give one σ in {span.unit}{' (orientation_deg in degrees)' if span.unit == 'rad' else ''}"
            )
    return out


def noise_mapping(noise: dict[str, float], kind: str) -> dict[str, float]:
    """A declared noise (σ by group) as a setup file's ``noise:`` mapping (``d`` for a ballbar)."""
    if kind == "ballbar":
        return {"d": float(noise["position"])}
    return {group: float(sigma) for group, sigma in noise.items()}


__all__ = [
    "DEVICES",
    "LEG_ENCODERS",
    "PLAUSIBLE_FACTOR",
    "Device",
    "NoiseRange",
    "declared_noise",
    "device_for",
    "noise_mapping",
]
