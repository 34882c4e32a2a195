"""One version, said once: ``emmi_gym.__version__`` (which pyproject.toml reads) is the CHANGELOG's newest
release, every release is dated and says its breaking changes under their own heading, and each has its page on
the docs site."""

import re

import pytest
from helpers import ROOT

import emmi_gym

tomllib = pytest.importorskip("tomllib")  # Python 3.11+

CHANGELOG = (ROOT / "CHANGELOG.md").read_text()
RELEASES = re.findall(r"^## (\d+\.\d+\.\d+)(?: - (\d{4}-\d{2}-\d{2}))?$", CHANGELOG, re.M)


def release_section(version: str) -> str:
    anchor = f"release-{version.replace('.', '-')}"
    return CHANGELOG.split(f"<!-- --8<-- [start:{anchor}] -->")[1].split(f"<!-- --8<-- [end:{anchor}] -->")[0]


def test_the_package_s_version_is_the_newest_release():
    assert RELEASES[0][0] == emmi_gym.__version__
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert project["project"]["dynamic"] == ["version"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "emmi_gym.__version__"}


def test_releases_are_dated_newest_first_each_with_its_page():
    versions = [tuple(map(int, v.split("."))) for v, _ in RELEASES]
    assert versions == sorted(versions, reverse=True)
    for version, date in RELEASES[:-1]:  # 0.1.0, the first, was never dated
        assert date, f"release {version} has no date"
        page = ROOT / "docs" / "changelog" / f"{version}.md"
        assert f'"CHANGELOG.md:release-{version.replace(".", "-")}"' in page.read_text()
        assert release_section(version).lstrip().startswith(f"## {version} - {date}")


def test_a_release_after_the_first_says_its_breaking_changes_first():
    for version, _ in RELEASES[:-1]:
        headings = re.findall(r"^### (.+)$", release_section(version), re.M)
        assert headings[0] == "Breaking changes", (version, headings)
