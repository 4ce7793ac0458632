"""Training silhouettes made the way real ones are: a coloured body in a real room, filmed,
compressed, and cut out by the tracker itself.

Plain training masks (sequences.render.silhouette_mask) are exact rasterisations; real masks are
what background subtraction makes of a person in clothes over a cluttered room on a compressed
phone video. This module goes that way for each motion-capture sequence:

1. The body is drawn with flat-shaded colours per surface patch: skin, hair, a top (short or long
   sleeves), trousers and shoes, colours drawn per sequence (:func:`sample_look`), Lambert light
   from above (ambient 0.3-0.55), painter's order far to near, one ``cv2.fillPoly`` per patch
   and colour level (about 400 calls a frame, as the plain mask's 250).
2. A ground shadow: each bone's vertices projected onto the floor along the light, their convex
   hull darkening the floor (blurred).
3. Over a real empty room (sequences.backgrounds), in a camera like Pose2Sim's: 1.5-2.3 m up,
   2.8-6 m away, so looking down 5-25 degrees. The camera looks along the data set's view
   direction (so the labels are the plain data set's); it slides with the body's travel so
   the person crosses a static room (bouncing at the frame's sides), feet on the floor.
4. Lens blur and sensor noise, then H.264 (libx264, CRF 17-25, yuv420p) and decoding, through
   an ffmpeg binary (imageio-ffmpeg's bundled one when installed, else ffmpeg on PATH).
5. The tracker's own extractor (tracker.video.silhouettes.SilhouetteExtractor, default settings)
   primed as ``track`` primes it without a clean plate: the median of 25 frames spread over
   the clip, and learn_zone on them. Its largest person is the training mask.

Frames are BGR uint8 throughout (OpenCV's order). Everything random comes from the generator
passed in; ffmpeg's libx264 is deterministic for one build and settings.
"""
from __future__ import annotations

import shutil
import subprocess
from dataclasses import dataclass

import cv2
import numpy as np

from regressor.errors import SilhouettePoseError

from .body import BodyModel
from .render import Camera, _projected_triangles, centred_camera

#: Surface parts coloured separately; "forearm" takes the skin's or the top's colour.
PARTS = ("skin", "hair", "top", "bottom", "shoes", "forearm")
_PART_OF_JOINT = {
    "Head": 0, "Neck": 0, "Neck1": 0, "LeftHand": 0, "RightHand": 0, "LeftFingerBase": 0,
    "RightFingerBase": 0, "LeftHandIndex1": 0, "RightHandIndex1": 0, "LThumb": 0, "RThumb": 0,
    "Spine": 2, "Spine1": 2, "LowerBack": 2, "LeftShoulder": 2, "RightShoulder": 2,
    "LeftArm": 2, "RightArm": 2, "Hips": 3, "LHipJoint": 3, "RHipJoint": 3, "LeftUpLeg": 3,
    "RightUpLeg": 3, "LeftLeg": 3, "RightLeg": 3, "LeftFoot": 4, "RightFoot": 4,
    "LeftToeBase": 4, "RightToeBase": 4, "LeftForeArm": 5, "RightForeArm": 5}
_LEVELS = 8                     # shading levels: one fillPoly per patch, part and level
_SKIN = np.array([[200, 215, 240], [150, 180, 225], [110, 150, 200], [70, 100, 150],
                  [45, 65, 100]], np.float32)          # BGR, light to dark
_HAIR = np.array([[20, 20, 25], [30, 50, 80], [60, 110, 160], [150, 150, 150]], np.float32)


class SceneRenderError(SilhouettePoseError, ValueError):
    """No ffmpeg to encode with, or a frame that cannot be made."""


@dataclass(frozen=True)
class Look:
    """One sequence's appearance and light. colours: (6, 3) BGR 0-255 per PARTS entry;
    light: (3,) unit vector towards the light (world, Y up); ambient: share of unshaded light;
    shadow: floor brightness under the body's shadow (0..1); noise: sensor noise SD, grey
    levels; crf: H.264 quality (lower is better)."""

    colours: np.ndarray
    light: np.ndarray
    ambient: float
    shadow: float
    noise: float
    crf: int


def sample_look(rng: np.random.Generator) -> Look:
    """A random Look: skin from five tones, clothing uniform in BGR (dark and pale included),
    short sleeves half the time, light 0-30 degrees from overhead (rooms are lit from the
    ceiling: short, soft shadows, the floor kept at 65-90 % under them), CRF 17-25 (at 320 px
    this stands for a phone's high-definition stream shrunk by the tracker, which averages
    most of the compression noise away)."""
    skin = _SKIN[rng.integers(len(_SKIN))] * rng.uniform(0.9, 1.1)
    top, bottom = rng.uniform(15, 240, 3), rng.uniform(15, 200, 3)
    shoes = rng.uniform(10, 230) * np.ones(3)
    forearm = skin if rng.random() < 0.5 else top
    colours = np.clip(np.stack([skin, _HAIR[rng.integers(len(_HAIR))], top, bottom, shoes,
                                forearm]), 0, 255).astype(np.float32)
    tilt, turn = np.radians(rng.uniform(0, 30)), rng.uniform(0, 2 * np.pi)
    light = np.array([np.sin(tilt) * np.sin(turn), np.cos(tilt), np.sin(tilt) * np.cos(turn)])
    return Look(colours, light, float(rng.uniform(0.3, 0.55)), float(rng.uniform(0.65, 0.9)),
                float(rng.uniform(1.0, 3.0)), int(rng.integers(17, 26)))


def body_parts(body: BodyModel) -> tuple[np.ndarray, np.ndarray]:
    """(part of each surface patch (P,) int index into PARTS, the most common of its faces'
    first vertices', bone of each vertex (V,) int: its largest skin weight). Hair: the head's
    vertices in the top 9 cm of the rest body."""
    bone = np.argmax(body.weights, axis=1)
    lookup = np.array([_PART_OF_JOINT.get(n, 2) for n in body.joint_names])
    part = lookup[bone]
    top = body.vertices[:, 1].max()
    part[(part == 0) & (bone == body.joint_names.index("Head"))
         & (body.vertices[:, 1] > top - 0.09)] = 1
    face_part = part[body.faces[:, 0]]
    n_patches = len(body.patch_start) - 1
    patch = np.repeat(np.arange(n_patches), np.diff(body.patch_start))
    votes = np.zeros((n_patches, len(PARTS)), int)
    np.add.at(votes, (patch, face_part), 1)
    return votes.argmax(axis=1), bone


def draw_body(canvas: np.ndarray, vertices: np.ndarray, body: BodyModel, patch_part: np.ndarray,
              camera: Camera, look: Look) -> None:
    """Draw the posed body (vertices (V, 3) metres) into canvas, BGRA uint8 (H, W, 4), alpha
    255 where the body is: each surface patch flat-shaded by its mean normal in its part's
    colour (patch_part: (P,) index into PARTS), far patches first. Same triangles and fill rule
    as silhouette_mask (one fillPoly per patch), so the alpha is the plain mask. The patches'
    indices are drawn into a 16-bit image and coloured by lookup in one step."""
    tri, visible, facing, tri_z = _projected_triangles(vertices, body.faces, camera)
    kept = np.flatnonzero(visible & facing)
    n_patches = len(body.patch_start) - 1
    patch = np.searchsorted(body.patch_start, kept, side="right") - 1
    corners = vertices[body.faces[kept]]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal = np.stack([np.bincount(patch, normal[:, k], n_patches) for k in range(3)], axis=1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True) + 1e-12
    shade = look.ambient + (1 - look.ambient) * np.clip(normal @ look.light, 0, None)
    depth = np.bincount(patch, tri_z[kept].mean(axis=1), n_patches)
    count = np.bincount(patch, minlength=n_patches)
    depth /= np.maximum(count, 1)
    order = np.argsort(-depth[patch], kind="stable")       # far patches first
    patch, tri = patch[order], tri[kept[order]]
    bounds = np.flatnonzero(np.diff(patch)) + 1
    index = np.zeros(camera.size, np.uint16)
    for lo, hi in zip(np.r_[0, bounds].tolist(), np.r_[bounds, len(patch)].tolist()):
        cv2.fillPoly(index, tri[lo:hi], int(patch[lo]) + 1, lineType=cv2.LINE_8, shift=3)
    lut = np.zeros((n_patches + 1, 4), np.uint8)
    lut[1:, :3] = np.clip(look.colours[patch_part] * shade[:, None], 0, 255)
    lut[1:, 3] = 255
    canvas[:] = lut[index]


def shadow_map(vertices: np.ndarray, bone: np.ndarray, camera: Camera, light: np.ndarray,
               floor_y: float) -> np.ndarray:
    """Float32 (H, W) 0..1 shadow cover of the body on the floor y = floor_y (metres), cast
    along light (towards the light, Y up): each bone's vertices projected onto the floor, the
    convex hull of their image filled, blurred by 2 px."""
    lift = np.maximum(vertices[:, 1] - floor_y, 0.0)
    on_floor = vertices - (lift / light[1])[:, None] * light
    uv, z = camera.project(on_floor)
    cover = np.zeros(camera.size, np.uint8)
    ok = z > 0.05
    limit = 4.0 * max(camera.size)
    pts = np.clip(uv, -limit, limit).astype(np.int32)
    order = np.argsort(bone, kind="stable")
    cuts = np.flatnonzero(np.diff(bone[order])) + 1
    for group in np.split(order, cuts):
        group = group[ok[group]]
        if len(group) >= 3:
            cv2.fillConvexPoly(cover, cv2.convexHull(pts[group]), 255)
    return cv2.GaussianBlur(cover, (0, 0), 2.0).astype(np.float32) / 255.0


def reflect(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """x folded into [lo, hi] by bouncing at the ends (a walker turning at the frame's side)."""
    span = max(hi - lo, 1e-6)
    y = np.mod(np.asarray(x, np.float64) - lo, 2 * span)
    return lo + np.where(y > span, 2 * span - y, y)


def placed_camera(vertices: np.ndarray, azimuth_deg: float, elevation_deg: float,
                  distance_m: float, person_px: float, height_m: float,
                  size: tuple[int, int], centre_u: float, feet_v: float) -> Camera:
    """centred_camera (same rotation and focal length: the plain data set's view) moved
    parallel to its image plane so the body's box is centred at column centre_u with its
    lowest point at row feet_v (pixels)."""
    camera = centred_camera(vertices, azimuth_deg, elevation_deg, size, person_px, distance_m,
                            reference_height_m=height_m)
    uv, _ = camera.project(vertices)
    du = centre_u - (uv[:, 0].min() + uv[:, 0].max()) / 2
    dv = feet_v - uv[:, 1].max()
    shift = (distance_m / camera.focal_px) * (du * camera.rotation[0] + dv * camera.rotation[1])
    return Camera(camera.rotation, camera.position - shift, camera.focal_px, camera.size)


def compose(background: np.ndarray, person: np.ndarray, shadow: np.ndarray,
            look: Look, noise: np.ndarray | None = None) -> np.ndarray:
    """A frame BGR uint8 (H, W, 3): background (H, W, 3) darkened by shadow (H, W) 0..1 to
    look.shadow, the person (BGRA (H, W, 4)) over it, a lens blur of 0.6 px and sensor noise
    (H, W, 3) int16 added when given."""
    dim = cv2.merge([1.0 - (1.0 - look.shadow) * shadow] * 3)
    floor = cv2.multiply(background, dim, dtype=cv2.CV_8U)
    frame = np.where(person[..., 3:4] > 0, person[..., :3], floor)
    frame = cv2.GaussianBlur(frame, (0, 0), 0.6)
    if noise is not None:
        frame = cv2.add(frame, noise, dtype=cv2.CV_8U)
    return frame


def ffmpeg_exe() -> str:
    """The ffmpeg binary: imageio-ffmpeg's bundled one, else ffmpeg on PATH."""
    try:
        import imageio_ffmpeg
        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        found = shutil.which("ffmpeg")
        if found is None:
            raise SceneRenderError("realistic masks need ffmpeg: pip install imageio-ffmpeg "
                                   "(the .[train] extra) or apt install ffmpeg") from None
        return found


def h264_round_trip(frames: np.ndarray, crf: int = 23, fps: float = 30.0) -> np.ndarray:
    """frames (T, H, W, 3) BGR uint8 (H, W even) encoded to H.264 (libx264, preset veryfast,
    yuv420p, CRF crf) and decoded again: the same shape, with compression's artefacts."""
    T, H, W, _ = frames.shape
    exe = ffmpeg_exe()
    encode = [exe, "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "bgr24", "-s", f"{W}x{H}",
              "-r", f"{fps:g}", "-i", "-", "-c:v", "libx264", "-preset", "veryfast", "-crf",
              str(int(crf)), "-pix_fmt", "yuv420p", "-threads", "1", "-f", "h264", "-"]
    decode = [exe, "-loglevel", "error", "-f", "h264", "-i", "-", "-f", "rawvideo", "-pix_fmt",
              "bgr24", "-threads", "1", "-"]
    coded = subprocess.run(encode, input=np.ascontiguousarray(frames).tobytes(),
                           capture_output=True)
    raw = subprocess.run(decode, input=coded.stdout, capture_output=True)
    if coded.returncode or raw.returncode or len(raw.stdout) != frames.nbytes:
        message = (coded.stderr or raw.stderr).decode(errors="replace").strip()
        raise SceneRenderError(f"ffmpeg H.264 round trip failed: {message or 'short output'}")
    return np.frombuffer(raw.stdout, np.uint8).reshape(frames.shape)


def extract_people(frames: np.ndarray, samples: int = 25) -> list:
    """The tracker's extractor on decoded frames (T, H, W, 3) BGR uint8, primed as ``track``
    primes it without a clean plate (the median of ``samples`` frames spread over the clip,
    then learn_zone on them). Per frame its largest PersonMask, or None."""
    from tracker.video.silhouettes import SilhouetteExtractor
    extractor = SilhouetteExtractor()
    picks = np.unique(np.linspace(0, len(frames) - 1, min(samples, len(frames))).round()
                      .astype(int))
    sample = frames[picks]
    extractor.prime(np.median(sample, axis=0).astype(np.uint8))
    extractor.learn_zone(sample)
    out = []
    for frame in frames:
        people = extractor(frame)
        out.append(people[0] if people else None)
    return out


def in_frame(person, size: tuple[int, int]) -> np.ndarray:
    """A PersonMask (or None) as a bool mask of the whole frame (H, W)."""
    full = np.zeros(size, bool)
    if person is not None:
        x, y, w, h = person.bbox
        full[y:y + h, x:x + w] = person.mask[:size[0] - y, :size[1] - x]
    return full


def on_canvas(mask: np.ndarray, size: tuple[int, int] = (224, 224), fill: float = 0.96
              ) -> np.ndarray:
    """The bounding box of mask (any (h, w) bool) centred on a canvas of size (H, W) at its own
    scale, shrunk (area averaging, cut at half) only when larger than fill x the canvas."""
    ys, xs = np.nonzero(mask)
    canvas = np.zeros(size, bool)
    if len(ys) == 0:
        return canvas
    crop = mask[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
    scale = min(1.0, fill * size[0] / crop.shape[0], fill * size[1] / crop.shape[1])
    if scale < 1.0:
        small = cv2.resize(crop.astype(np.float32), (max(1, round(crop.shape[1] * scale)),
                           max(1, round(crop.shape[0] * scale))), interpolation=cv2.INTER_AREA)
        crop = small >= 0.5
    h, w = crop.shape
    y0, x0 = (size[0] - h) // 2, (size[1] - w) // 2
    canvas[y0:y0 + h, x0:x0 + w] = crop
    return canvas


@dataclass(frozen=True)
class SceneConfig:
    """How realistic frames are filmed. frame_size: (H, W) px (W = the tracker's working
    width, so it works on the frames as they are); person_px: (low, high) standing height;
    camera_height_m, distance_m: (low, high) ranges, metres (Pose2Sim's cameras: 1.7-2.1 m up,
    about 2.5-4 m from the person); clip_frames: longest clip encoded and primed as one video;
    fps: frame rate given to the encoder."""

    frame_size: tuple[int, int] = (240, 320)
    person_px: tuple[float, float] = (90.0, 200.0)
    camera_height_m: tuple[float, float] = (1.5, 2.3)
    distance_m: tuple[float, float] = (2.8, 6.0)
    clip_frames: int = 150
    fps: float = 30.0


#: Height of the camera's aim above the floor, metres: the middle of a standing body's box.
AIM_HEIGHT_M = 0.9


def scene_camera(rng: np.random.Generator, config: SceneConfig = SceneConfig()) -> dict:
    """A camera like the real clips': elevation_deg (looking down), distance_m, person_px,
    camera height_m, and where the body stands in the frame (centre_u, feet_v px)."""
    d = float(rng.uniform(*config.distance_m))
    h = float(rng.uniform(*config.camera_height_m))
    H, W = config.frame_size
    return {"elevation_deg": float(np.degrees(np.arcsin(np.clip((h - AIM_HEIGHT_M) / d, -1, 1)))),
            "distance_m": d, "height_m": h, "person_px": float(rng.uniform(*config.person_px)),
            "centre_u": float(rng.uniform(0.3, 0.7) * W),
            "feet_v": float(rng.uniform(0.86, 0.97) * H)}


def film_clip(vertices: np.ndarray, body: BodyModel, parts: tuple[np.ndarray, np.ndarray],
              view: dict, azimuth_deg: float, height_m: float, background: np.ndarray,
              look: Look, rng: np.random.Generator, config: SceneConfig = SceneConfig()
              ) -> tuple[np.ndarray, np.ndarray]:
    """Frames (T, H, W, 3) BGR uint8 before compression and the plain masks (T, H, W) bool of
    posed vertices (T, V, 3) metres, filmed by view (scene_camera) at azimuth_deg over
    background (H, W, 3); height_m: the body's standing height (sets the focal length)."""
    patch_part, bone = parts
    T = len(vertices)
    H, W = config.frame_size
    floor = float(np.percentile(vertices[..., 1].min(axis=1), 10))
    probe = centred_camera(vertices[0], azimuth_deg, view["elevation_deg"], config.frame_size,
                           view["person_px"], view["distance_m"], reference_height_m=height_m)
    px_per_m = probe.focal_px / view["distance_m"]
    travel = (vertices.mean(axis=1) - vertices[0].mean(axis=0)) @ probe.rotation[0]
    centre_u = reflect(view["centre_u"] + px_per_m * travel, 0.2 * W, 0.8 * W)
    feet_v = view["feet_v"] - px_per_m * (vertices[..., 1].min(axis=1) - floor)
    noise = np.round(rng.normal(0, look.noise, (4, H, W, 3))).astype(np.int16)
    frames = np.empty((T, H, W, 3), np.uint8)
    masks = np.empty((T, H, W), bool)
    person = np.empty((H, W, 4), np.uint8)
    for t in range(T):
        camera = placed_camera(vertices[t], azimuth_deg, view["elevation_deg"],
                               view["distance_m"], view["person_px"], height_m, config.frame_size,
                               float(centre_u[t]), float(feet_v[t]))
        person[:] = 0
        draw_body(person, vertices[t], body, patch_part, camera, look)
        shadow = shadow_map(vertices[t], bone, camera, look.light, floor)
        frames[t] = compose(background, person, shadow, look, noise[t % len(noise)])
        masks[t] = person[..., 3] > 0
    return frames, masks


def clip_bounds(T: int, clip_frames: int) -> list[tuple[int, int]]:
    """(start, stop) of ceil(T / clip_frames) clips of nearly equal length covering 0..T."""
    n = max(1, -(-T // max(clip_frames, 1)))
    edges = np.linspace(0, T, n + 1).round().astype(int)
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def realistic_masks(vertices_of, T: int, body: BodyModel, azimuth_deg: float, height_m: float,
                    plates, rng: np.random.Generator, config: SceneConfig = SceneConfig(),
                    mask_size: tuple[int, int] = (224, 224), on_clip=None
                    ) -> tuple[np.ndarray, dict]:
    """Training masks (T, H, W) bool of one sequence made the realistic way (module docstring).

    vertices_of(start, stop) -> posed vertices (stop - start, V, 3) metres; azimuth_deg: the
    view's world azimuth; height_m: the body's standing height; plates: (image, inpainted)
    pairs (sequences.backgrounds). One camera, look and room per sequence; each clip of at most
    config.clip_frames is encoded and primed on its own. A frame where the extractor finds no
    one gets its plain mask. on_clip(decoded frames (n, H, W, 3) BGR uint8, first frame index),
    when given, sees each clip as the extractor does (e.g. to write it as a video).
    Returns (masks on mask_size canvases (on_canvas), info: the camera (scene_camera's dict),
    'fallback' frames, 'iou' (T,) of each frame's extracted mask with its plain mask in the
    frame, 'area' (T,) its area over the plain mask's)."""
    from .backgrounds import background_view
    parts = body_parts(body)
    view = scene_camera(rng, config)
    look = sample_look(rng)
    background = background_view(plates, config.frame_size, rng)
    masks = np.empty((T, *mask_size), bool)
    iou, area = np.zeros(T), np.zeros(T)
    fallback = 0
    for start, stop in clip_bounds(T, config.clip_frames):
        frames, plain = film_clip(vertices_of(start, stop), body, parts, view, azimuth_deg,
                                  height_m, background, look, rng, config)
        decoded = h264_round_trip(frames, look.crf, config.fps)
        if on_clip is not None:
            on_clip(decoded, start)
        people = extract_people(decoded)
        for i, person in enumerate(people):
            found = in_frame(person, config.frame_size)
            union = (found | plain[i]).sum()
            iou[start + i] = (found & plain[i]).sum() / union if union else 0.0
            area[start + i] = found.sum() / max(plain[i].sum(), 1)
            if person is None:
                fallback += 1
                found = plain[i]
            masks[start + i] = on_canvas(found, mask_size)
    return masks, {**view, "fallback": fallback, "iou": iou, "area": area}


def write_video(path, frames: np.ndarray, crf: int = 12, fps: float = 30.0) -> None:
    """frames (T, H, W, 3) BGR uint8 written as an H.264 MP4 at path (libx264, yuv420p)."""
    T, H, W, _ = frames.shape
    command = [ffmpeg_exe(), "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "bgr24",
               "-s", f"{W}x{H}", "-r", f"{fps:g}", "-i", "-", "-c:v", "libx264", "-preset",
               "veryfast", "-crf", str(int(crf)), "-pix_fmt", "yuv420p", str(path)]
    run = subprocess.run(command, input=np.ascontiguousarray(frames).tobytes(),
                         capture_output=True)
    if run.returncode:
        raise SceneRenderError(f"ffmpeg could not write {path}: "
                               f"{run.stderr.decode(errors='replace').strip()}")
