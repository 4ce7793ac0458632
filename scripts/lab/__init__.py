"""Offline work: training the model, evaluating methods on whole sequences, reports.

May import everything (tracker, regressor, sequences); nothing in the online tracker imports it.
"""
