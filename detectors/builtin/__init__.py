"""The built-in detectors, one module per registry name."""
