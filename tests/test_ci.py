"""CI cannot pass without testing: missing requirements fail under ``$CI``; .ci/run is strict."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import conftest

CI_RUN = Path(__file__).resolve().parents[1] / ".ci" / "run"


def test_require_skips_for_users(monkeypatch):
    monkeypatch.setattr(conftest, "ON_CI", False)
    with pytest.raises(pytest.skip.Exception, match="shared real recordings absent"):
        conftest.require("shared real recordings absent")


def test_require_fails_under_ci(monkeypatch):
    monkeypatch.setattr(conftest, "ON_CI", True)
    with pytest.raises(pytest.fail.Exception, match="CI is set: required"):
        conftest.require("shared real recordings absent")


def test_missing_browser_fails_under_ci(monkeypatch):
    monkeypatch.setattr(conftest, "ON_CI", True)
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(pytest.fail.Exception, match="no browser on PATH"):
        conftest.browser()


def test_ci_script_is_strict():
    text = CI_RUN.read_text()
    assert "set -euo pipefail" in text
    assert "|| true" not in text and ">/dev/null 2>&1; then" in text
    assert "export CI=" in text
    assert "/usr/bin/chromium" not in text
    # Separate steps: venv, install, tests, slow tests and lint each a line of their own.
    for command in (
        "python3 -m venv .venv",
        ".venv/bin/pip install",
        ".venv/bin/python -m pytest\n",
        ".venv/bin/python -m pytest -m slow",
        ".venv/bin/ruff check src tests benchmarks",
    ):
        assert re.search(rf"^{re.escape(command)}", text, re.M), command
    assert "&&" not in text.replace("&& !", "")
