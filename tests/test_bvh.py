"""BVH reading, writing, resampling and malformed-input errors."""
from __future__ import annotations

import csv
import math
from dataclasses import replace

import numpy as np
import pytest

from sequences.bvh import BVHError, Motion, read_bvh, write_bvh
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS, CMU_REST_OFFSETS
from sequences.skeleton_tables import CMU_REST_END_SITES

# A two-joint skeleton; the line numbers in the comments are the file's (1-based).
TINY_HEAD = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
\tJOINT Chest
\t{
\t\tOFFSET 0 2 0
\t\tCHANNELS 3 Zrotation Yrotation Xrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 1 0
\t\t}
\t}
}
MOTION
Frames: 3
Frame Time: 0.0083333
"""
TINY_FRAMES = [  # lines 19, 20, 21
    "1.5 2.5 3.5 10.25 20.5 30.75 1.125 2.25 3.375",
    "1.6 2.6 3.6 11.25 21.5 31.75 2.125 3.25 4.375",
    "1.7 2.7 3.7 12.25 22.5 32.75 3.125 4.25 5.375",
]


def _tiny_text(frames=TINY_FRAMES, head=TINY_HEAD) -> str:
    return head + "\n".join(frames) + "\n"


def _write(tmp_path, text: str, name: str = "tiny.bvh"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _cmu_motion(T: int, seed: int, fps: float = 30.0) -> Motion:
    rng = np.random.default_rng(seed)
    channels = [["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]]
    channels += [["Zrotation", "Yrotation", "Xrotation"]] * (len(CMU_JOINT_NAMES) - 1)
    return Motion(names=list(CMU_JOINT_NAMES), parents=CMU_PARENTS.copy(),
                  offsets=CMU_REST_OFFSETS.copy(), end_sites=CMU_REST_END_SITES.copy(),
                  channels=[list(c) for c in channels],
                  euler_deg=rng.uniform(-170, 170, (T, len(CMU_JOINT_NAMES), 3)),
                  root_position=rng.uniform(-50, 50, (T, 3)), fps=fps, source="synthetic")


# ------------------------------------------------------------------ well-formed input


def test_tiny_file_values_land_in_root_position_and_joint_angles(tmp_path):
    motion = read_bvh(_write(tmp_path, _tiny_text()), fps=None, drop_tpose=False)
    assert motion.names == ["Hips", "Chest"]
    assert motion.parents.tolist() == [-1, 0]
    np.testing.assert_array_equal(motion.offsets, [[0, 0, 0], [0, 2, 0]])
    assert np.isnan(motion.end_sites[0]).all()
    np.testing.assert_array_equal(motion.end_sites[1], [0, 1, 0])
    assert motion.fps == 120.0 and motion.source == "tiny.bvh"
    np.testing.assert_array_equal(motion.root_position[2], [1.7, 2.7, 3.7])
    np.testing.assert_array_equal(motion.euler_deg[1, 1], [2.125, 3.25, 4.375])


def test_local_rotations_compose_z_then_y_then_x(tmp_path):
    motion = read_bvh(_write(tmp_path, _tiny_text()), fps=None, drop_tpose=False)
    z, y, x = np.radians(motion.euler_deg[0, 0])
    rz = np.array([[math.cos(z), -math.sin(z), 0], [math.sin(z), math.cos(z), 0], [0, 0, 1]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rx = np.array([[1, 0, 0], [0, math.cos(x), -math.sin(x)], [0, math.sin(x), math.cos(x)]])
    np.testing.assert_allclose(motion.local_rotations()[0, 0], rz @ ry @ rx, atol=1e-12)


def test_crlf_line_endings_read_the_same(tmp_path):
    plain = read_bvh(_write(tmp_path, _tiny_text()), fps=None, drop_tpose=False)
    crlf = read_bvh(_write(tmp_path, _tiny_text().replace("\n", "\r\n"), "crlf.bvh"),
                    fps=None, drop_tpose=False)
    np.testing.assert_array_equal(plain.euler_deg, crlf.euler_deg)
    np.testing.assert_array_equal(plain.root_position, crlf.root_position)


def test_auto_drops_an_added_tpose_frame_only(tmp_path):
    tpose = "1.5 2.5 3.5 0 0 0 -21 0 16"
    dropped = read_bvh(_write(tmp_path, _tiny_text([tpose] + TINY_FRAMES[1:])), fps=None)
    assert dropped.n_frames == 2
    np.testing.assert_array_equal(dropped.root_position[0], [1.6, 2.6, 3.6])
    kept = read_bvh(_write(tmp_path, _tiny_text(), "real.bvh"), fps=None)
    assert kept.n_frames == 3


def test_integer_rate_ratio_decimates_exactly(tmp_path):
    motion = _cmu_motion(13, seed=1, fps=120.0)
    write_bvh(tmp_path / "m.bvh", motion)
    at_30 = read_bvh(tmp_path / "m.bvh", fps=30.0, drop_tpose=False)
    assert at_30.fps == 30.0 and at_30.n_frames == 4
    np.testing.assert_allclose(at_30.euler_deg, motion.euler_deg[::4], atol=1e-6)
    np.testing.assert_allclose(at_30.root_position, motion.root_position[::4], atol=1e-6)


def test_non_integer_rate_ratio_slerps_between_frames(tmp_path):
    motion = _cmu_motion(25, seed=2, fps=120.0)
    motion.euler_deg[:] = np.linspace(0, 24, 25)[:, None, None]  # slow, monotonic turns
    write_bvh(tmp_path / "m.bvh", motion)
    at_50 = read_bvh(tmp_path / "m.bvh", fps=50.0, drop_tpose=False)
    assert at_50.n_frames == 11  # t = 0, 0.02, ..., 0.2 s (the last input frame)
    # 50 fps frame 5 (t = 0.1 s) is 120 fps frame 12 exactly.
    np.testing.assert_allclose(at_50.local_rotations()[5], motion.local_rotations()[12],
                               atol=1e-7)
    np.testing.assert_allclose(at_50.root_position[1],
                               motion.root_position[2] + 0.4 * (motion.root_position[3]
                                                                - motion.root_position[2]),
                               atol=1e-6)
    # A single-axis turn at constant rate interpolates to the in-between angle (frame 2.4).
    one_axis = _cmu_motion(25, seed=3, fps=120.0)
    one_axis.euler_deg[:] = 0.0
    one_axis.euler_deg[:, 5, 0] = np.linspace(0, 48, 25)
    write_bvh(tmp_path / "z.bvh", one_axis)
    z_50 = read_bvh(tmp_path / "z.bvh", fps=50.0, drop_tpose=False)
    np.testing.assert_allclose(z_50.euler_deg[1, 5], [4.8, 0, 0], atol=1e-6)


def test_write_then_read_is_exact_on_synthetic_motion(tmp_path):
    motion = _cmu_motion(7, seed=4)
    write_bvh(tmp_path / "m.bvh", motion)
    back = read_bvh(tmp_path / "m.bvh", fps=None, drop_tpose=False)
    assert back.names == motion.names and back.channels == motion.channels
    np.testing.assert_array_equal(back.parents, motion.parents)
    np.testing.assert_allclose(back.offsets, motion.offsets, atol=1e-6)
    np.testing.assert_allclose(back.end_sites, motion.end_sites, atol=1e-6)
    np.testing.assert_allclose(back.euler_deg, motion.euler_deg, atol=1e-6)
    np.testing.assert_allclose(back.root_position, motion.root_position, atol=1e-6)
    assert back.fps == pytest.approx(30.0)


# ------------------------------------------------------------------ malformed input


def _error(tmp_path, text: str) -> str:
    with pytest.raises(BVHError) as info:
        read_bvh(_write(tmp_path, text), fps=None, drop_tpose=False)
    return str(info.value)


def test_truncated_mid_line_names_the_short_line(tmp_path):
    text = _tiny_text()
    message = _error(tmp_path, text[: text.rindex("3.125") + 5])
    assert "tiny.bvh line 21" in message and "expected 9 values, got 7" in message


def test_truncated_at_a_line_end_names_the_missing_frames(tmp_path):
    message = _error(tmp_path, _tiny_text(TINY_FRAMES[:2]))
    assert "tiny.bvh line 20" in message and "truncated" in message


def test_wrong_value_count_names_the_line(tmp_path):
    frames = [TINY_FRAMES[0], TINY_FRAMES[1] + " 7.0", TINY_FRAMES[2]]
    message = _error(tmp_path, _tiny_text(frames))
    assert "tiny.bvh line 20" in message and "expected 9 values, got 10" in message


def test_non_numeric_value_names_the_line_and_value(tmp_path):
    frames = [TINY_FRAMES[0].replace("20.5", "abc")] + TINY_FRAMES[1:]
    message = _error(tmp_path, _tiny_text(frames))
    assert "tiny.bvh line 19" in message and "'abc'" in message


def test_nan_value_is_refused(tmp_path):
    frames = TINY_FRAMES[:2] + [TINY_FRAMES[2].replace("22.5", "nan")]
    assert "tiny.bvh line 21" in _error(tmp_path, _tiny_text(frames))


def test_missing_hierarchy_keyword(tmp_path):
    message = _error(tmp_path, _tiny_text().replace("HIERARCHY\n", "", 1))
    assert "tiny.bvh line 1" in message and "HIERARCHY" in message


def test_unclosed_joint_is_unbalanced_braces(tmp_path):
    lines = _tiny_text().splitlines(keepends=True)
    del lines[13]  # Chest's closing brace
    message = _error(tmp_path, "".join(lines))
    assert "tiny.bvh line 15" in message and "unbalanced braces" in message


def test_extra_closing_brace_is_unbalanced_braces(tmp_path):
    message = _error(tmp_path, _tiny_text().replace("}\nMOTION", "}\n}\nMOTION"))
    assert "tiny.bvh line 16" in message and "unbalanced braces" in message


def test_zero_frames_is_refused(tmp_path):
    message = _error(tmp_path, _tiny_text([]).replace("Frames: 3", "Frames: 0"))
    assert "tiny.bvh line 17" in message and "frames" in message


def test_bad_offset_names_the_line(tmp_path):
    message = _error(tmp_path, _tiny_text().replace("OFFSET 0 2 0", "OFFSET 0 x 0"))
    assert "tiny.bvh line 8" in message


# ------------------------------------------------------------------ the real CMU files


def _manifest_frames(cmu_bvh_dir) -> dict[str, int]:
    with open(cmu_bvh_dir.parent / "MANIFEST.tsv", newline="") as handle:
        return {row["file"].split("/")[-1]: int(row["frames"])
                for row in csv.DictReader(handle, delimiter="\t")}


def test_every_cmu_file_parses_to_the_cmu_skeleton_at_30_fps(cmu_bvh_dir):
    frames = _manifest_frames(cmu_bvh_dir)
    paths = sorted(cmu_bvh_dir.glob("*.bvh"))
    assert len(paths) == len(frames) == 99
    for path in paths:
        motion = read_bvh(path)
        has_tpose = path.stem not in ("16_11", "141_16")
        assert motion.n_frames == math.ceil((frames[path.name] - has_tpose) / 4), path.name
        assert tuple(motion.names) == CMU_JOINT_NAMES
        np.testing.assert_array_equal(motion.parents, CMU_PARENTS)
        assert motion.fps == 30.0 and np.isfinite(motion.euler_deg).all()


def test_cmu_rest_offsets_are_subject_02s(cmu_bvh_dir):
    motion = read_bvh(cmu_bvh_dir / "02_01.bvh")
    np.testing.assert_array_equal(motion.offsets, CMU_REST_OFFSETS)
    np.testing.assert_array_equal(motion.end_sites, CMU_REST_END_SITES)


def test_cmu_read_write_read_is_exact(cmu_bvh_dir, tmp_path):
    for name in ("02_01.bvh", "16_11.bvh"):
        first = read_bvh(cmu_bvh_dir / name, fps=None)
        write_bvh(tmp_path / name, first)
        second = read_bvh(tmp_path / name, fps=None, drop_tpose=False)
        assert second.n_frames == first.n_frames and second.fps == first.fps
        np.testing.assert_allclose(second.euler_deg, first.euler_deg, atol=1e-6, rtol=0)
        np.testing.assert_allclose(second.root_position, first.root_position, atol=1e-6, rtol=0)
        np.testing.assert_allclose(second.offsets, first.offsets, atol=1e-6, rtol=0)


@pytest.mark.parametrize("change, says", [
    (("\nMOTION\n", "\nMOTION extra\n"), "line 16: 'MOTION' must stand alone"),
    (("Frames: 3", "Frames: inf"), "need a positive whole number of frames"),
    (("Frames: 3", "Frames: nan"), "need a positive whole number of frames"),
    (("Frame Time: 0.0083333", "Frame Time: 1e-310"), "frame time must be between"),
    (("Frame Time: 0.0083333", "Frame Time: 100"), "frame time must be between"),
    (("JOINT Chest", "JOINT Hips"), "a second joint named 'Hips'"),
    (("1.6 2.6 3.6", "1.6 1e300 3.6"), "line 20: root position beyond"),
], ids=["motion-not-alone", "frames-inf", "frames-nan", "frame-time-subnormal",
        "frame-time-100", "duplicate-joint", "root-1e300"])
def test_damaged_headers_and_values_are_one_bvh_error(tmp_path, change, says):
    """Each had been a traceback (AttributeError, OverflowError, ValueError), a 12 GB
    resampling, or a file read with two joints of one name (the body model took the first,
    the pose vector the last)."""
    text = _tiny_text()
    assert change[0] in text
    message = _error(tmp_path, text.replace(change[0], change[1], 1))
    assert message.startswith("tiny.bvh") and says in message


def test_a_byte_order_mark_is_read_and_binary_junk_is_named_briefly(tmp_path):
    text = _tiny_text()
    path = tmp_path / "bom.bvh"
    path.write_bytes("\ufeff".encode() + text.encode())
    assert read_bvh(path, fps=None, drop_tpose=False).n_frames == 3
    message = _error(tmp_path, "\x00" * 20000)
    assert "expected HIERARCHY" in message and len(message) < 300     # was 80,000


def test_thousands_of_nested_joints_are_refused_not_a_recursion_error(tmp_path):
    depth = 3000
    joints = "".join(f"JOINT J{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Yrotation "
                     f"Xrotation\n" for i in range(depth))
    text = ("HIERARCHY\nROOT Hips\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition "
            "Zrotation Yrotation Xrotation\n" + joints + "}\n" * (depth + 1)
            + "MOTION\nFrames: 1\nFrame Time: 0.0333333\n" + " ".join(["0"] * (6 + 3 * depth))
            + "\n")
    assert "nested more than" in _error(tmp_path, text)


def test_an_offset_beyond_reason_and_a_resampling_too_long_are_refused(tmp_path):
    message = _error(tmp_path, _tiny_text().replace("OFFSET 0 2 0", "OFFSET 0 2e7 0"))
    assert message.startswith("tiny.bvh") and "OFFSET beyond" in message
    from sequences.bvh import MAX_RESAMPLED_FRAMES, resample
    motion = read_bvh(_write(tmp_path, _tiny_text()), fps=None, drop_tpose=False)
    long = replace(motion, fps=1.0 / 9.0)                # 3 frames 9 s apart: 18 s
    with pytest.raises(BVHError, match=f"at most {MAX_RESAMPLED_FRAMES:,}"):
        resample(long, 1e6)
