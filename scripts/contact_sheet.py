"""Contact sheet of the body renderer: one real walking frame (CMU 02_01) from 12 azimuths
(every 30 degrees) for 3 body shapes, shaded render above its binary silhouette.

    python scripts/contact_sheet.py [--bvh ../shared/data/cmu/bvh/02_01.bvh] [--frame 40]
                                    [--out docs/contact_sheet.png]

Needs the CMU data in ../shared. All tiles of a row share one camera distance and focal length,
so taller or broader shapes look taller or broader.
"""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

import cv2
import numpy as np

from sequences.body import BodyShape, Skinner, load_body
from sequences.bvh import read_bvh
from sequences.render import look_at_camera, shaded_render, silhouette_mask
from tracker.one_line_parser import OneLineParser

SHAPES = (BodyShape(0.9, 0.85), BodyShape(1.0, 1.0), BodyShape(1.1, 1.3))
TILE = (170, 115)                      # height, width in pixels
ELEVATION_DEG = 10.0


def tile_pair(body, vertices, azimuth, label):
    """Shaded tile and silhouette tile (H, W, 3) RGB of posed vertices from one azimuth."""
    target = [vertices[:, 0].mean(), 0.85, vertices[:, 2].mean()]
    camera = look_at_camera(target, azimuth, ELEVATION_DEG, 6.0, 6.0 * 140 / 1.8, TILE)
    shaded, _ = shaded_render(vertices, body.faces, camera, background=(40, 40, 48))
    mask = silhouette_mask(vertices, body.faces, body.patch_start, camera)
    silhouette = np.repeat((mask * 255).astype(np.uint8)[..., None], 3, axis=2)
    cv2.putText(shaded, label, (3, 11), cv2.FONT_HERSHEY_SIMPLEX, 0.33, (255, 255, 255), 1)
    return shaded, silhouette


def main() -> None:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bvh", type=Path,
                        default=ROOT.parent / "shared" / "data" / "cmu" / "bvh" / "02_01.bvh")
    parser.add_argument("--frame", type=int, default=40)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "contact_sheet.png")
    args = parser.parse_args()
    motion = read_bvh(args.bvh)
    body = load_body()
    rows = []
    for shape in SHAPES:
        skinner = Skinner(body, motion.offsets, motion.names, motion.end_sites, shape=shape)
        vertices = skinner.pose(motion.local_rotations()[args.frame],
                                skinner.root_from_bvh(motion.root_position[args.frame]))
        vertices = vertices - [0.0, vertices[:, 1].min(), 0.0]       # feet on the floor
        pairs = [tile_pair(body, vertices, az, f"az {az} h{shape.height_scale:.1f} "
                           f"g{shape.girth_scale:.2f}") for az in range(0, 360, 30)]
        rows.append(np.hstack([p[0] for p in pairs]))
        rows.append(np.hstack([p[1] for p in pairs]))
    sheet = np.vstack(rows)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(args.out), cv2.cvtColor(sheet, cv2.COLOR_RGB2BGR))
    print(f"{args.out}: {sheet.shape[1]}x{sheet.shape[0]}, {motion.source} frame {args.frame}")


if __name__ == "__main__":
    main()
