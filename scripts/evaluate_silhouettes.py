"""Silhouettes of a real video against a 3-D reference: Pose2Sim's balancing trial, per view.

Also for swings: --trial ../shared/data/pose2sim/swings.

    python scripts/evaluate_silhouettes.py [--trial ../shared/data/pose2sim/balancing]
        [--extractor before after colour] [--views cam01 ...] [--json OUT]
        [--silhouettes background segment auto]

Projects the reference keypoints into each view and prints, per extractor and view: coverage
(keypoints on the subject's mask dilated by 3 px), spill (mask area outside the keypoints' box
padded by 10 % of its height, over the box area; mean and 90th percentile), off-body (the
share of the mask off a generous body drawn from the keypoints: background inside the box),
tracks, tracks holding the subject, the fraction of frames the subject's main track
covers, and the fraction of frames in which the subject has a track of their own (a mask
holding at least half the keypoints, its spill at most 0.3 and at most 0.6 of it off the
body: not joined with a second person; silhouette_evaluation.own_track_frames). "before"
is the extractor and associator as they were (median background, shadows dropped, area gate
always on), "after" the extractor primed with frames of the clip, the
subtractor's foreground inside the unreliable zone sure person (``track --zone-foreground
sure``), "colour" the same with colour also deciding on that foreground
(tracker.video.zone.refine_in_zone, trust_zone_foreground=False; track's default since
2026-12-04). ``--silhouettes`` measures ``track --silhouettes``'s sources instead (background:
the "colour" extractor; segment and auto: tracker.video.segmenter, which needs the segment extra).
Measures:
lab.silhouette_evaluation.

A --trial folder that does not exist, or a --json that could not be written or is one of the
files read, is refused before any work (exit 2); bad data (a trial file that is not text, a NaN
in the calibration, a view's video missing or undecodable: lab.pose2sim_trial's
checks, also before any work) ends the run in one line naming the file (exit 1); Ctrl-C in one
line (exit 130). It prints each extractor and view as it starts it. --json is written whole or
not at all."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from regressor.errors import SilhouettePoseError
from sequences.pose2sim import DEFAULT_TRIAL, VIEWS, Pose2SimError
from lab.pose2sim_trial import checked_trial, missing_trial, trial_files
from lab.silhouette_evaluation import (ASSOCIATORS, EXTRACTORS, default_associator,
                                                   evaluate_pose2sim_view, format_table)
from tracker.pipeline import TrackerSettings
from tracker.video.sources import (INSTALL_HINT, SOURCES, segmenter_available,
                                   silhouette_extractor)
from tracker.video.segmenter import PersonSegmenter
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line
from tracker.outputs.files import OutputWriteError
from tracker.outputs.whole_files import write_whole


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trial", type=Path, default=DEFAULT_TRIAL, help="the balancing trial "
                    "folder (default: ../shared/data/pose2sim/balancing beside the repo)")
    ap.add_argument("--extractor", nargs="+", choices=sorted(EXTRACTORS),
                    default=["before", "after", "colour"], help="before: as before issue "
                    "11; after: track --zone-foreground sure; colour: track's default")
    ap.add_argument("--views", nargs="+", choices=VIEWS, default=list(VIEWS))
    ap.add_argument("--json", type=Path, metavar="OUT", help="write the measures as JSON")
    ap.add_argument("--silhouettes", nargs="+", choices=SOURCES, help="measure track "
                    "--silhouettes's sources instead of --extractor's (segment and auto need "
                    f"the segment extra: {INSTALL_HINT})")
    args = ap.parse_args(argv)
    extractors, associators = dict(EXTRACTORS), dict(ASSOCIATORS)
    if args.silhouettes:
        if "segment" in args.silhouettes and not segmenter_available():
            ap.error(f"--silhouettes segment needs the person segmenter: {INSTALL_HINT}")
        args.extractor = args.silhouettes
        extractors.update(background=EXTRACTORS["colour"], segment=_segmenter,
                          auto=_auto_extractor)
        associators.update(background=default_associator, segment=default_associator,
                           auto=default_associator)
    if missing_trial(args.trial):
        ap.error(missing_trial(args.trial))
    # Before minutes of work: writable, and none of the files read.
    ap.check_outputs([("--json", args.json)], trial_files(args.trial))
    quiet_decoder_logs()          # as track: one line, not FFmpeg's too
    results = {label: {} for label in args.extractor}
    try:
        trial = checked_trial(args.trial, args.views)
        runs = [(label, view) for label in args.extractor for view in args.views]
        for done, (label, view) in enumerate(runs, 1):      # a minute or so each
            print(f"[{done}/{len(runs)}] extractor {label}, view {view}", file=sys.stderr,
                  flush=True)
            results[label][view] = evaluate_pose2sim_view(trial, view, extractors[label],
                                                          make_associator=associators[label])
    except (Pose2SimError, SilhouettePoseError) as exc:
        print(f"evaluate_silhouettes: error: {exc}", file=sys.stderr)
        return 1
    print(format_table(results))
    if args.json:
        try:
            write_whole(args.json, lambda path: path.write_text(json.dumps(results, indent=1)))
        except OutputWriteError as exc:
            print(f"evaluate_silhouettes: error: {exc}", file=sys.stderr)
            return 1
    return 0


def _segmenter(frames) -> PersonSegmenter:
    """``track --silhouettes segment``'s extractor primed with the sampled frames."""
    extractor = PersonSegmenter()
    extractor.prime(frames)
    return extractor


def _auto_extractor(frames):
    """``track --silhouettes auto``'s extractor primed with the sampled frames."""
    extractor = silhouette_extractor("auto", TrackerSettings())
    extractor.prime(list(frames))
    return extractor


main = stops_in_one_line("evaluate_silhouettes", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
