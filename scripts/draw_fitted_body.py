"""Draw the training body fitted to Pose2Sim's reference over the real video, to check the fit.

    python scripts/draw_fitted_body.py docs/evaluation/pose2sim/fitted_body.jpg
        [--trial ../shared/data/pose2sim/balancing] [--frames 10 50 90]

Fits the project's body to the reference keypoints of those frames (sequences.keypoint_fit,
~0.3 s a frame), renders
it through each calibrated camera (sequences.pose2sim.render_view_masks) and draws its outline
in red on the given video frames, one row per view, each tile cropped round the body. The
outline should follow the subject: it is the silhouette `evaluate_real.py --reference-masks
rendered` gives the regressor.

An output that is not a .jpg or .png name, could not be written or is one of the trial's files,
and a --trial folder that does not exist, are refused before any work (exit 2); bad data (a
trial file that is not text, a view's video missing or undecodable:
lab.pose2sim_trial's checks) ends the run in one line naming the file (exit 1);
Ctrl-C in one line (exit 130). The image is written whole or not at all."""
from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from sequences.body import load_body
from sequences.keypoint_fit import KeypointFitError, fit_body, posed_vertices
from sequences.pose2sim import (DEFAULT_TRIAL, VIEWS, Pose2SimError, render_view_masks,
                                video_frames)
from lab.pose2sim_trial import checked_trial, missing_trial, trial_files
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line
from tracker.outputs.files import OutputWriteError
from tracker.outputs.whole_files import write_whole
from tracker.video.decode import VideoError, open_video

_TILE_PX = 260          # tile height
_MARGIN_PX = 100        # around the body's box in the frame


def _tile(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The frame with the mask's outline drawn, cropped round it, _TILE_PX tall."""
    image = image.copy()
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    cv2.drawContours(image, contours, -1, (0, 0, 255), 4)
    rows, cols = np.nonzero(mask)
    y0, x0 = max(rows.min() - _MARGIN_PX, 0), max(cols.min() - _MARGIN_PX, 0)
    crop = image[y0:rows.max() + _MARGIN_PX, x0:cols.max() + _MARGIN_PX]
    scale = _TILE_PX / crop.shape[0]
    return cv2.resize(crop, (max(1, round(crop.shape[1] * scale)), _TILE_PX))


def draw(trial, frames: list[int]) -> np.ndarray:
    """One BGR image: a row per view, a tile per frame (video frame indices)."""
    available = set(video_frames(trial).tolist())
    missing = [f for f in frames if f not in available]
    if missing:
        raise Pose2SimError(f"frame {missing[0]} has no reference (the reference covers "
                            f"video frames {min(available)}..{max(available)})")
    body = load_body()
    fit = fit_body(trial.points(frames), trial.reference.names, body)
    vertices = posed_vertices(fit, body)
    lines = []
    for view in VIEWS:
        source = open_video(trial.video(view))
        masks = render_view_masks(vertices, body.faces, body.patch_start, trial.camera(view),
                                  (source.height, source.width))
        images = {}
        for index, _, image in source:          # decoded only as far as the last frame drawn
            if index in frames:
                images[index] = image
            if index >= max(frames):
                break
        lines.append(np.hstack([_tile(images[f], m) for f, m in zip(frames, masks)]))
    width = max(line.shape[1] for line in lines)
    return np.vstack([np.pad(line, ((0, 0), (0, width - line.shape[1]), (0, 0)))
                      for line in lines])


def _write_image(path: Path, image: np.ndarray, out: Path) -> None:
    """image written to path (out's temporary name) by OpenCV, in the format its suffix names;
    Pose2SimError naming out if it cannot be. (The JPEG quality flag only for a JPEG: OpenCV
    warns of it for a PNG.)"""
    jpeg = path.suffix.lower() in (".jpg", ".jpeg")
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_JPEG_QUALITY, 80] if jpeg else []):
        raise Pose2SimError(f"{out}: cannot write the image")


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="image to write (.jpg or .png)")
    ap.add_argument("--trial", type=Path, default=DEFAULT_TRIAL, help="the balancing trial "
                    "folder (default: ../shared/data/pose2sim/balancing beside the repo)")
    ap.add_argument("--frames", type=int, nargs="+", default=[10, 50, 90],
                    help="video frames to draw (default: 10 50 90)")
    args = ap.parse_args(argv)
    if args.out.suffix.lower() not in (".jpg", ".jpeg", ".png"):
        ap.error(f"{args.out}: give a .jpg or .png name")
    if missing_trial(args.trial):
        ap.error(missing_trial(args.trial))
    # Before the fitting and decoding: writable, and none of the files read.
    ap.check_outputs([("the output", args.out)], trial_files(args.trial))
    quiet_decoder_logs()          # as track: one line, not FFmpeg's too
    try:
        image = draw(checked_trial(args.trial), sorted(set(args.frames)))
        # Whole or not at all; the temporary name keeps the suffix, which OpenCV reads.
        write_whole(args.out, lambda path: _write_image(path, image, args.out),
                    keep_suffix=True)
    except (Pose2SimError, KeypointFitError, VideoError, OutputWriteError, cv2.error) as exc:
        print(f"draw_fitted_body: error: {exc}", file=sys.stderr)
        return 1
    print(f"wrote {args.out}")
    return 0


main = stops_in_one_line("draw_fitted_body", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
