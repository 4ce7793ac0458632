"""A trained pose model: silhouette -> descriptor -> stacked descriptors -> 55-D pose.

Everything the tracker needs from training, in one object and one file: descriptor settings
and codebook, the descriptor transform, the stacking depth k, the regressor (basis kind,
kernel width, retained centres, weights, offset), the angle centres the regressor was trained
around, the Kalman filter's noise models, and a description of the training data.

Angles are regressed around per-angle centres (their circular means on the training data):
the regressor predicts wrap(angle - centre), so an angle whose range straddles +-180 degrees
(shoulders, in Euler angles) is continuous for the regressor. predict() adds the centres back
and wraps to (-180, 180].

Output layout is the pose vector's (regressor/angles.py; sequences/pose_vector.py documents it):
[cos, sin] of the heading, then 53 angles in degrees.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .angles import N_ANGLES, POSE_DIM, wrap_deg
from .basis import gaussian_design
from .codebook import Codebook, CodebookError
from .descriptor import DescriptorSettings, DescriptorSettingsError, descriptor_for_mask
from .model_file import ModelFileError, load_model, save_model
from .errors import SilhouettePoseError

DEFAULT_MODEL_PATH = Path(__file__).resolve().parent / "models" / "default_model.npz"
TRANSFORMS = ("none", "sqrt")      # sqrt: Hellinger-like, tames the dominant histogram bins
MODEL_KIND = "silhouette-pose"
#: Raw heading norm below which a frame is ambiguous, for model files that do not store the
#: threshold they were trained with (all written before it was stored used this value).
DEFAULT_AMBIGUITY_THRESHOLD = 0.5


class PoseModelError(SilhouettePoseError, ValueError):
    """A model file that is missing, unreadable, tampered with or inconsistent."""


@dataclass
class PoseModel:
    """A trained model (see the module docstring). Shapes: D = codebook.n_centres descriptor
    length, k = stack_depth, R retained basis functions.

    centres: (R, k*D) kernel centres (Gaussian basis) or None (linear basis, then relevance:
    (R,) kept feature indices); width: kernel width; coef: (R, 55); intercept: (55,);
    angle_centre_deg: (53,); measurement_covariance: (54, 54) deg^2 (filter R, angle order:
    heading then the 53 angles); process_noise: (54,) (deg/s^2)^2 (filter q);
    ambiguity_threshold: raw heading norm below which a frame counts as ambiguous, as used to
    estimate measurement_covariance (the tracker uses it unless told otherwise).
    """

    settings: DescriptorSettings
    codebook: Codebook
    stack_depth: int
    transform: str
    basis: str
    width: float | None
    centres: np.ndarray | None
    relevance: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    angle_centre_deg: np.ndarray
    measurement_covariance: np.ndarray
    process_noise: np.ndarray
    ambiguity_threshold: float = DEFAULT_AMBIGUITY_THRESHOLD
    description: dict = field(default_factory=dict)

    @property
    def descriptor_length(self) -> int:
        """D, the length of one frame's descriptor."""
        return self.codebook.n_centres

    def describe(self, mask: np.ndarray) -> np.ndarray:
        """Transformed descriptor (D,) of a silhouette mask (H, W) bool. Raises
        regressor.edges.SilhouetteError (DegenerateSilhouetteError) for unusable masks."""
        return transform_descriptors(descriptor_for_mask(mask, self.settings, self.codebook),
                                     self.transform)

    def predict(self, stacked: np.ndarray) -> np.ndarray:
        """Raw pose (55,) from one stacked, transformed descriptor (k*D,)."""
        return self.predict_batch(np.asarray(stacked, dtype=np.float64)[None])[0]

    def predict_batch(self, stacked: np.ndarray) -> np.ndarray:
        """Raw poses (N, 55) from stacked, transformed descriptors (N, k*D)."""
        X = np.asarray(stacked, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != self.stack_depth * self.descriptor_length:
            raise PoseModelError(f"stacked descriptors must be (N, {self.stack_depth} x "
                                 f"{self.descriptor_length}), got {X.shape}")
        if self.basis == "gaussian":
            Phi = gaussian_design(X, self.centres, self.width)
        else:
            Phi = X[:, self.relevance]
        Y = Phi @ self.coef + self.intercept
        Y[:, 2:] = wrap_deg(Y[:, 2:] + self.angle_centre_deg)
        return Y

    def summary(self) -> dict:
        """Plain facts for metadata and logs."""
        return {"basis": self.basis, "n_basis": int(len(self.coef)),
                "stack_depth": self.stack_depth, "transform": self.transform,
                "training": self.description}


def transform_descriptors(X: np.ndarray, transform: str) -> np.ndarray:
    """Descriptors (..., D) -> transformed for regression ("none" or "sqrt")."""
    if transform == "sqrt":
        return np.sqrt(np.maximum(X, 0.0))
    return np.asarray(X, dtype=np.float64)


def save_pose_model(path: str | Path, model: PoseModel) -> None:
    """Write the model as one versioned, checksummed .npz (no pickle)."""
    arrays = {
        **model.codebook.to_arrays(), **model.settings.to_arrays(),
        "model_kind": np.str_(MODEL_KIND),
        "stack_depth": np.int64(model.stack_depth),
        "transform": np.str_(model.transform), "basis": np.str_(model.basis),
        "width": np.float64(np.nan if model.width is None else model.width),
        "centres": (np.zeros((0, 0)) if model.centres is None else model.centres),
        "relevance": np.asarray(model.relevance, dtype=np.int64),
        "coef": model.coef, "intercept": model.intercept,
        "angle_centre_deg": model.angle_centre_deg,
        "measurement_covariance": model.measurement_covariance,
        "process_noise": model.process_noise,
        "ambiguity_threshold": np.float64(model.ambiguity_threshold),
        "description": np.str_(json.dumps(model.description, sort_keys=True)),
    }
    save_model(path, arrays)


def load_pose_model(path: str | Path = DEFAULT_MODEL_PATH) -> PoseModel:
    """Read and validate a model file; PoseModelError (one line, naming the file) if it is
    missing, not a model, from another version, tampered with, or inconsistent."""
    path = Path(path)
    try:
        a = load_model(path)
        if str(a.get("model_kind", "")) != MODEL_KIND:
            raise PoseModelError(f"{path}: not a silhouette-pose model file")
        settings = DescriptorSettings.from_arrays(a)
        codebook = Codebook.from_arrays(a)
        model = PoseModel(
            settings=settings, codebook=codebook, stack_depth=int(a["stack_depth"]),
            transform=str(a["transform"]), basis=str(a["basis"]),
            width=None if np.isnan(a["width"]) else float(a["width"]),
            centres=None if a["centres"].size == 0 else a["centres"].astype(np.float64),
            relevance=a["relevance"].astype(np.int64), coef=a["coef"].astype(np.float64),
            intercept=a["intercept"].astype(np.float64),
            angle_centre_deg=a["angle_centre_deg"].astype(np.float64),
            measurement_covariance=a["measurement_covariance"].astype(np.float64),
            process_noise=a["process_noise"].astype(np.float64),
            ambiguity_threshold=float(a.get("ambiguity_threshold", DEFAULT_AMBIGUITY_THRESHOLD)),
            description=json.loads(str(a["description"])))
    except PoseModelError:
        raise
    except ModelFileError as exc:
        raise PoseModelError(str(exc)) from exc
    except (KeyError, ValueError, TypeError, CodebookError, DescriptorSettingsError) as exc:
        raise PoseModelError(f"{path}: malformed model file ({exc})") from exc
    _validate(path, model)
    return model


def _validate(path: Path, m: PoseModel) -> None:
    D, k = m.descriptor_length, m.stack_depth
    R = len(m.coef)
    checks = [
        (1 <= k <= 16, f"stack depth {k} out of range 1..16"),
        (m.transform in TRANSFORMS, f"unknown descriptor transform {m.transform!r}"),
        (m.basis in ("gaussian", "linear"), f"unknown basis {m.basis!r}"),
        (m.coef.ndim == 2 and m.coef.shape[1] == POSE_DIM and R >= 1,
         f"weights must be (R, {POSE_DIM}), got {m.coef.shape}"),
        (m.intercept.shape == (POSE_DIM,), f"offset must be ({POSE_DIM},)"),
        (m.angle_centre_deg.shape == (POSE_DIM - 2,), "angle centres must be (53,)"),
        (m.measurement_covariance.shape == (N_ANGLES, N_ANGLES),
         "measurement covariance must be (54, 54)"),
        (m.process_noise.shape == (N_ANGLES,), "process noise must be (54,)"),
    ]
    if m.basis == "gaussian":
        checks += [(m.centres is not None and m.centres.shape == (R, k * D),
                    f"kernel centres must be ({R}, {k * D})"),
                   (m.width is not None and m.width > 0, "kernel width must be > 0")]
    else:
        checks += [(m.relevance.shape == (R,) and m.relevance.min() >= 0
                    and m.relevance.max() < k * D, "kept features out of range")]
    arrays = [m.coef, m.intercept, m.angle_centre_deg, m.measurement_covariance, m.process_noise]
    if m.centres is not None:
        arrays.append(m.centres)
    checks.append((all(np.isfinite(x).all() for x in arrays), "non-finite values"))
    checks.append((0.0 <= m.ambiguity_threshold <= 1.0, "ambiguity threshold must be in [0, 1]"))
    for ok, problem in checks:
        if not ok:
            raise PoseModelError(f"{path}: invalid model: {problem}")
    if np.any(np.linalg.eigvalsh(m.measurement_covariance) <= 0) or np.any(m.process_noise < 0):
        raise PoseModelError(f"{path}: invalid model: noise models are not positive")
