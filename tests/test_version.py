"""The version has one source (pyproject.toml), and the changelog's newest entry is it."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest

import hexcal
from hexcal.cli import main

ROOT = Path(__file__).resolve().parents[1]


def newest_changelog_version() -> str:
    """The version of the first ``## X.Y.Z`` heading of docs/changelog.md."""
    text = (ROOT / "docs" / "changelog.md").read_text(encoding="utf-8")
    match = re.search(r"^## (\d+\.\d+\.\d+\S*)", text, flags=re.M)
    assert match, "docs/changelog.md has no '## X.Y.Z' entry"
    return match.group(1)


def test_the_installed_version_is_pyproject_s():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]["version"]
    assert version("hexcal") == declared
    assert hexcal.__version__ == declared


def test_hexcal_version_prints_the_metadata_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"hexcal {version('hexcal')}"


def test_the_command_prints_it_too():
    out = subprocess.run(
        [sys.executable, "-m", "hexcal", "--version"], capture_output=True, text=True, check=True
    ).stdout
    assert out == f"hexcal {version('hexcal')}\n"


def test_the_changelog_s_newest_entry_is_the_version():
    assert newest_changelog_version() == version("hexcal")


def test_the_citation_files_name_the_version():
    cff = (ROOT / "CITATION.cff").read_text(encoding="utf-8")
    assert re.search(rf"^version: {re.escape(version('hexcal'))}$", cff, flags=re.M)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"version = {{{version('hexcal')}}}" in readme
