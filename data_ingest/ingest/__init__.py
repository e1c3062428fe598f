"""The MCAP ingestor: drive logs (DESIGN.md, "Drive-log contract") -> a clip store (``lanelab-ingest``)."""
