"""lanelab-predict: a trained model over MCAP drive logs, its lanes written back as MCAP that
Foxglove shows beside the log (and lanelab-ingest reads as labels).

Downstream of both the ingestor (it reads logs with :mod:`data_ingest.ingest`) and the model
(:mod:`lanelab.deploy`); neither imports it.
"""
