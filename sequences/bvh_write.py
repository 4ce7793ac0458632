"""Writing a Motion as a BVH file (what ``track --bvh`` needs; reading is sequences.bvh)."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .motion import Motion


# Nine decimals: angles re-derived from rotations (folded joints, the root) then survive a
# write/read cycle to well within 1e-6 degrees.
_DECIMALS = 9


def _format_vec(values) -> str:
    return " ".join(f"{v:.{_DECIMALS}f}" for v in values)


def write_bvh(path: str | Path, motion: Motion) -> None:
    """Write ``motion`` as a BVH file that read_bvh(path, fps=None, drop_tpose=False) reads
    back to within 1e-6 (angles in degrees, positions in CMU units; 9 decimals are written).
    """
    J = len(motion.names)
    children: list[list[int]] = [[] for _ in range(J)]
    for j, p in enumerate(motion.parents):
        if p >= 0:
            children[p].append(j)
    out: list[str] = ["HIERARCHY"]

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        kind = "ROOT" if motion.parents[j] < 0 else "JOINT"
        out.append(f"{pad}{kind} {motion.names[j]}")
        out.append(f"{pad}{{")
        out.append(f"{pad}\tOFFSET {_format_vec(motion.offsets[j])}")
        chans = motion.channels[j]
        out.append(f"{pad}\tCHANNELS {len(chans)} {' '.join(chans)}")
        for c in children[j]:
            emit(c, depth + 1)
        if not np.isnan(motion.end_sites[j]).any():
            out.extend([f"{pad}\tEnd Site", f"{pad}\t{{",
                        f"{pad}\t\tOFFSET {_format_vec(motion.end_sites[j])}", f"{pad}\t}}"])
        out.append(f"{pad}}}")

    emit(int(np.flatnonzero(motion.parents < 0)[0]), 0)
    T = motion.n_frames
    out += ["MOTION", f"Frames: {T}", f"Frame Time: {1.0 / motion.fps:.10g}"]
    frames = np.concatenate([motion.root_position.reshape(T, 3),
                             motion.euler_deg.reshape(T, J * 3)], axis=1)
    buffer = io.StringIO()
    np.savetxt(buffer, frames, fmt=f"%.{_DECIMALS}f")
    Path(path).write_text("\n".join(out) + "\n" + buffer.getvalue(), encoding="utf-8")
