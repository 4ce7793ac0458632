"""Benchmark `track` on one 640x480 single-person video: decode-only fps vs tracking fps.

    python scripts/bench_track.py                      # renders out/bench/walk640-turn60.mp4 once
    python scripts/bench_track.py --frames 300         # out/bench/walk640-turn60-300f.mp4 once
    python scripts/bench_track.py --video my.mp4
    python scripts/bench_track.py --video ../shared/data/pose2sim/balancing/videos/cam01.mp4

Prints, from one run on the same video: decode-only fps, `track` fps end to end (decode,
silhouettes, descriptors, regression, filter, MCAP + JSON outputs; no --view) in one process
and with the frame worker (tracker/frame_worker.py: a second process finds and describes the
people; `track`'s default where there are two cores), their ratios,
the start-up cost (opening the video, sampling its background, priming; target <= 2 s on a
100-frame 1080x1920 H.264 Pose2Sim view), the per-frame cost of each stage, and resident memory
sampled along the video (flat = no leak; histories are kept only for smoothing, as `track`
does without --smooth). BLAS limited to one thread per process, as the `track` command does:
one core in one process, two with the worker.

The fps only means something for frames with a person: a frame where nobody is found skips
descriptors, regression and filtering and costs a quarter as much. So the default video keeps
the walker big enough to be found in (nearly) every frame (a walk turning at 60 deg/s: all
1200 frames; 1196 with the former minimum area), and the report says how many frames had a
pose. Until 2026-12-03 the default was a walk turning at 30 deg/s whose wider path took the
walker below the silhouettes' minimum area of the time (SilhouetteExtractor min_area_fraction
0.003, ~70 px tall at 640x480; 0.0015 since) in 54 % of the frames: its fps (83-200 over the
sessions) counted those cheap empty frames.

A video or model that cannot be used is refused in one line before any work (exit 2); bad data
found later (a video that stops decoding) ends the run in one line (exit 1), Ctrl-C too (exit
130). The default video is rendered under a temporary name and renamed once complete, so an
interrupted render leaves nothing that the next run would take for the video.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

from regressor.errors import SilhouettePoseError
from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from tracker import PoseTracker, TrackerSettings, track_video
from tracker.video.sources import (INSTALL_HINT, SOURCES, segmenter_available,
                                   silhouette_extractor)
from tracker.one_line_parser import OneLineParser, quiet_decoder_logs, stops_in_one_line
from tracker.outputs.json_summary import JsonSummarySink
from tracker.outputs.mcap import McapSink
from tracker.video.decode import open_video

#: What a bad video, model or motion capture raises: the project's errors, and what numpy and
#: the standard library raise on a file that is not what it says.
BAD_DATA = (SilhouettePoseError, ValueError, UnicodeDecodeError, MemoryError, OSError)

ROOT = Path(__file__).resolve().parents[1]


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


#: Turning rate of the default video's spiral walk, deg/s (see the module docstring).
_TURN_DEG_PER_S = 60.0
DEFAULT_FRAMES = 1200


def default_video(frames: int) -> Path:
    """Where the default video of that many frames is rendered once and reused: the frame
    count is in the name (but for the default count's, kept from before), so that --frames
    takes effect whatever was rendered before."""
    suffix = "" if frames == DEFAULT_FRAMES else f"-{frames}f"
    return ROOT / "out" / "bench" / f"walk640-turn60{suffix}.mp4"


def _make_video(path: Path, frames: int) -> None:
    from sequences.bvh import read_bvh
    from sequences.spiral import spiral_walk
    from sequences.video import Actor, replace_video, write_video
    bvh = ROOT.parent / "shared" / "data" / "cmu" / "bvh" / "07_12.bvh"
    if not bvh.is_file():
        sys.exit(f"bench_track: {bvh} not found; pass --video")
    motion = spiral_walk(read_bvh(bvh), _TURN_DEG_PER_S, n_frames=frames)
    print(f"rendering {frames} frames of 640x480 video to {path} ...", file=sys.stderr)
    # Whole or not at all: an interrupted render leaves no half-written video to be
    # benchmarked next time.
    replace_video(path, lambda partial: write_video(partial, [Actor(motion)], size=(480, 640),
                                                    noise_sigma=2.0))


def _decode_fps(video: Path) -> tuple[float, int]:
    source = open_video(video)
    start = time.perf_counter()
    n = sum(1 for _ in source)
    return n / (time.perf_counter() - start), n


class _MemorySampler:
    """A progress object for track_video: resident memory every 200 frames, and how many
    frames had someone in view."""

    def __init__(self):
        self.frames, self.memory, self.with_people = 0, [], 0

    def update(self, people_in_view: int) -> None:
        self.frames += 1
        self.with_people += people_in_view > 0
        if self.frames % 200 == 0:
            self.memory.append((self.frames, _rss_mb()))

    def close(self) -> None:
        pass


def _track(video: Path, model_path: Path, workdir: Path, workers: int,
           silhouettes: str = "background"):
    """`track`'s loop (tracker.run.track_video) with MCAP and JSON outputs, in one process or
    with the frame worker (workers 2, `track`'s default on two cores); returns fps, stage
    ms, memory samples (the main process's), frames, the start-up seconds (open, sample,
    prime) and the frames with someone in view. silhouettes: track --silhouettes."""
    model = load_pose_model(model_path)
    start = time.perf_counter()
    source = open_video(video)
    opened = time.perf_counter() - start
    settings = TrackerSettings(keep_history=False)
    tracker = PoseTracker(model, source.fps, settings,
                          extractor=silhouette_extractor(silhouettes, settings))
    sampler = _MemorySampler()
    result = track_video(source, tracker, [McapSink(workdir / "bench.mcap"),
                                           JsonSummarySink(workdir / "bench.json", source.fps)],
                         progress=sampler, workers=workers).stop_if_interrupted()
    elapsed = time.perf_counter() - start
    frames = result.frames
    stages = dict(tracker.stage_seconds)
    startup_s = opened + stages.pop("background")
    return (frames / elapsed, {k: 1000 * v / frames for k, v in stages.items()}, sampler.memory,
            frames, startup_s, sampler.with_people)


def _main(argv) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--video", type=Path, default=None, help="640x480 single-person video")
    ap.add_argument("--frames", type=int,
                    help=f"frames of the default video, 10..100000 (default {DEFAULT_FRAMES}; "
                         "each count rendered once, then reused); not with --video")
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH)
    ap.add_argument("--silhouettes", choices=SOURCES, default="background",
                    help="track --silhouettes (default background: the benchmark as before; "
                         f"segment and auto need {INSTALL_HINT})")
    args = ap.parse_args(argv)
    if args.silhouettes == "segment" and not segmenter_available():
        ap.error(f"--silhouettes segment needs the person segmenter: {INSTALL_HINT}")
    if args.frames is not None and not 10 <= args.frames <= 100000:
        ap.error(f"--frames must be in 10..100000, got {args.frames}")
    if args.video is not None and args.frames is not None:
        ap.error("--frames sets the length of the default video; --video is benchmarked whole")
    if args.video is not None and not args.video.is_file():
        ap.error(f"--video {args.video}: no such file")
    if not args.model.is_file():
        ap.error(f"--model {args.model}: no such file")
    quiet_decoder_logs()          # as track: one line, not FFmpeg's too
    try:                # both open in a fraction of a second: refused before the long work
        load_pose_model(args.model)
    except BAD_DATA as exc:
        ap.error(f"--model {args.model}: {_one_line(exc, args.model)}")
    if args.video is not None:
        try:
            open_video(args.video)
        except BAD_DATA as exc:
            ap.error(f"--video {args.video}: {_one_line(exc, args.video)}")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    video = args.video
    try:
        if video is None:
            frames = args.frames or DEFAULT_FRAMES
            video = default_video(frames)
            if not video.is_file():
                video.parent.mkdir(parents=True, exist_ok=True)
                _make_video(video, frames)
        with threadpool_limits(1), tempfile.TemporaryDirectory() as tmp:
            decode_fps, n = _decode_fps(video)
            # The frame worker first: a process that has run MediaPipe forks none
            # (tracker.video.segmenter.made_a_graph), so one process after it would measure nothing.
            two_fps, two_ms, two_memory, _, two_startup_s, _ = _track(
                video, args.model, Path(tmp), 2, args.silhouettes)
            track_fps, stage_ms, memory, frames, startup_s, with_people = _track(
                video, args.model, Path(tmp), 1, args.silhouettes)
    except BAD_DATA as exc:
        print(f"bench_track: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    if not frames or not n:
        print(f"bench_track: error: {video}: no frames could be decoded", file=sys.stderr)
        return 1
    print(f"video: {video} ({n} frames, someone in view in {with_people})")
    print(f"decode only : {decode_fps:8.1f} fps")
    print(f"track       : {track_fps:8.1f} fps   one process (ratio track/decode "
          f"{track_fps / decode_fps:.2f}; target >= 150 fps)")
    print(f"track       : {two_fps:8.1f} fps   with the frame worker, `track`'s default on two "
          f"cores ({two_fps / track_fps:.2f} x one process)")
    print(f"start-up    : {startup_s:8.2f} s     one process; {two_startup_s:.2f} s with the "
          f"worker (open, sample the background, prime; target <= 2 s on a 1080x1920 H.264 "
          f"clip)")
    if with_people < 0.9 * frames:
        print(f"warning: nobody in view in {frames - with_people} of {frames} frames; those skip "
              f"most stages, so the fps overstates the cost of tracking a person")
    print("per-frame cost of each stage (ms), one process / with the worker (its first four "
          "in the worker, the rest in the main process):")
    for stage, ms in sorted(stage_ms.items(), key=lambda kv: -kv[1]):
        print(f"  {stage:12s} {ms:7.3f}  {two_ms.get(stage, 0.0):7.3f}")
    print(f"  {'waiting':12s} {'':7s}  {two_ms.get('waiting', 0.0):7.3f}  (the main process "
          f"for the worker)")
    print("resident memory (MB) by frames done: " +
          ", ".join(f"{f}: {m:.0f}" for f, m in memory))
    if len(memory) >= 2:
        print(f"memory growth from frame {memory[0][0]} to {memory[-1][0]}: "
              f"{memory[-1][1] - memory[0][1]:+.1f} MB (one process), "
              f"{two_memory[-1][1] - two_memory[0][1]:+.1f} MB (the main process with the "
              f"worker)")
    return 0


def _one_line(exc: BaseException, path: Path | None = None) -> str:
    """An exception as one line (its type's name if it has no message: MemoryError), without
    a leading "PATH: " when the caller names path itself."""
    text = str(exc).strip()
    line = text.splitlines()[0] if text else type(exc).__name__
    return line.removeprefix(f"{path}: ") if path is not None else line


main = stops_in_one_line("bench_track", _main)       # Ctrl-C: one line, no traceback


if __name__ == "__main__":
    sys.exit(main())
