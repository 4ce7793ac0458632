"""Model files: one versioned, checksummed .npz of plain arrays (no pickle), validated on load.

Known parts (PART_KINDS) are checked for kind, shape, consistency and finite values when
present; others are returned as they are. The checksum (sha256 over every part's name, dtype,
shape and bytes) catches accidents, not tampering: loading never runs code from a file.
"""
from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from .errors import SilhouettePoseError

#: 2: a mixture's experts may be sparse RVMs (mixture_expert_* parts); 1 still loads.
FORMAT_VERSION = 2
SUPPORTED_VERSIONS = (1, 2)
_RESERVED = ("format_version", "checksum")
_KIND_NAMES = {"fiu": "numbers", "iu": "whole numbers", "b": "a boolean", "U": "text"}
BASIS_KINDS = ("linear", "gaussian")
#: The numpy dtype kinds each named part may have (read as another kind, "False" would become
#: True and 300.7 300); the limb network and side classifier check their own parts.
_FLOAT_PARTS = (
    "codebook_centres", "codebook_sigma", "descriptor_r_inner", "descriptor_r_outer",
    "descriptor_total", "width", "centres", "coef", "intercept", "angle_centre_deg",
    "measurement_covariance", "process_noise", "ambiguity_threshold", "layout_weight",
    "projection", "projection_mean", "canonical_direction", "mixture_expert_width",
    "mixture_expert_intercept", "mixture_partition_centres", "mixture_gate_centres",
    "mixture_gate_width", "mixture_gate_feature_mean", "mixture_gate_feature_std",
    "mixture_gate_weights", "heading_index_inputs", "heading_index_folded_deg",
    "heading_index_limit_deg", "heading_index_typical_distance", "mixture_expert_sigma",
    "mixture_expert_phi_mean", "mixture_expert_beta", "mixture_expert_y_scale",
    "mixture_variance_calibration")
_INTEGER_PARTS = (
    "descriptor_n_points", "descriptor_n_angular", "descriptor_n_radial", "descriptor_n_votes",
    "stack_depth", "relevance", "layout_grid", "mixture_expert_offsets", "mixture_top_experts",
    "heading_index_k", "mixture_expert_rows")
PART_KINDS = {**{name: "fiu" for name in _FLOAT_PARTS}, **{name: "iu" for name in _INTEGER_PARTS},
              "descriptor_include_holes": "b",
              **{name: "U" for name in ("model_kind", "transform", "basis", "description",
                                        "mixture_params", "mixture_expert_kind")}}


class ModelFileError(SilhouettePoseError, ValueError):
    """A model file (or the parts given to save_model) failed validation; names the file."""


@dataclass(frozen=True)
class ModelFile:
    """A loaded model file: ``parts`` maps every stored name (but _RESERVED) to its array."""

    path: str
    format_version: int
    parts: dict = field(repr=False)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.parts[name]

    def __contains__(self, name: str) -> bool:
        return name in self.parts

    def get(self, name: str, default=None):
        return self.parts.get(name, default)

    def keys(self):
        return self.parts.keys()


def checksum(parts: Mapping[str, np.ndarray]) -> str:
    """sha256 hex digest over the parts' names, dtypes, shapes and bytes, in name order."""
    h = hashlib.sha256()
    for name in sorted(parts):
        a = np.ascontiguousarray(parts[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def load_model(path: str | Path) -> ModelFile:
    """Read and validate a model file; ModelFileError naming the file and the problem if the
    file is missing, not an .npz, pickled, from an unsupported version, altered (checksum) or
    inconsistent."""
    where = str(path)
    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
    except FileNotFoundError:
        raise ModelFileError(f"{where}: model file not found") from None
    except OSError as exc:
        raise ModelFileError(f"{where}: cannot read the model file ({exc.strerror})") from None
    if magic != b"PK\x03\x04":          # every .npz is a zip archive
        raise ModelFileError(f"{where}: not a model file (a model is an .npz archive written "
                             f"by save_model; this file is not an .npz at all)")
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {k: npz[k] for k in npz.files}
    except FileNotFoundError:
        raise ModelFileError(f"{where}: model file not found") from None
    except (zipfile.BadZipFile, OSError, EOFError, ValueError) as exc:
        raise ModelFileError(f"{where}: not a readable model file ({exc})") from None
    except MemoryError:                 # a part whose header declares an absurd size
        raise ModelFileError(f"{where}: not a readable model file (a part declares more data "
                             f"than fits in memory)") from None
    foreign = [k for k, a in arrays.items() if not isinstance(a, np.ndarray)]
    if foreign:       # np.load gives a member that is not an .npy array as its raw bytes
        raise ModelFileError(f"{where}: not a model file: member {foreign[0]!r} of the archive "
                             f"is not an array")
    if "format_version" not in arrays:
        raise ModelFileError(f"{where}: no format_version; not a model file")
    version = arrays.pop("format_version")
    if version.shape != () or version.dtype.kind not in "iu" or int(version) not in SUPPORTED_VERSIONS:
        raise ModelFileError(f"{where}: format version {version!r} is not supported (supported: {SUPPORTED_VERSIONS})")
    stored = arrays.pop("checksum", None)
    if stored is None:
        raise ModelFileError(f"{where}: no checksum; refusing an unverifiable model file")
    if str(stored) != checksum(arrays):
        raise ModelFileError(f"{where}: checksum mismatch: the file was damaged or changed after "
                             f"it was saved (the checksum catches accidents, not deliberate "
                             f"tampering; use model files only from sources you trust)")
    for k, a in arrays.items():
        if a.dtype.kind not in "biufU":
            raise ModelFileError(f"{where}: part {k!r} has dtype {a.dtype}")
    _validate(where, arrays)
    return ModelFile(where, int(version), arrays)


def _validate(where: str, p: Mapping[str, np.ndarray]) -> None:
    """Check the known parts that are present; raise ModelFileError on the first problem."""
    def fail(problem: str):
        raise ModelFileError(f"{where}: invalid model: {problem}")

    def need(name: str, ndim: int, kinds: str = "f") -> np.ndarray | None:
        a = p.get(name)
        if a is None:
            return None
        if a.ndim != ndim or a.dtype.kind not in kinds:
            fail(f"{name} must be a {ndim}-D array of kind {kinds!r}; got shape {a.shape} dtype {a.dtype}")
        return a

    for name, kinds in PART_KINDS.items():
        if name in p and p[name].dtype.kind not in kinds:
            fail(f"{name} is stored as {p[name].dtype}, not as {_KIND_NAMES[kinds]}")
    basis = need("basis", 0, "U")
    if basis is not None and str(basis) not in BASIS_KINDS:
        fail(f"basis {str(basis)!r} is not one of {BASIS_KINDS}")
    for name, a in p.items():  # finite floats everywhere (width may be NaN for a linear basis)
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            if not (name == "width" and basis is not None and str(basis) == "linear" and np.isnan(a).all()):
                fail(f"{name} has NaN or infinite values")
    k = need("stack_depth", 0, "iu")
    if k is not None and int(k) < 1:
        fail(f"stack_depth {int(k)} must be >= 1")
    need("transform", 0, "U")
    width = need("width", 0, "f")
    if width is not None and basis is not None and str(basis) == "gaussian" and not float(width) > 0:
        fail(f"kernel width {float(width)} must be > 0")
    coef, intercept = need("coef", 2), need("intercept", 1)
    R = None if coef is None else coef.shape[0]
    K = None if coef is None else coef.shape[1]
    if intercept is not None and K is not None and intercept.shape != (K,):
        fail(f"intercept {intercept.shape} does not match coef {coef.shape}")
    relevance = need("relevance", 1, "iu")
    if relevance is not None:
        if R is not None and relevance.shape != (R,):
            fail(f"relevance {relevance.shape} does not match coef {coef.shape}")
        if relevance.size and relevance.min() < 0:
            fail("relevance has negative indices")
    centres = need("centres", 2)
    if centres is not None and centres.size and R is not None and centres.shape[0] != R:
        fail(f"centres {centres.shape} does not match coef {coef.shape}")
    if basis is not None and str(basis) == "gaussian" and coef is not None and (centres is None or centres.shape[0] != R):
        fail("a Gaussian basis needs one centre per weight row")
    _validate_input_shapes(need, fail, k, centres)
    direction = need("canonical_direction", 1)
    if direction is not None and (direction.shape != (55,) or not np.linalg.norm(direction) > 0):
        fail(f"canonical_direction must be 55 values, not all zero; got shape {direction.shape}")
    _validate_noise(p, fail)
    desc = need("description", 0, "U")
    if desc is not None:
        try:
            json.loads(str(desc))
        except json.JSONDecodeError as exc:
            fail(f"description is not JSON ({exc})")
    for name, a in p.items():
        if name.startswith("descriptor_") and a.shape != ():
            fail(f"descriptor setting {name} must be a single number or string; got shape {a.shape}")


def _validate_input_shapes(need, fail, k, centres) -> None:
    """The codebook, layout and projection agree with the stacking depth k and the kernel
    centres (need, fail: _validate's part getter and failure)."""
    cb = need("codebook_centres", 2)
    sigma = need("codebook_sigma", 0)
    if sigma is not None and not float(sigma) > 0:
        fail("codebook_sigma must be > 0")
    grid = need("layout_grid", 0, "iu")
    layout = 0 if grid is None else int(grid) ** 2
    projection = need("projection", 2)
    if projection is not None and cb is not None and k is not None and \
            projection.shape[0] != int(k) * (cb.shape[0] + layout):
        fail(f"projection has {projection.shape[0]} rows; stack_depth {int(k)} x "
             f"({cb.shape[0]} codebook centres + {layout} layout cells) expected")
    if centres is not None and centres.size and projection is not None and \
            centres.shape[1] != projection.shape[1]:
        fail(f"centres have {centres.shape[1]} columns; the projection gives {projection.shape[1]}")
    if centres is not None and centres.size and projection is None and cb is not None and \
            k is not None and centres.shape[1] != int(k) * (cb.shape[0] + layout):
        fail(f"centres have {centres.shape[1]} columns; stack_depth {int(k)} x "
             f"({cb.shape[0]} codebook centres + {layout} layout cells) expected")


def _validate_noise(p: Mapping[str, np.ndarray], fail) -> None:
    R = p.get("measurement_covariance")
    if R is not None:
        if R.dtype.kind != "f" or R.ndim not in (1, 2) or (R.ndim == 2 and R.shape[0] != R.shape[1]):
            fail(f"measurement_covariance must be (P, P) or (P,) floats; got {R.shape} {R.dtype}")
        if R.ndim == 2 and not np.allclose(R, R.T, rtol=1e-9, atol=1e-12 * max(1.0, float(np.abs(R).max(initial=0)))):
            fail("measurement_covariance is not symmetric")
        if (np.diag(R) if R.ndim == 2 else R).min(initial=1.0) <= 0:
            fail("measurement_covariance has non-positive variances")
    q = p.get("process_noise")
    if q is not None:
        if q.dtype.kind != "f" or q.ndim > 2:
            fail(f"process_noise must be a float scalar, (P,) or (P, P); got {q.shape} {q.dtype}")
        if (np.diag(q) if q.ndim == 2 else q).min(initial=0.0) < 0:
            fail("process_noise has negative variances")
        if R is not None and q.ndim >= 1 and q.shape[0] != R.shape[0]:
            fail(f"process_noise {q.shape} and measurement_covariance {R.shape} disagree on P")
