"""pyproject.toml lists rlq's packages by hand (conf/ is mapped into the package as rlq.conf): the list holds
every package under rlq/ and every config folder under conf/ (setuptools warns of any it is not told of)."""

import tomllib

from setuptools import find_packages

from tests.helpers import REPO


def test_the_package_list_holds_every_package_and_the_configs():
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    conf = REPO / "conf"
    config_folders = {"rlq.conf"} | {
        "rlq.conf." + ".".join(d.relative_to(conf).parts)
        for d in conf.rglob("*")
        if d.is_dir() and any(d.rglob("*.yaml"))
    }
    assert set(setuptools["packages"]) == set(find_packages(str(REPO), include=["rlq*"])) | config_folders
    assert setuptools["package-dir"] == {"rlq.conf": "conf"}
    assert (REPO / "conf" / "config.yaml").is_file()
