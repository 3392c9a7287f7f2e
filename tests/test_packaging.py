"""What `pip install .` builds: every package of the source tree, and every data folder in
it, is in the wheel. An editable install (the README's) finds a package missing from the
list all the same, so only this test tells a non-editable install that cannot import it.
setuptools warns of a data folder it was not told of and will stop building one day, so a
folder without ``__init__.py`` is listed too, with package-data covering its files."""

import fnmatch
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def _folders() -> dict[str, Path]:
    tool = PYPROJECT["tool"]["setuptools"]
    # The models' folders install under the engine's namespace (package-dir).
    where = {ROOT / path: name for name, path in tool["package-dir"].items()}
    where.setdefault(ROOT / "netsim", "netsim")
    found = {}
    for top, name in where.items():
        for folder in [top, *(p for p in top.rglob("*") if p.is_dir())]:
            parts = folder.relative_to(top).parts
            if "__pycache__" not in parts:
                found[".".join((name, *parts))] = folder
    return found


def test_every_package_and_data_folder_of_the_tree_is_built():
    tool = PYPROJECT["tool"]["setuptools"]
    listed = set(tool["packages"])
    found = _folders()
    assert "netsim.world" in found and "netsim.world.example_maps" in found
    assert sorted(set(found) - listed) == []
    assert sorted(listed - set(found)) == []
    data = tool.get("package-data", {})
    for package in data:
        assert package in listed, f"package-data names {package}, which is not built"
    for name, folder in found.items():
        if (folder / "__init__.py").exists():
            continue
        files = [p.name for p in folder.iterdir() if p.is_file()]
        missed = [f for f in files if not any(fnmatch.fnmatch(f, g) for g in data.get(name, []))]
        assert files and missed == [], f"{name}: files no package-data pattern ships: {missed}"


def test_the_licence_is_an_spdx_expression():
    # A TOML table here is deprecated by setuptools, whose builds refuse it from 2027-02-18.
    assert PYPROJECT["project"]["license"] == "MIT"
    assert (ROOT / PYPROJECT["project"]["license-files"][0]).read_text().startswith("MIT License")
