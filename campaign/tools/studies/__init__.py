"""Studies: fixed comparisons and censuses outside a campaign, run by
``fdd-campaign study NAME``, each printing one table.

- :mod:`campaign.tools.studies.vanek` (``fdd-campaign study vanek``) reproduces a comparison
  of [VANEK] on a handful of named scenarios through the evaluation pipeline of
  :mod:`campaign.evaluate` (detection and scoring by :mod:`reports.scoring.metrics`), as a campaign
  does;
- :mod:`campaign.tools.studies.saturation` (``fdd-campaign study saturation``) counts the
  aircraft laws' servo saturation and surface activity on fault-free runs sampled as a
  campaign samples them (simulation only, no detector).
"""
