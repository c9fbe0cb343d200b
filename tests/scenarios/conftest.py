"""Shared fixtures of the scenario tests."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).with_name("data")


@pytest.fixture
def scenarios_dir():
    return ROOT / "scenarios"


@pytest.fixture
def data_dir():
    return DATA
