"""Design mathematics of the built-in detectors: filters, LPV synthesis, models."""
