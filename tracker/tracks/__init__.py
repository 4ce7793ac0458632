"""Stage 2: silhouettes over time (association of people to tracks, front/back hypotheses,
Kalman filters, fixed-lag and whole-track smoothing)."""
