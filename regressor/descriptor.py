"""Silhouette descriptor: mask -> edge points -> shape contexts -> soft histogram on a codebook
(Agarwal & Triggs, CVPR 2004, section 2). Many masks at once: regressor.descriptor_batch.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
import numpy as np

from regressor.codebook import Codebook, CodebookError, soft_histogram, soft_histograms
from regressor.edges import DegenerateSilhouetteError, SilhouetteError, sample_edge_points
from regressor.shape_context import mirrored_bins, shape_contexts

from .errors import SilhouettePoseError

__all__ = ["Codebook", "CodebookError", "DegenerateSilhouetteError", "DescriptorSettings",
           "DescriptorSettingsError", "SilhouetteError", "descriptor_and_mirror",
           "descriptor_for_mask", "mask_contexts"]

class DescriptorSettingsError(SilhouettePoseError, ValueError):
    """A descriptor setting is out of range, or stored settings are malformed."""


#: At most this many points sampled along a silhouette's edge (DescriptorSettings.n_points).
MAX_EDGE_POINTS = 4096


@dataclass(frozen=True)
class DescriptorSettings:
    """How a silhouette becomes a descriptor (everything but the codebook). n_points: edge
    points at equal arc length; include_holes: also the holes' boundaries; n_angular, n_radial:
    shape context sectors and rings; r_inner, r_outer: the innermost / outermost ring in units
    of the RMS distance between edge points (about 0.38 of a standing person's height: r_outer
    = 3 spans the body from any point, r_inner = 1/8 is about a limb's width); n_votes: nearest
    codebook centres each context votes into; total: the descriptor's sum (100, the scale of
    the paper's released data)."""

    n_points: int = 300
    include_holes: bool = False
    n_angular: int = 12
    n_radial: int = 5
    r_inner: float = 0.125
    r_outer: float = 3.0
    n_votes: int = 5
    total: float = 100.0

    def __post_init__(self) -> None:
        # Upper bounds far above any useful value: the contexts of n points take n^2 memory
        # (4,096 points: 134 MB), so a model file asking for 10^12 is refused, not run.
        checks = {
            "n_points": 10 <= self.n_points <= MAX_EDGE_POINTS,
            "n_angular": 1 <= self.n_angular <= 360,
            "n_radial": 1 <= self.n_radial <= 100,
            "r_inner": 0 < self.r_inner,
            "r_outer": self.r_inner < self.r_outer < 1e6,    # named on its own (it said r_inner)
            "n_votes": 1 <= self.n_votes <= 10_000,
            "total": 0 < self.total < 1e12,
        }
        for name, ok in checks.items():
            if not ok:
                why = (f" (it must exceed r_inner={self.r_inner!r} and stay under 1e6)"
                       if name == "r_outer" else "")
                raise DescriptorSettingsError(f"descriptor setting {name}={getattr(self, name)!r} "
                                              f"is out of range{why}")

    @property
    def context_size(self) -> int:
        """Length of one shape context, n_radial * n_angular."""
        return self.n_radial * self.n_angular

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "descriptor_") -> "DescriptorSettings":
        """Rebuild from regressor.model_writer.settings_arrays' mapping (e.g. an NpzFile);
        validates every field."""
        values = {}
        for f in fields(cls):
            key = prefix + f.name
            if key not in arrays:
                raise DescriptorSettingsError(f"descriptor settings missing {key}")
            value = np.asarray(arrays[key])
            if value.shape != ():
                raise DescriptorSettingsError(f"{key} must be a scalar, got shape {value.shape}")
            # The stored kind must be the field's: bool("False") is True, int(300.7) 300.
            kinds, convert = {"int": ("iu", int), "bool": ("b", bool),
                              "float": ("fiu", float)}[f.type]
            if value.dtype.kind not in kinds:
                raise DescriptorSettingsError(f"{key} must be {f.type}, got {value.dtype} "
                                              f"{value.item()!r}")
            values[f.name] = convert(value.item())
        return cls(**values)


def mask_contexts(mask: np.ndarray, settings: DescriptorSettings) -> np.ndarray:
    """Shape contexts (settings.n_points, settings.context_size) float64, rows summing to 1, of
    the edge points of mask (H, W) bool/integer (nonzero = person). Raises
    DegenerateSilhouetteError for an empty, tiny or line-like silhouette."""
    points = sample_edge_points(mask, settings.n_points, settings.include_holes)
    return shape_contexts(points, settings.n_angular, settings.n_radial, settings.r_inner, settings.r_outer)


def check_codebook(settings: DescriptorSettings, codebook: Codebook) -> None:
    if codebook.centres.shape[1] != settings.context_size:
        raise CodebookError(
            f"codebook centres have {codebook.centres.shape[1]} columns but the settings give "
            f"{settings.context_size}-bin shape contexts ({settings.n_radial} x {settings.n_angular})"
        )


def descriptor_for_mask(mask: np.ndarray, settings: DescriptorSettings, codebook: Codebook) -> np.ndarray:
    """The histogram-of-shape-contexts descriptor (K,) float64 (K = codebook.n_centres, summing
    to settings.total) of a silhouette mask (H, W). Raises as mask_contexts."""
    check_codebook(settings, codebook)
    return soft_histogram(mask_contexts(mask, settings), codebook, settings.n_votes, settings.total)


def descriptor_and_mirror(mask: np.ndarray, settings: DescriptorSettings,
                          codebook: Codebook) -> tuple[np.ndarray, np.ndarray]:
    """(descriptor_for_mask(mask), the descriptor of the mask flipped left to right), (K,)
    float64 each: the mask's own contexts with their sectors reflected (mirrored_bins; the
    flipped mask's own differs only by where the edge sampling starts); with an odd number of
    sectors the flipped mask is described. Raises as mask_contexts."""
    check_codebook(settings, codebook)
    try:
        order = mirrored_bins(settings.n_angular, settings.n_radial)
    except ValueError:
        return (descriptor_for_mask(mask, settings, codebook),
                descriptor_for_mask(np.asarray(mask)[:, ::-1], settings, codebook))
    contexts = mask_contexts(mask, settings)
    own, mirror = soft_histograms((contexts, contexts[:, order]), codebook, settings.n_votes,
                                  settings.total)
    return own, mirror
