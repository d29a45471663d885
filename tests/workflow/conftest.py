"""Fixtures shared by the workflow tests."""
import pytest

import fakestages


@pytest.fixture
def fakes(tmp_path, monkeypatch):
    """Fake stage modules registered in place of the real ones."""
    return fakestages.install(tmp_path, monkeypatch)
