"""The command line's option strings -> values (cli/_parsers.py), with errors that name the text."""

import doctest

import numpy as np
import pytest

from robovib.cli import _parsers
from robovib.cli._parsers import (
    parse_mode_spec,
    parse_mode_specs,
    parse_operating_point,
    parse_rpm_range,
)


def test_parsers():
    d, m = parse_mode_spec("y:650,2.1e7,0.03")
    assert d == "y" and m.natural_frequency_hz == 650 and m.stiffness_n_per_m == 2.1e7
    np.testing.assert_allclose(parse_rpm_range("1000:2000:3"), [1000, 1500, 2000])
    for bad in ("z:1,2,0.1", "x:1,2", "x:650,2e7,3"):
        with pytest.raises(ValueError, match="mode"):
            parse_mode_spec(bad)
    with pytest.raises(ValueError, match="rpm range"):
        parse_rpm_range("2000:1000:3")


def test_mode_texts_split_by_direction():
    mx, my = parse_mode_specs(["y:8.2,1e6,0.18", "x:16.5,3.4e6,0.11", "x:63.5,4.2e7,0.055"])
    assert [m.natural_frequency_hz for m in mx] == [16.5, 63.5]
    assert [m.stiffness_n_per_m for m in my] == [1e6]
    assert parse_mode_specs([]) == ((), ())
    with pytest.raises(ValueError, match="direction must be x"):
        parse_mode_specs(["z:10,1e6,0.1"])
    assert doctest.testmod(_parsers, verbose=False).failed == 0


def test_operating_point_in_si():
    rpm, depth_m = parse_operating_point("1750,2")
    assert rpm == 1750 and depth_m == pytest.approx(2e-3)
    for bad in ("1750", "1750,-1", "nan,2"):
        with pytest.raises(ValueError, match="operating point"):
            parse_operating_point(bad)
