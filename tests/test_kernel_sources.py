"""The kernel modules keep the habits that make a first compile short (docs/architecture.md,
the compiled cache), checked on their sources."""

import ast
import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def kernel_modules() -> list[Path]:
    return sorted(p for top in ("netsim", "protocols", "mobility") for p in (ROOT / top).rglob("_*kernels.py"))


def _sliced(node: ast.expr) -> bool:
    if isinstance(node, ast.Slice) or (isinstance(node, ast.Constant) and node.value is Ellipsis):
        return True
    return isinstance(node, ast.Tuple) and any(_sliced(e) for e in node.elts)


def _scalar(node: ast.expr) -> bool:
    """A literal or a named constant (``-1``, ``np.inf``): a fill, which has no shape check."""
    if isinstance(node, ast.UnaryOp):
        return _scalar(node.operand)
    return isinstance(node, ast.Constant | ast.Attribute)


def copies_into_slices(source: str) -> list[int]:
    """Lines that assign (or add, ...) an array into a slice of another."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Assign):
            targets = [e for t in node.targets for e in (t.elts if isinstance(t, ast.Tuple | ast.List) else [t])]
        elif isinstance(node, ast.AugAssign | ast.AnnAssign) and node.value is not None:
            targets = [node.target]
        else:
            continue
        if not _scalar(node.value) and any(isinstance(t, ast.Subscript) and _sliced(t.slice) for t in targets):
            found.append(node.lineno)
    return found


def test_copies_into_slices_are_found_in_every_form_and_fills_are_not():
    source = "\n".join(
        [
            "out[:n] = a",
            "out[:, 0] = a[:k]",
            "out[...] = a",
            "out[:n] += a",
            "a[:n], b[:n] = x, y",
            "out[:n] = -1",
            "out[:] = np.inf",
            "out[k] = a[k]",
        ]
    )
    assert copies_into_slices(source) == [1, 2, 3, 4, 5]


def test_no_kernel_copies_an_array_into_a_slice():
    """numba compiles a slice copy's shape check with the formatting of its message: kernels
    copy element by element (as netsim._kernels.grown does)."""
    modules = kernel_modules()
    assert len(modules) >= 10
    found = [f"{p.relative_to(ROOT)}:{line}" for p in modules for line in copies_into_slices(p.read_text())]
    assert found == []


# numpy evaluates these with its own vectorised code (SVML on CPUs with AVX-512), which can
# round differently from the C library a compiled kernel calls; Python's math.hypot is an
# algorithm of its own. A kernel run as plain Python must give the compiled run's bits, so
# kernels call math.exp, math.log10, ... and np.hypot (docs/architecture.md).
ROUNDS_ITS_OWN_WAY = {("np", f) for f in ("exp", "expm1", "exp2", "log", "log10", "log2", "log1p", "power", "cbrt")}
ROUNDS_ITS_OWN_WAY |= {("np", f) for f in ("sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2")}
ROUNDS_ITS_OWN_WAY |= {("np", f) for f in ("sinh", "cosh", "tanh")} | {("math", "hypot"), ("math", "dist")}


def calls_rounding_their_own_way(source: str) -> list[int]:
    """Lines that name a function of :data:`ROUNDS_ITS_OWN_WAY`."""
    return sorted(
        node.lineno
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Name)
        and (node.value.id, node.attr) in ROUNDS_ITS_OWN_WAY
    )


def test_functions_that_round_their_own_way_are_found():
    source = "\n".join(
        ["a = np.log10(x)", "b = math.log10(x)", "c = np.exp(-x)", "d = math.hypot(x, y)", "e = np.hypot(x, y)"]
    )
    assert calls_rounding_their_own_way(source) == [1, 3, 4]


def test_no_kernel_calls_a_function_whose_plain_bits_may_differ():
    """Plain and compiled runs give the same outputs bit for bit on every CPU: no kernel calls
    numpy's transcendental functions or Python's hypot."""
    found = [
        f"{p.relative_to(ROOT)}:{line}"
        for p in kernel_modules()
        for line in calls_rounding_their_own_way(p.read_text())
    ]
    assert found == []


def test_numba_is_told_not_to_use_intel_svml():
    """With Intel's SVML installed numba would vectorise the kernels' maths with functions
    that round their own way; netsim turns that off before numba loads (a user's own
    setting wins)."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_DISABLE_INTEL_SVML"}
    code = "import os, netsim.compiled; print(os.environ.get('NUMBA_DISABLE_INTEL_SVML'))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "1"
    env["NUMBA_DISABLE_INTEL_SVML"] = "0"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "0"


def kernels_called_around_load(path: Path) -> list[str]:
    """Kernels that a module outside the kernel modules takes by import, or kernel modules it
    imports whole: a call of either runs the plain source whatever the run's size, where
    netsim.compiled.load alone decides between compiled and plain."""
    import importlib

    from netsim.compiled import is_kernel

    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names if alias.name.endswith("kernels")]
            continue
        if not isinstance(node, ast.ImportFrom) or not node.module:
            continue
        module = node.module
        for alias in node.names:
            if alias.name.endswith("kernels"):
                found.append(f"{module}.{alias.name}")
            elif module.rpartition(".")[2].endswith("kernels"):
                if is_kernel(getattr(importlib.import_module(module), alias.name, None)):
                    found.append(f"{module}.{alias.name}")
    return found


def test_kernels_are_called_only_through_load():
    """Outside the kernel modules, a kernel is reached through netsim.compiled.load: a module
    imports only the kernel modules' records and constants."""
    kernels = set(kernel_modules())
    bad = {
        str(p.relative_to(ROOT)): found
        for top in ("netsim", "protocols", "mobility", "hooks")
        for p in sorted((ROOT / top).rglob("*.py"))
        if p not in kernels and (found := kernels_called_around_load(p))
    }
    assert not bad


def loads_deciding_for_themselves(source: str) -> list[int]:
    """Lines of ``source`` that call ``load(module, None)`` without ``values``: a call site
    choosing the compiled copy whatever the team, beside the one place that decides
    (:func:`netsim.compiled.load`, where the kernels' marks decide a map's walks)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not (isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) == "load"):
            continue
        unknown = len(node.args) >= 2 and isinstance(node.args[1], ast.Constant) and node.args[1].value is None
        if unknown and len(node.args) < 3 and not any(k.arg == "values" for k in node.keywords):
            found.append(node.lineno)
    return found


def test_loads_deciding_for_themselves_are_found():
    source = 'a = load("m", None)\nb = load("m", n)\nc = load("m", None, values=3)\nd = compiled.load("m", None)\n'
    assert loads_deciding_for_themselves(source) == [1, 4]


def test_no_call_site_decides_compiled_for_itself():
    """Whether a call runs compiled is decided in netsim.compiled (by the team's size, a
    batch's length or a kernel's walks mark), not at the call site."""
    sources = sorted(p for top in ("netsim", "protocols", "mobility") for p in (ROOT / top).rglob("*.py"))
    found = [f"{p.relative_to(ROOT)}:{line}" for p in sources for line in loads_deciding_for_themselves(p.read_text())]
    assert found == []


def test_a_maps_walks_are_compiled_by_load_whatever_the_batch(monkeypatch):
    """Code that walks a map asks netsim.compiled.load like any other, giving its batch's
    length: the map's kernel modules come compiled at any length (their walks pay the
    interpreter at every cell), a module with some walking kernels comes plain with those
    compiled, and NETSIM_COMPILED=0 gives plain Python throughout."""
    from netsim import compiled

    monkeypatch.delenv("NETSIM_COMPILED", raising=False)
    world = "netsim.world._kernels"
    assert compiled.load(world, None, values=1) is compiled.compiled_copy(world)
    assert compiled.load(world, 3) is compiled.compiled_copy(world)
    local = compiled.load("netsim.mobility._local_kernels", None, values=1)
    assert local is not compiled.compiled_copy("netsim.mobility._local_kernels")
    assert not compiled.is_kernel(local.steps_clear)  # the walking kernel: compiled on its first call
    monkeypatch.setenv("NETSIM_COMPILED", "0")
    assert compiled.is_kernel(compiled.load(world, None, values=1000).trace)
