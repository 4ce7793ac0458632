"""Motion capture, the human body model, silhouette rendering and data sets.

Everything that turns real motion capture (CMU BVH) into ground-truthed silhouettes
for training and evaluating the regressor. Never imports ``tracker``.
"""
