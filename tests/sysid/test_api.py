"""The public API: names, docstrings, independence from pneusim."""
import subprocess
import sys

import pytest

import sysid

MATLAB_NAMES = ["iddata", "arx", "armax", "oe", "bj", "n4sid", "tfest", "rls", "RecursiveARX",
                "predict", "compare", "resid", "SysidError"]


def test_matlab_style_names_are_exported():
    for name in MATLAB_NAMES:
        assert name in sysid.__all__ and hasattr(sysid, name)


@pytest.mark.parametrize("name", sysid.__all__)
def test_public_names_have_docstrings(name):
    obj = getattr(sysid, name)
    assert obj.__doc__ and len(obj.__doc__.strip()) > 20, name


@pytest.mark.slow
def test_sysid_does_not_import_pneusim():
    code = "import sys, sysid; sysid.arx; assert not any(m.startswith('pneusim') for m in sys.modules)"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_estimator_constructor_only_stores_options():
    est = sysid.ARX(-1, 2, 1)  # invalid, but not checked until fit
    assert est.na == -1
    with pytest.raises(sysid.SysidError, match="na must be"):
        est.fit(sysid.iddata([0.0] * 20, [1.0] * 20, 1.0))
