"""rlq.lib.versions: installed versions read from metadata."""

import importlib.metadata

from rlq.lib.versions import installed_versions


def test_each_name_gets_its_version_and_none_where_it_is_not_installed() -> None:
    found = installed_versions(["pytest", "no-such-distribution-rlq"])
    assert found == {"pytest": importlib.metadata.version("pytest"), "no-such-distribution-rlq": None}
