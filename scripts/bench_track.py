"""Benchmark `track` on one 640x480 single-person video: decode-only fps vs tracking fps.

    python scripts/bench_track.py                      # renders out/bench/walk640-turn60.mp4 once
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
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

from threadpoolctl import threadpool_limits

from regressor.pose_model import DEFAULT_MODEL_PATH, load_pose_model
from tracker import PoseTracker, TrackerSettings, track_video
from tracker.one_line_parser import OneLineParser
from tracker.sinks.json_summary import JsonSummarySink
from tracker.sinks.mcap import McapSink
from tracker.video import open_video

ROOT = Path(__file__).resolve().parents[1]


def _rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


#: Turning rate of the default video's spiral walk, deg/s (see the module docstring).
_TURN_DEG_PER_S = 60.0


def _make_video(path: Path, frames: int) -> None:
    from sequences.bvh import read_bvh
    from sequences.spiral import spiral_walk
    from sequences.video import Actor, write_video
    bvh = ROOT.parent / "shared" / "data" / "cmu" / "bvh" / "07_12.bvh"
    if not bvh.is_file():
        sys.exit(f"bench_track: {bvh} not found; pass --video")
    motion = spiral_walk(read_bvh(bvh), _TURN_DEG_PER_S, n_frames=frames)
    print(f"rendering {frames} frames of 640x480 video to {path} ...", file=sys.stderr)
    write_video(path, [Actor(motion)], size=(480, 640), noise_sigma=2.0)


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


def _track(video: Path, model_path: Path, workdir: Path, workers: int):
    """`track`'s loop (tracker.run.track_video) with MCAP and JSON outputs, in one process or
    with the frame worker (workers 2, `track`'s default on two cores); returns fps, stage
    ms, memory samples (the main process's), frames, the start-up seconds (open, sample,
    prime) and the frames with someone in view."""
    model = load_pose_model(model_path)
    start = time.perf_counter()
    source = open_video(video)
    opened = time.perf_counter() - start
    tracker = PoseTracker(model, source.fps, TrackerSettings(keep_history=False))
    sampler = _MemorySampler()
    result = track_video(source, tracker, [McapSink(workdir / "bench.mcap"),
                                           JsonSummarySink(workdir / "bench.json", source.fps)],
                         progress=sampler, workers=workers)
    elapsed = time.perf_counter() - start
    frames = result.frames
    stages = dict(tracker.stage_seconds)
    startup_s = opened + stages.pop("background")
    return (frames / elapsed, {k: 1000 * v / frames for k, v in stages.items()}, sampler.memory,
            frames, startup_s, sampler.with_people)


def main(argv=None) -> int:
    ap = OneLineParser(description=__doc__.splitlines()[0])
    ap.add_argument("--video", type=Path, default=None, help="640x480 single-person video")
    ap.add_argument("--frames", type=int, default=1200, help="frames to render if no --video")
    ap.add_argument("--model", type=Path, default=DEFAULT_MODEL_PATH)
    args = ap.parse_args(argv)
    if not 10 <= args.frames <= 100000:
        ap.error(f"--frames must be in 10..100000, got {args.frames}")
    if args.video is not None and not args.video.is_file():
        ap.error(f"--video {args.video}: no such file")
    if not args.model.is_file():
        ap.error(f"--model {args.model}: no such file")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    video = args.video
    if video is None:
        video = ROOT / "out" / "bench" / "walk640-turn60.mp4"
        if not video.is_file():
            video.parent.mkdir(parents=True, exist_ok=True)
            _make_video(video, args.frames)
    with threadpool_limits(1), tempfile.TemporaryDirectory() as tmp:
        decode_fps, n = _decode_fps(video)
        track_fps, stage_ms, memory, frames, startup_s, with_people = _track(video, args.model,
                                                                             Path(tmp), 1)
        two_fps, two_ms, two_memory, _, two_startup_s, _ = _track(video, args.model, Path(tmp), 2)
    print(f"video: {video} ({n} frames, someone in view in {with_people})")
    print(f"decode only : {decode_fps:8.1f} fps")
    print(f"track       : {track_fps:8.1f} fps   one process (ratio track/decode "
          f"{track_fps / decode_fps:.2f}; target >= 150 fps)")
    print(f"track       : {two_fps:8.1f} fps   with the frame worker, `track`'s default on two "
          f"cores ({two_fps / track_fps:.2f} x one process)")
    print(f"start-up    : {startup_s:8.2f} s     one process; {two_startup_s:.2f} s with the worker "
          f"(open, sample the background, prime; target <= 2 s on a 1080x1920 H.264 clip)")
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


if __name__ == "__main__":
    sys.exit(main())
