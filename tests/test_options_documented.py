"""docs/options.md lists every option, and only options that exist.

The settings are read from the code: the world's (`WorldConfig`), the scenario's parts (`OBSTACLES`, `PRIORS`,
`TARGETS`), each registered controller's schema (`HEURISTICS`), training's (`TrainConfig` and its nested
dataclasses, the three algorithm schemas) and evaluation's (`EvaluateConfig`). The page's tables are read section
by section (a `##` or `###` heading; a controller's heading names it in backticks), each row's first cell one key
in backticks. A setting without a row, a row without a setting, or a row whose "needed by" cell is empty fails
here.
"""

from __future__ import annotations

import re
import types
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Union, get_args, get_origin, get_type_hints

from searchrl.controllers.registry import HEURISTICS
from searchrl.evaluate.schema import EvaluateConfig
from searchrl.train.schema import A2CConfig, RecurrentPPOConfig, TrainConfig
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import OBSTACLES, PRIORS, TARGETS

PAGE = Path(__file__).resolve().parents[1] / "docs" / "options.md"
COLUMNS = ["option", "default", "what it does", "needed by"]
ALGOS = (RecurrentPPOConfig, A2CConfig)  # `algo` is untyped in TrainConfig: one of these, by `algo=`


def nested_schema(hint: object) -> tuple[type | None, bool]:
    """(the dataclass a field's type holds, whether as a list): `X`, `X | None` and `list[X]`; (None, False) else."""
    if is_dataclass(hint):
        return hint, False
    origin, args = get_origin(hint), get_args(hint)
    if origin is list and args and is_dataclass(args[0]):
        return args[0], True
    if origin in (Union, types.UnionType):
        inner = [a for a in args if is_dataclass(a)]
        if len(inner) == 1:
            return inner[0], False
    return None, False


def dotted_keys(schema: type, prefix: str = "", skip: frozenset[str] = frozenset()) -> set[str]:
    """Every setting of `schema` as the dotted key a user types, nested dataclasses flattened (a list of them as
    `key` and `key[].<field>`), the keys in `skip` and everything under them left out."""
    hints = get_type_hints(schema)
    keys: set[str] = set()
    for f in fields(schema):
        key = prefix + f.name
        if key in skip:
            continue
        if key == "algo":
            keys |= {k for algo in ALGOS for k in dotted_keys(algo, "algo.")}
            continue
        nested, is_list = nested_schema(hints[f.name])
        if nested is None:
            keys.add(key)
        elif is_list:
            keys.add(key)
            keys |= dotted_keys(nested, f"{key}[].", skip)
        else:
            keys |= dotted_keys(nested, f"{key}.", skip)
    return keys


def code_options() -> dict[str, set[str]]:
    """Section of docs/options.md -> the keys the code has for it."""
    scenario = set()
    for part, kinds in (("obstacles", OBSTACLES), ("prior", PRIORS), ("targets", TARGETS)):
        scenario.add(f"scenario.{part}.kind")
        scenario |= {f"scenario.{part}.{f.name}" for cls in kinds.values() for f in fields(cls)}
    scenario.add("scenario.mix")  # a training distribution over whole scenarios (ScenarioMix.from_spec)
    controllers = {name: {f"controller.{f.name}" for f in fields(entry.schema) if f.name != "name"}
                   for name, entry in HEURISTICS.items()}  # fmt: skip
    return {
        "World": {f"env.world.{f.name}" for f in fields(WorldConfig)},
        "Scenario": scenario,
        **controllers,  # one section per controller, named by its heading
        # env.world and scenario have their own sections
        "Training": dotted_keys(TrainConfig, skip=frozenset({"env.world", "scenario"})),
        # env.world: World (env.n_worlds and env.extra_teams are refused by evaluation); controller: Controllers
        "Evaluation": dotted_keys(EvaluateConfig, skip=frozenset({"env", "controller", "scenario"})),
    }


def cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def page_rows() -> dict[str, list[list[str]]]:
    """Section -> the cells of each row of its tables. A heading with a name in backticks is that name's section
    (`### \\`greedy\\``), any other heading its own text; a table's header is checked against COLUMNS."""
    sections: dict[str, list[list[str]]] = {}
    section = ""
    lines = PAGE.read_text().splitlines()
    for i, line in enumerate(lines):
        heading = re.match(r"#{1,6} (.*)", line)
        if heading:
            named = re.search(r"`([^`]+)`", heading.group(1))
            section = named.group(1) if named else heading.group(1).strip()
            sections.setdefault(section, [])
            continue
        if not line.startswith("|") or re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", line.strip()):
            continue
        if i + 1 < len(lines) and lines[i + 1].startswith("|---"):
            assert cells(line) == COLUMNS, f"docs/options.md, {section}: a table's columns must be {COLUMNS}"
            continue
        sections[section].append(cells(line))
    return sections


def test_every_option_is_documented():
    """The keys of each section of the page are exactly the code's: none missing, none stale."""
    expected = code_options()
    documented: dict[str, list[str]] = {}
    problems = []
    for section, rows in page_rows().items():
        for row in rows:
            key = re.fullmatch(r"`([^`]+)`", row[0])
            if not key:
                problems.append(f"{section}: a row's first cell is not one key in backticks: {row[0]!r}")
                continue
            documented.setdefault(section, []).append(key.group(1))
    for section in sorted(set(expected) | set(documented)):
        keys = documented.get(section, [])
        duplicates = sorted({k for k in keys if keys.count(k) > 1})
        missing = sorted(expected.get(section, set()) - set(keys))
        stale = sorted(set(keys) - expected.get(section, set()))
        if section not in expected:
            problems.append(f"section {section!r} has options, but the code has no such section: {stale}")
            continue
        if missing:
            problems.append(f"{section}: in the code, not in the page: {missing}")
        if stale:
            problems.append(f"{section}: in the page, not in the code: {stale}")
        if duplicates:
            problems.append(f"{section}: listed twice: {duplicates}")
    assert not problems, "docs/options.md does not match the code's options:\n" + "\n".join(problems)


def test_every_option_says_what_needs_it():
    """Each row has its four cells, and the last, "needed by", is not empty."""
    problems = [
        f"{section}: {row[0]}" + (f" has {len(row)} cells" if len(row) != len(COLUMNS) else ' has no "needed by"')
        for section, rows in page_rows().items()
        for row in rows
        if len(row) != len(COLUMNS) or not row[-1].strip(" -–")
    ]
    assert not problems, "docs/options.md rows without what needs them:\n" + "\n".join(problems)
