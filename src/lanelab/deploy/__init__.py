"""Trained models outside training: a checkpoint rebuilt as a detector to run frame by frame
(``trained``, ``stream``: what lanelab-predict runs on drive logs) and exported as a graph with
its memory as explicit inputs and outputs (``export``, lanelab-export)."""
