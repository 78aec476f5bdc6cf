"""The scoring and statistics layer: run-level scoring (FA / MD / DTP, margin), summaries with
exact confidence bounds, detection time as survival data, the acceptance gate, the comparison of
two campaigns. Plain arrays and tables in and out; detectors and the evidence import only this
layer of :mod:`reports`, and it imports nothing of :mod:`reports.render`."""
