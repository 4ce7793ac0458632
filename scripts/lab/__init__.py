"""The scripts' shared research steps: training's data sets and masks (the fitting itself is
regressor.training), evaluation on whole sequences, reports, silhouette measures.

Not installed: scripts/ puts it on the path (``python scripts/X.py``; pytest's pythonpath). May
import everything (tracker, regressor, sequences); nothing ``track`` runs imports it.
"""
