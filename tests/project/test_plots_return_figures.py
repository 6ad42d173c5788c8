"""Library figures are returned (``plot_*(result, ax=None) -> Figure``); only the CLI saves."""

import pathlib
import re

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")  # tests choose the backend, never the library

from matplotlib.figure import Figure

from robovib.modal import ModalParameters


def test_library_never_saves_figures():
    import robovib

    root = pathlib.Path(robovib.__file__).parent
    allowed = {root / "files" / "safe_write.py", root / "report" / "html.py"}
    offenders = [
        str(f.relative_to(root))
        for f in root.rglob("*.py")
        if f not in allowed
        and "cli" not in f.relative_to(root).parts
        and re.search(r"\.savefig\(|matplotlib\.use\(|save_figure\(", f.read_text())
    ]
    assert not offenders, f"library modules saving figures / choosing a backend: {offenders}"


def test_plots_return_figures_and_draw_into_given_axes():
    import matplotlib.pyplot as plt

    from robovib.control.schedule import schedule_gains
    from robovib.frf import FRF
    from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
    from robovib.milling.stability import stability_lobes
    from robovib.modal.plot import plot_frf_fit
    from robovib.studies.analytical import compare_with_table_a1, plot_comparison

    mode = ModalParameters(30.0, 2e6, 0.05)
    lobes = stability_lobes([mode], [], MillingTool(0.0254, 2),
                            CuttingConditions(1750.0, 1e-4, 1e-3, 6e-3), ALUMINIUM_7075)  # fmt: skip
    fig = lobes.plot()
    assert isinstance(fig, Figure) and fig.axes[0].get_ylabel() == "critical axial depth [mm]"
    _, ax = plt.subplots()
    assert lobes.plot(ax=ax) is ax.figure

    s = np.linspace(0.335, 1.235, 6)
    sched = schedule_gains(s, [ModalParameters(f, 2e6, 0.05) for f in 14 + 4 * s])
    assert isinstance(sched.plot(), Figure)
    fig2, axes2 = plt.subplots(1, 2)
    assert sched.plot(ax=axes2) is fig2
    with pytest.raises(ValueError, match="two Axes"):
        sched.plot(ax=[axes2[0]])

    f = np.linspace(10, 60, 200)
    fig3 = plot_frf_fit(FRF(f, mode.compliance(f)), [mode], title="t")
    assert isinstance(fig3, Figure) and len(fig3.axes) == 2

    fig4 = plot_comparison(compare_with_table_a1())
    assert isinstance(fig4, Figure) and len(fig4.axes) == 2
    plt.close("all")
