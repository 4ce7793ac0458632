"""Video decoding: metadata, time ranges, grayscale, and one-line errors for bad files."""
from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from tracker.video.decode import FrameTimes, VideoError, _as_bgr, open_video
from tracker.video.stream_report import (VideoGrowingWarning, VideoTimingWarning,
                                         VideoTruncatedWarning)

#: The sample walk at 30 fps for 6 s, then 10 fps to 12 s (scripts/make_vfr_clip.py): 241 frames;
#: Matroska announces 30 fps and 361 frames (its duration at 30 fps).
VFR_CLIP = Path(__file__).parent / "data" / "vfr_walk.mkv"


def write_video(path: Path, frames: list[np.ndarray], fps: float = 25.0) -> Path:
    """Write frames (BGR (H,W,3) or gray (H,W) uint8) to ``path`` with the mp4v codec."""
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height),
                             isColor=frames[0].ndim == 3)
    assert writer.isOpened()
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


def noise_frames(count: int, width: int = 96, height: int = 64, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (height, width, 3), dtype=np.uint8) for _ in range(count)]


def flat_frames(count: int, width: int = 96, height: int = 64) -> list[np.ndarray]:
    """Frame i shows i in binary as 8 black/white vertical bands, so a decoded frame tells its
    own index despite compression."""
    bands = np.arange(width) * 8 // width
    frames = []
    for i in range(count):
        row = np.where((i >> bands) & 1, 255, 0).astype(np.uint8)
        frames.append(np.ascontiguousarray(np.broadcast_to(row[None, :, None], (height, width, 3))))
    return frames


def decoded_index(image: np.ndarray) -> int:
    width = image.shape[1]
    band_means = [image[:, b * width // 8 + width // 32:(b + 1) * width // 8 - width // 32].mean()
                  for b in range(8)]
    return sum(1 << b for b, m in enumerate(band_means) if m > 127)


def test_reads_every_frame_with_metadata(tmp_path):
    path = write_video(tmp_path / "clip.mp4", flat_frames(30), fps=25.0)
    source = open_video(path)
    assert (source.width, source.height, source.fps, source.frame_count) == (96, 64, 25.0, 30)
    frames = list(source)
    assert [f.index for f in frames] == list(range(30))
    assert frames[10].time_s == pytest.approx(10 / 25.0)
    assert all(f.image.shape == (64, 96, 3) and f.image.dtype == np.uint8 for f in frames)
    assert [decoded_index(f.image) for f in frames] == list(range(30))
    assert source.frames_read == 30 and not source.truncated


def test_frames_unpack_as_index_time_image(tmp_path):
    path = write_video(tmp_path / "clip.mp4", flat_frames(3))
    index, time_s, image = next(iter(open_video(path)))
    assert (index, time_s, image.shape) == (0, 0.0, (64, 96, 3))


def test_start_and_end_seconds_select_frames(tmp_path):
    path = write_video(tmp_path / "clip.mp4", flat_frames(40), fps=20.0)
    frames = list(open_video(path, start_s=0.5, end_s=1.0))
    assert [f.index for f in frames] == list(range(10, 20))
    assert [decoded_index(f.image) for f in frames] == list(range(10, 20))
    assert frames[0].time_s == pytest.approx(0.5)


def test_source_can_be_iterated_twice(tmp_path):
    source = open_video(write_video(tmp_path / "clip.mp4", flat_frames(5)))
    assert len(list(source)) == len(list(source)) == 5


def test_grayscale_video_gives_three_equal_channels(tmp_path):
    gray = [np.full((64, 96), 40 * i, np.uint8) for i in range(4)]
    frames = list(open_video(write_video(tmp_path / "gray.mp4", gray)))
    image = frames[2].image
    assert image.shape == (64, 96, 3)
    assert np.array_equal(image[..., 0], image[..., 1])
    assert np.array_equal(image[..., 1], image[..., 2])
    assert abs(float(image.mean()) - 80) < 4


def test_gray_and_bgra_arrays_become_bgr():
    gray = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert np.array_equal(_as_bgr(gray), np.repeat(gray[..., None], 3, axis=2))
    bgra = np.dstack([gray, gray + 1, gray + 2, np.zeros_like(gray)])
    assert np.array_equal(_as_bgr(bgra), bgra[..., :3])


def test_missing_file_is_refused(tmp_path):
    with pytest.raises(VideoError, match="nope.mp4: no such file"):
        open_video(tmp_path / "nope.mp4")


def test_text_file_named_mp4_is_refused(tmp_path):
    path = tmp_path / "notes.mp4"
    path.write_text("this is not a video\n" * 50)
    with pytest.raises(VideoError, match="notes.mp4: is not a video"):
        open_video(path)


def test_empty_file_is_refused(tmp_path):
    path = tmp_path / "empty.mp4"
    path.write_bytes(b"")
    with pytest.raises(VideoError, match="empty.mp4: is empty"):
        open_video(path)


def test_zero_frame_video_is_refused(tmp_path):
    path = tmp_path / "zero.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (96, 64))
    writer.release()
    with pytest.raises(VideoError, match="zero.mp4: contains no video frames"):
        open_video(path)


def test_mp4_with_its_tail_cut_off_is_refused(tmp_path):
    data = write_video(tmp_path / "full.mp4", noise_frames(20)).read_bytes()
    cut = tmp_path / "cut.mp4"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(VideoError, match="cut.mp4: is a truncated MP4"):
        open_video(cut)


def band_index(image: np.ndarray) -> int:
    """The index a flat_frames frame shows (its 8 vertical bands read as bits)."""
    bands = np.arange(image.shape[1]) * 8 // image.shape[1]
    row = image[image.shape[0] // 2, :, 1] > 127
    return sum(int(row[bands == b].mean() > 0.5) << b for b in range(8))


def damaged_video(folder: Path, at: float) -> Path:
    """folder/damaged.mp4: 60 flat_frames with every third of 300 bytes flipped from the
    fraction ``at`` of the file on (a glitch of a few frames)."""
    data = bytearray(write_video(folder / "full.mp4", flat_frames(60)).read_bytes())
    start = int(len(data) * at)
    for i in range(start, start + 300, 3):
        data[i] ^= 0xFF
    (folder / "damaged.mp4").write_bytes(bytes(data))
    return folder / "damaged.mp4"


def test_damaged_frames_mid_stream_are_skipped_and_the_rest_read(tmp_path):
    """A glitch inside a file used to end the stream there, the rest of the video lost."""
    source = open_video(damaged_video(tmp_path, 0.5))
    with pytest.warns(VideoTruncatedWarning, match=r"damaged.mp4: skipped \d+ undecodable"):
        frames = list(source)
    assert not source.truncated and source.frames_skipped > 0
    assert source.frames_read == len(frames) == 60 - source.frames_skipped
    indices = [f.index for f in frames]
    assert indices == sorted(set(indices)) and indices[0] == 0 and indices[-1] == 59
    # Each frame keeps its own index after the gap (the decoder's concealment may repeat the
    # last good picture in the frames just after it, hence only the tail is compared).
    assert [band_index(f.image) for f in frames[-10:]] == indices[-10:]


def test_a_cut_off_stream_stops_cleanly_with_a_warning(tmp_path):
    avi = tmp_path / "full.avi"
    writer = cv2.VideoWriter(str(avi), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (96, 64))
    for frame in noise_frames(40):
        writer.write(frame)
    writer.release()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(avi.read_bytes()[: avi.stat().st_size // 2])
    source = open_video(cut)
    with pytest.warns(VideoTruncatedWarning, match="cut.avi: decoding stopped at frame"):
        frames = list(source)
    assert 0 < len(frames) < 40
    assert source.truncated and source.frames_read == len(frames)
    assert [f.index for f in frames] == list(range(len(frames)))


def test_background_samples_pass_over_a_damaged_frame(tmp_path):
    samples = open_video(damaged_video(tmp_path, 0.25)).sample_frames(6)
    # Spread over the whole clip: before the fix, sampling stopped at the damage.
    assert len(samples) >= 5 and band_index(samples[-1]) == 59


def test_complete_video_gives_no_truncation_warning(tmp_path):
    source = open_video(write_video(tmp_path / "clip.mp4", noise_frames(10)))
    with warnings.catch_warnings():
        warnings.simplefilter("error", VideoTruncatedWarning)
        assert len(list(source)) == 10


def test_tiny_resolution_is_refused(tmp_path):
    path = write_video(tmp_path / "tiny.mp4", flat_frames(3, width=8, height=8))
    with pytest.raises(VideoError, match=r"tiny.mp4: resolution 8x8 is too small"):
        open_video(path)


def test_large_video_is_read(tmp_path):
    frames = flat_frames(2, width=4000, height=3000)
    path = write_video(tmp_path / "large.mp4", frames)
    full = open_video(path)
    assert (full.width, full.height) == (4000, 3000)
    (_, _, first), (_, _, second) = list(full)
    assert first.shape == (3000, 4000, 3) and decoded_index(second) == 1


@pytest.mark.parametrize("start_s, end_s", [(-1.0, None), (1.0, 0.5), (100.0, None)])
def test_bad_time_range_is_refused(tmp_path, start_s, end_s):
    path = write_video(tmp_path / "clip.mp4", flat_frames(10))
    with pytest.raises(VideoError, match="clip.mp4: .*start_s"):
        open_video(path, start_s=start_s, end_s=end_s)


def test_unusable_fps_override_is_refused(tmp_path):
    path = write_video(tmp_path / "clip.mp4", flat_frames(3))
    with pytest.raises(VideoError, match="clip.mp4: frame rate 0 frames/s is unusable"):
        open_video(path, fps=0.0)


def test_a_damaged_frame_rate_names_track_s_option(tmp_path):
    """It said "pass fps= to state it", an argument track does not have."""
    path = write_video(tmp_path / "clip.mp4", flat_frames(3), fps=2000.0)
    with pytest.raises(VideoError, match=r"clip.mp4: frame rate 2000 .*\(track --fps\)"):
        open_video(path)
    assert open_video(path, fps=30.0).fps == 30.0


def test_track_s_fps_bound_is_the_decoder_s():
    from tracker import cli
    from tracker.video import decode as video
    assert cli.MAX_FPS == video.MAX_FPS


def test_errors_are_one_line(tmp_path):
    path = tmp_path / "bad.mp4"
    path.write_text("x")
    with pytest.raises(VideoError) as info:
        open_video(path)
    assert "\n" not in str(info.value) and "bad.mp4" in str(info.value)


def test_sample_frames_are_evenly_spaced(tmp_path):
    source = open_video(write_video(tmp_path / "clip.mp4", flat_frames(40), fps=20.0),
                        start_s=0.5)
    samples = source.sample_frames(4)
    assert [decoded_index(image) for image in samples] == [10, 20, 29, 39]
    assert all(image.shape == (64, 96, 3) for image in samples)


class _FailingCapture:
    """A capture whose read() fails at the given read numbers (as FFmpeg's does on a damaged
    frame, consuming it), then ends after ``frames`` reads."""

    def __init__(self, frames: int, failing: set[int]):
        self.frames, self.failing, self.reads = frames, failing, 0

    def read(self):
        self.reads += 1
        if self.reads > self.frames or self.reads - 1 in self.failing:
            return False, None
        return True, np.full((64, 96, 3), self.reads - 1, np.uint8)

    def get(self, prop):
        """The last frame read's time, ms, at 25 fps (the only property read while reading)."""
        assert prop == cv2.CAP_PROP_POS_MSEC
        return (self.reads - 1) * 40.0

    def release(self):
        pass


@pytest.mark.parametrize("announced", [True, False])
def test_a_damaged_frame_is_skipped_whether_or_not_the_length_is_known(tmp_path, monkeypatch,
                                                                        announced):
    """With no frame count in the container, one failed read had ended the stream, silently."""
    import tracker.video.decode as video
    source = open_video(write_video(tmp_path / "clip.mp4", flat_frames(3)))
    source.end_index = 20 if announced else None
    monkeypatch.setattr(video, "_open_capture", lambda path: _FailingCapture(20, {5}))
    with pytest.warns(VideoTruncatedWarning, match=r"skipped 1 undecodable frame\(s\) from "
                                                   r"frame 5"):
        frames = list(source)
    assert [f.index for f in frames] == [i for i in range(20) if i != 5]
    assert [int(f.image[0, 0, 0]) for f in frames] == [f.index for f in frames]
    assert not source.truncated


def test_a_long_damaged_stretch_ends_the_stream_as_cut_off(tmp_path, monkeypatch):
    import tracker.video.decode as video
    source = open_video(write_video(tmp_path / "clip.mp4", flat_frames(3)))   # 25 fps
    source.end_index = 200
    monkeypatch.setattr(video, "_open_capture",
                        lambda path: _FailingCapture(200, set(range(10, 200))))
    with pytest.warns(VideoTruncatedWarning, match="decoding stopped at frame 10 of 200"):
        frames = list(source)
    assert len(frames) == 10 and source.truncated


def test_a_variable_frame_rate_keeps_each_frame_s_own_time():
    """Frames were stamped index / fps: frame 181 at 6.03 s instead of 6.1, the last at 8.0 s
    instead of 12.0; the stream's end, short of the 361 frames its duration makes at 30 fps,
    was taken for a cut-off file."""
    source = open_video(VFR_CLIP)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frames = list(source)
    assert [str(w.message) for w in caught] == [
        "vfr_walk.mkv: variable frame rate (frames 33 to 100 ms apart, 30 fps announced); "
        "each frame keeps its own time"]
    assert caught[0].category is VideoTimingWarning
    assert [f.index for f in frames] == list(range(241)) and not source.truncated
    times = np.array([f.time_s for f in frames])
    np.testing.assert_allclose(times[:180], np.arange(180) / 30.0, atol=1e-3)  # ms in MKV
    np.testing.assert_allclose(times[180:], 6.0 + np.arange(61) / 10.0, atol=1e-9)


def test_a_variable_frame_rate_s_time_range_is_by_time():
    """--start and --end counted frames at the announced 30 fps: 7.0 s was frame 210, 8.9 s."""
    source = open_video(VFR_CLIP, start_s=5.5, end_s=7.0)
    with pytest.warns(VideoTimingWarning):
        times = [f.time_s for f in source]
    assert times[0] == pytest.approx(5.5, abs=1e-3) and times[-1] == pytest.approx(6.9)
    assert len(times) == 15 + 10      # 5.5-5.97 s at 30 fps, 6.0-6.9 s at 10 fps


@pytest.mark.parametrize("start_s, end_s, first, count", [
    (7.0, 8.0, 7.0, 10),       # a seek by frame number at 30 fps landed at 9.0 s
    (7.0, None, 7.0, 51),
    (10.0, 11.5, 10.0, 15),    # frame 300 at 30 fps is past the clip's 241 frames
    (11.9, None, 11.9, 2),
])
def test_a_variable_frame_rate_s_start_after_the_rate_changes_is_found_by_time(
        start_s, end_s, first, count):
    source = open_video(VFR_CLIP, start_s=start_s, end_s=end_s)
    with pytest.warns(VideoTimingWarning):
        times = [f.time_s for f in source]
    assert len(times) == count and times[0] == pytest.approx(first)
    np.testing.assert_allclose(np.diff(times), 0.1, atol=1e-9)


def test_background_samples_of_a_variable_rate_s_late_range_are_found_by_time():
    """10-11.5 s of the clip: frame 300 at the announced 30 fps is past its 241 frames, so
    sampling by frame number found nothing ('no decodable frames from 10 s on')."""
    source = open_video(VFR_CLIP, start_s=10.0, end_s=11.5)
    samples = source.sample_frames(5)
    assert len(samples) == 5 and samples[0].shape == (source.height, source.width, 3)


def test_a_seek_into_a_container_without_times_keeps_the_frames_own_times():
    """After a seek, a raw stream reports 0 ms for the frame it landed on: that is no time
    (it had been taken as one, stamping frames 24-36 with 0.48-0.96 s)."""
    times = FrameTimes(25.0)
    assert times(12, 0.0) == pytest.approx(0.48) and times.problem == "gives no frame times"
    assert times(13, 0.0) == pytest.approx(0.52)


def test_a_stated_frame_rate_spaces_the_frames_evenly(tmp_path):
    source = open_video(write_video(tmp_path / "clip.mp4", flat_frames(10), fps=25.0), fps=50.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert [f.time_s for f in source] == pytest.approx(np.arange(10) / 50.0)


class _TimelessCapture(_FailingCapture):
    """A capture whose container gives every frame the time 0 (no times)."""

    def get(self, prop):
        return 0.0


def test_a_container_without_frame_times_gets_even_ones_and_says_so(tmp_path, monkeypatch):
    import tracker.video.decode as video
    source = open_video(write_video(tmp_path / "clip.mp4", flat_frames(3)))     # 25 fps
    source.end_index = 12
    monkeypatch.setattr(video, "_open_capture", lambda path: _TimelessCapture(12, set()))
    with pytest.warns(VideoTimingWarning, match=r"clip.mp4: the container gives frame 1 a time "
                                                r"not after frame 0's; frames from there on "
                                                r"are taken as evenly spaced at 25 fps"):
        times = [f.time_s for f in source]
    assert times == pytest.approx(np.arange(12) / 25.0)


class _GrowingCapture:
    """A capture of a file that a recorder is still writing: ``rest`` (bytes) is appended to
    the file after read number ``after`` or, with ``after`` None, at the first failed read
    (the reader has caught up with the writer), before that read returns."""

    def __init__(self, path: Path, rest: bytes, after: int | None = None):
        self.capture, self.path = cv2.VideoCapture(str(path)), path
        self.rest, self.after, self.reads = rest, after, 0

    def read(self):
        ok, image = self.capture.read()
        self.reads += 1
        if self.rest and (self.reads == self.after or (self.after is None and not ok)):
            with self.path.open("ab") as file:
                file.write(self.rest)
            self.rest = b""
        return ok, image

    def get(self, prop):
        return self.capture.get(prop)

    def release(self):
        self.capture.release()


def test_a_file_still_being_written_stops_at_its_live_end(tmp_path, monkeypatch):
    """The last frame before the end of what was written came out half decoded (the tail of a
    half-written frame), the stream was reported cut off and nothing said it was growing."""
    import tracker.video.decode as video
    with pytest.warns(VideoTimingWarning):
        whole = {f.index: f.image for f in open_video(VFR_CLIP) if f.index < 150}
    data = VFR_CLIP.read_bytes()
    path = tmp_path / "recording.mkv"
    path.write_bytes(data[:len(data) // 2])
    source = open_video(path)
    monkeypatch.setattr(video, "_open_capture",
                        lambda p: _GrowingCapture(p, data[len(data) // 2:]))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frames = list(source)
    assert [w.category for w in caught] == [VideoGrowingWarning]
    assert str(caught[0].message) == (f"{path} is still being written (grew from 42 KB to 84 KB "
                                      f"while read); tracked the first 4.0 s")
    assert source.grew and not source.truncated
    assert [f.index for f in frames] == list(range(119))
    for frame in frames:        # every frame whole: none decoded from a half-written tail
        np.testing.assert_array_equal(frame.image, whole[frame.index])


def test_a_file_that_grows_while_read_is_said_to(tmp_path, monkeypatch):
    """An MPEG-TS still being written stopped where its length when opened said, silently."""
    import tracker.video.decode as video
    path = write_video(tmp_path / "clip.mp4", flat_frames(20))
    source = open_video(path)
    monkeypatch.setattr(video, "_open_capture", lambda p: _GrowingCapture(p, b"\0" * 200_000,
                                                                          after=5))
    with pytest.warns(VideoGrowingWarning, match=r"clip.mp4 is still being written \(grew from "
                                                 r"\d+ KB to 0.2 MB while read\); tracked the "
                                                 r"first 0.8 s"):
        frames = list(source)
    assert len(frames) == 20 and source.grew


def without_duration(data: bytes) -> bytes:
    """A Matroska file's bytes with its Duration element (ID 0x4489) made a Void one of the same
    length: the file states no length, as one still being written does not."""
    at = data.index(b"\x44\x89")
    length = 3 + (data[at + 2] & 0x7F)               # ID, one-byte size, the float
    return data[:at] + bytes([0xEC, 0x80 | (length - 2)]) + bytes(length - 2) + data[at + length:]


def test_background_samples_of_a_stream_of_unknown_length_span_it(tmp_path):
    """They were its first 25 frames: a Matroska file still being written states no length,
    and the person standing there in its first second became a phantom second track."""
    path = tmp_path / "recording.mkv"
    path.write_bytes(without_duration(VFR_CLIP.read_bytes()))
    source = open_video(path)
    assert source.frame_count is None and source.end_index is None
    with pytest.warns(VideoTimingWarning):
        frames = [f.image for f in open_video(VFR_CLIP)]
    samples = source.sample_frames(7)
    shown = [next(i for i, frame in enumerate(frames) if np.array_equal(frame, sample))
             for sample in samples]
    assert len(shown) == 7 and shown[0] == 0 and shown[-1] >= 200      # of 241 frames
    assert np.all(np.diff(shown) >= 20)


class _RemovingCapture(_GrowingCapture):
    """A capture whose file is removed after its third read (it reads on: the file is open)."""

    def read(self):
        ok, image = self.capture.read()
        self.reads += 1
        if self.reads == 3:
            self.path.unlink()
        return ok, image


def test_a_file_removed_while_read_is_said_to(tmp_path, monkeypatch):
    import tracker.video.decode as video
    path = write_video(tmp_path / "clip.mp4", flat_frames(10))
    source = open_video(path)
    monkeypatch.setattr(video, "_open_capture", lambda p: _RemovingCapture(p, b""))
    with pytest.warns(VideoGrowingWarning, match=r"clip.mp4 was removed or replaced while "
                                                 r"read; tracked the first 0.4 s"):
        assert len(list(source)) == 10
