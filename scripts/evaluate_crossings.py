"""Identity through crossings: the sample walk beside its own mirror image, who is who.

    python scripts/evaluate_crossings.py                       # before and after, 8 videos
    python scripts/evaluate_crossings.py --associator after --offsets 0 30

Each video is a one-walker render (default the shipped sample) with the walker of ``offset``
frames later pasted in mirrored (lab.crossings.mirror_crossing), once as a twin and
once in other (tinted) colours: the two walk towards each other, merge into one blob, and
part, twice per video. The track command's extractor and associator run on it (the identities
are decided there), and the script prints per video and in total: crossings, identity
switches, tracks per person (1 is perfect) and the share of person-frames tracked while the
two are apart, and of the person-frames while their true boxes overlap, the share with a
silhouette of their own under their id (tracker.video.blob_split's split of the blob). ``before``
is the association without groups or appearance (as before issue 50's crossing item);
``after`` is track's default.
"""
from __future__ import annotations

import sys
from pathlib import Path

from regressor.errors import SilhouettePoseError
from tracker.tracks.association import Associator
from lab.crossings import (identity_measures, mirror_crossing, read_frames,
                                       track_identities)
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line
from sequences.video import load_truth, truth_path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sequences" / "data" / "sample_spiral_walk.mp4"
ASSOCIATORS = {"before": lambda: Associator(appearance_weight=0.0, max_occluded=0),
               "after": Associator}


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--video", type=Path, default=SAMPLE, help="a one-person static-camera "
                    "video with a ground-truth sidecar (default: the shipped sample)")
    ap.add_argument("--offsets", type=int, nargs="+", default=[0, 20, 40, 60],
                    help="frames by which the mirrored walker is ahead (default 0 20 40 60)")
    ap.add_argument("--associator", nargs="+", choices=list(ASSOCIATORS),
                    default=list(ASSOCIATORS))
    args = ap.parse_args(argv)
    if not args.video.is_file() or not truth_path(args.video).is_file():
        ap.error(f"--video {args.video}: needs the video and its {truth_path(args.video).name}")
    quiet_decoder_logs()
    try:
        frames, truth = read_frames(args.video), load_truth(args.video)
        if any(not 0 <= o < len(frames) - 1 for o in args.offsets):
            ap.error(f"--offsets must be within 0..{len(frames) - 2} for this video")
        clips = [(o, tint, mirror_crossing(frames, truth, o, tint))
                 for o in args.offsets for tint in (False, True)]
    except (SilhouettePoseError, ValueError) as exc:
        print(f"evaluate_crossings: error: {exc}", file=sys.stderr)
        return 1
    print(f"{'associator':10} {'offset':>6} {'copy':6} {'crossings':>9} {'switches':>8} "
          f"{'tracks/person':>13} {'found':>6} {'touching':>8}")
    for label in args.associator:
        total = {"crossings": 0, "switches": 0, "tracks": [], "found": [], "touching": []}
        for offset, tint, (clip, background, centroids, boxes) in clips:
            reported = track_identities(clip, background, ASSOCIATORS[label]())
            m = identity_measures(reported, centroids, boxes)
            print(f"{label:10} {offset:6d} {'tinted' if tint else 'twin':6} {m['crossings']:9d} "
                  f"{m['switches']:8d} {_per_person(m['tracks_per_person']):>13} "
                  f"{m['found']:6.1%} {m['found_touching']:8.1%}", flush=True)
            total["crossings"] += m["crossings"]
            total["switches"] += m["switches"]
            total["tracks"] += m["tracks_per_person"]
            total["found"].append(m["found"])
            total["touching"].append(m["found_touching"])
        print(f"{label:10} {'total':>6} {'':6} {total['crossings']:9d} {total['switches']:8d} "
              f"{sum(total['tracks']) / len(total['tracks']):13.2f} "
              f"{sum(total['found']) / len(total['found']):6.1%} "
              f"{sum(total['touching']) / len(total['touching']):8.1%}")
    return 0


def _per_person(tracks: list[int]) -> str:
    return " ".join(str(t) for t in tracks)


main = stops_in_one_line("evaluate_crossings", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
