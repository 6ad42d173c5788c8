"""Thesis reproductions: each study returns a frozen result with ``to_frame()`` and ``to_dict()``.

* :mod:`.chapter3` — GPR of the modal parameters vs Table 2, MLR baseline, Table A2 (§3.3);
* :mod:`.analytical` — analytical KR500 model vs Table A1 (Fig. 11), GP inputs (§3.4);
* :mod:`.hybrid_learning_curve` — pure GP vs analytical-mean hybrid vs training poses;
* :mod:`.table9` — LQR gains vs Table 9 (§4.3);
* :mod:`.control` — chapter 4 on the virtual robot: §4.3.2, Table 7 and Table 10
  analogues, command-channel calibration, controller comparison (:func:`simulate_control`).
* :mod:`.hybrid` — chapter 5: Table 12 / 13 analogues over simulator seeds, OMA estimator
  settings, the whole-workspace FRF model, next hammer poses.

Studies may import every package; no core package (``frf, modal, gp, robot, milling, control,
hybrid, io``) may import ``studies`` (checked by ``tests/project/test_architecture.py``).
"""
