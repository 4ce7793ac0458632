"""Make tests/data/vfr_walk.mkv: the sample walk at 30 fps for 6 s, then at 10 fps to its end.

    python scripts/make_vfr_clip.py [--out tests/data/vfr_walk.mkv]

A variable frame rate as a camera gives it when it drops to 10 fps: frames 0-179 of
sequences/data/sample_spiral_walk.mp4 (30 fps), then every third frame from 180 on, each kept
at its own time (6.0 s, 6.1 s, ... 12.0 s): 241 frames, about 84 KB (H.264, CRF 28, in Matroska,
whose container announces 30 fps). It needs the ffmpeg program (Debian: apt-get install
ffmpeg); the tests use the committed clip and do not need it. A missing ffmpeg or sample is
refused in one line (exit 2).
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from tracker.one_line_parser import OneLineParser, stops_in_one_line

SAMPLE = ROOT / "sequences" / "data" / "sample_spiral_walk.mp4"
#: Frames at 30 fps before the rate drops, and the step (in 30 fps frames) after.
FULL_RATE_FRAMES, STEP = 180, 3


def ffmpeg_command(sample: Path, out: Path) -> list[str]:
    """The ffmpeg call: select frames (their timestamps kept: -fps_mode vfr), encode
    reproducibly (bit-exact flags, no metadata)."""
    select = f"select='lt(n\\,{FULL_RATE_FRAMES})+not(mod(n-{FULL_RATE_FRAMES}\\,{STEP}))'"
    return ["ffmpeg", "-loglevel", "error", "-y", "-i", str(sample), "-vf", select,
            "-fps_mode", "vfr", "-c:v", "libx264", "-preset", "veryslow", "-crf", "28",
            "-pix_fmt", "yuv420p", "-an", "-map_metadata", "-1", "-fflags", "+bitexact",
            "-flags:v", "+bitexact", str(out)]


def _main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "tests" / "data" / "vfr_walk.mkv",
                        help="the clip to write (default tests/data/vfr_walk.mkv)")
    args = parser.parse_args(argv)
    if shutil.which("ffmpeg") is None:
        parser.error("the ffmpeg program is not installed (Debian: apt-get install ffmpeg)")
    if not SAMPLE.is_file():
        parser.error(f"{SAMPLE}: no such file (the sample video)")
    done = subprocess.run(ffmpeg_command(SAMPLE, args.out), capture_output=True, text=True)
    if done.returncode != 0:
        lines = done.stderr.strip().splitlines() or ["no message"]
        print(f"make_vfr_clip: ffmpeg failed: {lines[-1]}", file=sys.stderr)
        return 1
    print(f"{args.out}: {args.out.stat().st_size / 1e3:.0f} KB")
    return 0


main = stops_in_one_line("make_vfr_clip", _main)       # Ctrl-C: one line, exit 130

if __name__ == "__main__":
    sys.exit(main())
