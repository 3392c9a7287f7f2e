"""The kernel modules keep the habits that make a first compile short (docs/architecture.md,
the compiled cache), checked on their sources."""

import ast
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
