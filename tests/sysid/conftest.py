"""Shared fixtures for the sysid tests."""
import pytest

from sysid_helpers import REAL_DATA


@pytest.fixture
def real_data_dir():
    if not REAL_DATA.is_dir():
        pytest.skip(f"real data folder {REAL_DATA} is absent (clone the repo next to shared/)")
    return REAL_DATA
