"""scripts/bench_track.py refuses in one line (exit 2), before any work, a --video it cannot
decode (garbage, empty, cut short, too small) and a --model that does not load (garbage, cut
short, a NaN written over its numbers); a tracking run cut short by Ctrl-C stops the benchmark in
one line (exit 130); the default video is renamed into place only once rendered."""
from __future__ import annotations

import io
import zipfile

import cv2
import numpy as np
import pytest

from conftest import cut_run, load_script, refused_in_one_line
from regressor.pose_model import DEFAULT_MODEL_PATH

SAMPLE = DEFAULT_MODEL_PATH.parents[2] / "sequences" / "data" / "sample_spiral_walk.mp4"


@pytest.fixture(scope="module")
def bench_track():
    return load_script("bench_track")


def _video(path, size: tuple[int, int], frames: int = 5) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, size)
    for _ in range(frames):
        writer.write(np.full((size[1], size[0], 3), 100, np.uint8))
    writer.release()


def test_videos_that_cannot_be_decoded_are_refused_in_one_line(bench_track, tmp_path, capsys):
    videos = {"garbage.mp4": bytes(range(256)) * 20, "empty.mp4": b"",
              "cut.mp4": SAMPLE.read_bytes()[:100_000]}
    for name, data in videos.items():
        (tmp_path / name).write_bytes(data)
    _video(tmp_path / "tiny.mp4", (8, 8))
    for name, says in (("garbage.mp4", "not a video"), ("empty.mp4", "is empty"),
                       ("cut.mp4", "truncated"), ("tiny.mp4", "too small")):
        err = refused_in_one_line(bench_track, ["--video", str(tmp_path / name)], capsys)
        assert f"error: --video {tmp_path / name}: " in err
        assert says in err


def _nan_model(path) -> None:
    """The default model with a NaN written over its first codebook number, as a file edited
    by hand (its checksum then no longer matches)."""
    with np.load(DEFAULT_MODEL_PATH, allow_pickle=False) as z:
        parts = {k: z[k] for k in z.files}
    parts["codebook_centres"] = parts["codebook_centres"].copy()
    parts["codebook_centres"].flat[0] = np.nan
    np.savez(path, **parts)


def test_models_that_do_not_load_are_refused_in_one_line(bench_track, tmp_path, capsys):
    video = tmp_path / "still.mp4"
    _video(video, (320, 240))
    (tmp_path / "garbage.npz").write_bytes(bytes(range(256)) * 20)
    (tmp_path / "cut.npz").write_bytes(DEFAULT_MODEL_PATH.read_bytes()[:3000])
    _nan_model(tmp_path / "nan.npz")
    buffer = io.BytesIO()                              # a zip, but not an .npz of a model
    with zipfile.ZipFile(buffer, "w") as archive:
        archive.writestr("notes.txt", "hello")
    (tmp_path / "zip.npz").write_bytes(buffer.getvalue())
    for name in ("garbage.npz", "cut.npz", "nan.npz", "zip.npz"):
        model = tmp_path / name
        err = refused_in_one_line(bench_track, ["--video", str(video), "--model", str(model)],
                                  capsys)
        assert f"error: --model {model}: " in err


def test_ctrl_c_ends_the_benchmark_in_one_line(bench_track, tmp_path, capsys, monkeypatch):
    video = tmp_path / "still.mp4"
    _video(video, (320, 240))
    monkeypatch.setattr(bench_track, "track_video",       # tracking stopped early by Ctrl-C
                        lambda *args, **kwargs: cut_run())
    assert bench_track.main(["--video", str(video)]) == 130
    assert capsys.readouterr().err == "bench_track: interrupted\n"


def test_the_default_video_is_renamed_into_place_only_once_rendered(bench_track, tmp_path,
                                                                    monkeypatch):
    if not (bench_track.ROOT.parent / "shared/data/cmu/bvh/07_12.bvh").is_file():
        pytest.skip("CMU motion capture not found (needs ../shared beside the repo)")
    import sequences.video as video_module

    def interrupted_render(path, *args, **kwargs):
        path.write_bytes(b"half a video")
        raise KeyboardInterrupt
    monkeypatch.setattr(video_module, "write_video", interrupted_render)
    with pytest.raises(KeyboardInterrupt):
        bench_track._make_video(tmp_path / "walk.mp4", 20)
    assert list(tmp_path.iterdir()) == []

    def render(path, *args, **kwargs):
        path.write_bytes(b"a video")
        truth = video_module.truth_path(path)
        truth.write_bytes(b"its truth")
        return truth
    monkeypatch.setattr(video_module, "write_video", render)
    bench_track._make_video(tmp_path / "walk.mp4", 20)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.mp4", "walk.truth.npz"]
