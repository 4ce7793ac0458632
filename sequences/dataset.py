"""Training and evaluation data sets: real motion capture rendered as silhouettes.

For each BVH trial and each of several *views*, one silhouette sequence is rendered: the view
fixes a world camera azimuth and elevation and a body shape for the whole trial, and the camera
follows the body (centred), so the heading relative to the camera changes as the subject turns,
and consecutive frames form a real sequence for the stacked (multi-frame) regressor. Views of one
trial get evenly spread azimuths with a random offset, so every trial is seen from all sides.

Everything is reproducible from one seed: the per-view camera and shape come from a generator
seeded by (seed, trial name, view index), so adding a trial does not change the others.

Cache: one ``.npz`` per trial (no pickle) keyed by a digest of the settings, holding the masks
as packed bits and the per-frame pose vectors and camera settings.
"""
from __future__ import annotations

import hashlib
import json
import zlib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from regressor.errors import SilhouettePoseError

from .body import BodyShape, Skinner, load_body
from .bvh import read_bvh
from .pose_conversions import motion_to_pose_vectors
from .pose_vector import POSE_DIM
from .render import centred_camera, silhouette_mask

#: Trials that training never sees; evaluation and demos use them. 16_11 is the curved walk
#: used for spiral-walk evaluation; the others keep one example of each kind of motion out;
#: 06_06 (backward dribble) and 06_08 (sideways dribble) evaluate motion whose direction of
#: travel is not the direction the body faces.
HELD_OUT_TRIALS = ("16_11", "07_12", "09_11", "06_14", "141_16", "06_06", "06_08")

CACHE_FORMAT_VERSION = 1
#: How training masks are made (DatasetConfig.masks).
MASK_KINDS = ("plain", "realistic")
_FRAMES_PER_BATCH = 64          # frames skinned at once: bounds memory at ~T*V*12 floats


class DatasetError(SilhouettePoseError, ValueError):
    """Bad data-set options, missing trials, or an unreadable cache file."""


@dataclass(frozen=True)
class DatasetConfig:
    """How silhouettes are rendered from motion capture.

    fps: frame rate of the sequences (the tracker's video rate; stacking depends on it).
    views_per_trial: sequences rendered per trial, azimuths evenly spread plus a random offset.
    elevation_deg: (low, high) range of camera elevations, degrees, uniform per view.
    distance_m: (low, high) camera distance range, metres, uniform per view (sets perspective).
    person_px: standing height of the body in pixels; mask_size: (height, width) pixels.
    seed: everything random derives from it.
    masks: "plain" (exact rasterised silhouettes) or "realistic" (sequences.scene_render: the
    body shaded over a real room, filmed by a camera like the real clips', H.264, cut out by the
    tracker's extractor; camera elevation and distance then come from scene_render.SceneConfig,
    the person at its own scale on the canvas). backgrounds: with "realistic", the rooms
    (sequences.backgrounds.load_plates: "" procedural, or a folder of plates or Pose2Sim trials).
    """

    fps: float = 30.0
    views_per_trial: int = 6
    elevation_deg: tuple[float, float] = (-5.0, 30.0)
    distance_m: tuple[float, float] = (3.5, 8.0)
    person_px: float = 160.0
    mask_size: tuple[int, int] = (224, 224)
    seed: int = 0
    masks: str = "plain"
    backgrounds: str = ""

    def __post_init__(self):
        checks = [
            (self.fps > 0 and np.isfinite(self.fps), f"fps must be > 0, got {self.fps}"),
            (1 <= self.views_per_trial <= 360,
             f"views_per_trial must be 1..360, got {self.views_per_trial}"),
            (-60 <= self.elevation_deg[0] <= self.elevation_deg[1] <= 60,
             f"elevation_deg must be an ordered range within -60..60, got {self.elevation_deg}"),
            (0.5 <= self.distance_m[0] <= self.distance_m[1] <= 100,
             f"distance_m must be an ordered range within 0.5..100, got {self.distance_m}"),
            (16 <= self.person_px <= min(self.mask_size),
             f"person_px must be within 16..min(mask_size), got {self.person_px}"),
            (self.masks in MASK_KINDS,
             f"masks must be one of {', '.join(MASK_KINDS)}, got {self.masks!r}"),
        ]
        for ok, message in checks:
            if not ok:
                raise DatasetError(message)

    def digest(self) -> str:
        """Short digest of the settings (cache key); plain masks keep the digest they had
        before the masks and backgrounds settings existed."""
        settings = asdict(self)
        if self.masks == "plain":
            del settings["masks"], settings["backgrounds"]
        text = json.dumps(settings, sort_keys=True) + f"v{CACHE_FORMAT_VERSION}"
        return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass
class TrialViews:
    """All rendered views of one trial. N = views x frames rows, view-major.

    masks: (N, H, W) bool silhouettes; pose: (N, 55) pose vectors relative to each view's camera;
    view: (N,) view index; frame: (N,) frame index in the trial at config.fps;
    azimuth_deg, elevation_deg, distance_m: (N,) camera of each row; height_scale, girth_scale:
    (N,) body shape of each row; trial: the trial name (e.g. "02_01").
    """

    trial: str
    masks: np.ndarray
    pose: np.ndarray
    view: np.ndarray
    frame: np.ndarray
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    distance_m: np.ndarray
    height_scale: np.ndarray
    girth_scale: np.ndarray


@dataclass
class Dataset:
    """Concatenated views of many trials. Rows as in TrialViews; sequence: (N,) int, one id per
    (trial, view), consecutive rows of one id are consecutive frames (for stacking)."""

    masks: np.ndarray
    pose: np.ndarray
    sequence: np.ndarray
    frame: np.ndarray
    azimuth_deg: np.ndarray
    elevation_deg: np.ndarray
    trials: list[str] = field(default_factory=list)
    trial_of_sequence: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.pose)


def trial_name(path: str | Path) -> str:
    """'02_01' for '.../02_01.bvh'."""
    return Path(path).stem


def training_files(bvh_dir: str | Path, held_out: Sequence[str] = HELD_OUT_TRIALS) -> list[Path]:
    """All BVH files of bvh_dir except the held-out trials, sorted by name."""
    bvh_dir = Path(bvh_dir)
    if not bvh_dir.is_dir():
        raise DatasetError(f"BVH folder not found: {bvh_dir}")
    files = sorted(p for p in bvh_dir.glob("*.bvh") if trial_name(p) not in set(held_out))
    if not files:
        raise DatasetError(f"no training BVH files in {bvh_dir}")
    return files


def bvh_frame_count(path: str | Path) -> int:
    """Frames of a BVH file at its own rate, from its 'Frames:' header line (no parsing)."""
    with open(path, "r", errors="replace") as f:
        for line in f:
            if line.strip().startswith("Frames:"):
                return int(line.split(":", 1)[1])
    raise DatasetError(f"{path}: no 'Frames:' line")


def views_by_rows(bvh_files: Iterable[str | Path], config: DatasetConfig, rows_per_trial: int,
                  max_views: int = 12, min_views: int = 1) -> dict[str, int]:
    """Views per trial so that each trial gives about rows_per_trial silhouettes at config.fps:
    short trials (walks, runs: 100-150 frames) get many views (every heading seen), long ones
    (several minutes of climbing) few. Trial name -> views, clipped to min_views..max_views."""
    out = {}
    for p in bvh_files:
        frames = bvh_frame_count(p) * config.fps / 120.0      # CMU files are 120 fps
        out[trial_name(p)] = int(np.clip(round(rows_per_trial / max(frames, 1.0)),
                                         min_views, max_views))
    return out


def _view_rng(seed: int, trial: str, view: int) -> np.random.Generator:
    key = zlib.crc32(f"{trial}/{view}".encode())
    return np.random.default_rng([seed, key])


def view_settings(config: DatasetConfig, trial: str) -> list[dict]:
    """Per view: azimuth_deg, elevation_deg, distance_m, shape (BodyShape). Deterministic in
    (config.seed, trial)."""
    offset = _view_rng(config.seed, trial, -1).uniform(0, 360)
    views = []
    for v in range(config.views_per_trial):
        rng = _view_rng(config.seed, trial, v)
        views.append({
            "azimuth_deg": float((offset + 360.0 * v / config.views_per_trial) % 360.0),
            "elevation_deg": float(rng.uniform(*config.elevation_deg)),
            "distance_m": float(rng.uniform(*config.distance_m)),
            "shape": BodyShape(height_scale=float(np.clip(rng.normal(1.0, 0.05), 0.88, 1.12)),
                               girth_scale=float(np.clip(np.exp(rng.normal(0, 0.12)), 0.8, 1.35))),
        })
    return views


def render_motion_masks(motion, skinner: Skinner, azimuth_deg: float, elevation_deg: float,
                        distance_m: float, person_px: float, mask_size: tuple[int, int],
                        progress: Callable[[int], None] | None = None) -> np.ndarray:
    """Silhouettes (T, H, W) bool of a Motion seen by a camera that follows the body.

    The camera sits at a fixed world azimuth/elevation (degrees) and distance (metres) from the
    body's bounding-box centre each frame; its focal length images the body's standing height
    at person_px pixels. progress(n) is called with the number of frames done.
    """
    body = skinner.body
    local = motion.local_rotations()
    root_m = skinner.root_from_bvh(motion.root_position)
    standing = skinner.pose(skinner.rest_local_rotations(), skinner.rest_root_m)
    height_m = float(np.ptp(standing[:, 1]))
    T = motion.n_frames
    masks = np.empty((T, *mask_size), dtype=bool)
    for start in range(0, T, _FRAMES_PER_BATCH):
        stop = min(T, start + _FRAMES_PER_BATCH)
        verts = skinner.pose(local[start:stop], root_m[start:stop])
        for i, v in enumerate(verts):
            camera = centred_camera(v, azimuth_deg, elevation_deg, mask_size, person_px,
                                    distance_m, reference_height_m=height_m)
            masks[start + i] = silhouette_mask(v, body.faces, body.patch_start, camera)
        if progress is not None:
            progress(stop)
    return masks


def realistic_motion_masks(motion, skinner: Skinner, azimuth_deg: float, plates,
                           rng: np.random.Generator, mask_size: tuple[int, int], on_clip=None
                           ) -> tuple[np.ndarray, dict]:
    """Masks (T, H, W) bool of a Motion made the realistic way
    (sequences.scene_render.realistic_masks, which also says what on_clip gets) and its info
    (the camera's elevation_deg and distance_m among it)."""
    from .scene_render import realistic_masks
    local = motion.local_rotations()
    root_m = skinner.root_from_bvh(motion.root_position)
    standing = skinner.pose(skinner.rest_local_rotations(), skinner.rest_root_m)
    return realistic_masks(lambda a, b: skinner.pose(local[a:b], root_m[a:b]), motion.n_frames,
                           skinner.body, azimuth_deg, float(np.ptp(standing[:, 1])), plates,
                           rng, mask_size=mask_size, on_clip=on_clip)


def _view_masks(motion, skinner: Skinner, view: dict, config: DatasetConfig, trial: str,
                v: int) -> np.ndarray:
    """One view's masks as config.masks asks; a realistic view's camera elevation and
    distance are written into view."""
    if config.masks == "plain":
        return render_motion_masks(motion, skinner, view["azimuth_deg"], view["elevation_deg"],
                                   view["distance_m"], config.person_px, config.mask_size)
    from .backgrounds import load_plates
    masks, info = realistic_motion_masks(motion, skinner, view["azimuth_deg"],
                                         load_plates(config.backgrounds),
                                         _view_rng(config.seed, trial + "/scene", v),
                                         config.mask_size)
    view["elevation_deg"], view["distance_m"] = info["elevation_deg"], info["distance_m"]
    return masks


def render_trial(path: str | Path, config: DatasetConfig) -> TrialViews:
    """Render every view of one BVH trial (see module docstring)."""
    trial = trial_name(path)
    motion = read_bvh(path, fps=config.fps)
    body = load_body()
    parts = []
    for v, view in enumerate(view_settings(config, trial)):
        skinner = Skinner(body, offsets=motion.offsets, names=motion.names,
                          end_sites=motion.end_sites, shape=view["shape"])
        masks = _view_masks(motion, skinner, view, config, trial, v)
        T = motion.n_frames
        parts.append(dict(
            masks=masks, pose=motion_to_pose_vectors(motion, view["azimuth_deg"]),
            view=np.full(T, v), frame=np.arange(T),
            azimuth_deg=np.full(T, view["azimuth_deg"]),
            elevation_deg=np.full(T, view["elevation_deg"]),
            distance_m=np.full(T, view["distance_m"]),
            height_scale=np.full(T, view["shape"].height_scale),
            girth_scale=np.full(T, view["shape"].girth_scale)))
    return TrialViews(trial=trial, **{k: np.concatenate([p[k] for p in parts]) for k in parts[0]})


def _cache_path(cache_dir: Path, trial: str, config: DatasetConfig) -> Path:
    return cache_dir / f"{trial}-{config.digest()}.npz"


def save_trial(path: Path, views: TrialViews, config: DatasetConfig) -> None:
    """Write a trial's views as .npz (masks as packed bits), atomically."""
    arrays = {k: getattr(views, k) for k in ("pose", "view", "frame", "azimuth_deg",
                                             "elevation_deg", "distance_m", "height_scale",
                                             "girth_scale")}
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, format_version=np.int64(CACHE_FORMAT_VERSION),
                        config=np.str_(json.dumps(asdict(config), sort_keys=True)),
                        trial=np.str_(views.trial), mask_shape=np.array(views.masks.shape),
                        masks_packed=np.packbits(views.masks, axis=-1), **arrays)
    tmp.replace(path)


def load_trial(path: Path) -> TrialViews:
    """Read a cached trial written by save_trial; DatasetError if it is not one."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if int(z["format_version"]) != CACHE_FORMAT_VERSION:
                raise DatasetError(f"{path}: cache format {int(z['format_version'])}, "
                                   f"expected {CACHE_FORMAT_VERSION}; delete it to rebuild")
            shape = tuple(int(s) for s in z["mask_shape"])
            masks = np.unpackbits(z["masks_packed"], axis=-1, count=shape[-1]).astype(bool)
            fields = {k: z[k] for k in ("pose", "view", "frame", "azimuth_deg", "elevation_deg",
                                        "distance_m", "height_scale", "girth_scale")}
            trial = str(z["trial"])
    except (OSError, KeyError, ValueError, zlib.error) as exc:
        if isinstance(exc, DatasetError):
            raise
        raise DatasetError(f"{path}: unreadable data-set cache ({exc}); delete it to rebuild")
    if masks.shape != shape or fields["pose"].shape != (shape[0], POSE_DIM):
        raise DatasetError(f"{path}: inconsistent shapes in data-set cache; delete it to rebuild")
    return TrialViews(trial=trial, masks=masks, **fields)


def _render_and_cache(args) -> str:
    path, config, cache_file = args
    save_trial(Path(cache_file), render_trial(path, config), config)
    return str(path)


def build_dataset(bvh_files: Iterable[str | Path], config: DatasetConfig = DatasetConfig(),
                  cache_dir: str | Path = "cache/dataset", workers: int = 1,
                  progress: Callable[[str, int, int], None] | None = None,
                  views: dict[str, int] | None = None) -> Dataset:
    """Render (or load from cache) every view of every trial and concatenate them.

    bvh_files: the trials to use (e.g. training_files(dir)); held-out trials are refused, so a
    training set can never include them by accident (use render_trial for evaluation).
    workers: processes rendering trials in parallel. progress(trial, done, total) is called as
    each trial becomes available. views: trial name -> views_per_trial for that trial (e.g.
    views_by_rows), overriding config's; each trial is cached under its own settings. Returns
    a Dataset whose sequence ids are numbered in the order of bvh_files x views.
    """
    files = [Path(p) for p in bvh_files]
    leaked = sorted({trial_name(p) for p in files} & set(HELD_OUT_TRIALS))
    if leaked:
        raise DatasetError(f"held-out trials {leaked} cannot be part of a training data set")
    missing = [str(p) for p in files if not p.is_file()]
    if missing:
        raise DatasetError(f"BVH files not found: {missing}")
    cache = Path(cache_dir)
    cache.mkdir(parents=True, exist_ok=True)
    configs = {trial_name(p): (replace(config, views_per_trial=views[trial_name(p)])
                               if views and trial_name(p) in views else config) for p in files}
    cached = {trial_name(p): _cache_path(cache, trial_name(p), configs[trial_name(p)])
              for p in files}
    todo = [(p, configs[trial_name(p)], cached[trial_name(p)]) for p in files
            if not cached[trial_name(p)].is_file()]
    # Longest trials first, so the pool's last tasks are short ones.
    todo.sort(key=lambda job: -bvh_frame_count(job[0]) * job[1].views_per_trial)
    done = len(files) - len(todo)
    if todo:
        if workers > 1:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                for name in pool.map(_render_and_cache, todo):
                    done += 1
                    if progress:
                        progress(trial_name(name), done, len(files))
        else:
            for job in todo:
                _render_and_cache(job)
                done += 1
                if progress:
                    progress(trial_name(job[0]), done, len(files))
    return _concatenate([load_trial(cached[trial_name(p)]) for p in files])


def _concatenate(trials: list[TrialViews]) -> Dataset:
    sequence, offset, trial_of_sequence = [], 0, []
    for t in trials:
        sequence.append(t.view + offset)
        trial_of_sequence += [t.trial] * (int(t.view.max()) + 1)
        offset += int(t.view.max()) + 1
    cat = lambda k: np.concatenate([getattr(t, k) for t in trials])  # noqa: E731
    return Dataset(masks=cat("masks"), pose=cat("pose"), sequence=np.concatenate(sequence),
                   frame=cat("frame"), azimuth_deg=cat("azimuth_deg"),
                   elevation_deg=cat("elevation_deg"), trials=[t.trial for t in trials],
                   trial_of_sequence=trial_of_sequence)
