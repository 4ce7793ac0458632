"""Stage 2: silhouettes over time (association of people to tracks, front/back hypotheses,
Kalman filters, fixed-lag and whole-track smoothing)."""


def streamed_kind(lag_s: float) -> str:
    """What the poses written while tracking are, as the outputs name them: "filtered", or
    "fixed-lag smoothed" with a lag (seconds) above 0 (tracker.tracks.fixed_lag)."""
    return "fixed-lag smoothed" if lag_s > 0 else "filtered"
