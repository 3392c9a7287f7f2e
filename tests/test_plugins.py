"""Models are found by name: built-in entry points, or a user's ``module:function``."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from netsim import plugins
from netsim.errors import ConfigError


def test_builtin_models_are_registered():
    assert {"random_waypoint", "random_direction", "static", "trace"} <= set(plugins.available(plugins.MOBILITY))
    assert "ack" in plugins.available(plugins.PROTOCOLS)


def test_unknown_model_lists_the_choices():
    with pytest.raises(ConfigError, match="random_waypoint"):
        plugins.resolve(plugins.MOBILITY, "teleport", "mobility.model")


def test_missing_user_module_is_a_clear_error():
    with pytest.raises(ConfigError, match="cannot be loaded"):
        plugins.resolve(plugins.MOBILITY, "no_such_module_xyz:install", "mobility.model")


PLUGINS_DOC = (Path(__file__).resolve().parents[1] / "docs" / "plugins.md").read_text()


def _doc_block(first_line: str) -> str:
    """The fenced block of docs/plugins.md whose first line is ``first_line``."""
    for m in re.finditer(r"^```(\w*)\n(.*?)^```", PLUGINS_DOC, re.S | re.M):
        if m[2].startswith(first_line + "\n"):
            return m[2]
    raise LookupError(first_line)


@pytest.mark.slow
def test_the_docs_mobility_model_runs_as_shown_from_the_current_directory(tmp_path):
    """docs/plugins.md's example module, as the page shows it, in the working directory,
    named on the command line of the installed console script (whose import path, unlike
    python -m, lacks the working directory): the robots stand on the circle of the radius
    the command sets."""
    (tmp_path / "mymodels.py").write_text(_doc_block("# mymodels.py"))
    shown = "netsim run --set mobility.model=mymodels:CIRCLE --set mobility.radius_m=150"
    assert shown in PLUGINS_DOC
    script = Path(sys.executable).parent / "netsim"
    if not script.exists():
        pytest.skip("the netsim console script is not installed next to this Python")
    out = tmp_path / "out"
    args = shlex.split(shown)[1:] + [
        "--quiet",
        "--out",
        str(out),
        "--set",
        "duration_s=5",
        "--set",
        "world.n_robots=12",
    ]
    run = subprocess.run([str(script), *args], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    pos = pd.read_parquet(out / "positions.parquet")
    r = ((pos.x_m - 500) ** 2 + (pos.y_m - 500) ** 2) ** 0.5
    assert r.to_numpy() == pytest.approx(150.0)


def test_a_plain_function_is_not_a_plugin(tmp_path, monkeypatch):
    """The one form of plugin: a plain function (the removed ``install(sim)`` form) named
    as a model is refused in one line naming the key and what a plugin is."""
    (tmp_path / "plain_models.py").write_text("def circle(sim):\n    raise AssertionError('never called')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError, match="is not a netsim plugin") as caught:
        plugins.resolve(plugins.MOBILITY, "plain_models:circle", "mobility.model")
    assert "mobility.model" in str(caught.value) and "\n" not in str(caught.value)


def test_each_group_lists_exactly_its_installed_entry_points():
    """The plugins of a group are its entry points as installed, in their order (read in
    one pass for all the groups)."""
    from importlib.metadata import entry_points

    for group in (plugins.MOBILITY, plugins.PROTOCOLS, plugins.CONTROLLERS, plugins.HOOKS, "netsim.none"):
        assert plugins._entry_points(group) == tuple(entry_points(group=group)), group
    assert plugins.available(plugins.PROTOCOLS) == ["ack", "aodv", "clustering", "greedy", "none", "olsr"]


@pytest.mark.parametrize(
    "source, line, kind",
    [
        ("import math\n\ndef circle(:\n    pass\n", 3, "SyntaxError: invalid syntax"),
        ("import math\nraise RuntimeError('the model is\\nnot ready')\n", 2, "RuntimeError: the model is not ready"),
        ("import no_such_module_of_the_user_xyz\n", 1, "ModuleNotFoundError: No module named"),
        ("x = 1\nfrom math import no_such_name\n", 2, "ImportError: cannot import name 'no_such_name'"),
        ("def f():\n    return 1 / 0\n\nPLUGIN = f()\n", 2, "ZeroDivisionError: division by zero"),
    ],
    ids=["syntax-error", "exception", "missing-import", "bad-from-import", "error-in-a-call"],
)
def test_a_plugin_module_that_fails_to_import_is_one_line_naming_file_and_line(
    tmp_path, capfd, monkeypatch, source, line, kind
):
    """A user's plugin module that fails as it is imported (a syntax error, an exception its
    code raises, an import of its own that fails) is one line, exit 2, nothing written: the
    key, the plugin's file and the line where it failed, the error's kind and message."""
    from netsim.tools.cli import main

    name = f"broken_model_{tmp_path.name.replace('-', '_')}"
    path = tmp_path / f"{name}.py"
    path.write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    code = main(["run", "--quiet", "--out", str(out), "--set", f"mobility.model={name}:PLUGIN"])
    err = capfd.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("netsim: error: mobility.model = "), err
    assert f"{path}, line {line}: {kind}" in err, err
    assert not out.exists()


PARAMS_MISTAKES = """
from dataclasses import dataclass
from netsim.params import Params
from netsim.plugins import PluginSpec

def build(params, parts):
    return None

@dataclass
class Loose:
    radius_m: float = 1.0

class Plain:
    radius_m = 1.0

@dataclass(frozen=True)
class Needs(Params):
    section = "mobility"
    radius_m: float

LOOSE = PluginSpec(Params=Loose, build=build, moves_robots=False)
PLAIN = PluginSpec(Params=Plain, build=build, moves_robots=False)
NEEDS = PluginSpec(Params=Needs, build=build, moves_robots=False)
"""


@pytest.mark.parametrize(
    "attr, words",
    [
        ("LOOSE", "its Params (Loose) must be a frozen dataclass deriving from netsim.params.Params"),
        ("PLAIN", "its Params (Plain) must be a frozen dataclass deriving from netsim.params.Params"),
        ("NEEDS", "mobility.radius_m = None: must be set: mobility.model = '{name}:NEEDS' gives it no default"),
    ],
)
def test_a_plugins_params_that_cannot_hold_its_keys_are_one_line(tmp_path, capfd, monkeypatch, attr, words):
    """A plugin's Params that is not a frozen Params dataclass, or a key of it without a
    default that the user did not set: one line naming it, exit 2, nothing written (they were
    tracebacks of an AttributeError or a TypeError inside netsim, exit 1)."""
    from netsim.tools.cli import main

    name = f"params_mistakes_{tmp_path.name.replace('-', '_')}"
    (tmp_path / f"{name}.py").write_text(PARAMS_MISTAKES)
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    code = main(["run", "--quiet", "--out", str(out), "--set", f"mobility.model={name}:{attr}"])
    err = capfd.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert words.format(name=name) in err, err
    assert not out.exists()


def test_the_docs_moving_model_runs_as_shown(tmp_path, monkeypatch):
    """docs/plugins.md's model that moves robots (set_leg, arrive), as the page shows it:
    each robot walks its own line between the turning points, at the speed set."""
    from netsim import load
    from netsim.run import execute

    (tmp_path / "patrol.py").write_text(_doc_block("# patrol.py"))
    shown = "netsim run --set mobility.model=patrol:PATROL --set mobility.speed_mps=3"
    assert shown in PLUGINS_DOC
    monkeypatch.syspath_prepend(str(tmp_path))
    sets = [a.split("=", 1)[0] + "=" + a.split("=", 1)[1] for a in shlex.split(shown)[3::2]]
    config = load(None, [*sets, "world.n_robots=4", "duration_s=400", "protocol.model=none"])
    frames = execute(config).frames
    legs = frames["legs"]
    assert set(legs["cause"]) == {"start", "command", "waypoint"}
    moving = legs[legs["cause"] == "command"]
    assert (abs(moving["vx_mps"]) == 3.0).all() and (moving["vy_mps"] == 0.0).all()
    pos = frames["positions"]
    assert pos["x_m"].between(50.0, 950.0).all() and pos["x_m"].max() > 940.0
    lines = pos.groupby("robot")["y_m"].agg(["min", "max"])
    assert (lines["min"] == lines["max"]).all() and lines["min"].tolist() == [125.0, 375.0, 625.0, 875.0]


CIRCLE_MODULE = """
import math
from dataclasses import dataclass

from netsim.params import Params, param, positive
from netsim.plugins import Parts, PluginSpec


@dataclass(frozen=True)
class CircleParams(Params):
    section = "mobility"
    radius_m: float = param(100.0, positive, "radius of the circle, metres")


def circle(params, parts):
    n, centre = parts.state.n, parts.world.side_m / 2
    angles = [2 * math.pi * i / n for i in range(n)]
    r = params.radius_m
    parts.state.place([[centre + r * math.cos(a), centre + r * math.sin(a)] for a in angles])


PLUGIN = PluginSpec(Params=CircleParams, build=circle, moves_robots=False)
"""


@pytest.mark.slow
@pytest.mark.parametrize("own", ["mobility.py", "protocols.py", "hooks.py"])
def test_a_users_module_named_like_a_model_package_shadows_nothing(tmp_path, own):
    """A user's own ``mobility.py`` (or ``protocols.py``, ``hooks.py``) in the working
    directory, named as a plugin, leaves netsim's built-in models where they are: the run
    loads the user's model and the built-in coverage controller, clustering and hook."""
    (tmp_path / own).write_text(CIRCLE_MODULE)
    module = own.removesuffix(".py")
    sets = [
        f"mobility.model={module}:PLUGIN",
        "world.n_robots=6",
        "duration_s=5",
        "protocol.model=clustering",
        "coverage.enabled=true",
        'events.hooks=["link_breaks"]',
    ]
    command = [str(Path(sys.executable).with_name("netsim")), "run", "--quiet", "--out", "out"]
    run = subprocess.run(
        command + [a for s in sets for a in ("--set", s)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "out" / "positions.parquet").is_file()


def _controller(section: str, switched: bool = False):
    """A controller with a section of its own; ``switched``: with an ``enabled`` key, true."""
    from dataclasses import dataclass

    from netsim.params import Params, param, positive
    from netsim.plugins import PluginSpec

    keys = {"section": section, "__annotations__": {"gap_m": float}, "gap_m": param(1.0, positive, "m")}
    if switched:
        keys["__annotations__"]["enabled"] = bool
        keys["enabled"] = param(True, None, "on")
    params = dataclass(frozen=True)(type("P", (Params,), keys))
    return PluginSpec(Params=params, build=lambda params, parts: None)


def test_an_installed_controller_whose_section_is_taken_stops_no_run_that_does_not_name_it(monkeypatch):
    """An installed controller whose section the engine uses ([mobility]), or a controller
    the configuration names already declares, is left out with a warning naming it, not a
    refusal of every run; two controllers the configuration names with one section are
    refused, naming the other."""
    import netsim.config as cfgmod
    from netsim.config import load

    named = _controller("separation")
    cfgmod._LEFT_OUT_TOLD.clear()
    installed = {**plugins.registered(plugins.CONTROLLERS), "badsec": _controller("mobility", switched=True)}
    installed["separation"] = _controller("separation")
    real_registered = plugins.registered
    monkeypatch.setattr(
        plugins, "registered", lambda group: installed if group == plugins.CONTROLLERS else real_registered(group)
    )
    real_resolve = plugins.resolve
    users = {"mine:SEP": named, "yours:SEP": _controller("separation")}
    monkeypatch.setattr(
        plugins, "resolve", lambda group, name, key: users[name] if name in users else real_resolve(group, name, key)
    )
    with pytest.warns(UserWarning, match=r"'badsec' is left out: its section \[mobility\] is used by the engine"):
        config = load(None, ["duration_s=5", "world.n_robots=5"])
    assert "separation" in config.sections  # the installed one, named by nobody, owns it
    assert [name for name, _, _ in cfgmod.controllers(config)] == []  # badsec, switched on, is not built
    from netsim.run import execute

    execute(config)  # a run that names neither (it ended in a KeyError with badsec left out)
    with pytest.warns(UserWarning) as caught:
        owners = cfgmod.section_owners(cfgmod.ControlParams(controllers=("mine:SEP",)))
    told = [str(w.message) for w in caught]
    assert "installed controller 'separation' is left out: its section [separation] is used by 'mine:SEP'" in told
    assert owners["separation"] is named
    with pytest.raises(ConfigError, match=r"declares the section \[separation\], as 'mine:SEP' does"):
        cfgmod.section_owners(cfgmod.ControlParams(controllers=("mine:SEP", "yours:SEP")))


def test_a_plugin_object_keeps_every_flag_a_pluginspec_has(tmp_path, monkeypatch):
    """An object with a PluginSpec's members (not a PluginSpec) keeps its flags as well:
    a mobility model that leaves the robots where they are (``moves_robots = False``) lets a
    controller move them (the flags were dropped, and it was refused)."""
    (tmp_path / "duck_models.py").write_text(
        "from netsim.params import NoParams\n"
        "class Still:\n"
        "    Params = NoParams\n"
        "    tables = {}\n"
        "    moves_robots = False\n"
        "    respects_map = True\n"
        "    @staticmethod\n"
        "    def check(params, config):\n"
        "        pass\n"
        "    @staticmethod\n"
        "    def build(params, parts):\n"
        "        parts.state.place([[500.0, 500.0]] * parts.state.n)\n"
        "STILL = Still()\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    spec = plugins.resolve(plugins.MOBILITY, "duck_models:STILL", "mobility.model")
    assert spec.moves_robots is False and spec.respects_map is True


def test_a_model_whose_keys_live_in_another_section_is_refused_as_another_kind(tmp_path, monkeypatch):
    """The docs' mobility model CIRCLE (its keys in [mobility]) named as the protocol is
    refused in one line (it was accepted: its radius went under [protocol], and the robots
    moved by the default mobility)."""
    from netsim.config import load

    (tmp_path / "mymodels.py").write_text(_doc_block("# mymodels.py"))
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError, match=r"^protocol.model = 'mymodels:CIRCLE': its keys are of \[mobility\]"):
        load(None, ["protocol.model=mymodels:CIRCLE"])
    # A section no other model uses says no kind: its keys are read from [mobility], as ever.
    own = _doc_block("# mymodels.py").replace('section = "mobility"', 'section = "circle"')
    (tmp_path / "own_section.py").write_text(own)
    config = load(None, ["mobility.model=own_section:CIRCLE", "mobility.radius_m=150"])
    assert config.mobility.params.radius_m == 150


@pytest.mark.parametrize(
    "summary, said",
    [
        ('{"mean_degree": -1.0}', "its summary() gives mean_degree, already in the summary"),
        ("[1, 2]", "its summary() must return a dict, not list"),
    ],
)
def test_a_hooks_summary_cannot_overwrite_the_engines_figures(tmp_path, monkeypatch, capsys, summary, said):
    """A hook whose summary() gives a figure the summary already holds (it silently replaced
    the engine's mean degree), or no dict, is refused in one line naming it, nothing
    written."""
    from netsim.tools.cli import main

    module = f"loud_hook_{len(said)}"
    (tmp_path / f"{module}.py").write_text(
        "from netsim.params import Params\n"
        "from netsim.plugins import PluginSpec\n"
        "class Loud:\n"
        "    def summary(self, frames, duration_s):\n"
        f"        return {summary}\n"
        "LOUD = PluginSpec(Params=Params, build=lambda params, parts: Loud())\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "out"
    hooks = f'events.hooks=["{module}:LOUD"]'
    code = main(["run", "--quiet", "--set", "duration_s=5", "--set", hooks, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"netsim: error: {module}:LOUD: {said}")
    assert not out.exists()


@pytest.mark.parametrize("name", [":CIRCLE", "mymodels:"])
def test_a_plugin_path_missing_its_module_or_attribute_is_named_so(name):
    """``:CIRCLE`` and ``mymodels:`` are refused as paths missing a part (the first named
    netsim's own file as if the user's code had failed)."""
    with pytest.raises(ConfigError, match=r"must be 'package.module:attr', both parts given$"):
        plugins.resolve(plugins.MOBILITY, name, "mobility.model")


def test_a_controller_switched_on_by_its_section_is_refused_in_the_controllers_list(tmp_path, capsys):
    """An installed controller with an ``enabled`` key of its own (coverage) named in
    ``control.controllers`` is refused in one line that names the switch, exit 2, nothing
    written: listed there too it would be built twice."""
    from tests.fixtures import check_refused

    check_refused(
        tmp_path,
        capsys,
        ['control.controllers=["coverage"]'],
        "control.controllers",
        "is switched on by coverage.enabled = true, not listed here",
    )


def test_a_hook_with_a_section_of_its_own_is_refused(tmp_path, capsys, monkeypatch):
    """A hook is built from no keys (events.hooks names it, nothing sets it): one that
    declares a configuration section is refused in one line naming its place in the list,
    exit 2, nothing written, not run with its keys silently at their defaults."""
    from tests.fixtures import check_refused

    (tmp_path / "sectioned_hook.py").write_text(
        "from dataclasses import dataclass\n"
        "from netsim.params import Params, param, positive\n"
        "from netsim.plugins import PluginSpec\n"
        "@dataclass(frozen=True)\n"
        "class MyParams(Params):\n"
        "    section = 'mine'\n"
        "    every_s: float = param(1.0, positive, 's')\n"
        "HOOK = PluginSpec(Params=MyParams, build=lambda params, parts: None)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    check_refused(
        tmp_path,
        capsys,
        ['events.hooks=["link_breaks", "sectioned_hook:HOOK"]'],
        "events.hooks[1]",
        "a hook cannot own a configuration section",
    )
