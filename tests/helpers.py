"""Checks and tables shared by tests in several folders (imported as ``from helpers import``)."""

import numpy as np
import pandas as pd

from robovib.modal import ModalParameters


def assert_self_describing(doc: dict, args: list[str]) -> None:
    """Provenance and units keys every --json document must carry."""
    import hashlib
    import re

    from robovib import __version__

    assert doc["robovib_version"] == __version__
    assert doc["command"] == ["robovib", *args]
    settings, units = doc["settings"], doc["settings_units"]
    assert isinstance(settings, dict) and "json_out" not in settings
    for name, value in settings.items():
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
            assert units.get(name), f"setting {name} = {value} has no unit"
    for item in doc["input_files"]:
        with open(item["path"], "rb") as fh:
            assert item["sha256"] == hashlib.sha256(fh.read()).hexdigest()
    assert re.fullmatch(r"\d+\.\d+\.\d+.*", doc["robovib_version"])
    unknown = [k for k, u in doc["units"].items() if not u or u == "unknown"]
    assert not unknown, f"numbers without a unit: {unknown}"


def synthetic_modes_table(n=14, seed=0):
    """Smooth fields: x has 2 modes, y has 1; pose 3 misses x2, pose 5 has a spurious x mode."""
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(2100, 2600, n), rng.uniform(-300, 600, n),
                         rng.uniform(0, 180, n)])  # fmt: skip
    s = (X[:, 0] - 2100) / 500
    fields = {
        "x1": (15 + 6 * s, 3e6 * (1 + 0.3 * s), 0.1),
        "x2": (40 + 15 * s, 3e7 * (1 + 0.2 * s), 0.05),
        "y1": (8 + 0.5 * np.cos(np.radians(X[:, 2])), 1e6 * (1 + 0.2 * s), 0.18),
    }
    rows = []
    for i in range(n):
        for k, (fn, kk, z) in fields.items():
            if i == 3 and k == "x2":
                continue
            fi, ki = float(np.atleast_1d(fn)[i]), float(np.atleast_1d(kk)[i])
            m = ModalParameters(fi, ki, z)
            rows.append({"row": 2 * i + (k[0] == "y"), "direction": k[0], "x_mm": X[i, 0],
                         "y_mm": X[i, 1], "rz_deg": X[i, 2], "fn_hz": fi,
                         "stiffness_n_per_m": ki, "damping_ns_per_m": m.damping_ns_per_m,
                         "damping_ratio": z, "true_id": k})  # fmt: skip
        if i == 5:  # a spurious mode far from every tracked one
            rows.append({**rows[-2], "fn_hz": 95.0, "true_id": ""})
    return pd.DataFrame(rows), X, fields
