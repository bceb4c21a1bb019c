# SPDX-License-Identifier: GPL-3.0-or-later
"""Results in a notebook: sweep() carries its axes (dims, coords), and every result converts to a
dict, a pandas DataFrame and (Averages) an xarray Dataset whose entries are the result's own
numbers at the labelled positions. pandas and xarray are optional: without them the
conversions raise ImportError with one line.
"""
import sys

import numpy as np
import pytest

import pendavg

from test_pendavg import optional_module


def test_sweep_returns_its_coordinates():
    beta, l2 = [0.1, 1, 10], np.array([0.5, 2.0])
    r = pendavg.sweep(beta=beta, l2=l2)
    assert r.dims == ("beta", "l2")
    assert list(r.coords) == ["beta", "l2"]
    np.testing.assert_array_equal(r.coords["beta"], [0.1, 1.0, 10.0])
    np.testing.assert_array_equal(r.coords["l2"], l2)
    assert r.coords["beta"].dtype == np.float64
    assert r.beta_K.shape == (3, 2, 2) and r.ratio.shape == (3, 2)  # array access as before
    # the labels say which call each entry is
    point = pendavg.average([0.5, 0.5], [1, 2.0], 10)
    np.testing.assert_array_equal(r.beta_K[2, 1], point.beta_K)
    d = r.to_dict()
    assert d["dims"] == ("beta", "l2") and d["beta_K"].shape == (3, 2, 2)
    # str and mpf axis values: coordinates as floats, computed from the exact values
    mpmath = optional_module("mpmath")
    s = pendavg.sweep(beta=1, mu1=["0.05", mpmath.mpf(0.25)])
    assert s.dims == ("mu1",)
    np.testing.assert_array_equal(s.coords["mu1"], [0.05, 0.25])


def test_unnamed_axes_and_single_points():
    grid = pendavg.average([0.5, 0.5], [1, 1], np.array([[1.0, 2.0, 3.0]]))
    assert grid.dims == ("axis0", "axis1")
    np.testing.assert_array_equal(grid.coords["axis1"], [0, 1, 2])
    one = pendavg.average([0.5, 0.5], [1, 1], 1.0)
    assert one.dims == () and one.coords == {}
    d = one.to_dict()
    assert d.keys() == one.as_dict().keys() and d["ratio"] == one.ratio
    np.testing.assert_array_equal(d["beta_K"], one.beta_K)


def test_averages_to_dataframe():
    pandas = optional_module("pandas")
    r = pendavg.sweep(beta=[0.1, 1, 10], l2=[0.5, 2])
    df = r.to_dataframe()
    assert isinstance(df, pandas.DataFrame)
    assert list(df.index.names) == ["beta", "l2", "particle"] and len(df) == 3 * 2 * 2
    for b, beta in enumerate([0.1, 1.0, 10.0]):
        for l, l2 in enumerate([0.5, 2.0]):
            for i in range(2):
                row = df.loc[(beta, l2, i + 1)]
                assert row["beta_K"] == r.beta_K[b, l, i]
                assert row["beta_K_error"] == r.beta_K_error[b, l, i]
                assert row["cos_phi"] == r.cos_phi[b, l, i]
                assert row["ratio"] == r.ratio[b, l]  # per point, on each particle's row
                assert row["method"] == r.method[b, l]
    one = pendavg.average([1, 2, 0.5], [1, 0.5, 2], 0.7)
    df1 = one.to_dataframe()
    assert list(df1.index) == [1, 2, 3] and df1.index.name == "particle"
    np.testing.assert_array_equal(df1["beta_K"].to_numpy(), one.beta_K)
    np.testing.assert_array_equal(df1["K"].to_numpy(), one.K)
    assert set(df1["method"]) == {one.method}
    # the limits: one frame, indexed by (limit, particle); no K or var_K there
    lim = pendavg.limit([0.5, 0.5])
    dfl = lim.to_dataframe()
    assert list(dfl.index.names) == ["limit", "particle"] and "K" not in dfl
    assert dfl.loc[("high_temperature", 1), "beta_K"] == lim.high_temperature.beta_K[0]
    assert lim.to_dict()["low_temperature"]["beta_K"][1] == lim.low_temperature.beta_K[1]
    empty = pendavg.sweep(beta=[])
    assert len(empty.to_dataframe()) == 0


def test_averages_to_xarray():
    optional_module("xarray")
    r = pendavg.sweep(beta=[0.1, 1, 10], mu1=[0.25, 0.5])
    ds = r.to_xarray()
    assert ds["beta_K"].dims == ("beta", "mu1", "particle")
    assert ds["ratio"].dims == ("beta", "mu1")
    assert float(ds["beta_K"].sel(beta=10.0, mu1=0.25, particle=2)) == r.beta_K[2, 0, 1]
    assert float(ds["ratio"].sel(beta=0.1, mu1=0.5)) == r.ratio[0, 1]
    assert ds.attrs["N"] == 2 and ds.attrs["digits"] == 16
    one = pendavg.average([0.5, 0.5], [1, 1], 2.0).to_xarray()
    assert one["beta_K"].dims == ("particle",) and one["ratio"].dims == ()


def test_other_results_to_dataframe():
    optional_module("pandas")
    s = pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=20)
    df = s.to_dataframe()
    assert df.index.name == "n" and list(df.index) == list(s.n)
    np.testing.assert_array_equal(df["beta_K1_error"].to_numpy(), s.beta_K1_error)
    assert s.to_dict()["certified"] == s.certified
    m = pendavg.microcanonical([1, 0.3], [1.3, 0.6], excitation="1e-8")
    dm = m.to_dataframe()
    assert list(dm.index) == [1, 2] and dm.index.name == "particle"
    np.testing.assert_array_equal(dm["K"].to_numpy(), m.K)
    assert set(dm["density_of_states"]) == {m.density_of_states}
    sim = pendavg.simulate([1, 1], [1, 1], theta=1, time=1, exact=True, every=100)
    dsim = sim.to_dataframe()
    np.testing.assert_array_equal(dsim["exact_K"].to_numpy(), sim.exact_K)
    assert "trajectory" not in dsim
    p = pendavg.poincare([1, 1], [1, 1], -2, orbits=2, points=3)
    dp = p.to_dataframe()
    assert len(dp) == 6 and dp.index.name == "crossing"
    np.testing.assert_array_equal(dp["p2"].to_numpy(), p.p2)
    np.testing.assert_array_equal(dp["orbit"].to_numpy(), p.orbit)


def test_missing_pandas_or_xarray_is_one_clear_import_error(monkeypatch):
    r = pendavg.average([0.5, 0.5], [1, 1], 1.0)
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas then raises ImportError
    monkeypatch.setitem(sys.modules, "xarray", None)
    with pytest.raises(ImportError, match=r"^pendavg: to_dataframe\(\) needs pandas, which is not "
                                          r"installed"):
        r.to_dataframe()
    with pytest.raises(ImportError, match=r"^pendavg: to_xarray\(\) needs xarray"):
        r.to_xarray()
    with pytest.raises(ImportError, match="needs pandas"):
        pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=20).to_dataframe()
