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


def test_the_plain_copy_follows_netsim_compiled_set_within_the_process(monkeypatch):
    """With ``NETSIM_COMPILED=0`` a small run's loops are all plain Python, map walks too (the
    module itself); cleared again in the same process, the walks are compiled again (the
    copy): the choice made first is not kept for the other setting."""
    module = "netsim.mobility._local_kernels"
    source = importlib.import_module(module)
    monkeypatch.setenv("NETSIM_COMPILED", "0")
    assert compiled.load(module, 2) is source
    monkeypatch.delenv("NETSIM_COMPILED")
    assert compiled.load(module, 2) is not source


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


def test_a_kernels_argument_has_one_type_whether_broadcast_or_given_whole():
    """numba compiles a kernel once per array type, and a read-only view is a type of its
    own: an argument made from a number and one made from a whole array of the caller's
    must come out the same type (writable, C-contiguous), and not share the caller's memory."""
    import numba
    import numpy as np

    whole = np.arange(4.0)
    from_number, from_whole = compiled.filled(2.0, (4,)), compiled.filled(whole, (4,))
    assert numba.typeof(from_number) == numba.typeof(from_whole)
    assert from_whole.flags.writeable and from_whole.flags.c_contiguous
    assert not np.shares_memory(from_whole, whole)
    assert from_number.tolist() == [2.0] * 4 and from_whole.tolist() == whole.tolist()


def test_a_batch_of_values_stands_for_an_unknown_team_only():
    """A law called on a batch: the team's size decides when known; else the batch's length."""
    module = "netsim.radio._kernels"
    small, large = compiled.SMALL_RUN_ROBOTS - 1, compiled.SMALL_RUN_ROBOTS
    assert compiled.load(module, small, values=large) is compiled.plain_copy(module)
    assert compiled.load(module, large, values=small) is compiled.compiled_copy(module)
    assert compiled.load(module, None, values=small) is compiled.plain_copy(module)
    assert compiled.load(module, None, values=large) is compiled.compiled_copy(module)
