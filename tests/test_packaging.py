"""pyproject.toml lists rlq's packages by hand (conf/ is mapped into the package as rlq.conf): the list holds
every package under rlq/."""

import tomllib

from setuptools import find_packages

from tests.helpers import REPO


def test_the_package_list_holds_every_package_and_the_configs():
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert set(setuptools["packages"]) == set(find_packages(str(REPO), include=["rlq*"])) | {"rlq.conf"}
    assert setuptools["package-dir"] == {"rlq.conf": "conf"}
    assert (REPO / "conf" / "config.yaml").is_file()
