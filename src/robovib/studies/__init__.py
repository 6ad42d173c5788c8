"""Thesis reproductions on the virtual robot (they may import :mod:`robovib.sim`; the core may not).

* :mod:`robovib.studies.control_closed_loop` — chapter 4: §4.3.2, Table 7 and Table 10 analogues,
  command-channel calibration, controller comparison.
"""
