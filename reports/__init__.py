"""Per-run scoring (FA / MD / DTP), summaries with confidence bounds, the gate, reports."""
