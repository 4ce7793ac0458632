"""How far the tracker's front/back chain (tracker.tracks.hypotheses) trusts one model's
canonical pair (issue 10): how often the truer of the limbs' member and its flip changes per
frame, and how right the side classifier is at each of its probabilities, learned on
validation renders (lab.hypothesis_priors). Parts "canonical_prior_" (float64).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PREFIX = "canonical_prior_"
PARTS = ("switch", "front_edges", "by_front", "overall")
#: Parts of mechanisms since removed (docs/ablation.md): older model files carry them; ignored.
_REMOVED_PARTS = ("raw_side_edges", "raw_side_by_norm", "raw_side_overall")


@dataclass(frozen=True)
class CanonicalPriors:
    """switch: (P(canonical -> flip), P(flip -> canonical)) per frame, how often the truer
    member changes. by_front (C,): P(the canonical member is the true one | the side
    classifier's probability for that member in [front_edges[c], next edge)); overall: the
    same over all frames. Table probabilities in [0, 1]; the switch and overall rates
    strictly between 0 and 1; edges increasing from 0 and below 1."""

    switch: tuple[float, float]
    front_edges: tuple[float, ...]
    by_front: tuple[float, ...]
    overall: float

    def __post_init__(self):
        for name in ("switch", "front_edges", "by_front"):
            values = np.asarray(getattr(self, name), dtype=np.float64)
            if values.ndim != 1:
                raise ValueError(f"invalid canonical priors: {name} must be a list of numbers")
            object.__setattr__(self, name, tuple(float(v) for v in values))
        object.__setattr__(self, "overall", float(self.overall))
        problem = self._problem()
        if problem:
            raise ValueError(f"invalid canonical priors: {problem}")

    def _problem(self) -> str | None:
        """The first inconsistency, or None."""
        values = [*self.switch, *self.front_edges, *self.by_front, self.overall]
        if not np.isfinite(values).all():
            return "non-finite values"
        if len(self.switch) != 2 or not all(0.0 < p < 1.0 for p in self.switch):
            # 0 would make the flip state unreachable, 1 a certain switch every frame
            return f"switch must be two probabilities strictly between 0 and 1, got " \
                   f"{self.switch}"
        edges, table = self.front_edges, self.by_front
        if len(edges) < 1 or len(table) != len(edges):
            return f"the front table needs one value per edge ({len(edges)} edges, " \
                   f"{len(table)} values)"
        if edges[0] != 0.0 or np.any(np.diff(edges) <= 0):
            return f"the front edges must increase from 0, got {edges}"
        if not all(0.0 <= p <= 1.0 for p in table):
            return f"the front table must hold probabilities, got {table}"
        if edges[-1] >= 1.0:
            return f"the front edges bin a probability: they must stay below 1, got {edges}"
        if not 0.0 < self.overall < 1.0:
            return "the overall rate must be strictly between 0 and 1"
        return None

    @classmethod
    def from_arrays(cls, a) -> "CanonicalPriors | None":
        """The priors in a file's parts a (mapping), None when it has none; ValueError when
        they are incomplete, carry an unknown part (but _REMOVED_PARTS) or are inconsistent."""
        present = sorted(str(k) for k in a.keys() if str(k).startswith(PREFIX))
        if not present:
            return None
        needed = [f"{PREFIX}{name}" for name in PARTS]
        missing = [k for k in needed if k not in present]
        if missing:
            raise ValueError(f"canonical priors are incomplete (no {missing[0]})")
        removed = [f"{PREFIX}{name}" for name in _REMOVED_PARTS]
        extra = [k for k in present if k not in needed and k not in removed]
        if extra:
            raise ValueError(f"canonical priors have an unknown part ({extra[0]})")
        arrays = {}
        for name in PARTS:
            v = np.asarray(a[f"{PREFIX}{name}"])
            if v.dtype.kind != "f":
                raise ValueError(f"canonical prior {name} must hold floats, not {v.dtype}")
            if (v.ndim != 0) != (name != "overall"):
                raise ValueError(f"canonical prior {name} has shape {v.shape}")
            arrays[name] = v
        return cls(**arrays)
