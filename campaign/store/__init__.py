"""The campaign directory: its files, manifest, lock and fitted detectors."""
