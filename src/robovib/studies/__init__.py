"""Thesis reproductions on the virtual robot (they may import :mod:`robovib.sim`; the core may not).

* :mod:`robovib.studies.hybrid` — chapter 5: Table 12 / 13 analogues over simulator seeds,
  OMA estimator settings, next hammer poses.
"""
