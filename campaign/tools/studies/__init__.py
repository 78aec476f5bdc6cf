"""Studies: fixed comparisons reproduced from a paper, outside a campaign, run by
``fdd-campaign study NAME`` (:mod:`campaign.tools.studies.vanek`: ``fdd-campaign study vanek``).

A study simulates a handful of named scenarios and prints one table; it goes through the
evaluation pipeline of :mod:`campaign.evaluate` (detection and scoring by
:mod:`reports.metrics`) like a campaign does.
"""
