"""The CMU skeleton's (sequences.skeleton) end sites, which ``track`` needs only for BVH files."""
from __future__ import annotations

import numpy as np

#: End-site offsets (31, 3) in CMU units for CMU_REST_OFFSETS; NaN rows: the joint has none.
CMU_REST_END_SITES: np.ndarray = np.full((31, 3), np.nan)
CMU_REST_END_SITES[5] = [0.0, 0.0, 1.11249]        # LeftToeBase
CMU_REST_END_SITES[10] = [0.0, 0.0, 1.11569]       # RightToeBase
CMU_REST_END_SITES[16] = [0.01305, 1.6256, -0.05265]  # Head
CMU_REST_END_SITES[22] = [0.53306, 0.0, 0.0]       # LeftHandIndex1
CMU_REST_END_SITES[23] = [0.5412, 0.0, 0.5412]     # LThumb
CMU_REST_END_SITES[29] = [-0.58887, 0.0, 0.0]      # RightHandIndex1
CMU_REST_END_SITES[30] = [-0.59786, 0.0, 0.59786]  # RThumb
CMU_REST_END_SITES.flags.writeable = False
