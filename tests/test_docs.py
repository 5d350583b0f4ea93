"""The README is a user guide that stays short and runs; the docs say only what their cited outputs say.

- README.md has at most 250 lines, and every command in its `bash` blocks parses: Hydra composes the train and
  evaluate overrides, render and bench accept their flags, and every file a command names exists.
- Every relative link and image in README.md and docs/*.md points at a file of the repository.
- A block that follows `<!-- cite: <path> -->` (a table, a list or a fenced block, up to the next blank line or
  closing fence) quotes `<path>`: each of its lines is a line of that file, so a rerun that changes a number
  without the docs following fails here.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir

import searchrl.evaluate.app
import searchrl.train.app  # noqa: F401  (registers the training schemas)
from searchrl.shared_schema import CONF_DIR

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").rglob("*.md"))]  # the product docs and the lab notebook (docs/lab/)
CITE = re.compile(r"<!-- cite: (\S+) -->")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def bash_commands(text: str) -> list[str]:
    """The commands of the ```bash blocks: continuation lines joined, comments and shell assignments dropped."""
    commands: list[str] = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            line = line.split(" #")[0].strip()
            if line and not line.startswith("#"):
                commands.extend(part.strip() for part in line.split("&&"))
    return commands


def test_readme_is_a_short_guide():
    lines = README.read_text().splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines; results and history belong in docs/"


def test_ci_runs_the_readme_test_command():
    """The install section's second command (the one that ends in pytest) is a line of `.ci/run`."""
    commands = re.findall(r"```bash\n(.*?)\n```", README.read_text().split("## Install")[1], flags=re.S)
    test_command = next(c for c in commands if c.endswith("python -m pytest"))
    assert test_command in (ROOT / ".ci" / "run").read_text().splitlines()


def _compose(app: str, overrides: list[str]) -> None:
    hydra_keys = [o for o in overrides if o.startswith(("hydra/", "hydra."))]
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        compose(config_name=app, overrides=overrides, return_hydra_config=bool(hydra_keys))


def _check_paths(words: list[str]) -> None:
    for word in words:
        value = word.split("=", 1)[-1]
        if value.endswith((".zip", ".py", ".yaml")) and "<" not in value:
            assert (ROOT / value).is_file(), f"{word}: no file {value}"


def _help(module, capsys) -> str:
    with pytest.raises(SystemExit):
        module.main(["--help"])
    return capsys.readouterr().out


@pytest.mark.parametrize("command", bash_commands(README.read_text()))
def test_readme_command_parses(command, capsys):
    words = shlex.split(command)
    if words[0] == "pip":
        return
    assert words[0] == "python", f"unexpected command {command!r}"
    if "<" in command:  # a placeholder the user fills in (a run folder): the rest is checked in its other examples
        return
    if words[1] == "-m":
        module, args = words[2], words[3:]
        if "-m" in args:  # a multirun sweep: compose its first job (the first value of each swept list)
            args = [re.sub(r"=([^\[,]*),.*", r"=\1", a) for a in args if a != "-m"]
        args = [a for a in args if a not in ("--cfg", "job")]
        _check_paths(args)
        if module in ("searchrl.train", "searchrl.evaluate"):
            _compose(module.split(".")[1], args)
        elif module in ("searchrl.render", "searchrl.bench"):
            import importlib

            mod = importlib.import_module(module if module == "searchrl.render" else "searchrl.bench.__main__")
            text = _help(mod, capsys)
            for flag in (a.split("=")[0] for a in args if a.startswith("--")):
                assert flag in text, f"{command!r}: {flag} is not an option of {module}"
            for subcommand in (a for a in args if not a.startswith("-") and module == "searchrl.bench"):
                assert subcommand in text, f"{command!r}: no subcommand {subcommand}"
                break
        elif module != "pytest":
            raise AssertionError(f"unexpected module in {command!r}")
    else:
        assert (ROOT / words[1]).is_file(), f"{command!r}: no script {words[1]}"


@pytest.mark.slow  # the README's shell commands are checked in the default run
def test_readme_python_examples_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "README has no python example"
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_links_point_at_files(page):
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    for target in LINK.findall(text):
        if target.startswith(("http://", "https://", "#", "mailto:")):
            continue
        path = (page.parent / target.split("#")[0]).resolve()
        assert path.exists(), f"{page.name}: link to {target}, which does not exist"


def cited_blocks(text: str) -> list[tuple[str, list[str]]]:
    """(cited path, quoted lines) for every cite marker of a page."""
    blocks = []
    for match in CITE.finditer(text):
        rest = text[match.end() :].lstrip("\n").splitlines()
        quoted: list[str] = []
        if rest and rest[0].startswith("```"):
            for line in rest[1:]:
                if line.startswith("```"):
                    break
                quoted.append(line)
        else:
            for line in rest:
                if not line.strip():
                    break
                quoted.append(line)
        blocks.append((match.group(1), [q for q in quoted if q.strip()]))
    return blocks


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_cited_blocks_quote_their_outputs(page):
    for path, quoted in cited_blocks(page.read_text()):
        source = ROOT / path
        assert source.is_file(), f"{page.name} cites {path}, which does not exist"
        assert quoted, f"{page.name}: the citation of {path} quotes nothing"
        lines = set(source.read_text().splitlines())
        for line in quoted:
            assert line in lines, f"{page.name} quotes {path}, which has no line {line!r}"


def test_the_cite_check_catches_a_changed_number(tmp_path):
    page = "<!-- cite: analysis/out/claims.md -->\n- b − c: better on 3 of 30 cells\n"
    [(path, quoted)] = cited_blocks(page)
    assert path == "analysis/out/claims.md" and quoted == ["- b − c: better on 3 of 30 cells"]
    assert quoted[0] not in set((ROOT / path).read_text().splitlines())


def test_the_docs_name_only_registered_controllers_and_controllers_md_names_every_one():
    """Names come from the registry: a `controller=<name>` or `imitation.teacher=<name>` in the README, the docs or
    the configs is registered, and docs/controllers.md gives every registered heuristic its name in backticks."""
    from searchrl.controllers.registry import HEURISTICS

    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "conf").rglob("*.yaml"))]
    # a user's package registers its own (docs/extending.md's example), and so do the research modules of analysis/
    modules = [*(ROOT / "tests" / "extension_example").glob("*.py"), *(ROOT / "analysis").glob("*.py")]
    users = {m for p in modules for m in re.findall(r'register\("([a-z_]+)"', p.read_text())}
    for page in pages:
        if page.name == "log.md":  # history: commands as they were run then
            continue
        for name in re.findall(r"(?:controller|imitation\.teacher)=([a-z_]+)\b", page.read_text()):
            assert name in HEURISTICS or name in ("name", "null", *users), (page.name, name)
    text = (ROOT / "docs" / "controllers.md").read_text()
    assert [name for name in HEURISTICS if f"`{name}`" not in text and f"controller={name}" not in text] == []


GROUPS = ("scenario", "suite", "model", "experiment", "machine", "algo", "network", "world", "teacher", "families")


def test_the_docs_name_only_group_options_that_exist():
    """A `<group>=<option>` in the README, the docs, the configs or the analysis scripts names a file of conf/<group>/
    (schema.group_options): a renamed scenario, suite, recipe or model cannot leave a stale command behind."""
    from searchrl.shared_schema import group_options

    options = {group: set(group_options(group)) for group in GROUPS}
    for path in (ROOT / "tests" / "extension_example").glob("*.py"):  # what a user's package stores (extending.md)
        for group, name in re.findall(r'group="([a-z]+)",\s*name="([a-z_]+)"', path.read_text()):
            options[group].add(name)
        options["network"].update(re.findall(r'@register_network\("([a-z_]+)"\)', path.read_text()))  # network=<name>
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "conf").rglob("*.yaml")),
             *sorted((ROOT / "analysis").glob("*.py")), *sorted((ROOT / "analysis").glob("*.sh"))]  # fmt: skip
    stale = []
    for page in pages:
        if page.name == "log.md":  # history: commands as they were run then
            continue
        text = page.read_text()
        if page.suffix == ".py":  # a notebook's commands are in its comments; its code's `world=` is a Python name
            text = "\n".join(line for line in text.splitlines() if line.lstrip().startswith("#"))
        for group, name in re.findall(
            rf"(?<![\w.]){'|'.join(GROUPS).join('()')}=([a-z0-9_]+(?:/[a-z0-9_]+)*)(?![\w/<{{$*,])", text
        ):
            if name not in options[group] and name not in ("null", "none"):
                stale.append(f"{page.relative_to(ROOT)}: {group}={name}")
        # and the lists "`algo` (`recurrent_ppo`, `a2c`)" that say which options a group has
        for group, listed in re.findall(rf"`({'|'.join(GROUPS)})` \(((?:`[a-z0-9_]+`(?:, )?)+)\)", text):
            names = re.findall(r"`([a-z0-9_]+)`", listed)
            stale += [f"{page.relative_to(ROOT)}: {group} lists {name}" for name in names if name not in options[group]]
    assert not stale, stale


def test_the_trainable_models_are_the_files_of_conf_model():
    from searchrl.shared_schema import TRAINABLE_MODELS, group_options

    assert group_options("model") == sorted(TRAINABLE_MODELS)


def test_the_settings_reference_names_every_scenario_and_suite():
    """docs/options.md, the settings' reference, names every scenario file and every suite."""
    from searchrl.shared_schema import group_options

    text = (ROOT / "docs" / "options.md").read_text()
    missing = [f"{g}={o}" for g in ("scenario", "suite") for o in group_options(g) if f"`{o}`" not in text
               and f"{g}={o}" not in text]  # fmt: skip
    assert not missing, missing


@pytest.mark.parametrize("app", ["train", "evaluate"])
def test_help_names_groups_and_options_that_exist_and_where_the_options_are(app):
    """`--help` (hydra.help.template): each group it lists is a folder of conf/, each option it names a file there,
    each page it points to exists; no schema pseudo-option."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name=app, overrides=[], return_hydra_config=True)
    text = cfg.hydra.help.template
    block = text.split("Groups (group=option, each a folder of conf/):\n")[1].split("\n\n")[0]
    groups = 0
    for line in block.splitlines():
        group, listed = line.split(None, 1)
        folder = ROOT / "conf" / group.lstrip("+")
        assert folder.is_dir(), f"--help of {app} names group {group}: no {folder}"
        for option in listed.split(":")[0].split(","):
            option = option.replace("(default)", "").strip()
            if option and "<" not in option:
                assert (folder / f"{option}.yaml").is_file(), f"--help of {app}: {group}={option} does not exist"
        groups += 1
    assert groups >= 5 and "_schema" not in text
    for page in re.findall(r"docs/\w+\.md", text):
        assert (ROOT / page).is_file(), page


def test_every_figure_the_readme_embeds_is_written_by_a_notebook_it_names():
    """An image of analysis/out/ in the README is an output of the analysis script its caption names (the script's
    source writes a file of that name), so the figure can be made again and its caption says by what."""
    images = re.findall(r"!\[([^\]]*)\]\((analysis/out/[^)]+\.png)\)", README.read_text())
    assert images
    for caption, path in images:
        scripts = re.findall(r"analysis/\w+\.py", caption)
        assert scripts, f"README's {path}: its caption names no analysis script"
        assert any(Path(path).name in (ROOT / script).read_text() for script in scripts), (path, scripts)


def test_the_product_docs_stay_a_reference_and_the_lab_notebook_holds_the_rest():
    """README a user guide (<= 250 lines), the product docs (README and docs/*.md, not docs/lab/) <= 1,600 lines, and
    results.md a reference of about 300."""
    lines = {
        path.name: len(path.read_text().splitlines()) for path in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]
    }
    assert lines["README.md"] <= 250 and lines["results.md"] <= 330, lines
    assert sum(lines.values()) <= 1600, lines
