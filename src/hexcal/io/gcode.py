"""G-code programs (RS274/NGC, LinuxCNC's dialect): a streaming reader of the moves and a
writer of the corrected program.

:func:`read_program` reads a program in blocks of lines and yields, per block, the source
lines and the intended path of their G0/G1/G2/G3 moves as :class:`hexcal.core.Moves` (mm,
rad). The modal state follows the program: G0 G1 G2 G3 (G80 cancels), G17 G18 G19, G90 G91,
G90.1 G91.1, G21 mm or G20 inch (converted: numbers are read and written in the program's
unit); axis words left out keep their values; A B C are degrees. Arcs follow LinuxCNC: I J K
offsets or R (negative: more than half a turn), P turns, helices, the direction seen from the
positive end of the plane's normal (G18 is the ZX plane). Refused with one line naming file
and line: parameters and expressions (``#``, ``[ ]``), O-words, polar words, block delete on
a line with words, U V W, codes that change the frame or offset the path (G10 G28 G30 G52
G53 G55-G59.3 G92, G41 G42 G43), canned cycles, splines, probing, threading, G93. Lines after
M2/M30 or a closing ``%`` are copied unread, as LinuxCNC does not read them.

:class:`ProgramWriter` writes every line back unchanged but the moves: their axis words become
the six corrected ones (G91: increments between the written numbers, no rounding adds up),
an arc becomes G1 lines, a move cut into segments several lines, the first with the line's
other words and comments, the last with its stop codes (M0 M1 M2 M30 M60 act after motion).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import IO, NoReturn

import numpy as np
from numpy.typing import NDArray

from hexcal.core.path_compensation import CorrectedPath, Moves
from hexcal.errors import InputError
from hexcal.io.inputs import open_input

#: Lines per block: the reader's and the writer's memory is bounded by one block.
BLOCK_LINES = 10_000

#: Longest line read (LinuxCNC's limit is 256 characters).
MAX_LINE = 4096

AXES = "XYZABC"
_NUMBER = r"[+-]?[ \t]*(?:\d[\d \t]*(?:\.[\d \t]*)?|\.[ \t]*\d[\d \t]*)"
_WORD = re.compile(rf"([A-Za-z])[ \t]*({_NUMBER})")
_CODE = re.compile(rf"[ \t]*(?:[A-Za-z][ \t]*{_NUMBER})*")  # a number takes its trailing blanks
_TIGHT_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)"  # no blanks inside
_TIGHT = re.compile(rf"(([A-Za-z])({_TIGHT_NUMBER})[ \t]*)")
_PLAIN = re.compile(rf"[ \t]*(?:[A-Za-z]{_TIGHT_NUMBER}[ \t]*)*")
_FAST = re.compile(rf"([ \t]*)(?:[Gg]0*([01])(?![\d.])[ \t]*)?((?:[XYZABCxyzabc]{_TIGHT_NUMBER}[ \t]*)+)")
_COMMENT = re.compile(r"\([^()]*\)|;.*|[()]")
_LETTERS = set("ABCDFGHIJKLMNPQRSTUVWXYZ")
_PLANES = {(0, 1): ("IJ", "G17 (XY)"), (2, 0): ("KI", "G18 (ZX)"), (1, 2): ("JK", "G19 (YZ)")}
_GROUPS = {"motion": {0: 0, 10: 1, 20: 2, 30: 3, 800: None}, "plane": {170: (0, 1), 180: (2, 0), 190: (1, 2)}}
_GROUPS |= {"distance": {900: 0, 910: 1}}
_GROUPS |= {"arc_distance": {901: 0, 911: 1}, "units": {200: 25.4, 210: 1.0}}
_BY_CODE = {code: (group, mode) for group, codes in _GROUPS.items() for code, mode in codes.items()}
_AXIS = {letter: k for k, letter in enumerate(AXES)}
_KEPT = {40, 400, 490, 540, 610, 611, 640, 940, 950, 960, 970, 980, 990}
_FRAME = {100, 280, 281, 300, 301, 520, 530, 550, 560, 570, 580, 590, 591, 592, 593, 920, 921, 922, 923}
_OFFSET = {410, 411, 420, 421, 430, 431, 432}
_STOPS = {0, 1, 2, 30, 60}
_Word = tuple[str, float, int, int]  # letter, value, start and end in the line


def _refusal(code: int) -> str:
    g = f"G{code // 10}" + (f".{code % 10}" if code % 10 else "")
    if code in _FRAME:
        return (f"{g} changes or leaves the coordinate frame; hexcal filters programs whose "
                "X Y Z A B C are poses in the machine's frame (G54 without offsets)")  # fmt: skip
    if code in _OFFSET:
        return f"{g} makes the controller offset the path, which would move the corrected path"
    if code == 930:
        return "G93 (inverse-time feed) is not supported: a move cut into segments would need new F words"
    return f"{g} is not supported (only G0 G1 G2 G3 moves can be corrected; expand it into them)"


@dataclass
class _State:
    pose: list[float]
    motion: int | None = None
    plane: tuple[int, int] = (0, 1)
    distance: int = 0
    arc_distance: int = 1
    units: float = 1.0
    started: bool = False  # a first '%' line was seen
    ended: bool = False  # after M2/M30 or the closing '%': lines are copied unread


@dataclass(frozen=True, eq=False)
class ProgramBlock:
    """One block of a program: its source lines and the moves among them.

    ``first_line`` is the file's number (1-based) of ``lines[0]``; ``lines`` are the source lines
    as read (endings included); ``moves`` the intended path (mm, rad) of the moves, on the
    block-local lines ``move_lines``; per move, ``templates`` hold the line before and after its
    new motion and axis words, the same without its stop codes (the first line of a move cut
    into segments), the stop codes (for its last line) and the motion word ``G0`` or ``G1``;
    ``scale`` is mm per program unit (1 or 25.4) and ``incremental`` G91; ``chars`` counts the
    characters read so far (for progress). Move ``k`` is on line ``first_line + move_lines[k]``.
    """

    first_line: int
    lines: list[str]
    moves: Moves
    move_lines: NDArray[np.intp]
    templates: list[tuple[str, str, str, str, str, str]]
    scale: NDArray[np.float64]
    incremental: NDArray[np.bool_]
    chars: int


def _arc_moves(name: str, first: int, lines: list[int], start: NDArray[np.float64],
               end: NDArray[np.float64], arcs: list[tuple[float, ...]]) -> Moves:  # fmt: skip
    """The block's moves, its arcs' centres found from I J K or R and checked as LinuxCNC does."""
    if not arcs:
        return Moves.lines(start, end)
    k, u, v, cw, du, dv, big_r, absolute, turns, scale = np.array(arcs).T
    k, plane = k.astype(np.intp), np.stack([u, v], axis=1).astype(np.intp)
    s = np.take_along_axis(np.concatenate([start[None], end[:-1]])[k], plane, axis=1)
    e = np.take_along_axis(end[k], plane, axis=1)
    center = np.stack([du, dv], axis=1) + np.where(absolute[:, None] > 0, 0.0, s)
    r_form = np.isfinite(big_r)
    chord = e - s
    half = 0.5 * np.hypot(chord[:, 0], chord[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):  # R form: the centre off the chord's middle
        normal = np.stack([-chord[:, 1], chord[:, 0]], axis=1) / (2 * half[:, None])
        side = np.where(cw > 0, -1.0, 1.0) * np.sign(big_r) * np.sqrt(np.maximum(big_r**2 - half**2, 0.0))
        center = np.where(r_form[:, None], 0.5 * (s + e) + side[:, None] * normal, center)
    moves = Moves.with_arcs(start, end, k, plane, center, cw > 0, turns.astype(np.intp))
    r0, r1 = moves.radius[k], moves.end_radius[k]
    diff, inch = np.abs(r1 - r0), scale != 1.0
    problems = [
        (r_form & (half == 0), "an R-form arc cannot end where it starts (use I J K for a full circle)"),
        (r_form & (half - np.abs(big_r) > np.where(inch, 1e-4 * 25.4, 1e-3)),
         "the arc radius R is smaller than half the distance to the end point"),
        (r0 <= 0, "the arc has zero radius"),
        (~r_form & ((diff > np.where(inch, 0.05 * 25.4, 0.5))
                    | ((diff > np.where(inch, 5e-4 * 25.4, 5e-3)) & (diff > 1e-3 * r0))),
         "the radius to the end of the arc differs from the radius to its start"),
    ]  # fmt: skip
    for bad, text in problems:
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            raise InputError(f"{name}: line {first + lines[k[j]]}: {text} (radius at the start "
                             f"{r0[j]:.6g} mm, at the end {r1[j]:.6g} mm)")  # fmt: skip
    return moves


def _words(text: str, fail: Callable[[str], NoReturn]) -> list[_Word]:
    """``(letter, value, start, end)`` of every word of a line (comments left out)."""
    parts = [(0, text)]
    if "(" in text or ")" in text or ";" in text:
        parts, pos = [], 0
        for m in _COMMENT.finditer(text):
            if m.group() in "()":
                fail("a '(' without ')' or a ')' without '(' (comments cannot be nested)")
            parts.append((pos, text[pos : m.start()]))
            pos = m.end()
        parts.append((pos, text[pos:]))
    out: list[_Word] = []
    for offset, part in parts:
        if _PLAIN.fullmatch(part):  # the usual line: no blanks inside the numbers
            pos = offset + len(part) - len(part.lstrip(" \t"))
            for full, letter, number in _TIGHT.findall(part):
                out.append((letter.upper(), float(number), pos, pos := pos + len(full)))
            continue
        if not _CODE.fullmatch(part):
            if "#" in part or "[" in part:
                fail("parameters and expressions (#, [ ]) are not supported; give plain numbers")
            if part.lstrip()[:1] in ("o", "O"):
                fail("O-words (subroutines, loops) are not supported")
            fail(f"cannot read {_WORD.sub(' ', part).strip()[:20]!r} (a word is a letter and a number)")
        out += [(m[1].upper(), float(re.sub("[ \t]", "", m[2])), offset + m.start(), offset + m.end())
                for m in _WORD.finditer(part)]  # fmt: skip
    for letter, value, start, end in out:
        if letter not in _LETTERS or not math.isfinite(value):
            fail("O-words (subroutines, loops) are not supported" if letter == "O" else
                 f"{text[start:end].strip()!r} is not a word of the language")  # fmt: skip
    return out


def read_program(
    path: str | os.PathLike[str], start: NDArray[np.float64], block_lines: int = BLOCK_LINES
) -> Iterator[ProgramBlock]:
    """The blocks of a G-code program, each with the intended path of its moves.

    Parameters
    ----------
    path : str or path-like
        A regular file (UTF-8 or ASCII).
    start : ndarray, shape (6,)
        The pose (mm, rad) before the first move: the values of the axes not yet programmed.
    block_lines : int

    Raises
    ------
    InputError
        ``FILE: line N: ...`` for the first line that cannot be read or corrected.
    """
    name = os.fspath(path)
    state = _State([float(v) for v in start])
    number, chars = 0, 0
    with open_input(name) as fh:
        while True:
            lines: list[str] = []
            try:
                while len(lines) < block_lines and (line := fh.readline(MAX_LINE + 1)):
                    if len(line) > MAX_LINE and not line.endswith(("\n", "\r")):
                        where = f"{name}: line {number + len(lines) + 1}"
                        raise InputError(f"{where}: longer than {MAX_LINE} characters")
                    lines.append(line)
                    chars += len(line)
            except UnicodeDecodeError:
                raise InputError(f"{name}: line {number + len(lines) + 1}: not UTF-8 text") from None
            if not lines:
                return
            yield _block(name, number + 1, lines, state, chars)
            number += len(lines)


def _block(name: str, first: int, lines: list[str], state: _State, chars: int) -> ProgramBlock:
    start = np.array(state.pose)
    rows: list[tuple] = []
    arcs: list[tuple[float, ...]] = []
    for i, raw in enumerate(lines):
        text = raw.rstrip("\r\n")
        bare = text.strip()
        if state.ended or not bare:
            continue
        if bare == "%":
            state.ended, state.started = state.started, True
            continue
        fast = _FAST.fullmatch(text)  # the usual line: a G0/G1 move and nothing else
        if fast and (fast[2] or state.motion in (0, 1)):
            pairs = _TIGHT.findall(fast[3])
            axes = {letter.upper(): float(number) for _, letter, number in pairs}
            if len(axes) == len(pairs):  # else: an axis twice, said by the general reading
                state.motion = int(fast[2]) if fast[2] else state.motion
                state.pose = end = _end(state, axes)
                word = "G0" if state.motion == 0 else "G1"
                rows.append((end, i, (fast[1], "", fast[1], "", "", word), state.units, bool(state.distance)))
                continue

        def fail(message: str, i: int = i) -> NoReturn:
            raise InputError(f"{name}: line {first + i}: {message}")

        blocked = bare.startswith("/")
        words = _words(text.replace("/", " ", 1) if blocked else text, fail)
        if blocked and words:
            fail("block delete '/' on a line with words: the path would depend on the switch")
        move = _line(state, words, fail)
        if move is None:
            continue
        end, anchor, drop, stop, arc = move
        if arc is not None:
            arcs.append((len(rows), *arc, state.units))
        head = _head(text, words, anchor, drop)
        split = _head(text, words, anchor, drop | stop) if stop else head
        stops = " ".join(text[words[j][2] : words[j][3]].strip() for j in sorted(stop))
        template = (*head, *split, stops, "G0" if state.motion == 0 else "G1")
        rows.append((end, i, template, state.units, bool(state.distance)))
    ends, at, templates, scale, incremental = (list(c) for c in zip(*rows, strict=True)) if rows else [[]] * 5
    moves = _arc_moves(name, first, at, start, np.array(ends, dtype=float).reshape(-1, 6), arcs)
    return ProgramBlock(first, lines, moves, np.array(at, dtype=np.intp), templates, np.array(scale),
                        np.array(incremental, dtype=bool), chars)  # fmt: skip


def _line(state: _State, words: list[_Word], fail: Callable[[str], NoReturn]) -> tuple | None:
    """Update the modal state with one line's words; the move it makes, or None.

    The move: ``(end pose, anchor word, words to drop, stop words, arc words or None)``.
    """
    seen: set[str] = set()
    axes: dict[str, float] = {}
    arc_words: dict[str, float] = {}
    new: dict[str, object] = {}
    anchor, drop, stop, others = None, set(), set(), set()
    for j, (letter, value, _, _) in enumerate(words):
        if letter in seen and letter not in "GM":
            fail(f"{letter} appears twice on the line")
        seen.add(letter)
        if letter in _AXIS:
            axes[letter] = value
            drop.add(j)
        elif letter == "G":
            code = round(value * 10)
            group, mode = _BY_CODE.get(code, (None, None))
            if abs(value * 10 - code) > 1e-3 or (group is None and code not in _KEPT):
                fail(_refusal(code) if abs(value * 10 - code) <= 1e-3 else f"G{value:g} is not a G code")
            if group in new:
                fail(f"two {group.replace('_', ' ')} codes on one line")
            if group is None:
                others.add(code)
            else:
                new[group] = mode
                anchor = j if group == "motion" else anchor
        elif letter == "M" and value in (98, 99):
            fail("M98/M99 subprograms are not supported")
        elif letter == "M" and value in _STOPS:
            stop.add(j)
            state.ended = state.ended or value in (2, 30)
        elif letter in "UVW":
            fail(f"the {letter} axis is not part of a hexapod's pose (X Y Z A B C)")
        elif letter in "IJKRP":
            arc_words[letter] = value
    for group, value in new.items():
        setattr(state, group, value)
    is_arc = state.motion in (2, 3)
    offsets = {k: v for k, v in arc_words.items() if k in "IJK"}
    if not is_arc and (offsets or "R" in arc_words):
        fail("I J K R words without G2 or G3")
    if not axes and not (is_arc and (offsets or "R" in arc_words)):
        return None
    if state.motion is None:
        fail("axis words without a motion mode (G0, G1, G2 or G3)")
    end = _end(state, axes)
    arc = None
    if is_arc:
        letters, plane_name = _PLANES[state.plane]
        if set(offsets) - set(letters):
            fail(f"{'/'.join(sorted(set(offsets) - set(letters)))} offset outside the arc plane {plane_name}")
        if (not offsets) == ("R" not in arc_words):
            fail("an arc takes I J K offsets or an R radius (one of them)")
        if "R" in arc_words and not any(AXES[k] in axes for k in state.plane):
            fail("an R-form arc needs an end point in its plane")
        turns = arc_words.get("P", 1.0)
        if turns != round(turns) or turns < 1 or others & {40, 640}:
            fail("the P word of an arc must be a whole number of turns >= 1 (and no G4 or G64 P on the line)")
        pair = [offsets.get(c, math.nan if "R" in arc_words else 0.0) * state.units for c in letters]
        radius = arc_words.get("R", math.nan) * state.units
        arc = (*state.plane, state.motion == 2, *pair, radius, not state.arc_distance, turns)
        drop |= {j for j, w in enumerate(words) if w[0] in "IJKRP"}
    anchor = min(drop) if anchor is None else anchor
    state.pose = end
    return end, anchor, drop - {anchor}, stop, arc


def _end(state: _State, axes: dict[str, float]) -> list[float]:
    """The pose after a move to the axis words ``axes`` (program units, degrees)."""
    end = list(state.pose)
    for letter, value in axes.items():
        k = _AXIS[letter]
        number = value * state.units if k < 3 else math.radians(value)
        end[k] = end[k] + number if state.distance else number
    return end


def _head(text: str, words: list[_Word], anchor: int, drop: set[int]) -> tuple[str, str]:
    """The line without the dropped words, split where the anchor word was."""
    parts, pos = [], 0
    for j in sorted(drop | {anchor}):
        parts += [text[pos : words[j][2]], "\0" if j == anchor else ""]
        pos = words[j][3]
    before, after = "".join([*parts, text[pos:]]).split("\0")
    return before, (" " + after if after and not after[0].isspace() else after).rstrip()


def gcode_comment(text: str, most: int = 250) -> str:
    """``text`` as one comment line ``(...)``: outside printable ASCII, and ``( ) \\ ;``,
    escaped as ``\\xNN``, ``\\uNNNN`` or ``\\UNNNNNNNN``, so that no input text (a geometry's
    name, a file name) can end the comment or the line; cut to ``most`` characters.

    >>> gcode_comment("evil) M2 (\\n")
    '(evil\\\\x29 M2 \\\\x28\\\\x0a)'
    """
    out = "".join(c if " " <= c <= "~" and c not in "()\\;" else _escape(c) for c in text)
    return f"({out[: most - 3] + '...' if len(out) > most else out})"


def _escape(c: str) -> str:
    return f"\\x{ord(c):02x}" if c < "\x80" else ascii(c)[1:-1]  # \xNN, \uNNNN or \UNNNNNNNN


class ProgramWriter:
    """Writes a corrected program block by block on an open text handle.

    Parameters
    ----------
    fh : text handle
    header : list of str
        Comment lines written before the program (after its first line if that is ``%``).
    decimals : (int, int, int)
        Decimals of X Y Z in a millimetre and in an inch program, and of A B C (degrees).
    start : ndarray, shape (6,)
        The corrected start pose (mm, rad): where a G91 program's first increment starts.
    """

    def __init__(
        self, fh: IO[str], header: list[str], decimals: tuple[int, int, int], start: NDArray[np.float64]
    ) -> None:
        self.fh, self.header, self.decimals = fh, header, decimals
        angles = np.round(np.degrees(start[3:]), decimals[2])
        self.last = np.concatenate([np.round(start[:3], decimals[0]), angles])

    def _numbers(self, block: ProgramBlock, path: CorrectedPath) -> list[str]:
        """The six axis words of every output point, as written."""
        d_mm, d_inch, d_angle = self.decimals
        scale = block.scale[path.move][:, None]
        inch = scale[:, 0] != 1.0
        values = np.concatenate([path.corrected[:, :3] / scale, np.degrees(path.corrected[:, 3:])], axis=1)
        factor = np.where(np.arange(6) < 3, np.where(inch, 10.0**d_inch, 10.0**d_mm)[:, None], 10.0**d_angle)
        written = np.round(values * factor) / factor
        absolute = np.concatenate([written[:, :3] * scale, written[:, 3:]], axis=1)  # mm, deg
        step = np.diff(np.concatenate([self.last[None], absolute]), axis=0)
        step[:, :3] /= scale
        out = np.where(block.incremental[path.move][:, None], np.round(step * factor) / factor, written)
        out += 0.0  # no "-0.00000"
        if len(absolute):
            self.last = absolute[-1]
        texts = np.empty(len(out), dtype=object)
        for mask, d in ((~inch, d_mm), (inch, d_inch)):
            if mask.any():
                one = " ".join(f"{a}%.{d if a in 'XYZ' else d_angle}f" for a in AXES) + "\n"
                texts[mask] = ((one * int(mask.sum())) % tuple(out[mask].ravel().tolist())).split("\n")[:-1]
        return texts.tolist()

    def write(self, block: ProgramBlock, path: CorrectedPath) -> None:
        """Write one block's lines, its moves replaced by the corrected points of ``path``."""
        out: list[str] = []
        skip = 0
        if self.header is not None:
            first = next((i for i, line in enumerate(block.lines) if line.strip()), None)
            skip = first + 1 if first is not None and block.lines[first].strip() == "%" else 0
            ending = next((line[len(line.rstrip("\r\n")) :] for line in block.lines[:1]), "") or "\n"
            out += block.lines[:skip] + [line + ending for line in self.header]
            self.header = None  # type: ignore[assignment]
        texts = self._numbers(block, path)
        starts, counts = (np.cumsum(path.counts) - path.counts).tolist(), path.counts.tolist()
        at_line, m = block.move_lines.tolist(), 0
        for i in range(skip, len(block.lines)):
            raw = block.lines[i]
            if m == len(at_line) or at_line[m] != i:
                out.append(raw)
                continue
            text = raw.rstrip("\r\n")
            before, after, split_before, split_after, stops, word = block.templates[m]
            ending, c, s = raw[len(text) :], counts[m], starts[m]
            if c == 1:
                out.append(f"{before}{word} {texts[s]}{after}{ending}")
            else:
                sep, indent = ending or "\n", text[: len(text) - len(text.lstrip())]
                out.append(f"{split_before}{word} {texts[s]}{split_after}{sep}")
                out += [f"{indent}{word} {texts[j]}{sep}" for j in range(s + 1, s + c - 1)]
                out.append(f"{indent}{word} {texts[s + c - 1]}{' ' + stops if stops else ''}{ending}")
            m += 1
        self.fh.write("".join(out))
