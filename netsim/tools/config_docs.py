"""The tables of keys of docs/configuration.md, made from the configuration's own
descriptions (the text ``netsim config`` prints), so that the page cannot fall behind the
code.

``python -m netsim.tools.config_docs`` rewrites the part of docs/configuration.md between
its two markers (``--check``: exit status 1 if it is stale, writing nothing);
``tests/test_config_docs.py`` fails while it is stale.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from netsim import config as cfgmod
from netsim.tools.args import Parser

PAGE = Path(__file__).resolve().parents[2] / "docs" / "configuration.md"
COMMAND = "python -m netsim.tools.config_docs"
BEGIN = f"<!-- the tables of keys below are made by `{COMMAND}` from the code's descriptions: edit those -->"
END = "<!-- end of the tables of keys -->"


def _value(v: Any) -> str:
    """A default as it is written in TOML."""
    import tomli_w

    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value(e) for e in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_value(e)}" for k, e in v.items()) + "}"
    if v is None:
        return "(none)"
    return tomli_w.dumps({"v": v}).split("=", 1)[1].strip()


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _owners(value: Any) -> list:
    if isinstance(value, cfgmod.ModelSection):
        return [value.params]
    if isinstance(value, cfgmod.ChannelParams):
        return [value, value.medium, value.radio, value.loss]
    return [value]


FOLLOWS = " (follows; set it to fix it)"


def default_rows() -> list[tuple[str, str, str]]:
    """(key, default, meaning) of every key of the built-in configuration; a default that
    follows another key is its rule."""
    config = cfgmod.Config()
    fields = cfgmod.Config.__dataclass_fields__
    rows = [(k, f"`{_value(getattr(config, k))}`", fields[k].metadata["doc"]) for k in ("seed", "duration_s")]
    for section in cfgmod.to_dict(config):
        if section in ("seed", "duration_s"):
            continue
        value = getattr(config, section)
        for key, v, doc, derived in cfgmod._section_rows(section, value):
            if derived:
                owner = next(p for p in _owners(value) if key in cfgmod.names(type(p)))
                shown = f"{cfgmod._rule(type(owner), key)}{FOLLOWS}"
            else:
                shown = f"`{_value(v)}`"
            rows.append((f"{section}.{key}", shown, doc))
    return rows


def other_model_rows() -> list[tuple[str, str, str, str]]:
    """(key, models, default, meaning) of the keys of the built-in models the default
    configuration does not choose (a key several of them share: once, naming them all, with
    each model's default where they differ), and the keys of the built-in configuration that
    another model gives another default. A default derived from other keys is its rule."""
    chosen = {k: shown.removesuffix(FOLLOWS) for k, shown, _ in default_rows()}
    merged: dict[str, tuple[list[tuple[str, str]], str]] = {}
    for section in ("mobility", "channel", "protocol"):
        for model, key, default, doc, rule in cfgmod._other_models(section):
            dotted = f"{section}.{key}"
            shown = rule if default is None and rule else f"`{_value(cfgmod.plain(default))}`"
            if chosen.get(dotted) != shown:
                merged.setdefault(dotted, ([], doc))[0].append((model, shown))
    rows = []
    for key, (per_model, doc) in merged.items():
        models = ", ".join(f"`{m}`" for m, _ in per_model)
        if len({shown for _, shown in per_model}) == 1:
            default = per_model[0][1]
        else:
            default = ", ".join(f"{shown} (`{m}`)" for m, shown in per_model)
        rows.append((key, models, default, doc))
    return rows


def tables() -> str:
    """The generated part of the page, markers included."""
    out = [
        BEGIN,
        "",
        "## Keys",
        "",
        "The built-in configuration, every key (`netsim config` prints the same, as a file to edit): the"
        " engine's, and those of the default models (random waypoint's speeds and pause, the clustering's"
        " timings, ...); another model named in its section reads its own keys instead (below), and a key"
        " of the default model left beside it is warned of and ignored:",
        "",
        "| key | default | meaning |",
        "| --- | --- | --- |",
    ]
    out += [f"| `{key}` | {_cell(default)} | {_cell(doc)} |" for key, default, doc in default_rows()]
    out += [
        "",
        "## Keys of the other built-in models",
        "",
        "Read when the section names the model (`mobility.model`, `protocol.model`, `channel.propagation`, "
        "`channel.loss_model`, `channel.mac`):",
        "",
        "| key | model | default | meaning |",
        "| --- | --- | --- | --- |",
    ]
    out += [f"| `{key}` | {models} | {_cell(d)} | {_cell(doc)} |" for key, models, d, doc in other_model_rows()]
    return "\n".join([*out, "", END])


def render(page: str) -> str:
    """``page`` with its generated part made anew."""
    start, end = page.find(BEGIN), page.find(END)
    if start < 0 or end < start:
        raise ValueError(f"the page has no markers {BEGIN!r} ... {END!r}")
    return page[:start] + tables() + page[end + len(END) :]


def main(argv: list[str] | None = None) -> int:
    p = Parser(prog=COMMAND, description="Remake the tables of keys of docs/configuration.md.")
    p.add_argument("--check", action="store_true", help="exit status 1 if the page is stale; write nothing")
    args = p.parse_args(argv)
    page = PAGE.read_text()
    fresh = render(page)
    if args.check:
        if fresh != page:
            print(f"{PAGE}: stale; run {COMMAND}", file=sys.stderr)
            return 1
        return 0
    if fresh != page:
        PAGE.write_text(fresh)
        print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
