"""Fixtures of the tests in this folder."""

import pytest


@pytest.fixture
def write(tmp_path):
    def _write(text, name="rec.csv"):
        path = tmp_path / name
        (path.write_bytes if isinstance(text, bytes) else path.write_text)(text)
        return path
    return _write
