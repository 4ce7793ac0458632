"""Silhouette descriptors (histograms of shape contexts) and pose regressors (DLS, RVM).

A self-contained library: it imports neither ``tracker`` nor ``sequences``.
"""
