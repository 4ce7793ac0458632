"""The limbs by an ensemble of small neural networks on the regressor's input (issue 9): each
silhouette's canonical body (sequences.pose_conversions.canonical_member). Plain arrays (no
pickle): ReLU hidden layers, a linear output; seeded networks differ, so several are averaged
(why: docs/code_notes/regress.md). The output width says what they give: the pose vector's 55
values (the 53 angles as wrapped offsets from angle_centre_deg) or ROT6D_OUTPUTS values (the
heading's (cos, sin), the root's two tilts as such offsets, 6 per joint: regressor.rotation6d).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .angles import POSE_DIM, wrap_deg
from .relu_layers import (as_float32_layers, check_parts, dequantised_int8, forward,
                          standardised, typical_inputs)

PREFIX = "limb_net_"        # the file parts' names
MAX_MEMBERS, MAX_LAYERS = 16, 8
#: The networks' outputs with 6-D rotations: (cos, sin), then regressor.rotation6d's
#: ROT6D_LENGTH values (the root's two tilts, 6 for each of the 17 joints).
ROT6D_OUTPUTS = 2 + 2 + 6 * 17
#: regressor.limb_net_training.fit_limb_net's target representations -> the networks' output width.
OUTPUT_WIDTHS = {"euler": POSE_DIM, "rot6d": ROT6D_OUTPUTS}


@dataclass
class LimbNet:
    """members: per network, its layers [(W (n_in, n_out), b (n_out,)), ...]; the output is
    the members' mean. input_mean (P,), input_scale (scalar) standardise the regressor's input
    X (N, P); output_mean, output_scale (O,) undo the targets' (O = 55 or ROT6D_OUTPUTS);
    angle_centre_deg (53,); canonical_direction (55,): the rule the targets' members were
    chosen by (sequences.pose_conversions.canonical_member)."""

    members: list[list[tuple[np.ndarray, np.ndarray]]]
    input_mean: np.ndarray
    input_scale: float
    output_mean: np.ndarray
    output_scale: np.ndarray
    angle_centre_deg: np.ndarray
    canonical_direction: np.ndarray

    def __post_init__(self):
        self.members = [as_float32_layers(layers, "limb network") for layers in self.members]
        self.input_mean = np.asarray(self.input_mean, dtype=np.float64)
        self.input_scale = float(self.input_scale)
        self.output_mean = np.asarray(self.output_mean, dtype=np.float64)
        self.output_scale = np.asarray(self.output_scale, dtype=np.float64)
        self.angle_centre_deg = np.asarray(self.angle_centre_deg, dtype=np.float64)
        self.canonical_direction = np.asarray(self.canonical_direction, dtype=np.float64)
        problem = self._problem()
        if problem:
            raise ValueError(f"invalid limb network: {problem}")

    def _problem(self) -> str | None:
        """The first inconsistency of the parts, or None."""
        if not self.members or not all(self.members):
            return "no members or a member without layers"
        if len(self.members) > MAX_MEMBERS \
                or any(len(layers) != len(self.members[0]) for layers in self.members) \
                or len(self.members[0]) > MAX_LAYERS:
            return (f"members must be 1..{MAX_MEMBERS} networks of the same 1..{MAX_LAYERS} "
                    f"layers")
        if self.input_mean.ndim != 1 or len(self.input_mean) < 1:
            return f"input mean has shape {self.input_mean.shape}"
        for m, layers in enumerate(self.members):
            n_in = len(self.input_mean)
            for i, (W, b) in enumerate(layers):
                if W.ndim != 2 or W.shape[0] != n_in or b.shape != (W.shape[1],):
                    return (f"member {m} layer {i} has shape {W.shape} / {b.shape} after "
                            f"{n_in} values")
                n_in = W.shape[1]
            if n_in not in OUTPUT_WIDTHS.values() or n_in != self.output_width:
                return (f"member {m} gives {n_in} values, not "
                        f"{' or '.join(map(str, sorted(OUTPUT_WIDTHS.values())))}"
                        + ("" if m == 0 else " as member 0"))
        width = self.output_width
        if self.output_mean.shape != (width,) or self.output_scale.shape != (width,) \
                or self.angle_centre_deg.shape != (POSE_DIM - 2,) \
                or self.canonical_direction.shape != (POSE_DIM,):
            return (f"output parts do not have {width} values (53 centres, a direction of "
                    f"{POSE_DIM})")
        arrays = [self.input_mean, self.output_mean, self.output_scale, self.angle_centre_deg,
                  self.canonical_direction,
                  *(a for layers in self.members for layer in layers for a in layer)]
        if not all(np.isfinite(a).all() for a in arrays) or not np.isfinite(self.input_scale):
            return "non-finite values"
        if not (self.input_scale > 0 and np.all(self.output_scale > 0)):
            return "scales must be positive"
        if np.any(np.abs(self.angle_centre_deg) > 180.0) \
                or not abs(np.linalg.norm(self.canonical_direction) - 1) < 1e-6:
            return "centres must be angles in [-180, 180] and the direction a unit vector"
        # absurd but finite parts (a tiny scale, a huge mean) overflow on typical inputs
        with np.errstate(all="ignore"):
            if not np.isfinite(self.predict(typical_inputs(self.input_mean))).all():
                return "it gives non-finite poses"
        return None

    @cached_property
    def _stacked(self) -> list | None:
        """The members as one batched stack for predict on one row (a copy; members stay as
        they are), or None when their shapes differ (regressor.relu_stacked)."""
        from .relu_stacked import stacked_members
        return stacked_members(self.members)

    @property
    def output_width(self) -> int:
        """The networks' output width: 55 (Euler angles) or ROT6D_OUTPUTS (6-D rotations)."""
        return int(self.members[0][-1][0].shape[1])

    @property
    def input_length(self) -> int:
        """P, the length of the regressor's input the network takes."""
        return len(self.input_mean)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Canonical poses (N, 55) from the regressor's inputs X (N, P): (cos, sin) of the
        heading, then the 53 body angles in degrees wrapped to (-180, 180]."""
        x = standardised(X, self.input_mean, self.input_scale)
        # batched for one row; for many, one member at a time is faster and holds less
        if len(x) == 1 and self._stacked is not None:
            from .relu_stacked import forward_mean
            mean = forward_mean(x, self._stacked)
        else:
            mean = np.mean([forward(x, layers) for layers in self.members], axis=0,
                           dtype=np.float64)
        out = mean * self.output_scale + self.output_mean
        if out.shape[1] == ROT6D_OUTPUTS:
            # the mean 6-D values made rotations; the root's tilts are offsets from centres
            from .rotation6d import rot6d_to_angles
            angles = rot6d_to_angles(out[:, 2:])
            angles[:, :2] += self.angle_centre_deg[:2]
            return np.hstack([out[:, :2], wrap_deg(angles)])
        out[:, 2:] = wrap_deg(out[:, 2:] + self.angle_centre_deg)
        return out

    @classmethod
    def from_arrays(cls, a, prefix: str = PREFIX) -> "LimbNet | None":
        """The network in a file's parts a (mapping), None when it has none; ValueError when
        it is incomplete or inconsistent."""
        if f"{prefix}shape" not in a:
            if any(str(k).startswith(prefix) for k in a.keys()):
                raise ValueError("limb network is incomplete")
            return None
        shape = np.asarray(a[f"{prefix}shape"])
        if shape.shape != (2,) or not np.issubdtype(shape.dtype, np.integer) \
                or not (1 <= shape[0] <= MAX_MEMBERS and 1 <= shape[1] <= MAX_LAYERS):
            raise ValueError(f"limb network shape must be two integers (members "
                             f"1..{MAX_MEMBERS}, layers 1..{MAX_LAYERS})")
        names = [f"{prefix}{s}" for s in ("input_mean", "input_scale", "output_mean",
                                          "output_scale", "angle_centre_deg",
                                          "canonical_direction")]
        layers = [[(f"{prefix}W{m}_{i}", f"{prefix}b{m}_{i}", f"{prefix}S{m}_{i}")
                   for i in range(int(shape[1]))] for m in range(int(shape[0]))]
        # int8 weights with per-column scales (model_writer.limb_net_arrays; any int8 weight
        # or scale part: all needed), or float16 ones (older files)
        quantised = (f"{prefix}W0_0" in a and np.asarray(a[f"{prefix}W0_0"]).dtype == np.int8) \
            or any(str(k).startswith(f"{prefix}S") for k in a.keys())
        weights = [k for member in layers for k, _, _ in member]
        needed = names + [k for member in layers for W, b, S in member
                          for k in ((W, b, S) if quantised else (W, b))]
        scale = check_parts(a, needed, prefix, f"{prefix}shape", "limb network",
                            "shape does not declare",
                            int8_parts=tuple(weights) if quantised else ())

        def weight(W: str, S: str) -> np.ndarray:
            return (dequantised_int8(a[W], a[S], f"limb network part {W}") if quantised
                    else a[W])

        return cls([[(weight(W, S), a[b]) for W, b, S in member] for member in layers],
                   a[names[0]], scale, a[names[2]], a[names[3]], a[names[4]], a[names[5]])
