"""Contact sheet of the body renderer: one real walking frame (CMU 02_01) from 12 azimuths
(every 30 degrees) for 3 body shapes, shaded render above its binary silhouette.

    python scripts/contact_sheet.py [--bvh ../shared/data/cmu/bvh/02_01.bvh] [--frame 40]
                                    [--out docs/contact_sheet.png]

Needs the CMU data in ../shared. All tiles of a row share one camera distance and focal length,
so taller or broader shapes look taller or broader.

A --bvh that does not exist, a negative --frame, and an --out that is not a .png or .jpg name,
could not be written or is the --bvh file are refused before any work (exit 2), as is a
--frame the motion does not have; a malformed --bvh is one line naming it (exit 1); Ctrl-C one
line (exit 130). --out is written whole or not at all.
"""
from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError
from sequences.body import BodyPoseError, BodyShape, Skinner, load_body
from sequences.bvh import BVHError, read_bvh
from sequences.render import look_at_camera, shaded_render, silhouette_mask
from tracker.one_line_parser import OneLineParser, stops_in_one_line
from tracker.outputs.files import OutputWriteError
from tracker.outputs.whole_files import write_whole

SHAPES = (BodyShape(0.9, 0.85), BodyShape(1.0, 1.0), BodyShape(1.1, 1.3))
TILE = (170, 115)                      # height, width in pixels
ELEVATION_DEG = 10.0
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def tile_pair(body, vertices, azimuth, label):
    """Shaded tile and silhouette tile (H, W, 3) RGB of posed vertices from one azimuth."""
    target = [vertices[:, 0].mean(), 0.85, vertices[:, 2].mean()]
    camera = look_at_camera(target, azimuth, ELEVATION_DEG, 6.0, 6.0 * 140 / 1.8, TILE)
    shaded, _ = shaded_render(vertices, body.faces, camera, background=(40, 40, 48))
    mask = silhouette_mask(vertices, body.faces, body.patch_start, camera)
    silhouette = np.repeat((mask * 255).astype(np.uint8)[..., None], 3, axis=2)
    cv2.putText(shaded, label, (3, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.33, (255, 255, 255), 1)
    return shaded, silhouette


def _main(argv) -> int:
    # The docstring's first sentence, whole (its first line ends mid-sentence).
    parser = OneLineParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("--bvh", type=Path,
                        default=ROOT.parent / "shared" / "data" / "cmu" / "bvh" / "02_01.bvh",
                        help="the motion (default: CMU 02_01 in ../shared beside the repo)")
    parser.add_argument("--frame", type=int, default=40,
                        help="the frame of the motion to pose, from 0 (default 40)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "contact_sheet.png",
                        help="the image to write, .png or .jpg (default docs/contact_sheet.png)")
    args = parser.parse_args(argv)
    if not args.bvh.is_file():
        parser.error(f"--bvh {args.bvh}: " + ("not a file" if args.bvh.exists()
                                              else "no such file"))
    if args.frame < 0:
        parser.error(f"--frame must be 0 or more, got {args.frame}")
    if args.out.suffix.lower() not in IMAGE_SUFFIXES and not args.out.is_dir():
        parser.error(f"--out {args.out}: give an image name ending in "
                     f"{', '.join(IMAGE_SUFFIXES)}")
    parser.check_outputs([("--out", args.out)], [("--bvh", args.bvh)])
    try:
        motion = read_bvh(args.bvh)
    except BVHError as exc:
        print(f"contact_sheet: error: {exc}", file=sys.stderr)     # names the file and line
        return 1
    except (OSError, ValueError, MemoryError) as exc:
        print(f"contact_sheet: error: --bvh {args.bvh}: {exc or type(exc).__name__}",
              file=sys.stderr)
        return 1
    if args.frame >= motion.n_frames:
        parser.error(f"--frame {args.frame}: {args.bvh} has {motion.n_frames} frames "
                     f"(0..{motion.n_frames - 1})")
    try:
        sheet = _sheet(motion, args.frame)
        # Whole or not at all; the temporary name keeps the suffix, which OpenCV reads.
        write_whole(args.out, lambda path: _write(path, sheet, args.out), keep_suffix=True)
    except BodyPoseError as exc:            # the file's skeleton, which the message does not name
        print(f"contact_sheet: error: --bvh {args.bvh}: {exc}", file=sys.stderr)
        return 1
    except (SilhouettePoseError, OutputWriteError, ValueError) as exc:
        print(f"contact_sheet: error: {exc}", file=sys.stderr)
        return 1
    print(f"{args.out}: {sheet.shape[1]}x{sheet.shape[0]}, {motion.source} frame {args.frame}")
    return 0


def _write(path: Path, sheet: np.ndarray, out: Path) -> None:
    """The RGB sheet written to path (out's temporary name); OutputWriteError naming out."""
    if not cv2.imwrite(str(path), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR)):
        raise OutputWriteError(f"{out}: OpenCV could not write the image")


def _sheet(motion, frame: int) -> np.ndarray:
    """The contact sheet (RGB) of one frame of the motion: per body shape a row of shaded
    tiles over a row of silhouettes, one tile per azimuth."""
    body = load_body()
    rows = []
    for shape in SHAPES:
        skinner = Skinner(body, motion.offsets, motion.names, motion.end_sites, shape=shape)
        vertices = skinner.pose(motion.local_rotations()[frame],
                                skinner.root_from_bvh(motion.root_position[frame]))
        vertices = vertices - [0.0, vertices[:, 1].min(), 0.0]       # feet on the floor
        pairs = [tile_pair(body, vertices, az, f"az {az} h{shape.height_scale:.1f} "
                           f"g{shape.girth_scale:.2f}") for az in range(0, 360, 30)]
        rows.append(np.hstack([p[0] for p in pairs]))
        rows.append(np.hstack([p[1] for p in pairs]))
    return np.vstack(rows)


main = stops_in_one_line("contact_sheet", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
