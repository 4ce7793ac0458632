"""The cmu_extra converters: expmap sequences (sequences.expmap) and dance BVH retargeted to the
CMU skeleton (sequences.retarget): bone directions, left/right, frame rate, round trips."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from regressor.angles import wrap_deg
from sequences.bvh import Motion, read_bvh, write_bvh
from sequences.cmu_extra import DUPLICATES, FOOT_HEIGHT_M, settle_on_floor
from sequences.dataset import HELD_OUT_TRIALS
from sequences.expmap import (EXPMAP_JOINTS, EXPMAP_OFFSETS, EXPMAP_PARENTS, ExpmapError,
                              expmap_to_motion, motion_to_expmap, read_expmap,
                              read_expmap_motion)
from sequences.bvh_write import pose_vectors_to_motion
from sequences.pose_conversions import motion_to_pose_vectors
from sequences.pose_vector import forward_kinematics
from sequences.retarget import read_dance, retarget, source_from_cmu
from sequences.skeleton import CMU_JOINT_NAMES, CMU_UNIT_M

from conftest import SHARED

CMU_EXTRA = SHARED / "data" / "cmu_extra"


def _rodrigues(r: np.ndarray) -> np.ndarray:
    """The source's expmap2rotmat (data_utils_cmu.py), written out for one vector."""
    theta = np.linalg.norm(r)
    r0 = r / max(theta, np.finfo(np.float32).eps)
    k = np.array([[0, -r0[2], r0[1]], [0, 0, -r0[0]], [0, 0, 0]])
    k = k - k.T
    return np.eye(3) + np.sin(theta) * k + (1 - np.cos(theta)) * k @ k


def _source_fk(frame: np.ndarray) -> np.ndarray:
    """(38, 3) positions by the source's fkl (row vectors), offsets in CMU units: an
    independent reference for the converter's convention."""
    xyz, rot = np.zeros((38, 3)), [None] * 38
    for i in range(38):
        R = _rodrigues(frame[3 + 3 * i: 6 + 3 * i])
        p = EXPMAP_PARENTS[i]
        if p < 0:
            xyz[i], rot[i] = EXPMAP_OFFSETS[i] + frame[:3], R
        else:
            xyz[i] = EXPMAP_OFFSETS[i] @ rot[p] + xyz[p]
            rot[i] = R @ rot[p]
    return xyz


def _cmu_positions(motion: Motion) -> np.ndarray:
    P, _ = forward_kinematics(motion.offsets, motion.parents, motion.local_rotations(),
                              motion.root_position)
    return P


def _template() -> Motion:
    return expmap_to_motion(np.zeros((1, 117)), fps=None, drop_tpose=False)


def _hand_made_poses(T: int = 40, seed: int = 3) -> np.ndarray:
    """Smooth pose vectors (T, 55) within ordinary joint ranges, canonical Euler angles."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, T)[:, None]
    angles = rng.uniform(-40, 40, 53) * np.sin(2 * np.pi * (t + rng.uniform(0, 1, 53)))
    heading = np.radians(120 * t[:, 0] - 30)
    v = np.concatenate([np.cos(heading)[:, None], np.sin(heading)[:, None], angles], axis=1)
    return motion_to_pose_vectors(pose_vectors_to_motion(v, _template()), 0.0)


def _angle_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    heading = np.degrees(np.arctan2(a[:, 1], a[:, 0]) - np.arctan2(b[:, 1], b[:, 0]))
    return np.concatenate([np.abs(wrap_deg(heading))[:, None],
                           np.abs(wrap_deg(a[:, 2:] - b[:, 2:]))], axis=1)


# --------------------------------------------------------------------- a DAZ-like skeleton

_DAZ = (  # name, parent, offset (cm, as in the dances' standard.bvh), end site
    ("hip", None, (0, 0, 0), None),
    ("abdomen", "hip", (0, 20.69, -0.73), None),
    ("chest", "abdomen", (0, 11.70, -0.49), None),
    ("neck", "chest", (0, 22.19, -2.19), None),
    ("head", "neck", (-0.24, 7.07, 1.22), (0, 15, 0)),
    ("rCollar", "chest", (-2.68, 19.26, -4.88), None),
    ("rShldr", "rCollar", (-8.78, -1.95, 1.46), None),
    ("rForeArm", "rShldr", (-28.17, -1.71, 0.49), None),
    ("rHand", "rForeArm", (-22.59, 0.77, 7.07), None),
    ("rMid1", "rHand", (-8.25, 1.18, 3.41), (-3, 0, 1)),
    ("lCollar", "chest", (2.68, 19.26, -4.88), None),
    ("lShldr", "lCollar", (8.78, -1.95, 1.46), None),
    ("lForeArm", "lShldr", (28.17, -1.71, 0.49), None),
    ("lHand", "lForeArm", (22.59, 0.77, 7.07), None),
    ("lMid1", "lHand", (8.25, 1.18, 3.41), (3, 0, 1)),
    ("rButtock", "hip", (-8.78, 4.35, 1.22), None),
    ("rThigh", "rButtock", (0, -1.71, -2.19), None),
    ("rShin", "rThigh", (0, -36.82, 0.73), None),
    ("rFoot", "rShin", (0.73, -45.11, -5.12), (-1.12, -3.70, 12.10)),
    ("lButtock", "hip", (8.78, 4.35, 1.22), None),
    ("lThigh", "lButtock", (0, -1.71, -2.19), None),
    ("lShin", "lThigh", (0, -36.82, 0.73), None),
    ("lFoot", "lShin", (-0.73, -45.11, -5.12), (1.12, -3.70, 12.10)),
)


def _daz(euler_deg: np.ndarray | None = None, T: int = 1, fps: float = 120.0) -> Motion:
    """A Motion on a DAZ-like skeleton (ZXY joint channels, cm); zero angles by default."""
    names = [j[0] for j in _DAZ]
    J = len(names)
    root = ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"]
    euler = np.zeros((T, J, 3)) if euler_deg is None else euler_deg
    return Motion(names=names,
                  parents=np.array([-1 if p is None else names.index(p) for _, p, _, _ in _DAZ]),
                  offsets=np.array([o for _, _, o, _ in _DAZ], dtype=float),
                  end_sites=np.array([[np.nan] * 3 if e is None else e for *_, e in _DAZ],
                                     dtype=float),
                  channels=[root] + [["Zrotation", "Xrotation", "Yrotation"]] * (J - 1),
                  euler_deg=euler, root_position=np.tile([0.0, 90.0, 0.0], (len(euler), 1)),
                  fps=fps)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# --------------------------------------------------------------------------- expmap


def test_expmap_rest_frame_gives_cmu_bone_directions():
    """All-zero rotations are the CMU rest pose: every bone of the converted frame points as
    in the source's forward kinematics (which with zero angles is the offsets)."""
    frame = np.zeros((1, 117))
    frame[0, :3] = [1.0, 17.0, -2.0]
    motion = expmap_to_motion(frame, fps=None, drop_tpose=False)
    P = _cmu_positions(motion)[0]
    ref = _source_fk(frame[0])[[EXPMAP_JOINTS.index(n) for n in CMU_JOINT_NAMES]]
    assert np.abs(P - ref).max() < 1e-9


def test_expmap_known_frames_match_the_source_forward_kinematics():
    """Random frames: the converted CMU motion puts every joint where the source's own
    forward kinematics (row vectors, Rodrigues) does: bone directions agree within 0.01 deg."""
    rng = np.random.default_rng(0)
    frames = np.concatenate([rng.normal(0, 20, (5, 3)), rng.normal(0, 0.6, (5, 114))], axis=1)
    motion = expmap_to_motion(frames, fps=None, drop_tpose=False)
    P = _cmu_positions(motion)
    idx = [EXPMAP_JOINTS.index(n) for n in CMU_JOINT_NAMES]
    for t in range(5):
        ref = _source_fk(frames[t])[idx]
        bones = [(int(p), j) for j, p in enumerate(motion.parents) if p >= 0
                 and np.linalg.norm(motion.offsets[j]) > 0]
        d = np.array([_unit(P[t, j] - P[t, p]) for p, j in bones])
        d_ref = np.array([_unit(ref[j] - ref[p]) for p, j in bones])
        angle = np.degrees(np.arccos(np.clip((d * d_ref).sum(1), -1, 1)))
        assert angle.max() < 0.01


def test_expmap_left_arm_signal_raises_the_left_arm(tmp_path):
    """A hand-made source frame raising the joint the source calls LeftArm (index 21, whose
    rest bone points to +X, the body's left when facing +Z) overhead, found with the
    source's own forward kinematics, converts to the CMU LeftHand above the head and the
    right hand hanging low."""
    frame = np.zeros(117)
    frame[1] = 17.0
    for arm, hand, wanted in (("LeftArm", "LeftHand", lambda y: y > 25),     # overhead
                              ("RightArm", "RightHand", lambda y: y < 17)):  # hanging
        j = EXPMAP_JOINTS.index(arm)
        for angle in (1.4, -1.4):
            frame[3 + 3 * j: 6 + 3 * j] = [0, 0, angle]
            if wanted(_source_fk(frame)[EXPMAP_JOINTS.index(hand), 1]):
                break
        else:
            pytest.fail(f"no hand-made frame put the source's {hand} where wanted")
    path = tmp_path / "signal_1.txt"
    path.write_text(",".join(f"{v:.9g}" for v in frame) + "\n")
    motion = read_expmap_motion(path, fps=None)
    P = _cmu_positions(motion)[0]
    head = P[CMU_JOINT_NAMES.index("Head"), 1]
    assert P[CMU_JOINT_NAMES.index("LeftHand"), 1] > head
    assert P[CMU_JOINT_NAMES.index("RightHand"), 1] < P[0, 1]
    assert P[CMU_JOINT_NAMES.index("LeftHand"), 0] > 0      # the body's left is +X


def test_expmap_frame_rate(tmp_path):
    """2 s at the source's 120 fps (plus the added T-pose frame) are 60 frames at 30 fps."""
    frames = np.zeros((241, 117))
    frames[0, 3 + 3 * EXPMAP_JOINTS.index("LeftArm") + 2] = np.radians(21.0)   # T-pose frame
    frames[1:, :3] = [0.0, 17.0, 0.0]
    frames[1:, 3] = np.radians(np.linspace(0.3, 50.3, 240))                    # turning root
    path = tmp_path / "walking_1.txt"
    np.savetxt(path, frames, delimiter=",", fmt="%.9g")
    motion = read_expmap_motion(path)
    assert motion.fps == 30.0 and motion.n_frames == 2 * 30
    assert read_expmap_motion(path, fps=None).n_frames == 240


def test_expmap_round_trip_gives_the_same_angles(tmp_path):
    """CMU pose vectors -> CMU motion -> expmap text -> converted back: within a degree."""
    v = _hand_made_poses()
    motion = pose_vectors_to_motion(v, _template(), root_position=np.tile([0, 17, 0],
                                                                          (len(v), 1)))
    path = tmp_path / "soccer_9.txt"
    np.savetxt(path, motion_to_expmap(motion), delimiter=",", fmt="%.12g")
    back = motion_to_pose_vectors(read_expmap_motion(path, fps=None), 0.0)
    assert _angle_error(back, v).max() < 1.0


def test_expmap_bad_line_is_one_line_naming_file_and_line(tmp_path):
    path = tmp_path / "jumping_1.txt"
    path.write_text(",".join(["0"] * 117) + "\n" + ",".join(["0"] * 100) + "\n")
    with pytest.raises(ExpmapError, match=r"jumping_1.txt line 2: expected 117 numbers, got 100"):
        read_expmap(path)


# --------------------------------------------------------------------------- dances


def test_retarget_bone_directions_follow_the_source():
    """Random source poses: each driven CMU bone (upper arm, forearm, thigh, shin, foot)
    points exactly where the source's bone points (within 0.1 degree), whatever the rests."""
    rng = np.random.default_rng(1)
    src = _daz(rng.uniform(-45, 45, (6, len(_DAZ), 3)), T=6)
    out = retarget(src)
    P_src, _ = forward_kinematics(src.offsets, src.parents, src.local_rotations(),
                                  src.root_position)
    P = _cmu_positions(out.motion)
    pairs = (("lShldr", "lForeArm", "LeftArm", "LeftForeArm"),
             ("lForeArm", "lHand", "LeftForeArm", "LeftHand"),
             ("rShldr", "rForeArm", "RightArm", "RightForeArm"),
             ("rThigh", "rShin", "RightUpLeg", "RightLeg"),
             ("lShin", "lFoot", "LeftLeg", "LeftFoot"))
    s, c = src.names.index, CMU_JOINT_NAMES.index
    for a, b, ca, cb in pairs:
        d = np.degrees(np.arccos(np.clip((_unit(P_src[:, s(b)] - P_src[:, s(a)])
                                          * _unit(P[:, c(cb)] - P[:, c(ca)])).sum(-1), -1, 1)))
        assert d.max() < 0.1, (a, b, d)


def test_retarget_rest_pose_keeps_cmu_rest_directions_where_the_rests_agree():
    """The source's rest pose retargets to a CMU pose whose thighs point straight down like
    the source's (the CMU rest splays them 20 degrees: the fit follows the source, not the
    CMU rest angles) and whose upper arms stay level like both rests."""
    out = retarget(_daz())
    P = _cmu_positions(out.motion)[0]
    c = CMU_JOINT_NAMES.index
    thigh = _unit(P[c("LeftLeg")] - P[c("LeftUpLeg")])
    arm = _unit(P[c("LeftForeArm")] - P[c("LeftArm")])
    assert np.degrees(np.arccos(-thigh[1])) < 3.0       # source thigh: 0.03 of 36.8 cm off -Y
    assert abs(np.degrees(np.arcsin(arm[1]))) < 4.0     # source upper arm: 3.5 deg down


def test_retarget_left_arm_signal_raises_the_left_arm():
    """The source's lShldr turned 80 degrees about +Z lifts its left arm overhead; the CMU
    LeftHand (at +X, the body's left) goes above the head, the right hand stays low."""
    euler = np.zeros((1, len(_DAZ), 3))
    euler[0, [j[0] for j in _DAZ].index("lShldr"), 0] = 80.0      # Zrotation
    euler[0, [j[0] for j in _DAZ].index("rShldr"), 0] = 70.0      # right arm down
    P = _cmu_positions(retarget(_daz(euler)).motion)[0]
    c = CMU_JOINT_NAMES.index
    assert P[c("LeftHand"), 1] > P[c("Head"), 1]
    assert P[c("RightHand"), 1] < P[c("Spine"), 1]
    assert P[c("LeftHand"), 0] > P[0, 0] > P[c("RightHand"), 0]


def _write_dance(folder: Path, motion: Motion, name: str = "01.bvh") -> Path:
    """A dance file as the source writes them: the rest frame (zero angles), 8 frames
    settling from it (here: garbage angles), then ``motion``."""
    folder.mkdir(parents=True, exist_ok=True)
    J = len(motion.names)
    settling = np.random.default_rng(9).uniform(-90, 90, (8, J, 3))
    euler = np.concatenate([np.zeros((1, J, 3)), settling, motion.euler_deg])
    root = np.concatenate([np.repeat(motion.root_position[:1], 9, axis=0),
                           motion.root_position])
    write_bvh(folder / name, Motion(**{**motion.__dict__, "euler_deg": euler,
                                       "root_position": root}))
    return folder / name


def test_dance_frame_rate_is_the_folders_not_the_headers(tmp_path):
    """Every dance header says 120 fps; salsa really is 60: 2 s of salsa (120 frames after
    the rest and settling frames) become 60 frames at 30 fps, 2 s of martial arts (240) too."""
    rng = np.random.default_rng(2)
    for kind, n in (("salsa", 120), ("martial", 240)):
        src = _daz(rng.uniform(-20, 20, (n, len(_DAZ), 3)), T=n, fps=120.0)
        path = _write_dance(tmp_path / kind, src)
        assert read_bvh(path, fps=None).fps == 120.0
        out = read_dance(path)
        assert out.motion.fps == 30.0 and out.motion.n_frames == 60, kind
        assert len(out.residual_mm) == 60


def test_dance_round_trip_gives_the_same_angles(tmp_path):
    """CMU pose vectors -> CMU motion -> the source skeleton (bone directions from the CMU
    positions) -> a BVH file -> retargeted back: the pose vectors within a degree."""
    v = _hand_made_poses(seed=5)
    cmu = pose_vectors_to_motion(v, _template(), root_position=np.tile([0, 17, 0],
                                                                       (len(v), 1)))
    cmu.fps = 120.0
    path = _write_dance(tmp_path / "martial", source_from_cmu(cmu, _daz()))
    back = motion_to_pose_vectors(read_dance(path, fps=None).motion, 0.0)
    assert _angle_error(back, v).max() < 1.0


# --------------------------------------------------------------------------- glue


def test_settle_on_floor_puts_the_lowest_foot_at_the_cmu_height():
    motion = expmap_to_motion(np.tile(np.r_[0.0, 30.0, 0.0, np.zeros(114)], (3, 1)), fps=None,
                              drop_tpose=False)
    P = _cmu_positions(settle_on_floor(motion))
    feet = [CMU_JOINT_NAMES.index(n) for n in ("LeftFoot", "RightFoot", "LeftToeBase",
                                                "RightToeBase")]
    assert np.median(P[:, feet, 1].min(axis=1)) * CMU_UNIT_M == pytest.approx(FOOT_HEIGHT_M)


def test_duplicates_include_the_held_out_trial_they_repeat():
    """A converted sequence repeating a held-out ../cmu trial must stay out of training."""
    assert "06_06" in DUPLICATES.values()
    assert set(DUPLICATES.values()) <= {f"{s:02d}_{t:02d}" for s in range(1, 10)
                                        for t in range(1, 16)} | set(HELD_OUT_TRIALS)


# --------------------------------------------------------------------------- the real data


def _needs_cmu_extra():
    if not CMU_EXTRA.is_dir():
        pytest.skip(f"cmu_extra not found at {CMU_EXTRA} (needs ../shared beside the repo)")


def test_expmap_tables_are_the_sources():
    """EXPMAP_PARENTS and EXPMAP_OFFSETS (x 70) are the tables of the source's
    forward_kinematics_cmu.py."""
    _needs_cmu_extra()
    text = (CMU_EXTRA / "expmap" / "source" / "forward_kinematics_cmu.py").read_text()
    parent = re.search(r"parent = np\.array\(\[([^\]]*)\]\)-1", text).group(1)
    assert [int(x) - 1 for x in re.split(r"[,\s]+", parent.strip())] == list(EXPMAP_PARENTS)
    offset = re.search(r"offset = 70\*np\.array\(\[([^\]]*)\]\)", text).group(1)
    values = np.array([float(x) for x in re.split(r"[,\s]+", offset.strip()) if x])
    assert np.allclose(values.reshape(38, 3), EXPMAP_OFFSETS, atol=1e-9)


def test_expmap_walking_1_is_cmu_02_01(cmu_bvh_dir):
    """The evidence for the expmap rate and the duplicates: train/walking/walking_1.txt is
    02_01.bvh frame for frame at 120 fps (joint rotations within 0.01 degree; the root within
    0.8 degree, the source's own rounding), T-pose frame included."""
    _needs_cmu_extra()
    frames = read_expmap(CMU_EXTRA / "expmap" / "train" / "walking" / "walking_1.txt")
    ours = expmap_to_motion(frames, fps=None, drop_tpose=False)
    cmu = read_bvh(cmu_bvh_dir / "02_01.bvh", fps=None, drop_tpose=False)
    assert ours.n_frames == cmu.n_frames and cmu.fps == 120.0
    a, b = ours.local_rotations(), cmu.local_rotations()
    angle = np.degrees(np.arccos(np.clip((np.einsum("tjab,tjab->tj", a, b) - 1) / 2, -1, 1)))
    assert angle[:, 1:].max() < 0.01 and angle[:, 0].max() < 0.8
    assert np.abs(ours.root_position - cmu.root_position).max() < 1e-3


# --------------------------------------------------------------------------- the script


def test_convert_script_writes_cmu_bvh_files_the_builder_reads(tmp_path, capsys):
    """scripts/convert_cmu_extra.py on a hand-made cmu_extra folder (one expmap sequence, one
    salsa): CMU-skeleton BVH files at 30 fps that read_bvh reads, a summary with the frames."""
    from conftest import load_script
    data = tmp_path / "cmu_extra"
    walk = data / "expmap" / "train" / "walking_extra"
    walk.mkdir(parents=True)
    frames = np.zeros((121, 117))
    frames[:, 1] = 17.0
    frames[:, 3 + 3 * EXPMAP_JOINTS.index("LeftUpLeg")] = np.linspace(0.1, 0.5, 121)
    np.savetxt(walk / "walking_99.txt", frames, delimiter=",", fmt="%.9g")
    _write_dance(data / "dances" / "salsa", _daz(np.zeros((60, len(_DAZ), 3)), T=60))
    script = load_script("convert_cmu_extra")
    out, summary = tmp_path / "out", tmp_path / "summary.json"
    assert script.main(["--data", str(data), "--out", str(out), "--summary", str(summary)]) == 0
    files = sorted(p.name for p in out.iterdir())
    assert files == ["xd_salsa_01.bvh", "xm_train_walking_extra_99.bvh"]
    walk_motion = read_bvh(out / files[1], fps=None)
    assert walk_motion.fps == 30.0 and walk_motion.n_frames == 31
    assert walk_motion.names == list(CMU_JOINT_NAMES)
    assert read_bvh(out / files[0], fps=None).n_frames == 30          # 1 s of salsa at 60 fps
    assert '"frames": 31' in summary.read_text()


def test_convert_script_refuses_bad_input_in_one_line(tmp_path, capsys):
    from conftest import load_script, refused_in_one_line
    script = load_script("convert_cmu_extra")
    err = refused_in_one_line(script, ["--data", str(tmp_path / "none")], capsys)
    assert "--data folder not found" in err
    (tmp_path / "expmap" / "test" / "soccer").mkdir(parents=True)
    (tmp_path / "dances").mkdir()
    (tmp_path / "expmap" / "test" / "soccer" / "soccer_1.txt").write_text("1,2,3\n")
    assert script.main(["--data", str(tmp_path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith("soccer_1.txt line 1: expected 117 numbers, got 3")
    assert len(err.splitlines()) == 1


def test_extra_training_files_leave_the_repeats_out(tmp_path):
    from sequences.cmu_extra import extra_training_files
    for name in ("xm_train_walking_1", "xm_train_walking_extra_18", "xd_salsa_01", "02_01"):
        (tmp_path / f"{name}.bvh").write_text("")
    assert [p.stem for p in extra_training_files(tmp_path)] == ["xd_salsa_01",
                                                                "xm_train_walking_extra_18"]


def test_extra_views_count_frames_at_the_files_own_rate(tmp_path):
    """A 100-frame file at 30 fps is 100 frames at the data set's 30 fps: 800 rows want 8
    views (views_by_rows, which takes every file for 120 fps, would count 25 and give 12)."""
    from sequences.cmu_extra import extra_views
    from sequences.dataset import DatasetConfig, views_by_rows
    motion = expmap_to_motion(np.tile(np.r_[0.0, 17.0, 0.0, np.zeros(114)], (100, 1)),
                              fps=None, drop_tpose=False)
    motion.fps = 30.0
    write_bvh(tmp_path / "xm_train_jumping_1.bvh", motion)
    files = [tmp_path / "xm_train_jumping_1.bvh"]
    assert extra_views(files, 30.0, 800) == {"xm_train_jumping_1": 8}
    assert views_by_rows(files, DatasetConfig(), 800) == {"xm_train_jumping_1": 12}
