"""Every command in the README runs (a doc test).

The README's fenced blocks are taken in order and played in one scratch directory, as a
reader following it would:

- shell blocks (``bash``, ``sh``, ``shell``): each command line runs in ``bash`` with this
  environment's ``netsim`` first on the PATH, and must exit 0;
- ``console`` blocks: transcripts; each ``$ command`` runs and its output must be the
  lines shown under it;
- ``toml`` and ``python`` blocks whose first line is ``# name`` are files: written under
  that name (a TOML file must load as a scenario or a sweep); other ``python`` blocks run.

A block of any other language, or of none, fails the test: no command can sit in the
README untested.

Commands that would take minutes run with reduced parameters, by the explicit mapping
``REDUCED`` below (README line -> what runs instead, and why), and every ``netsim run``
that does not set ``duration_s`` simulates 60 s instead of the default 300 (``SHORTER``);
every other command runs exactly as written. Two checks keep the mapping honest: every entry must still match a
README line, and the commands table's synopses must name only options the CLI has, each
command with a runnable example. The experiment scripts of docs/experiments.md run in
``tests/test_experiments.py`` (at tiny sizes); this test checks that each is there, and
that ``.ci/run`` runs the README's test command as written.
"""

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from netsim import config as cfgmod
from netsim.tools import sweep as sweepmod
from netsim.tools import validate
from netsim.tools.cli import main, parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
SHELLS = ("bash", "sh", "shell")
PY = shlex.quote(sys.executable)

# README line -> (what runs instead, why). "{scheduler}" is the address of a Dask
# scheduler this test starts; "@validate" runs `netsim validate` in this process with its
# three quickest checks.
REDUCED = {
    "python3 -m venv .venv && source .venv/bin/activate": (
        "python3 -m venv --without-pip .venv && source .venv/bin/activate",
        "the commands that follow run this environment's netsim, not the new one's: its pip is not needed",
    ),
    "pip install -e . && netsim run": (
        "netsim run",
        "the environment running this test is that install; its netsim runs the default scenario",
    ),
    'pip install -e ".[test]" && python -m pytest -q -n auto': (
        f"cd {shlex.quote(str(ROOT))} && {PY} -m pytest -q --collect-only -p no:cacheprovider tests/test_readme.py",
        "the suite cannot run itself, and running it already imports every test module: the command"
        " line is checked by collecting this module",
    ),
    "netsim bridge --set mobility.model=external --set duration_s=10 --out runs/bridge"
    '   # needs pip install -e ".[ros]"': (
        "netsim bridge --set mobility.model=external --set duration_s=10 --out runs/bridge --rate 20",
        "the same run, at 20 simulated seconds per wall second instead of real time",
    ),
    "netsim figures": (
        "netsim figures --set duration_s=60",
        "the built-in coverage scenario, 60 simulated seconds instead of 300",
    ),
    "python -m tests.calibration_logs --write site.csv      # from the repository's folder": (
        f"PYTHONPATH={shlex.quote(str(ROOT))} {PY} -m tests.calibration_logs --write site.csv",
        "the test helpers are the repository's, not the install's: found from the repository's root",
    ),
    "netsim validate": ("@validate", "the full validation takes about a minute; its quick checks run"),
    "netsim sweep speed.toml --scheduler tcp://head:8786     # an existing Dask cluster": (
        "netsim sweep speed.toml --scheduler {scheduler}",
        "a local Dask scheduler stands in for the cluster 'head'",
    ),
}

# Appended to a `netsim run` command that does not set the simulated time.
SHORTER = " --set duration_s=60"

# Files the README defines, reduced the same way: file -> {dotted key: value}.
REDUCED_FILES = {
    "speed.toml": {"replications": 1, "base.duration_s": 20.0, "base.world.n_robots": 10},
}


def blocks(text: str) -> list[tuple[str, str]]:
    """(language, body) of every fenced block, in order."""
    return [(m[1], m[2]) for m in re.finditer(r"^```(\w*)\n(.*?)^```", text, re.S | re.M)]


def commands(body: str) -> list[str]:
    lines, out = body.splitlines(), []
    for line in lines:
        if out and out[-1].endswith("\\"):
            out[-1] = out[-1][:-1] + line.strip()
        elif line.strip() and not line.lstrip().startswith("#"):
            out.append(line.strip())
    return out


def _set_dotted(tree: dict, dotted: str, value) -> None:
    *path, last = dotted.split(".")
    for part in path:
        tree = tree[part]
    tree[last] = value


def write_file(name: str, body: str) -> None:
    if name in REDUCED_FILES:
        tree = tomllib.loads(body)
        for key, value in REDUCED_FILES[name].items():
            _set_dotted(tree, key, value)
        import tomli_w

        body = tomli_w.dumps(tree)
    Path(name).write_text(body)
    if name.endswith(".toml"):
        tree = tomllib.loads(body)
        if "grid" in tree or "random" in tree:
            sweepmod.load_file(name).runs()
        else:
            cfgmod.load(name)


def run_validate_quickly(monkeypatch) -> None:
    quick = (validate.check_unit_disk, validate.check_exact_links)
    monkeypatch.setattr(validate, "CHECKS", [c for c in validate.CHECKS if c.check in quick])
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["validate", "--no-progress"]) == 0
    rows = len(validate.check_unit_disk()) + len(validate.check_exact_links())
    assert f"{rows} of {rows} checks passed" in out.getvalue()


def shell(command: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", command], env=env, capture_output=True, text=True, timeout=600)


@pytest.mark.slow
def test_every_readme_command_runs(tmp_path, monkeypatch):
    from distributed import LocalCluster

    monkeypatch.chdir(tmp_path)
    (tmp_path / "README.md").write_text(README)  # the console transcript names it
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    ran, used = [], set()
    with LocalCluster(n_workers=1, processes=False, protocol="tcp", dashboard_address=None) as cluster:
        for lang, body in blocks(README):
            first = body.splitlines()[0] if body.strip() else ""
            named = re.fullmatch(r"# ([\w.-]+\.(?:py|toml))", first)
            if lang in ("toml", "python") and named:
                write_file(named[1], body)
            elif lang == "python":
                exec(compile(body, "<README python block>", "exec"), {"__name__": "readme"})
                ran.append(body.splitlines()[0])
            elif lang in SHELLS:
                for command in commands(body):
                    run, _why = REDUCED.get(command, (command, ""))
                    if command in REDUCED:
                        used.add(command)
                    if run == "@validate":
                        run_validate_quickly(monkeypatch)
                    else:
                        if re.search(r"\bnetsim run\b", run) and "duration_s=" not in run:
                            run += SHORTER
                        done = shell(run.format(scheduler=cluster.scheduler_address), env)
                        assert done.returncode == 0, f"{command}\n{done.stderr[-3000:]}"
                    ran.append(command)
            elif lang == "console":
                lines = body.splitlines()
                for k, line in enumerate(lines):
                    if not line.startswith("$ "):
                        continue
                    expected = []
                    for later in lines[k + 1 :]:
                        if later.startswith("$ "):
                            break
                        expected.append(later)
                    done = shell(line[2:], env)
                    assert (done.stdout + done.stderr).splitlines() == expected, line
                    ran.append(line[2:])
            else:
                pytest.fail(f"a README block that this test cannot check: ```{lang}\n{body[:200]}")
    assert set(REDUCED) == used, f"mapping entries no README line matches: {set(REDUCED) - used}"
    assert len(ran) >= 15
    assert (tmp_path / "netsim-out" / "manifest.json").is_file()
    assert (tmp_path / "netsim-figures" / "fig8_final_deployment.png").is_file()


def test_commands_table_names_only_real_options():
    """Each synopsis of the commands table: its command exists, every option it names is
    the CLI's, and the README runs an example of it."""
    section = README.split("## Commands", 1)[1].split("\n## ", 1)[0]
    synopses = re.findall(r"^\| `(netsim [^`]+)` \|", section, re.M)
    assert len(synopses) >= 6
    subparsers = next(a for a in parser()._actions if a.dest == "command").choices
    examples = [c for lang, body in blocks(README) if lang in SHELLS for c in commands(body)]
    for synopsis in synopses:
        words = synopsis.replace("\\|", "|").split()
        sub = subparsers[words[1]]
        if words[1] == "scenario":
            sub = next(a for a in sub._actions if a.dest == "scenario_command").choices[words[2]]
        known = {o for a in sub._actions for o in a.option_strings}
        named = {re.sub(r"[\[\]|]", "", w) for w in words if re.match(r"\[?-", w)}
        assert named <= known, (synopsis, named - known)
        head = " ".join(words[:3] if words[1] == "scenario" else words[:2])
        assert any(c.startswith(head) or f" {head}" in c for c in examples), f"no example of {head}"


def test_every_readme_block_is_one_this_test_checks():
    """Every fenced block of the README is a shell block, a console transcript, a named
    file, or Python that runs: none escapes test_every_readme_command_runs."""
    for lang, body in blocks(README):
        first = body.splitlines()[0] if body.strip() else ""
        named = re.fullmatch(r"# ([\w.-]+\.(?:py|toml))", first)
        assert lang in (*SHELLS, "console", "python") or (lang == "toml" and named), (lang, first)


def test_ci_runs_the_readmes_test_command():
    """.ci/run ends with the README's test command, exactly as written, in the activated
    virtual environment."""
    quick_start = README.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    test_command = next(c for lang, body in blocks(quick_start) for c in commands(body) if "pytest" in c)
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-2:] == ["source .venv/bin/activate", test_command]


def test_every_experiment_in_the_docs_is_run_by_the_experiment_tests():
    from tests.test_experiments import CASES

    named = set(re.findall(r"`python experiments/(\w+\.py)`", (ROOT / "docs" / "experiments.md").read_text()))
    assert named and named <= {case[0] for case in CASES}


def test_every_readme_file_block_loads():
    """The scenario and sweep files the README shows are valid as shown (quick, not slow)."""
    for lang, body in blocks(README):
        named = re.fullmatch(r"# ([\w.-]+\.toml)", body.splitlines()[0]) if body.strip() else None
        if lang == "toml" and named:
            tree = tomllib.loads(body)
            if "grid" in tree or "random" in tree:
                sweepmod.parse(tree).runs()
            else:
                cfgmod.from_dict(tree)


@pytest.mark.parametrize("page", ["README.md", "docs/sweeps.md"])
def test_the_sweep_files_base_file_comment_stands_where_it_is_valid(page, tmp_path, monkeypatch):
    """The sweep file a page shows names ``base_file`` in a comment: written out as a line
    where the comment stands (after the code on that line), the file is a valid sweep
    starting from that scenario file."""
    monkeypatch.chdir(tmp_path)
    Path("my.toml").write_text("seed = 7\n")
    shown = [body for lang, body in blocks((ROOT / page).read_text()) if lang == "toml" and "[grid]" in body]
    assert shown and any("base_file" in body for body in shown)
    for body in shown:
        lines = []
        for line in body.splitlines():
            code, _, comment = line.partition("#")
            named = re.search(r'base_file = "[^"]+"', comment)
            lines += [code] if code.strip() or not named else []
            lines += [named[0]] if named else []
        sweep = sweepmod.parse(tomllib.loads("\n".join(lines)), tmp_path / "speed.toml")
        assert sweep.base["seed"] == 7  # the scenario file was read
