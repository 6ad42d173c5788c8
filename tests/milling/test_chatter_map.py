"""Workspace stability maps on Dask: labelled NetCDF output equal to pose-by-pose envelopes."""

import json

import numpy as np
import pytest
import xarray as xr

from robovib.milling import ALUMINIUM_7075, CuttingConditions, MillingTool
from robovib.milling.maps import plot_lobe_map, save_lobe_map, workspace_lobe_map
from robovib.milling.sdm import sdm_lobes
from robovib.modal import ModalParameters

TOOL = MillingTool()
COND = CuttingConditions(1750, 0.058e-3, 3e-3, 6e-3)


class _LinearModel:
    """fn, k, c (thesis units) that vary linearly with X: a pose model with a known answer."""

    def predict(self, x, return_std=False):
        x = np.atleast_2d(x)
        s = (x[:, 0] - 2100) / 600
        mean = np.column_stack([16 + 4 * s, 4 + s, 3 + 0 * s, 9 + 0 * s, 1.5 + s, 1.6 + 0 * s,
                                30 + 0 * s, 8 + 0 * s, 2 + 0 * s])  # fmt: skip
        return (mean, 0.1 * mean) if return_std else mean


@pytest.mark.parametrize("scheduler", ["sync", "processes"])
def test_map_equals_pose_by_pose_sdm_and_round_trips_netcdf(tmp_path, scheduler):
    rpm = np.linspace(1000, 6000, 9)
    calls = []
    ds = workspace_lobe_map(_LinearModel(), [2100, 2700], [0, 300], [45], rpm, TOOL, COND, ALUMINIUM_7075,
                            scheduler=scheduler, n_workers=2, poses_per_chunk=3,
                            progress=lambda d, t: calls.append((d, t)))  # fmt: skip
    assert ds.a_lim_m.dims == ("x_mm", "y_mm", "rz_deg", "spindle_rpm")
    assert ds.a_lim_m.attrs["units"] == "m" and ds.spindle_rpm.attrs["units"] == "rpm"
    assert calls[-1] == (2, 2)
    assert json.loads(ds.attrs["settings"])["radial_depth_m"] == pytest.approx(6e-3)
    assert "robovib_version" in ds.attrs
    # Independent: the envelope of the modes at X = 2700 (s = 1) computed directly.
    mx = ModalParameters.from_fn_k_c(20.0, 5e6, 3e3)
    my = ModalParameters.from_fn_k_c(9.0, 2.5e6, 1.6e3)
    direct = sdm_lobes([mx], [my], TOOL, COND, ALUMINIUM_7075, rpm).a_lim_m
    np.testing.assert_allclose(
        ds.a_lim_m.sel(x_mm=2700, y_mm=300, rz_deg=45).values, direct, rtol=1e-9
    )
    path = save_lobe_map(ds, tmp_path / "map.nc")
    back = xr.load_dataset(path)
    np.testing.assert_allclose(back.a_lim_m.values, ds.a_lim_m.values)
    assert back.a_lim_m.attrs["units"] == "m" and back.attrs["method"] == "sdm"
    # The file header of every robovib file: format tag and layout version.
    assert (back.attrs["format"], int(back.attrs["format_version"])) == ("robovib-lobe-map", 1)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]
    fig = plot_lobe_map(ds, spindle_rpm=3000)
    assert "[mm]" in fig.axes[0].get_xlabel()


def test_map_bad_input(tmp_path):
    with pytest.raises(ValueError, match="scheduler"):
        workspace_lobe_map(_LinearModel(), [2100], [0], [0], [2000.0], TOOL, COND, ALUMINIUM_7075,
                           scheduler="gpu")  # fmt: skip
    with pytest.raises(ValueError, match="spindle_rpm"):
        workspace_lobe_map(_LinearModel(), [2100], [0], [0], [np.nan], TOOL, COND, ALUMINIUM_7075)
    with pytest.raises(ValueError, match="NetCDF"):
        save_lobe_map(xr.Dataset(), tmp_path / "map.h5")
