"""Simulated campaigns of the six instruments for ``tests/test_every_instrument.py``.

Every file is made through the command line (``hexcal candidates``, ``hexcal synthesize
--setup``, seeded) from the presets ``paper-hmt`` (nominal) and ``paper-hmt-true`` (the real
machine), so that the tests need no data files; a variant of a campaign (positions in metres,
angles in degrees, another Euler sequence, leg gain errors, poses that never rotate, one spoiled
observation) is made once, on first use, and kept for the module.

The five instruments:

- ``pose``: the platform pose in the base frame (a measurement file, no setup);
- ``pose-frame``: the platform pose in an instrument frame of its own (a ``tool`` setup whose
  tool is the identity, fixed, and whose frame is ``auto``);
- ``tool``: a 6-DOF tool, probe or motion-capture body (frame and tool unknown);
- ``target``: one laser-tracker target;
- ``targets``: three targets;
- ``ballbar``: a 150 mm ballbar at one pivot (one session), measured on circles: its poses are
  the 30 circles ``hexcal select --ballbar`` chooses there (12 points each; held out: 7 other
  points on each; never rotating: the level circles only), with its own noise (legs σ 2 µm,
  the bar's reading σ 1 µm: a ballbar reads a distance to a micrometre, and with the trackers'
  15 µm the 37 combinations one distance per pose must settle stay too weak for a verdict).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hexcal.cli.main import main

#: Noise of every simulated campaign: standard deviations (normal), mm and rad.
SIGMA = {"leg": 0.005, "position": 0.015, "orientation": 0.0002}
NOISE = ["--noise", "leg=0.005,pos=0.015,ang=0.0002", "--noise-dist", "normal"]

#: Where the instruments stand (the base frame's pose in the instrument frame), 2.6 m away.
FRAME = "{x: 2500, y: -800, z: 300, a_deg: 2, b_deg: -3, c_deg: 35}"
IDENTITY = "{x: 0, y: 0, z: 0, a_deg: 0, b_deg: 0, c_deg: 0}"
#: A tool 80 mm above the platform, turned, and what the user knows of it (about 1 mm, 0.5°).
TOOL_TRUE = "{x: 10, y: -20, z: 80, a_deg: 5, b_deg: 0, c_deg: 30}"
TOOL_START = "{x: 11, y: -21, z: 79, a_deg: 5.5, b_deg: 0.5, c_deg: 29.5}"

#: The real machine's leg gains for the unfitted-gains campaigns (scale errors of 0.3-0.5 %).
GAINS = [1.004, 0.996, 1.003, 0.997, 1.005, 0.995]

#: The spoiled observation (100 σ on every value of one row, or of one target).
SPOILED = "r05"


@dataclass(frozen=True)
class Instrument:
    """One instrument of the matrix.

    Attributes
    ----------
    name : str
    true_setup, start_setup : str or None
        The setup the campaign is simulated with (frame given) and the one identify starts
        from (frame ``auto``, what the user knows); None for the full pose in the base frame.
    poses : int
        Poses of a campaign (one target sees 3 coordinates per pose and needs about twice as
        many as the others to identify the 39 combinations beyond its gauges).
    angles : bool
        Whether the instrument measures angles (Euler and degree diagnoses apply).
    determines_pose : bool
        Whether one observation gives the platform pose in the base frame (the estimators
        ``gls``, ``length`` and ``paper`` need it).
    groups : tuple of str
        The noise groups learned from its data.
    position_columns : tuple of str
        The data columns that are lengths (mm).
    gauges : int
        The gauge freedoms of an identification (6 per free frame, 6 for the platform frame
        when the instrument's own quantities on the platform are free).
    spoil : tuple of str
        The columns of the spoiled observation that get 100 σ.
    noise : tuple of str
        The ``--noise`` options of its campaigns (the trackers' by default).
    circles : bool
        Whether its poses are ballbar circles (``hexcal select --ballbar``) instead of random.
    """

    name: str
    true_setup: str | None
    start_setup: str | None
    poses: int
    angles: bool
    determines_pose: bool
    groups: tuple[str, ...]
    position_columns: tuple[str, ...]
    gauges: int
    spoil: tuple[str, ...]
    noise: tuple[str, ...] = tuple(NOISE)
    circles: bool = False

    @property
    def sigma(self) -> dict[str, float]:
        """The true σ of each noise group label of its campaigns."""
        values = dict(item.split("=") for item in self.noise[1].split(","))
        pos = float(values["pos"])
        return {"leg": float(values["leg"]), "position": pos, "targets": pos, "ballbar": pos,
                "orientation": float(values["ang"])}  # fmt: skip


def _targets(names: tuple[str, ...], offset: float) -> str:
    where = {"t1": (0, 0, 60), "t2": (150, 20, 55), "t3": (-40, 160, 70)}
    rows = [f"  {n}: [{where[n][0] + offset}, {where[n][1] - offset}, {where[n][2] + offset}]" for n in names]
    return "targets:\n" + "\n".join(rows) + "\n"


POSE_GROUPS = ("leg", "position", "orientation")
#: The ballbar's setup (pivot at the workspace's centre less the ball) and what identify knows.
BALLBAR_TRUE = "units: mm\nballbar: {pivot: [0, 0, 750], ball: [0, 0, -50], length: 150.0}\n"
BALLBAR_START = "units: mm\nballbar: {pivot: [1, -1, 751], ball: [0.5, 0.5, -49], length: 150.5}\n"
BALLBAR_NOISE = ("--noise", "leg=0.002,pos=0.001,ang=0.0001", "--noise-dist", "normal")
XYZ = ("x", "y", "z")

INSTRUMENTS: dict[str, Instrument] = {
    "pose": Instrument("pose", None, None, 20, True, True, POSE_GROUPS, XYZ, 0, (*XYZ, "a", "b", "c")),
    "pose-frame": Instrument(
        "pose-frame",
        f"units: mm\ninstrument_frame: {FRAME}\ntool: {IDENTITY}\nfixed: [tool]\n",
        f"units: mm\ninstrument_frame: auto\ntool: {IDENTITY}\nfixed: [tool]\n",
        20,
        True,
        False,
        POSE_GROUPS,
        XYZ,
        6,
        (*XYZ, "a", "b", "c"),
    ),
    "tool": Instrument(
        "tool",
        f"units: mm\ninstrument_frame: {FRAME}\ntool: {TOOL_TRUE}\n",
        f"units: mm\ninstrument_frame: auto\ntool: {TOOL_START}\n",
        20,
        True,
        False,
        POSE_GROUPS,
        XYZ,
        12,
        (*XYZ, "a", "b", "c"),
    ),
    "target": Instrument(
        "target",
        f"units: mm\ninstrument_frame: {FRAME}\n" + _targets(("t2",), 0).replace("t2", "t1"),
        "units: mm\ninstrument_frame: auto\n" + _targets(("t2",), 1).replace("t2", "t1"),
        40,
        False,
        False,
        ("leg", "targets"),
        ("t1.x", "t1.y", "t1.z"),
        12,
        ("t1.x", "t1.y", "t1.z"),
    ),
    "targets": Instrument(
        "targets",
        f"units: mm\ninstrument_frame: {FRAME}\n" + _targets(("t1", "t2", "t3"), 0),
        "units: mm\ninstrument_frame: auto\n" + _targets(("t1", "t2", "t3"), 1),
        20,
        False,
        False,
        ("leg", "targets"),
        tuple(f"t{k}.{a}" for k in (1, 2, 3) for a in XYZ),
        12,
        ("t1.x", "t1.y", "t1.z"),
    ),
    "ballbar": Instrument(
        "ballbar",
        BALLBAR_TRUE,
        BALLBAR_START,
        360,
        False,
        False,
        ("leg", "ballbar"),
        ("d",),
        12,
        ("d",),
        BALLBAR_NOISE,
        True,
    ),
}


@dataclass(frozen=True)
class Run:
    """What a command did: exit status, standard output and standard error."""

    code: int
    out: str
    err: str


def run(*argv: Any) -> Run:
    """``hexcal ARGV`` in this process (``hexcal.cli.main.main``), its output captured."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return Run(code, out.getvalue(), err.getvalue())


def read_csv(path: Path) -> tuple[list[str], list[str], list[list[str]]]:
    """Comment lines, header and rows of a CSV file hexcal wrote."""
    lines = path.read_text().splitlines()
    comments = [ln for ln in lines if ln.startswith("#")]
    body = [ln for ln in lines if ln and not ln.startswith("#")]
    return comments, body[0].split(","), [ln.split(",") for ln in body[1:]]


def write_csv(path: Path, comments: list[str], header: list[str], rows: list[list[str]]) -> None:
    path.write_text("\n".join([*comments, ",".join(header), *(",".join(r) for r in rows)]) + "\n")


def edit_columns(source: Path, target: Path, columns: tuple[str, ...], change: Any, rows: Any = None) -> None:
    """``target``: ``source`` with ``change(value)`` applied to ``columns`` (of the rows whose id
    is in ``rows``, default all); empty cells (a target not seen) stay empty."""
    comments, header, body = read_csv(source)
    index = [header.index(c) for c in columns]
    for row in body:
        if rows is None or row[0] in rows:
            for i in index:
                if row[i]:
                    row[i] = repr(change(float(row[i]), header[i]))
    write_csv(target, comments, header, body)


class Campaigns:
    """The campaigns of every instrument in one folder, each file made on first use."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.files: dict[tuple[str, ...], Path] = {}
        (root / "gains-true.yaml").write_text(self._gains_machine())
        for inst in INSTRUMENTS.values():
            for which in ("true", "start"):
                text = getattr(inst, f"{which}_setup")
                if text is not None:
                    (root / f"{inst.name}-{which}.yaml").write_text(text)

    @staticmethod
    def _gains_machine() -> str:
        import yaml

        from hexcal.core.presets import preset

        data = preset("paper-hmt-true").to_dict()
        data["name"], data["leg_gains"] = "paper-hmt-true-gains", GAINS
        return yaml.safe_dump(data, sort_keys=False)

    def setup(self, kind: str, which: str = "start") -> list[str]:
        """``["--setup", FILE]`` of an instrument (none for the full pose in the base frame)."""
        if INSTRUMENTS[kind].true_setup is None:
            return []
        return ["--setup", str(self.root / f"{kind}-{which}.yaml")]

    def kind_poses(self, kind: str, name: str) -> Path:
        """The commanded poses ``name`` of instrument ``kind`` (see :meth:`poses`, :meth:`circles`)."""
        inst = INSTRUMENTS[kind]
        if inst.circles:
            return self.circles(name)
        return self.poses(name, 20 if name == "held" else inst.poses)

    def spoiled_id(self, kind: str) -> str:
        """The id of the observation the ``spoiled`` variant spoils: ``r05`` (the sixth
        commanded pose), or the sixth circle point's id for the ballbar."""
        if not INSTRUMENTS[kind].circles:
            return SPOILED
        return read_csv(self.circles("measure"))[2][5][0]

    def circles(self, name: str) -> Path:
        """Ballbar circles at the campaign's pivot: ``measure`` (the 30 ``select --ballbar``
        chooses, 12 points each), ``held`` (7 other points on every circle), ``flat`` (the
        level circles only: the platform never rotates)."""
        key = ("circles", name)
        if key not in self.files:
            path = self.root / f"circles-{name}.csv"
            bar = self.root / "ballbar-true.yaml"
            where = ["--geometry", "paper-hmt", "--ballbar", bar, "--pivots", "0,0,750"]
            if name == "measure":
                made = run("select", *where, "--circles", 30, *BALLBAR_NOISE[:2], "--out", path)
            else:
                points = ["--points", 7] if name == "held" else ["--tilt", 0]
                made = run("candidates", *where, *points, "--out", path)
            assert made.code == 0, made.err
            self.files[key] = path
        return self.files[key]

    def poses(self, name: str, n: int) -> Path:
        """Commanded poses: ``measure`` (seed 1), ``held`` (seed 2, held out), ``flat`` (the
        measured ones with every angle 0: poses that never rotate)."""
        key = ("poses", name, str(n))
        if key not in self.files:
            path = self.root / f"poses-{name}-{n}.csv"
            if name == "flat":
                edit_columns(self.poses("measure", n), path, ("a", "b", "c"), lambda v, c: 0.0)
            else:
                seed = {"measure": 1, "held": 2}[name]
                made = run("candidates", "--geometry", "paper-hmt", "--candidates", f"random:{n}",
                           "--seed", seed, "--out", path)  # fmt: skip
                assert made.code == 0, made.err
            self.files[key] = path
        return self.files[key]

    def data(self, kind: str, variant: str = "clean") -> Path:
        """A campaign of instrument ``kind``: ``clean``, ``held`` (20 held-out poses), ``metres``,
        ``degrees`` (angles in degrees in radian columns), ``absolute`` (strut lengths as readings),
        ``euler`` (angles in ZYX), ``gains``
        (a real machine with leg gain errors), ``flat`` (poses that never rotate) or ``spoiled``
        (one observation 100 σ off)."""
        key = ("data", kind, variant)
        if key in self.files:
            return self.files[key]
        inst = INSTRUMENTS[kind]
        path = self.root / f"{kind}-{variant}.csv"
        if variant in ("clean", "held", "euler", "gains", "flat"):
            which = {"held": "held", "flat": "flat"}.get(variant, "measure")
            poses = self.kind_poses(kind, which)
            true = self.root / "gains-true.yaml" if variant == "gains" else "paper-hmt-true"
            extra = ["--euler", "ZYX"] if variant == "euler" else []
            made = run("synthesize", "--nominal", "paper-hmt", "--true", true, "--poses", poses,
                       *self.setup(kind, "true"), *inst.noise, "--seed", 2 if variant == "held" else 11,
                       "--out", path, *extra)  # fmt: skip
            assert made.code == 0, made.err
        elif variant == "metres":
            edit_columns(self.data(kind), path, inst.position_columns, lambda v, c: v / 1000)
        elif variant == "degrees":
            edit_columns(self.data(kind), path, ("a", "b", "c"), lambda v, c: math.degrees(v))
        elif variant == "absolute":  # a controller's joint positions (strut lengths) given as dl
            from hexcal.core.presets import preset

            l0 = preset("paper-hmt").initial_leg_lengths
            legs = tuple(f"dl{i}" for i in range(1, 7))
            edit_columns(self.data(kind), path, legs, lambda v, c: v + float(l0[int(c[2:]) - 1]))
        elif variant == "spoiled":
            sigma = {
                c: inst.sigma["orientation"] if c in "abc" else inst.sigma["position"] for c in inst.spoil
            }
            spoil = {self.spoiled_id(kind)}
            edit_columns(self.data(kind), path, inst.spoil, lambda v, c: v + 100 * sigma[c], rows=spoil)
        else:
            raise ValueError(variant)
        self.files[key] = path
        return path


def outputs(folder: Path, stem: str, kind: str) -> dict[str, Path]:
    """The outputs of one identify run: geometry, report, JSON, HTML and, with a setup, the
    calibrated setup."""
    names = {"out": "cal.yaml", "report": "report.txt", "json": "result.json", "html": "report.html"}
    if INSTRUMENTS[kind].true_setup is not None:
        names["setup-out"] = "cal-setup.yaml"
    return {k: folder / f"{stem}-{v}" for k, v in names.items()}


def identify(campaigns: Campaigns, kind: str, data: Path, stem: str, *extra: Any) -> tuple[Run, dict]:
    """``hexcal identify`` of a campaign with every output; the run and the output paths."""
    files = outputs(campaigns.root, stem, kind)
    argv = ["identify", "--geometry", "paper-hmt", "--data", data, *campaigns.setup(kind)]
    for option, path in files.items():
        argv += [f"--{option}", path]
    return run(*argv, *extra), files


def load_json(path: Path) -> Any:
    return json.loads(path.read_text())
