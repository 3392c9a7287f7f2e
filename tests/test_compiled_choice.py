"""The one place a run's loops are chosen compiled or plain (netsim.compiled.load)."""

import importlib

import pytest

from netsim import compiled


@pytest.fixture(autouse=True)
def unforced(monkeypatch):
    monkeypatch.delenv("NETSIM_COMPILED", raising=False)


def test_a_small_team_gets_the_plain_module_and_a_large_or_unknown_one_the_compiled_copy():
    module = "netsim.mobility._local_kernels"
    assert compiled.load(module, compiled.SMALL_RUN_ROBOTS - 1) is compiled.plain_copy(module)
    assert compiled.load(module, compiled.SMALL_RUN_ROBOTS) is compiled.compiled_copy(module)
    assert compiled.load(module, None) is compiled.compiled_copy(module)


def test_a_kernel_marked_walks_is_called_compiled_from_the_plain_copy():
    """A kernel that walks a map (jit's walks) runs compiled even for a small team: the plain
    copy holds a caller of the compiled kernel, and its other kernels call that one."""
    module = "netsim.mobility._local_kernels"
    plain = compiled.load(module, 2)
    source = importlib.import_module(module)
    assert plain is not source
    for name in ("clear", "clear_many"):
        assert getattr(plain, name) is not getattr(source, name)
        assert getattr(plain, name).__name__ == name
    # An unmarked kernel stays plain Python, its globals the copy's (it sees the walks compiled).
    let_go = plain.let_go
    assert let_go.__code__ is source.let_go.__code__
    assert let_go.__globals__["clear"] is plain.clear
