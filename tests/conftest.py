"""Shared fixtures: the shipped rigs and the shared/ folder beside the repository."""

from pathlib import Path

import pytest

from pneusim.rig import load_rig

SHARED = Path(__file__).resolve().parents[1].parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip(f"shared/ folder not found beside the repository ({SHARED})")
    return SHARED


@pytest.fixture(scope="session", params=["paper1-mre", "paper2-enfield"])
def rig(request):
    return load_rig(request.param)


@pytest.fixture(scope="session")
def rig2():
    return load_rig("paper2-enfield")


@pytest.fixture(scope="session")
def rig1():
    return load_rig("paper1-mre")


def pytest_collection_modifyitems(config, items):
    """Tests marked ``minutes`` run first: with two workers stealing work from each other, a
    minute-long fit started last would leave one worker idle while the other finishes it."""
    items.sort(key=lambda item: item.get_closest_marker("minutes") is None)
