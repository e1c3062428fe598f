"""Producers of clip datasets: synthetic drive logs, MCAP ingestion, adapters, auto-labelling.

Imports :mod:`lanelab`; :mod:`lanelab` never imports this package.
"""
