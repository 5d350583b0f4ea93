"""A seed draws the same worlds on every x86-64 CPU, with AVX-512 or without.

numpy runs some float64 ufuncs (exp, log, power, the trigonometric ones) in code written for the CPU's vector unit
where the CPU has one it dispatches to: on AVX-512 their last bit differs from the C library's for a few inputs in a
thousand. The world, its scenarios, the heuristics and the search bound compute such functions through the C
library instead (searchrl/world/libm.py). Two checks hold them to it, on whatever CPU runs the suite:
- the source: no module of the world, the envs or the controllers calls one of those ufuncs outside compiled code;
- the bits: a child process with every numpy vector feature of this CPU switched off (NPY_DISABLE_CPU_FEATURES:
  on an AVX-512 CPU the child runs numpy as a CPU without AVX-512 does; on an AVX2 CPU, as one without AVX2) draws
  every frozen scenario's worlds, Γ, the heuristics' reach weights and the bound's target marginals, and they equal
  this process's bit for bit. tests/test_frozen_worlds.py holds this process's worlds to the recorded digests.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
# numpy's float64 ufuncs with code of their own for a vector unit (numpy/_core/src/umath/*.dispatch.*)
VECTOR_UFUNCS = {"exp", "exp2", "expm1", "log", "log2", "log10", "log1p", "power", "float_power", "sin", "cos",
                 "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh", "arcsinh", "arccosh",
                 "arctanh", "cbrt", "hypot"}  # fmt: skip
SCOPE = ("world", "envs", "controllers")


def _compiled(node: ast.AST) -> bool:
    """A function under numba's @njit (inlined or not): its np.* calls are numba's, the C library's per element."""
    return isinstance(node, ast.FunctionDef) and any(
        ast.unparse(d.func if isinstance(d, ast.Call) else d) in {"njit", "numba.njit"} for d in node.decorator_list
    )


def numpy_vector_calls(source: str, name: str = "<source>") -> list[str]:
    """`name:line np.f(...)` for each call of a VECTOR_UFUNCS ufunc of numpy outside compiled functions, and each
    `a ** b` there whose exponent is not an int literal (on a float array that is np.power)."""
    tree = ast.parse(source)
    inside = {id(n) for f in ast.walk(tree) if _compiled(f) for n in ast.walk(f)}
    found = []
    for node in ast.walk(tree):
        if id(node) in inside:
            continue
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in VECTOR_UFUNCS:
            if ast.unparse(node.func.value) in {"np", "numpy"}:
                found.append(f"{name}:{node.lineno} {ast.unparse(node.func)}(...)")
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            exponent = node.right.operand if isinstance(node.right, ast.UnaryOp) else node.right
            if not (isinstance(exponent, ast.Constant) and isinstance(exponent.value, int)):
                found.append(f"{name}:{node.lineno} {ast.unparse(node)}")
    return found


def test_the_world_calls_no_numpy_vector_ufunc():
    """The world, envs and controllers compute exp, log, powers and angles in compiled code or through `math`."""
    found = []
    for part in SCOPE:
        for path in sorted((ROOT / "searchrl" / part).glob("*.py")):
            if path.name != "oracle.py":  # the world's plain-Python reference, never on a run's path
                found += numpy_vector_calls(path.read_text(), str(path.relative_to(ROOT)))
    assert not found, found


def test_the_vector_call_finder_finds_each_kind():
    planted = """
import numpy as np
from numba import njit

def plain(x, a):
    y = np.exp(x) + numpy.log(x)
    return y ** a, x ** 2, x ** -2, np.sqrt(x), np.power(x, 3)

@njit(cache=True)
def compiled(x, a):
    return np.exp(x) ** a
"""
    found = numpy_vector_calls(planted)
    assert [f.split(" ", 1)[1] for f in found] == ["np.exp(...)", "numpy.log(...)", "y ** a", "np.power(...)"], found


def _sha(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()[:16]


def fingerprints(scenarios: dict[str, dict]) -> dict[str, str]:
    """Digests of the worlds (seed 0) of `scenarios` (label: `Scenario.to_dict()`), Γ, reach weights on iid walls
    and target marginals."""
    from searchrl.controllers.greedy_kernels import reach_weights
    from searchrl.world.bound import placement_weights, target_marginals
    from searchrl.world.config import WorldConfig
    from searchrl.world.footprint import GAMMA
    from searchrl.world.maps import Gaussians, probability_map, uncertainty_map
    from searchrl.world.reset import reset_worlds
    from searchrl.world.scenario import Scenario
    from searchrl.world.state import allocate
    from tests.test_generators import _digest

    config, out = WorldConfig(world_size=(20, 33), n_agents=6, n_targets=(4, 12), n_distributions=(3, 9)), {}
    for label, values in scenarios.items():  # tests/test_frozen_worlds.py's worlds
        state = allocate(config, 3)
        reset_worlds(config, state, np.ones(3, bool), np.random.default_rng(0), Scenario.from_dict(values))
        out[label] = _digest(state)
    rng = np.random.default_rng(7)
    blocked = rng.random((2, 30, 30)) < 0.3
    densities = Gaussians.draw(40, 12, 400.0, 1.0, 0.8, rng).densities(40)
    p, u = probability_map(densities[:6].sum(axis=0), 0.1), uncertainty_map(densities[6:].sum(axis=0))
    marginals, _ = target_marginals(placement_weights(p, u, np.ones((40, 40), bool)), 8, 64, rng)
    return out | {"gamma": _sha(GAMMA), "reach": _sha(reach_weights(blocked, 1.5)), "maps": _sha(densities),
                  "marginals": _sha(marginals)}  # fmt: skip


@pytest.mark.app  # a child interpreter: about 10 s, not in the fast layer
def test_worlds_are_the_same_with_numpys_vector_code_switched_off():
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    from tests.test_frozen_worlds import scenarios

    frozen = {label: scenario.to_dict() for label, scenario in scenarios().items()}
    features = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    env = {**os.environ, "NPY_DISABLE_CPU_FEATURES": " ".join(features)}
    code = ("import json, sys; from numpy._core._multiarray_umath import __cpu_features__ as f; "
            "from tests.test_cpu_independence import fingerprints; "
            f"print(json.dumps({{'on': [x for x in {features!r} if f[x]], "
            "'digests': fingerprints(json.load(sys.stdin))}))")  # fmt: skip
    child = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, input=json.dumps(frozen),
                           capture_output=True, text=True)  # fmt: skip
    assert child.returncode == 0, child.stderr[-3000:]
    seen = json.loads(child.stdout.strip().splitlines()[-1])
    assert seen["on"] == []  # the child's numpy ran without this CPU's vector code
    ours = fingerprints(frozen)
    assert len(ours) > 30 and seen["digests"] == ours, sorted(k for k in ours if seen["digests"].get(k) != ours[k])
