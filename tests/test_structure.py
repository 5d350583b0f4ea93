"""The package's shape, read from its source: short entry points, no import cycle, nothing below an entry point that
ends the process, one function for the repository's root."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "searchrl"
MODULES = {
    ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts): path
    for path in PACKAGE.rglob("*.py")
    for rel in [path.relative_to(ROOT).with_suffix("")]
}
# Allowed to end the process: multirun.exits (how every entry point turns a ConfigError or Stopped into an exit
# status) and the notebooks' command line (a notebook is a script; its refusal is its last line).
ENDS_THE_PROCESS = {"searchrl.multirun", "searchrl.reporting.cli"}


def _is_entry_point(path: Path) -> bool:
    return path.name == "__main__.py" or 'if __name__ == "__main__":' in path.read_text()


def _module_level_imports(name: str, path: Path, inside_functions: bool = False) -> set[str]:
    """The searchrl modules `name` imports when it is loaded (with `inside_functions`, also those its functions
    import when they run)."""
    out: set[str] = set()
    tree = ast.parse(path.read_text())
    nodes = [n for top in tree.body for n in (ast.walk(top) if isinstance(top, (ast.If, ast.Try)) else [top])]
    if inside_functions:
        nodes = list(ast.walk(tree))
    for node in nodes:
        if isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: resolved against the module's package
                package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
                base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))
            submodules = {f"{base}.{a.name}" for a in node.names if f"{base}.{a.name}" in MODULES}
            out |= submodules if len(submodules) == len(node.names) else submodules | {base}
    return {m for m in out if m in MODULES and m != name}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = stack[stack.index(v) :]
            del stack[stack.index(v) :]
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_package_is_formatted_and_linted():
    """ruff's formatter and linter on the whole package (ruff pinned to a minor release in the dev extra), with no
    marker left that keeps the formatter off a line."""
    for command in (["format", "--check", "--quiet"], ["check", "--quiet"]):
        done = subprocess.run(
            [sys.executable, "-m", "ruff", *command, "searchrl"], cwd=ROOT, capture_output=True, text=True
        )
        assert done.returncode == 0, f"ruff {' '.join(command)} searchrl:\n{done.stdout}{done.stderr}"
    marker = re.compile(r"#\s*fmt:\s*(skip|off)")
    kept = [
        f"{p.relative_to(ROOT)}:{n}"
        for p in MODULES.values()
        for n, line in enumerate(p.read_text().splitlines(), 1)
        if marker.search(line)
    ]
    assert not kept, f"formatter markers in the package: {kept}"


def links_out(root: Path) -> list[str]:
    """Tracked files of the repository at `root` that are symbolic links to a path outside it (git's mode 120000)."""
    listed = subprocess.run(["git", "ls-files", "-s"], cwd=root, capture_output=True, text=True, check=True).stdout
    links = [line.split("\t", 1)[1] for line in listed.splitlines() if line.startswith("120000 ")]
    return [name for name in links if not (root / name).resolve().is_relative_to(root.resolve())]


def test_no_tracked_file_links_out_of_the_repository(tmp_path):
    """A clone holds no link to a path of another machine (a tracked `.venv` link once broke `python -m venv .venv`);
    the finder sees one planted in a repository of its own."""
    assert links_out(ROOT) == []
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=True)
    (tmp_path / ".venv").symlink_to("/usr/lib")
    (tmp_path / "inside").symlink_to("README")
    subprocess.run(["git", "add", ".venv", "inside"], cwd=tmp_path, check=True)
    assert links_out(tmp_path) == [".venv"]


def test_entry_points_are_short():
    """An entry point parses, calls the library and turns its errors into exit statuses: 80 lines at most."""
    entry_points = [p for p in MODULES.values() if _is_entry_point(p)]
    assert len(entry_points) >= 4  # train, evaluate, bench, render (and the checkpoint slimmer)
    long = {str(p.relative_to(ROOT)): n for p in entry_points if (n := len(p.read_text().splitlines())) > 80}
    assert not long, f"entry points over 80 lines: {long}"


def test_no_import_cycle():
    """Not even through an import deferred into a function (which only hides a cycle from the loader)."""
    graph = {name: _module_level_imports(name, path, inside_functions=True) for name, path in MODULES.items()}
    assert any(graph.values())  # the reader finds imports at all
    assert not _cycles(graph)


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert not _cycles({"a": {"b"}, "b": set()})


def test_nothing_below_the_entry_points_ends_the_process():
    """Below the entry points a refusal raises (ConfigError); only an entry point exits."""
    for name, path in MODULES.items():
        if _is_entry_point(path) or name in ENDS_THE_PROCESS:
            continue
        calls = {ast.unparse(n.func) for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Call)}
        raised = {
            ast.unparse(n.exc) for n in ast.walk(ast.parse(path.read_text())) if isinstance(n, ast.Raise) and n.exc
        }
        assert not calls & {"sys.exit", "exit", "quit", "os._exit"}, name
        assert not any(r.startswith("SystemExit") for r in raised), name


def test_one_function_gives_the_repository_root():
    """searchrl.shared_schema.repository_root; no other module climbs from its own file."""
    climbers = [name for name, path in MODULES.items() if "Path(__file__)" in path.read_text()]
    assert climbers == ["searchrl.shared_schema"]


def _is_compiled(node: ast.AST) -> bool:
    """A function under numba's @njit (an inlined one, `inline="always"`, is typed in its caller: not counted)."""
    if not isinstance(node, ast.FunctionDef):
        return False
    for d in node.decorator_list:
        target = d.func if isinstance(d, ast.Call) else d
        inline = isinstance(d, ast.Call) and any(
            k.arg == "inline" and ast.unparse(k.value) in {"'always'", '"always"'} for k in d.keywords
        )
        if ast.unparse(target) in {"njit", "numba.njit"} and not inline:
            return True
    return False


def _retyped_compiled_calls(sources: dict[str, str]) -> list[str]:
    """Calls, inside compiled functions, to a compiled function of `sources` (name: text) that would compile it
    again for other argument types: an int or bool constant (typed Literal[int](0), not int64), a prange loop's
    own index (uint64), or an argument left to its default (a type of its own)."""
    trees = {name: ast.parse(text) for name, text in sources.items()}
    params = {f.name: len(f.args.args) for tree in trees.values() for f in ast.walk(tree) if _is_compiled(f)}
    found = []
    for name, tree in trees.items():
        for caller in filter(_is_compiled, ast.walk(tree)):
            loops = [n for n in ast.walk(caller) if isinstance(n, ast.For) and ast.unparse(n.iter)[:7] == "prange("]
            for call in (n for n in ast.walk(caller) if isinstance(n, ast.Call)):
                callee = call.func.attr if isinstance(call.func, ast.Attribute) else getattr(call.func, "id", None)
                if callee not in params:
                    continue
                indices = {ast.unparse(loop.target) for loop in loops if call in ast.walk(loop)}
                for arg in call.args:
                    value = arg.operand if isinstance(arg, ast.UnaryOp) else arg
                    constant = isinstance(value, ast.Constant) and isinstance(value.value, int)  # bool is an int
                    if constant or ast.unparse(arg) in indices:
                        found.append(f"{name}:{call.lineno} {callee}(... {ast.unparse(arg)} ...)")
                if len(call.args) != params[callee] or call.keywords:
                    found.append(f"{name}:{call.lineno} {callee}: not every argument given by position")
    return found


def test_compiled_calls_keep_one_signature_per_function():
    """numba compiles a function once per argument types, and everything it calls with it: a constant or a prange
    index where elsewhere an int64 variable goes compiled the world's step three to six times over (a cold start
    spent 147 s compiling, 85 s since). Such arguments are given as np.int64(...)."""
    sources = {name: path.read_text() for name, path in MODULES.items()}
    assert sum(_is_compiled(n) for text in sources.values() for n in ast.walk(ast.parse(text))) > 40
    assert not _retyped_compiled_calls(sources)


def test_the_signature_finder_finds_each_kind():
    planted = """
@njit
def leaf(a, b, c=0):
    return a + b + c

@njit(inline="always")
def inlined(a):
    return a

@njit(parallel=True)
def top(n):
    s = leaf(0, n, n) + leaf(n, -1, n) + leaf(n, n) + leaf(np.int64(0), n, n) + inlined(0) + leaf(n, n, 0.5)
    for k in prange(n):
        s += leaf(k, n, n) + leaf(np.int64(k), n, n)
    return s
"""
    found = _retyped_compiled_calls({"m": planted})
    assert sorted(f.split(" ", 1)[1] for f in found) == [
        "leaf(... -1 ...)", "leaf(... 0 ...)", "leaf(... k ...)", "leaf: not every argument given by position",
    ], found  # fmt: skip


# Research code and user packages plug in through the registries and `extensions=` (docs/extending.md): nothing
# replaces a searchrl module's or class's attribute at run time, and no behaviour is switched by the environment.
# The one reader of the environment is the notebooks' command line (a notebook kernel takes no arguments, so its
# inputs may come from SEARCHRL_* variables, searchrl/reporting/cli.py `setting`).
ENVIRONMENT_READERS = {"searchrl/reporting/cli.py"}
SOURCES = sorted([*PACKAGE.rglob("*.py"), *(ROOT / "analysis").rglob("*.py"), *(ROOT / "conf").rglob("*.py"),
                  *(ROOT / "tests" / "extension_example").rglob("*.py")])  # fmt: skip


def _searchrl_names(tree: ast.AST) -> set[str]:
    """The names a module binds to searchrl's modules or objects by import."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {(a.asname or a.name).split(".")[0] for a in node.names if a.name.split(".")[0] == "searchrl"}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "searchrl":
            names |= {a.asname or a.name for a in node.names}
    return names


def _root(node: ast.AST) -> str | None:
    while isinstance(node, ast.Attribute | ast.Subscript):
        node = node.value
    return node.id if isinstance(node, ast.Name) else None


def _patches_and_environment_reads(source: str) -> tuple[list[int], list[int]]:
    """(lines that assign or delete an attribute of something imported from searchrl, or setattr it; lines that
    read os.environ or os.getenv, except to hand the whole environment to a child process, `{**os.environ, ...}`,
    or to give a library's own variable a default, `os.environ.setdefault(...)` as a statement of its own: it
    switches nothing of searchrl)."""
    tree = ast.parse(source)
    imported, patches, reads = _searchrl_names(tree), [], []
    handed_on = {
        id(v)
        for d in ast.walk(tree)
        if isinstance(d, ast.Dict)
        for k, v in zip(d.keys, d.values, strict=True)
        if k is None
    } | {  # a statement of its own: a default given, its value not read
        id(e.value.func.value)
        for e in ast.walk(tree)
        if isinstance(e, ast.Expr)
        and isinstance(e.value, ast.Call)
        and isinstance(e.value.func, ast.Attribute)
        and e.value.func.attr == "setdefault"
    }
    for node in ast.walk(tree):
        targets = (node.targets if isinstance(node, ast.Assign | ast.Delete)
                   else [node.target] if isinstance(node, ast.AugAssign | ast.AnnAssign) else [])  # fmt: skip
        if any(isinstance(t, ast.Attribute) and _root(t) in imported for t in targets):
            patches.append(node.lineno)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("setattr", "delattr"):
            if node.args and _root(node.args[0]) in imported:
                patches.append(node.lineno)
        if (
            isinstance(node, ast.Attribute)
            and node.attr in ("environ", "getenv")
            and _root(node) == "os"
            and id(node) not in handed_on
        ):
            reads.append(node.lineno)
    return patches, reads


def test_nothing_patches_searchrl_at_run_time_or_switches_on_the_environment():
    patched, read = [], []
    for path in SOURCES:
        rel = path.relative_to(ROOT).as_posix()
        patches, reads = _patches_and_environment_reads(path.read_text())
        patched += [f"{rel}:{line}" for line in patches]
        if rel not in ENVIRONMENT_READERS:
            read += [f"{rel}:{line}" for line in reads]
    # Shell scripts take their settings as arguments; the one variable read is the folder the device tool gives
    for path in sorted([*(ROOT / "analysis").glob("*.sh"), ROOT / ".ci" / "run"]):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            names = set(re.findall(r"\$\{([A-Z_][A-Z0-9_]*):?-", line)) - {"OUT"}
            read += [f"{path.relative_to(ROOT).as_posix()}:{number} ({name})" for name in sorted(names)]
    assert not patched, f"run-time patches of searchrl: {patched}"
    assert not read, f"reads of the environment outside {sorted(ENVIRONMENT_READERS)}: {read}"


def test_the_patch_finder_finds_each_kind():
    source = """
import os
import searchrl.train.app as app
from searchrl.controllers import factory
from searchrl.controllers.policy import PolicyController
import searchrl
app.make_vec_env = None
factory.POLICY_CONTROLLER: type = object
PolicyController.act = print
searchrl.world.engine.step = None
setattr(factory, "x", 1)
local = {}
local.x = 1
flag = os.environ.get("X") or os.getenv("Y")
child = {**os.environ, "A": "1"}
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
wait = os.environ.get("OMP_WAIT_POLICY", "ACTIVE")
switch = os.environ.setdefault("SEARCHRL_X", "0") == "1"
"""
    patches, reads = _patches_and_environment_reads(source)
    assert patches == [7, 8, 9, 10, 11] and sorted(reads) == [14, 14, 17, 18]


def test_no_code_points_into_the_lab_notebook():
    """The package, its configs and its tests cite the product docs (docs/*.md), never the lab notebook
    (docs/lab/: the log, the research and the performance narrative), which records history, not behaviour. The
    research scripts in analysis/ may: their figures are the notebook's."""
    lab = ROOT / "docs" / "lab"
    names = ["docs/lab", *(p.name for p in lab.glob("*.md") if not (ROOT / "docs" / p.name).exists())]
    pattern = re.compile("|".join(re.escape(n) for n in names))
    files = [*PACKAGE.rglob("*.py"), *(ROOT / "conf").rglob("*.yaml"), *(ROOT / "tests").rglob("*.py")]
    found = [f"{p.relative_to(ROOT)}:{n}" for p in sorted(files) if p.name not in ("test_docs.py", "test_structure.py")
             for n, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]  # fmt: skip
    assert names[1:] and not found, found


def test_no_tracked_file_is_a_link_out_of_the_repository():
    """A link that git tracks resolves inside the checkout: a link to a path of one machine (a virtual environment
    elsewhere) breaks every other clone, and `python -m venv .venv` there fails on it."""
    listing = subprocess.run(["git", "ls-files", "-s"], cwd=ROOT, capture_output=True, text=True, check=False)
    if listing.returncode != 0:
        pytest.skip("not a git checkout")
    links = [line.split("\t", 1)[1] for line in listing.stdout.splitlines() if line.startswith("120000 ")]
    outside = [link for link in links if not (ROOT / link).resolve().is_relative_to(ROOT.resolve())]
    assert not outside, f"tracked links that point out of the repository: {outside}"


# Below the training plan (searchrl/train/plan.py) the settings are typed objects: the world, the envs, the policies,
# the controllers, imitation and what a run is built from read dataclasses, never a config. The checkpoint reader is
# the one border below it: it reads a run's config.yaml into a typed PolicyRecord.
BELOW_THE_PLAN = [
    name
    for name in MODULES
    if name.split(".")[1:2] in (["world"], ["envs"], ["policies"], ["controllers"], ["imitation"])
    or name in ("searchrl.train.build", "searchrl.train.callbacks", "searchrl.train.logs", "searchrl.registry")
]
RECORD_READERS = {"searchrl.policies.checkpoint"}


def _config_imports(path: Path) -> list[str]:
    """The config libraries (omegaconf, hydra) a module imports, at any depth."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
        names += [node.module or ""] if isinstance(node, ast.ImportFrom) else []
        found += [n for n in names if n.split(".")[0] in ("omegaconf", "hydra")]
    return found


def test_nothing_below_the_plan_reads_a_config():
    assert len(BELOW_THE_PLAN) > 40
    reading = {name: _config_imports(MODULES[name]) for name in BELOW_THE_PLAN if name not in RECORD_READERS}
    assert not {name: found for name, found in reading.items() if found}


def test_the_config_finder_finds_a_planted_one(tmp_path):
    planted = tmp_path / "planted.py"
    planted.write_text("def f(cfg):\n    from omegaconf import DictConfig\n    import hydra.utils\n    return cfg\n")
    assert _config_imports(planted) == ["omegaconf", "hydra.utils"]
    assert _config_imports(MODULES["searchrl.train.plan"])  # the plan reads the composed config
