"""Read and write BVH motion capture (the CMU conversion: 31 joints, ZYX channels, Y up).

A BVH file is a joint hierarchy (offsets, channels) and a MOTION block with one line of
channel values per frame. The reader parses the hierarchy token by token (it is small) and the
MOTION block in one call to ``np.loadtxt``; only when that fails does it walk the lines again
to name the first bad one.
"""
from __future__ import annotations

import io
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from regressor.errors import SilhouettePoseError
from .bvh_write import write_bvh  # noqa: F401  (the writer, re-exported for callers)
from .motion import ROTATION_CHANNELS, Motion

_POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
_TOKEN = re.compile(r"[{}]|[^\s{}]+")
#: Joints nested deeper than this are no skeleton (a body has about 10 levels); a file nesting
#: thousands had overflowed the parser's recursion.
MAX_DEPTH = 256
#: Frame times outside this range (seconds) are no motion capture: 10 kHz to one frame in
#: 10 s. A frame time of 100 s had made a 530-line file 1,026,001 frames at 30 fps (12 GB).
FRAME_TIME_RANGE = (1e-4, 10.0)
#: A motion longer than this (frames, at the rate asked for) is refused before resampling.
MAX_RESAMPLED_FRAMES = 10_000_000
#: Offsets and root positions beyond this (file units; CMU's are 5.6 cm, so 56 km) are damage,
#: not a body: 1e300 had passed, to be blamed later on a camera distance.
MAX_COORDINATE = 1e6


def euler_to_matrices(euler_deg: np.ndarray, orders: list[str]) -> np.ndarray:
    """Rotation matrices (T, J, 3, 3) from angles (T, J, 3) in degrees, intrinsic ``orders[j]``."""
    T, J, _ = euler_deg.shape
    out = np.empty((T, J, 3, 3))
    for order in set(orders):
        cols = [j for j, o in enumerate(orders) if o == order]
        angles = euler_deg[:, cols].reshape(-1, 3)
        mats = Rotation.from_euler(order, angles, degrees=True).as_matrix()
        out[:, cols] = mats.reshape(T, len(cols), 3, 3)
    return out


def matrices_to_euler(rot: np.ndarray, orders: list[str]) -> np.ndarray:
    """Angles (T, J, 3) in degrees, intrinsic ``orders[j]``, from rotation matrices (T, J, 3, 3)."""
    T, J = rot.shape[:2]
    out = np.empty((T, J, 3))
    for order in set(orders):
        cols = [j for j, o in enumerate(orders) if o == order]
        mats = rot[:, cols].reshape(-1, 3, 3)
        out[:, cols] = Rotation.from_matrix(mats).as_euler(order, degrees=True).reshape(
            T, len(cols), 3)
    return out


def _short(token: str, limit: int = 40) -> str:
    """repr() of a token, cut to ``limit`` characters: an error about a binary file's
    'token' had been one line of 20,000 characters."""
    return repr(token) if len(token) <= limit else repr(token[:limit]) + "..."


class BVHError(SilhouettePoseError, ValueError):
    """A malformed or unsupported BVH file; the message names the file and line."""


# ----------------------------------------------------------------------------- reading


class _Tokens:
    """Hierarchy tokens with their 1-based line numbers."""

    def __init__(self, lines: list[str], source: str):
        self.items = [(n, tok) for n, line in enumerate(lines, 1) for tok in _TOKEN.findall(line)]
        self.pos = 0
        self.source = source
        self.last_line = len(lines)

    def error(self, message: str, line: int | None = None) -> BVHError:
        if line is None:
            line = self.items[self.pos][0] if self.pos < len(self.items) else self.last_line
        return BVHError(f"{self.source} line {line}: {message}")

    def next(self, what: str) -> tuple[int, str]:
        if self.pos >= len(self.items):
            raise self.error(f"unexpected end of file, expected {what}")
        item = self.items[self.pos]
        self.pos += 1
        return item

    def expect(self, word: str) -> int:
        line, tok = self.next(repr(word))
        if tok != word:
            raise self.error(f"expected {word!r}, got {_short(tok)}", line)
        return line

    def number(self, what: str) -> float:
        line, tok = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise self.error(f"expected a number for {what}, got {_short(tok)}",
                             line) from None
        if not np.isfinite(value):
            raise self.error(f"non-finite {what}: {_short(tok)}", line)
        return value

    def peek(self) -> str | None:
        return self.items[self.pos][1] if self.pos < len(self.items) else None


@dataclass
class _Skeleton:
    names: list[str] = field(default_factory=list)
    parents: list[int] = field(default_factory=list)
    offsets: list[list[float]] = field(default_factory=list)
    end_sites: list[list[float]] = field(default_factory=list)
    channels: list[list[str]] = field(default_factory=list)


def _parse_offset(tok: _Tokens, owner: str) -> list[float]:
    tok.expect("OFFSET")
    return [tok.number(f"{owner} OFFSET") for _ in range(3)]


def _parse_channels(tok: _Tokens, name: str, is_root: bool) -> list[str]:
    line = tok.expect("CHANNELS")
    count = tok.number(f"{name} CHANNELS count")
    if count != int(count) or count < 0:
        raise tok.error(f"bad channel count {count} for {name}", line)
    channels = [tok.next(f"channel name of {name}")[1] for _ in range(int(count))]
    rotations = [c for c in channels if c in ROTATION_CHANNELS]
    positions = [c for c in channels if c in _POSITION_CHANNELS]
    unknown = [c for c in channels if c not in ROTATION_CHANNELS + _POSITION_CHANNELS]
    if unknown:
        raise tok.error(f"unknown channel {unknown[0]!r} for {name}", line)
    if sorted(rotations) != sorted(ROTATION_CHANNELS):
        raise tok.error(f"{name} needs exactly one X, Y and Z rotation channel", line)
    expected_positions = sorted(_POSITION_CHANNELS) if is_root else []
    if sorted(positions) != expected_positions:
        raise tok.error(f"{name}: only the root may (and must) have X, Y, Z position channels",
                        line)
    if is_root and channels[:3] != list(_POSITION_CHANNELS):
        raise tok.error(f"{name}: root channels must start Xposition Yposition Zposition", line)
    return channels


def _parse_joint(tok: _Tokens, skel: _Skeleton, name: str, parent: int, depth: int = 0
                 ) -> None:
    open_line = tok.expect("{")
    if depth > MAX_DEPTH:
        raise tok.error(f"joints nested more than {MAX_DEPTH} deep", open_line)
    if name in skel.names:
        # Two joints of one name: the body model took the first, the pose vector the last.
        raise tok.error(f"a second joint named {_short(name)}", open_line)
    index = len(skel.names)
    skel.names.append(name)
    skel.parents.append(parent)
    skel.offsets.append(_parse_offset(tok, name))
    skel.channels.append(_parse_channels(tok, name, parent < 0))
    skel.end_sites.append([np.nan] * 3)
    while True:
        word = tok.peek()
        if word == "}":
            tok.next("'}'")
            return
        if word == "JOINT":
            tok.next("JOINT")
            _, child = tok.next("joint name")
            _parse_joint(tok, skel, child, index, depth + 1)
        elif word == "End":
            tok.next("End")
            tok.expect("Site")
            tok.expect("{")
            skel.end_sites[index] = _parse_offset(tok, f"{name} End Site")
            tok.expect("}")
        elif word is None or word == "MOTION":
            raise tok.error(f"unbalanced braces: joint {name!r} opened on line {open_line} "
                            f"is not closed")
        else:
            raise tok.error(f"expected JOINT, End Site or '}}' in joint {name!r}, got "
                            f"{_short(word)}")


def _parse_hierarchy(lines: list[str], source: str) -> _Skeleton:
    tok = _Tokens(lines, source)
    if not tok.items:
        raise BVHError(f"{source} line 1: empty file, expected HIERARCHY")
    line, word = tok.next("HIERARCHY")
    if word != "HIERARCHY":
        raise tok.error(f"expected HIERARCHY, got {_short(word)}", line)
    tok.expect("ROOT")
    _, root = tok.next("root name")
    skel = _Skeleton()
    _parse_joint(tok, skel, root, -1)
    if tok.peek() != "MOTION":
        word = tok.peek()
        what = "end of file" if word is None else _short(word)
        if word == "}":
            raise tok.error("unbalanced braces: '}' without a matching '{'")
        raise tok.error(f"expected MOTION after the hierarchy, got {what}")
    return skel


def _header_value(line: str, key: str, source: str, lineno: int) -> float:
    label, _, value = line.partition(":")
    if " ".join(label.split()) != key:
        raise BVHError(f"{source} line {lineno}: expected '{key}:', got {line.strip()!r}")
    try:
        return float(value)
    except ValueError:
        raise BVHError(f"{source} line {lineno}: bad {key} value {value.strip()!r}") from None


def _diagnose_motion(block: str, first_line: int, n_frames: int, n_values: int,
                     source: str) -> BVHError:
    """Walk the MOTION lines (slow path, only after the fast parse failed) to name the bad one."""
    count = 0
    lineno = first_line
    for lineno, line in enumerate(block.splitlines(), first_line):
        values = line.split()
        if not values:
            continue
        count += 1
        if count > n_frames:
            return BVHError(f"{source} line {lineno}: more frame lines than 'Frames: {n_frames}'")
        if len(values) != n_values:
            return BVHError(f"{source} line {lineno}: expected {n_values} values, "
                            f"got {len(values)}")
        for value in values:
            try:
                number = float(value)
            except ValueError:
                return BVHError(f"{source} line {lineno}: non-numeric value {value!r}")
            if not np.isfinite(number):
                return BVHError(f"{source} line {lineno}: non-finite value {value!r}")
    return BVHError(f"{source} line {lineno}: truncated motion block: 'Frames: {n_frames}' but "
                    f"{count} frame lines")


def _file_fps(frame_time: float) -> float:
    """Frames per second from the 'Frame Time' (0.0083333 -> 120): snap to an integer rate when
    the file's rounding of the frame time is the only difference."""
    fps = 1.0 / frame_time
    return float(round(fps)) if abs(fps - round(fps)) < 1e-3 * fps else fps


def _is_added_tpose(frame: np.ndarray, n_root_pos: int) -> bool:
    """The CMU conversion's added T-pose frame: root rotation zero and every angle a whole
    number (the real frames carry 4-6 decimals)."""
    rotations = frame[n_root_pos:]
    return bool(np.all(rotations[:3] == 0) and np.all(rotations == np.round(rotations)))


def _motion_header(rest: str, source: str, motion_line: int) -> tuple[int, float, str]:
    """(frames, frame time in seconds, the data block) from the text after the MOTION line
    (at line motion_line); BVHError naming the line for a missing or absurd value."""
    if rest.startswith("\r"):
        rest = rest[1:]
    rest = rest[1:] if rest.startswith("\n") else rest
    header = rest.split("\n", 2)
    if len(header) < 3 and not (len(header) == 2 and header[1].strip()):
        raise BVHError(f"{source} line {motion_line + len(header)}: expected 'Frames:' and "
                       f"'Frame Time:' after MOTION")
    frames_value = _header_value(header[0], "Frames", source, motion_line + 1)
    frame_time = _header_value(header[1], "Frame Time", source, motion_line + 2)
    if not np.isfinite(frames_value) or frames_value != int(frames_value) or frames_value < 1:
        raise BVHError(f"{source} line {motion_line + 1}: need a positive whole number of "
                       f"frames, got {header[0].strip()!r}")
    low, high = FRAME_TIME_RANGE
    if not (np.isfinite(frame_time) and low <= frame_time <= high):
        raise BVHError(f"{source} line {motion_line + 2}: frame time must be between {low:g} "
                       f"and {high:g} s, got {_short(header[1].strip())}")
    return int(frames_value), frame_time, header[2] if len(header) == 3 else ""


def _motion_values(block: str, skel, n_frames: int, source: str, first_line: int
                   ) -> np.ndarray:
    """The motion's values (n_frames, channels), finite and within MAX_COORDINATE; BVHError
    naming the line otherwise."""
    n_values = sum(len(c) for c in skel.channels)
    try:
        data = np.loadtxt(io.StringIO(block), dtype=np.float64, ndmin=2, comments=None)
        ok = data.shape == (n_frames, n_values) and bool(np.isfinite(data).all())
    except ValueError:
        ok = False
    if not ok:
        raise _diagnose_motion(block, first_line, n_frames, n_values, source)
    far = np.flatnonzero(np.abs(data[:, :3]).max(axis=1) > MAX_COORDINATE)
    if len(far):
        raise BVHError(f"{source} line {first_line + int(far[0])}: root position beyond "
                       f"{MAX_COORDINATE:g} units")
    if np.abs(np.array(skel.offsets)).max() > MAX_COORDINATE:
        raise BVHError(f"{source}: a joint OFFSET beyond {MAX_COORDINATE:g} units")
    return data


def read_bvh(path: str | Path, fps: float | None = 30.0, drop_tpose: str | bool = "auto"
             ) -> Motion:
    """Read a BVH file into a Motion resampled to ``fps`` frames per second.

    fps: target rate; None keeps the file's rate. An integer ratio (120 -> 30) decimates
        exactly; otherwise rotations are slerped and root positions interpolated linearly.
    drop_tpose: True drops frame 0, False keeps it, "auto" drops it when it is the T-pose the
        CMU conversion added (root rotation zero and all angles whole numbers; 16_11 and 141_16
        have none).
    Raises BVHError naming the file and line for malformed input, FileNotFoundError if absent.
    """
    path = Path(path)
    source = path.name
    text = path.read_text(encoding="utf-8", errors="replace").removeprefix("\ufeff")  # a BOM
    match = re.search(r"^[ \t]*MOTION[ \t]*\r?$", text, flags=re.MULTILINE)
    head = text[: match.start()] if match else text
    head_lines = head.splitlines()
    skel = _parse_hierarchy(head_lines + (["MOTION"] if match else []), source)
    motion_line = len(head_lines) + 1
    if match is None:     # the hierarchy ended at a MOTION that shares its line with more
        word = re.compile(r"(?<![\w])MOTION(?![\w])")
        lineno = next((n for n, line in enumerate(head_lines, 1) if word.search(line)),
                      len(head_lines))
        raise BVHError(f"{source} line {lineno}: 'MOTION' must stand alone on its line")

    n_frames, frame_time, block = _motion_header(text[match.end():], source, motion_line)
    first_data_line = motion_line + 3
    data = _motion_values(block, skel, n_frames, source, first_data_line)

    n_pos = 3
    if drop_tpose == "auto":
        drop = _is_added_tpose(data[0], n_pos)
    elif isinstance(drop_tpose, bool):
        drop = drop_tpose
    else:
        raise ValueError(f"drop_tpose must be 'auto', True or False, got {drop_tpose!r}")
    if drop:
        data = data[1:]
        if len(data) == 0:
            raise BVHError(f"{source} line {first_data_line}: no frames left after dropping "
                           f"the T-pose frame")

    J = len(skel.names)
    root_position = data[:, :n_pos].copy()
    euler_deg = data[:, n_pos:].reshape(len(data), J, 3).copy()
    motion = Motion(
        names=skel.names,
        parents=np.array(skel.parents, dtype=np.int64),
        offsets=np.array(skel.offsets, dtype=np.float64),
        end_sites=np.array(skel.end_sites, dtype=np.float64),
        channels=skel.channels,
        euler_deg=euler_deg,
        root_position=root_position,
        fps=_file_fps(frame_time),
        source=source,
    )
    return motion if fps is None else resample(motion, fps)


def resample(motion: Motion, fps: float) -> Motion:
    """The motion at ``fps`` frames per second, starting at its first frame.

    An integer ratio of rates decimates exactly (angles untouched); otherwise rotations are
    slerped per joint (angles re-derived in each joint's order) and positions interpolated.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps!r}")
    frames_out = (motion.n_frames - 1) / motion.fps * fps + 1
    if frames_out > MAX_RESAMPLED_FRAMES:
        raise BVHError(f"{motion.source or 'motion'}: {motion.n_frames} frames at "
                       f"{motion.fps:g} fps would be {frames_out:.3g} frames at {fps:g} fps "
                       f"(at most {MAX_RESAMPLED_FRAMES:,})")
    ratio = motion.fps / fps
    step = round(ratio)
    if abs(ratio - step) < 1e-9 and step >= 1:
        return replace(motion, euler_deg=motion.euler_deg[::step].copy(),
                       root_position=motion.root_position[::step].copy(), fps=float(fps))
    T = motion.n_frames
    t_in = np.arange(T) / motion.fps
    t_out = np.arange(0.0, t_in[-1] + 1e-9, 1.0 / fps)
    rot_in = motion.local_rotations()
    rot_out = np.empty((len(t_out), rot_in.shape[1], 3, 3))
    if T == 1:
        rot_out[:] = rot_in[0]
    else:
        for j in range(rot_in.shape[1]):
            rot_out[:, j] = Slerp(t_in, Rotation.from_matrix(rot_in[:, j]))(t_out).as_matrix()
    position = np.stack([np.interp(t_out, t_in, motion.root_position[:, k]) for k in range(3)],
                        axis=1)
    euler = matrices_to_euler(rot_out, motion.rotation_orders())
    return replace(motion, euler_deg=euler, root_position=position, fps=float(fps))
