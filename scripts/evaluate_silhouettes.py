"""Silhouettes of a real video against a 3-D reference: Pose2Sim's balancing trial, per view.

    python scripts/evaluate_silhouettes.py [--trial ../shared/data/pose2sim/balancing]
        [--extractor before after colour] [--views cam01 ...] [--json OUT]

Projects the reference keypoints into each view and prints, per extractor and view: coverage
(keypoints on the subject's mask dilated by 3 px), spill (mask area outside the keypoints' box
padded by 10 % of its height, over the box area; mean and 90th percentile), off-body (the
share of the mask off a generous body drawn from the keypoints: background inside the box),
tracks, tracks holding the subject, and the fraction of frames the subject's main track
covers. "before" is the extractor and associator as they were (median background, shadows
dropped, area gate always on), "after" the extractor primed with frames of the clip, the
subtractor's foreground inside the unreliable zone sure person (``track --zone-foreground
sure``), "colour" the same with colour also deciding on that foreground
(tracker.silhouettes.refine_in_zone, trust_zone_foreground=False; track's default since
2026-12-04). Measures:
tracker.offline.silhouette_evaluation.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from sequences.pose2sim import DEFAULT_TRIAL, VIEWS, Pose2SimError, load_trial
from tracker.offline.silhouette_evaluation import (ASSOCIATORS, EXTRACTORS, evaluate_pose2sim_view,
                                                   format_table)
from tracker.one_line_parser import OneLineParser


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trial", type=Path, default=DEFAULT_TRIAL, help="the balancing trial")
    ap.add_argument("--extractor", nargs="+", choices=sorted(EXTRACTORS),
                    default=["before", "after", "colour"], help="before: as before issue "
                    "11; after: track --zone-foreground sure; colour: track's default")
    ap.add_argument("--views", nargs="+", choices=VIEWS, default=list(VIEWS))
    ap.add_argument("--json", type=Path, metavar="OUT", help="write the measures as JSON")
    args = ap.parse_args(argv)
    try:
        trial = load_trial(args.trial)
        results = {label: {view: evaluate_pose2sim_view(trial, view, EXTRACTORS[label],
                                                        make_associator=ASSOCIATORS[label])
                           for view in args.views} for label in args.extractor}
    except Pose2SimError as exc:
        print(f"evaluate_silhouettes: error: {exc}", file=sys.stderr)
        return 1
    print(format_table(results))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
