"""What `pip install .` builds: every package of the source tree is in the wheel. An editable
install (the README's) finds a package missing from the list all the same, so only this
test tells a non-editable install that cannot import it."""

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_of_the_tree_is_built():
    tool = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(tool["packages"])
    # The models' folders install under the engine's namespace (package-dir).
    where = {ROOT / path: name for name, path in tool["package-dir"].items()}
    where.setdefault(ROOT / "netsim", "netsim")
    found = set()
    for top, name in where.items():
        for init in top.rglob("__init__.py"):
            parts = init.parent.relative_to(top).parts
            found.add(".".join((name, *parts)))
    assert "netsim.world" in found
    assert sorted(found - listed) == []
    assert sorted(listed - found) == []
    for package in tool.get("package-data", {}):
        assert package in listed, f"package-data names {package}, which is not built"
