"""scripts/render_video.py refuses bad input in one line and never loses a video it wrote:
absurd numbers and unusable outputs are refused by the parser (exit 2) before any BVH is read,
an unusable BVH fails in one line (exit 1), a sidecar may not overwrite an input, and a failed
or interrupted run (Ctrl-C: exit 130) leaves the previous video and its sidecar as they were."""
from __future__ import annotations

import re

import numpy as np
import pytest

from conftest import load_script, refused_in_one_line
from sequences.bvh import write_bvh
from sequences.skeleton import CMU_JOINT_NAMES
from sequences.video import load_truth
from tests.synthetic import cmu_motion


@pytest.fixture(scope="module")
def render_video():
    return load_script("render_video")


@pytest.fixture
def walk_bvh(tmp_path):
    """A short CMU-skeleton walk written as BVH (no shared data needed)."""
    T, J = 6, len(CMU_JOINT_NAMES)
    euler = np.zeros((T, J, 3))
    euler[:, CMU_JOINT_NAMES.index("LeftUpLeg"), 2] = 20 * np.sin(np.arange(T) / 2)
    root = np.column_stack([np.arange(T, dtype=float), np.full(T, 17.0), np.zeros(T)])
    path = tmp_path / "walk.bvh"
    write_bvh(path, cmu_motion(euler, root, fps=30.0, source="walk"))
    return path


def _tiny_bvh(joint: str) -> str:
    """A two-joint BVH: well formed, but not the CMU skeleton the body model needs."""
    return ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition "
            f"Zposition Zrotation Yrotation Xrotation\n  JOINT {joint}\n  {{\n    OFFSET 0 1 0\n"
            "    CHANNELS 3 Zrotation Yrotation Xrotation\n    End Site\n    {\n"
            "      OFFSET 0 1 0\n    }\n  }\n}\nMOTION\nFrames: 2\n"
            "Frame Time: 0.0333\n0 0 0 0 0 0 0 0 0\n0 0 0 1 0 0 0 0 0\n")


@pytest.mark.parametrize("option, value, says", [
    ("--fps", "0", "--fps must be"), ("--fps", "-1", "--fps must be"),
    ("--fps", "nan", "--fps must be"), ("--fps", "inf", "--fps must be"),
    ("--distance", "0", "--distance must be"), ("--distance", "-3", "--distance must be"),
    ("--distance", "nan", "--distance must be"), ("--elevation", "90", "--elevation must be"),
    ("--elevation", "nan", "--elevation must be"), ("--azimuth", "nan", "--azimuth must be"),
    ("--azimuth", "inf", "--azimuth must be"), ("--spacing", "nan", "--spacing must be"),
    ("--spacing", "inf", "--spacing must be"), ("--frames", "-1", "--frames must be"),
    ("--frames", "0", "--frames must be"), ("--seed", "-1", "--seed must be"),
    ("--noise", "nan", "--noise must be"), ("--spiral", "inf", "--spiral must be"),
    ("--size", "0x5", "--size must be"), ("--size", "99999x99999", "--size must be")])
def test_absurd_numbers_are_refused_before_reading_anything(render_video, tmp_path, capsys,
                                                            option, value, says):
    out = tmp_path / "v.mp4"
    err = refused_in_one_line(render_video, ["--bvh", str(tmp_path / "none.bvh"), "--out",
                                             str(out), option, value], capsys)
    assert says in err
    assert list(tmp_path.iterdir()) == []


def test_outputs_that_cannot_be_written_or_would_overwrite_an_input_are_refused(
        render_video, walk_bvh, tmp_path, capsys):
    def refused(*options):
        return refused_in_one_line(render_video, list(options), capsys)
    bvh = str(walk_bvh)
    assert "no such file" in refused("--bvh", str(tmp_path / "none.bvh"),
                                     "--out", str(tmp_path / "v.mp4"))
    # The sidecar of x.mp4 is x.truth.npz: it would have overwritten this input.
    named_like_sidecar = tmp_path / "x.truth.npz"
    named_like_sidecar.write_bytes(walk_bvh.read_bytes())
    before = named_like_sidecar.read_bytes()
    err = refused("--bvh", str(named_like_sidecar), "--out", str(tmp_path / "x.mp4"))
    assert "sidecar" in err and "same file" in err
    assert named_like_sidecar.read_bytes() == before
    assert not (tmp_path / "x.mp4").exists()
    assert "no folder" in refused("--bvh", bvh, "--out", str(tmp_path / "nodir" / "a.mp4"))
    assert not (tmp_path / "nodir").exists()
    assert "is a folder" in refused("--bvh", bvh, "--out", str(tmp_path))
    assert "give a video name" in refused("--bvh", bvh, "--out", str(tmp_path / "v.txt"))
    assert "give a video name" in refused("--bvh", bvh, "--out", "/dev/full")


@pytest.mark.parametrize("kind", ["foreign skeleton", "latin-1 joint", "frame time 1e300"])
def test_unusable_bvh_files_fail_in_one_line_naming_the_file(render_video, walk_bvh, tmp_path,
                                                             capsys, kind):
    bvh = tmp_path / "odd.bvh"
    if kind == "frame time 1e300":      # refused as read (it was numpy refusing the frame count)
        bvh.write_text(re.sub(r"Frame Time:.*", "Frame Time: 1e300", walk_bvh.read_text()))
        names, says = "odd.bvh line ", "frame time must be between"
    else:
        joint = "Spine" if kind == "foreign skeleton" else "Sp\xe9ne"
        bvh.write_bytes(_tiny_bvh(joint).encode("latin-1"))
        names, says = f"--bvh {bvh}", "lacks the CMU joints"
    walk_bvh.unlink()
    assert render_video.main(["--bvh", str(bvh), "--out", str(tmp_path / "v.mp4")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert names in err and says in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["odd.bvh"]


def _old_outputs(tmp_path):
    """A previous video and sidecar (stand-ins: their bytes are what must survive)."""
    video, sidecar = tmp_path / "v.mp4", tmp_path / "v.truth.npz"
    video.write_bytes(b"old video")
    sidecar.write_bytes(b"old ground truth")
    return video, sidecar


def test_ctrl_c_while_rendering_keeps_the_previous_video_and_sidecar(render_video, walk_bvh,
                                                                     tmp_path, capsys,
                                                                     monkeypatch):
    video, sidecar = _old_outputs(tmp_path)
    real = render_video.write_video

    def interrupted_at_frame_3(path, actors, **options):
        def progress(done, total):
            if done == 3:
                raise KeyboardInterrupt
        return real(path, actors, **{**options, "progress": progress})
    monkeypatch.setattr(render_video, "write_video", interrupted_at_frame_3)
    code = render_video.main(["--bvh", str(walk_bvh), "--out", str(video), "--size", "64x48"])
    assert code == 130
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and "interrupted" in err
    assert video.read_bytes() == b"old video" and sidecar.read_bytes() == b"old ground truth"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4", "v.truth.npz", "walk.bvh"]


def test_a_render_replaces_the_video_and_its_sidecar_together(render_video, walk_bvh,
                                                               tmp_path, capsys):
    video, sidecar = _old_outputs(tmp_path)
    assert render_video.main(["--bvh", str(walk_bvh), "--out", str(video), "--size", "64x48",
                              "--frames", "4"]) == 0
    assert load_truth(video)["pose"].shape == (4, 1, 55)
    assert video.stat().st_size > 100
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4", "v.truth.npz", "walk.bvh"]
