"""Motion capture (CMU BVH), the human body model, silhouette rendering and data sets: what
turns motion capture into ground-truthed silhouettes for the regressor. Never imports tracker."""
