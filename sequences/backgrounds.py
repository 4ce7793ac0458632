"""Empty real scenes for realistic training renders: Pose2Sim's videos with the people removed.

The Pose2Sim demonstration videos (BSD 3-Clause, perfanalytics 2022; the shared data's
``pose2sim/*/videos``) are real rooms seen by real phone cameras from about 2 m up. Each trial
(balancing, swings) is filmed by the same four cameras from the same places, so one camera's
two clips show the same room. A clip's per-pixel median removes people who move; where someone
stays on the spot (balancing) the median shows them, and the tracker's own estimate of where
the median cannot be trusted (``tracker.video.background.clip_background``'s unreliable zone) says
where. A camera's plate takes each pixel from the clip that is reliable there, and what no clip
shows empty is inpainted (OpenCV's Telea method, a few per cent of the image at most).

Plates are made at the tracker's working width (320 px) and cached as PNG beside the data set,
never committed: they are derived from the shared data. Without the videos,
:func:`procedural_plates` gives textured synthetic rooms (``sequences.video``), our own scenes.
"""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError

from .video import textured_background

PLATE_WIDTH = 320               # the tracker's working width (tracker.video.silhouettes)
_SAMPLES = 25                   # frames per clip for the median, as `track` takes


class BackgroundError(SilhouettePoseError, ValueError):
    """Missing or unreadable background videos or plates."""


def _sample_frames(path: Path, n: int, width: int) -> np.ndarray:
    """n frames spread over a video, BGR uint8 (n', h, width, 3) shrunk by area averaging."""
    from tracker.video.area_shrink import shrink
    cap = cv2.VideoCapture(str(path))
    total = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    frames = []
    for index in np.linspace(0, max(total - 1, 0), n).round().astype(int):
        cap.set(cv2.CAP_PROP_POS_FRAMES, int(index))
        ok, frame = cap.read()
        if ok:
            h, w = frame.shape[:2]
            frames.append(shrink(frame, (width, max(1, round(h * width / w)))))
    cap.release()
    if not frames:
        raise BackgroundError(f"{path}: no frame decodes")
    return np.stack(frames)


def camera_plate(videos: list[Path], width: int = PLATE_WIDTH) -> tuple[np.ndarray, np.ndarray]:
    """The empty scene of one camera from its clips (paths of videos of the same view).

    Returns (plate BGR uint8 (h, width, 3), bool (h, width): True where no clip showed the
    scene empty, inpainted). Each pixel comes from the first clip whose median is reliable there
    (clip_background's zone)."""
    from tracker.video.background import clip_background
    plate, missing = None, None
    for path in videos:
        estimate = clip_background(_sample_frames(path, _SAMPLES, width))
        if plate is None:
            plate, missing = estimate.image.copy(), estimate.unreliable.copy()
        elif estimate.image.shape == plate.shape:
            fill = missing & ~estimate.unreliable
            plate[fill] = estimate.image[fill]
            missing &= estimate.unreliable
    hole = cv2.dilate(missing.astype(np.uint8) * 255, np.ones((5, 5), np.uint8))
    if hole.any():
        plate = cv2.inpaint(plate, hole, 5, cv2.INPAINT_TELEA)
    return plate, missing


def pose2sim_plates(root: str | Path, cache_dir: str | Path | None = None
                    ) -> list[tuple[np.ndarray, np.ndarray]]:
    """(plate, inpainted) per camera of the Pose2Sim trials under root (folders
    ``*/videos/camNN.mp4``), as camera_plate gives them, cached in cache_dir when given as
    ``plate-camNN.png`` and ``plate-camNN-inpainted.png``."""
    root = Path(root)
    videos: dict[str, list[Path]] = {}
    for path in sorted(root.glob("*/videos/*.mp4")):
        videos.setdefault(path.stem, []).append(path)
    if not videos:
        raise BackgroundError(f"no Pose2Sim videos (*/videos/*.mp4) under {root}")
    plates = []
    for name, paths in sorted(videos.items()):
        image_file = Path(cache_dir) / f"plate-{name}.png" if cache_dir else None
        hole_file = Path(cache_dir) / f"plate-{name}-inpainted.png" if cache_dir else None
        if image_file is not None and image_file.is_file() and hole_file.is_file():
            plate = cv2.imread(str(image_file), cv2.IMREAD_COLOR)
            hole = cv2.imread(str(hole_file), cv2.IMREAD_GRAYSCALE)
            if plate is None or hole is None or hole.shape != plate.shape[:2]:
                raise BackgroundError(f"{image_file}: unreadable plate; delete it to rebuild")
            missing = hole > 0
        else:
            plate, missing = camera_plate(paths)
            if image_file is not None:
                image_file.parent.mkdir(parents=True, exist_ok=True)
                cv2.imwrite(str(hole_file), missing.astype(np.uint8) * 255)
                cv2.imwrite(str(image_file), plate)
        plates.append((plate, missing))
    return plates


def plates_folder(backgrounds: str | Path, cache_dir: str | Path) -> str:
    """The folder of plates to render over (DatasetConfig.backgrounds): backgrounds itself
    when it holds plate-*.png, else the Pose2Sim trials in it made into plates once, in
    cache_dir/plates. Absolute, so the data set's cache key does not depend on the working
    folder."""
    backgrounds = Path(backgrounds)
    if any(backgrounds.glob("plate-*.png")):
        return str(backgrounds.resolve())
    folder = Path(cache_dir) / "plates"
    pose2sim_plates(backgrounds, folder)
    return str(folder.resolve())


def procedural_plates(n: int = 4, size: tuple[int, int] = (480, 320), seed: int = 0
                      ) -> list[tuple[np.ndarray, np.ndarray]]:
    """n synthetic rooms (sequences.video.textured_background), (BGR uint8 (H, W, 3), nothing
    inpainted (H, W) bool)."""
    return [(textured_background(size, seed + i)[..., ::-1].copy(), np.zeros(size, bool))
            for i in range(n)]


def background_view(plates: list[tuple[np.ndarray, np.ndarray]], size: tuple[int, int],
                    rng: np.random.Generator, tries: int = 6) -> np.ndarray:
    """A random view of a random plate ((image, inpainted) pairs) at size (H, W): zoomed
    1-1.5x, of ``tries`` random crops the one with the least inpainted area, maybe mirrored,
    its brightness scaled by 0.8-1.2. BGR uint8 (H, W, 3)."""
    plate, missing = plates[int(rng.integers(len(plates)))]
    h, w = size
    zoom = max(h / plate.shape[0], w / plate.shape[1]) * float(rng.uniform(1.0, 1.5))
    big_size = (max(w, round(plate.shape[1] * zoom)), max(h, round(plate.shape[0] * zoom)))
    big = cv2.resize(plate, big_size, interpolation=cv2.INTER_LINEAR)
    hole = cv2.resize(missing.astype(np.uint8), big_size, interpolation=cv2.INTER_NEAREST)
    integral = cv2.integral(hole)
    ys = rng.integers(big.shape[0] - h + 1, size=tries)
    xs = rng.integers(big.shape[1] - w + 1, size=tries)
    inpainted = (integral[ys + h, xs + w] - integral[ys, xs + w] - integral[ys + h, xs]
                 + integral[ys, xs])
    best = int(np.argmin(inpainted))
    y0, x0 = int(ys[best]), int(xs[best])
    view = big[y0:y0 + h, x0:x0 + w]
    if rng.random() < 0.5:
        view = view[:, ::-1]
    gain = float(rng.uniform(0.8, 1.2))
    return np.clip(view.astype(np.float32) * gain, 0, 255).astype(np.uint8)


@lru_cache(maxsize=4)
def load_plates(spec: str = "") -> list[tuple[np.ndarray, np.ndarray]]:
    """Plates for realistic renders: "" -> procedural_plates(); a folder holding
    ``plate-*.png`` (as pose2sim_plates caches them) -> those; else a folder of Pose2Sim trials
    -> pose2sim_plates(spec) (a minute: cache them with pose2sim_plates(root, cache_dir)).
    Kept per process (the data set's views of one worker share them); do not modify them."""
    if not str(spec):
        return procedural_plates()
    folder = Path(spec)
    if not folder.is_dir():
        raise BackgroundError(f"backgrounds folder not found: {folder}")
    images = sorted(p for p in folder.glob("plate-*.png") if not p.stem.endswith("-inpainted"))
    if not images:
        return pose2sim_plates(folder)
    plates = []
    for path in images:
        plate = cv2.imread(str(path), cv2.IMREAD_COLOR)
        hole_path = path.with_name(path.stem + "-inpainted.png")
        hole = cv2.imread(str(hole_path), cv2.IMREAD_GRAYSCALE) if hole_path.is_file() else None
        if plate is None:
            raise BackgroundError(f"{path}: unreadable background image")
        missing = (hole > 0) if hole is not None and hole.shape == plate.shape[:2] else \
            np.zeros(plate.shape[:2], bool)
        plates.append((plate, missing))
    return plates
