"""The docs say what the code does: docs/configuration.md lists every key as the code
describes it (its tables are made by ``python -m netsim.tools.config_docs``), and the pages
offer only what exists (docs/python.md's snapshot, no removed plugin form)."""

import re
import tomllib
import warnings

import pytest

from netsim import config as cfgmod
from netsim.tools import config_docs


def test_the_configuration_page_is_what_its_command_makes():
    """The tables of docs/configuration.md are exactly what `python -m
    netsim.tools.config_docs` makes now: a key added, removed or described anew without
    running it fails here."""
    page = config_docs.PAGE.read_text()
    assert config_docs.render(page) == page, f"docs/configuration.md is stale: run {config_docs.COMMAND}"


def test_the_configuration_page_names_every_key_with_its_default():
    """Every key `netsim config` knows has a row, with the default the code has (a rule for
    a default that follows another key)."""
    page = config_docs.PAGE.read_text()
    rows = dict(re.findall(r"^\| `([\w.]+)` \| (.*?) \|", page, re.M))
    assert set(cfgmod.all_keys()) <= set(rows)
    assert rows["mobility.stationary_start"] == '`"auto"`'
    assert rows["protocol.tau_s"].startswith("3 x ack_period_s")


@pytest.mark.parametrize("section", ["mobility", "channel", "protocol"])
def test_every_other_models_default_is_on_its_row(section):
    """Each model's own default of each of its keys is on the page, on its key's row of the
    other models' table (or, where it is the built-in configuration's, on that key's row
    there): a key two models share with different defaults (aodv's and olsr's
    hello_interval_s), a default derived by a rule, a default another model changes
    (message_rate_hz under the routing protocols)."""
    keys, other = config_docs.PAGE.read_text().split("## Keys of the other built-in models")
    chosen = dict(re.findall(r"^\| `([\w.]+)` \| (.*?) \| ", keys, re.M))
    others = {k: (models, d) for k, models, d in re.findall(r"^\| `([\w.]+)` \| (`.*?`) \| (.*?) \| ", other, re.M)}
    missing = []
    for model, key, default, _doc, rule in cfgmod._other_models(section):
        dotted = f"{section}.{key}"
        shown = rule if default is None and rule else f"`{config_docs._value(cfgmod.plain(default))}`"
        if dotted in others and f"`{model}`" in others[dotted][0]:
            where = others[dotted][1]
            ok = where == shown or f"{shown} (`{model}`)" in where
        else:
            ok = chosen.get(dotted, "").removesuffix(config_docs.FOLLOWS) == shown
        if not ok:
            missing.append((model, dotted, shown))
    assert missing == []


def test_the_check_fails_on_a_stale_page(tmp_path, monkeypatch, capsys):
    """`--check` exits 1 on a page whose tables differ, and writes nothing."""
    stale = config_docs.PAGE.read_text().replace('| `"auto"` |', "| `true` |")
    page = tmp_path / "configuration.md"
    page.write_text(stale)
    monkeypatch.setattr(config_docs, "PAGE", page)
    assert config_docs.main(["--check"]) == 1
    assert page.read_text() == stale
    assert config_docs.main([]) == 0
    assert config_docs.main(["--check"]) == 0


def test_the_example_scenario_of_the_page_loads_with_the_codes_defaults():
    """The scenario file the page shows loads without a warning, and every value it writes
    is the default."""
    body = re.search(r"```toml\n(# scenario.toml\n.*?)```", config_docs.PAGE.read_text(), re.S)[1]
    shown = tomllib.loads(body)
    default = cfgmod.to_dict(cfgmod.from_dict({}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cfgmod.from_dict(shown)
    for section, values in shown.items():
        if isinstance(values, dict):
            for key, value in values.items():
                assert default[section][key] == value, f"{section}.{key}"
        else:
            assert default[section] == values, section


DOCS = config_docs.PAGE.parent


@pytest.mark.slow
def test_the_python_pages_example_runs_and_its_snapshot_carries_roles(monkeypatch, tmp_path):
    """docs/python.md's block runs as shown, and its snapshot's nodes carry what its comment
    says: pos, role and leader."""
    monkeypatch.chdir(tmp_path)
    body = re.search(r"```python\n(.*?)```", (DOCS / "python.md").read_text(), re.S)[1]
    scope: dict = {}
    exec(compile(body.replace('"duration_s=60"', '"duration_s=40"'), "docs/python.md", "exec"), scope)
    assert "pos, role, leader" in body
    g = scope["g"]
    assert g.number_of_nodes() == 100
    assert all({"pos", "role", "leader"} <= set(data) for _, data in g.nodes(data=True))


def test_no_page_offers_the_removed_install_form():
    """The removed plugin form `install(sim)` is named only where docs/plugins.md says it
    was removed."""
    for page in sorted(DOCS.glob("*.md")):
        for line in page.read_text().splitlines():
            if "install(sim)" in line:
                assert page.name == "plugins.md" and "was removed" in line, f"{page.name}: {line}"
