"""numba's cache index under processes that save at once (analysis/compiled_index.py).

Two processes share nothing but the cache's files, so two ``FunctionCache`` objects of one kernel stand for them:
their steps (read the index, write the index, write the data) are put in an order that the scheduler can give two
processes, and a third cache, or a new dispatcher, then reads what they left, as a later process would.
"""

from __future__ import annotations

import ast
import fcntl
import importlib.util
import os
import threading
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numba
import pytest
from numba.core import caching, types

from analysis.compiled_index import LockedIndexDataCacheFile, exclusive

ROOT = Path(__file__).resolve().parents[2]
STOCK = LockedIndexDataCacheFile.__mro__[1]  # numba's own IndexDataCacheFile
INT, FLOAT = (types.int64,), (types.float64,)  # the keys' signatures as the dispatcher passes them


@pytest.fixture
def kernel(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Any:
    """``twice(x) = 2 x``, compiled for int64 and float64, its cache in ``tmp_path`` (emptied after compiling)."""
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path / "cache"))
    source = tmp_path / "kern.py"
    source.write_text("from numba import njit\n\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    spec = importlib.util.spec_from_file_location("kern", source)
    assert spec is not None and spec.loader is not None
    module: ModuleType = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    twice = module.twice
    assert twice(3) == 6 and twice(1.5) == 3.0
    for path in Path(twice._cache.cache_path).iterdir():
        path.unlink()
    return twice


def _in_order(caches: dict[str, caching.FunctionCache], order: list[tuple[str, str]]) -> None:
    """Make each cache's file steps wait for their turn in ``order`` ((cache, step) pairs)."""
    turn, moved = [0], threading.Condition()

    def gate(who: str, step: str, run: Callable[..., Any]) -> Callable[..., Any]:
        def gated(*args: Any) -> Any:
            with moved:
                moved.wait_for(lambda: turn[0] >= len(order) or order[turn[0]] == (who, step))
            try:
                return run(*args)
            finally:
                with moved:
                    turn[0] += 1
                    moved.notify_all()
        return gated

    for who, cache in caches.items():
        for step in ("_load_index", "_save_index", "_save_data"):
            setattr(cache._cache_file, step, gate(who, step, getattr(cache._cache_file, step)))


def _save_at_once(twice: Any, a: caching.FunctionCache, b: caching.FunctionCache) -> None:
    """``a`` saves twice's int64 machine code, ``b`` its float64 one, each in a thread of its own."""
    threads = [threading.Thread(target=a.save_overload, args=(INT, twice.overloads[INT])),
               threading.Thread(target=b.save_overload, args=(FLOAT, twice.overloads[FLOAT]))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()


# both read the index before either writes it; A's data lands last
INTERLEAVED = [("A", "_load_index"), ("B", "_load_index"), ("A", "_save_index"), ("B", "_save_index"),
               ("B", "_save_data"), ("A", "_save_data")]


def test_numbas_own_index_can_name_another_signatures_machine_code(kernel: Any,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Why analysis.compiled_index exists: with numba's index file, the interleaving leaves the float64 entry
    naming the int64 machine code, and a later process computes twice(1.5) = 2. (If a numba release fixes
    ``IndexDataCacheFile.save``, this fails: then the lock can go.)"""
    monkeypatch.setattr(caching, "IndexDataCacheFile", STOCK)
    a, b = caching.FunctionCache(kernel.py_func), caching.FunctionCache(kernel.py_func)
    _in_order({"A": a, "B": b}, INTERLEAVED)
    _save_at_once(kernel, a, b)
    later = caching.FunctionCache(kernel.py_func)
    loaded = later.load_overload(FLOAT, kernel.targetctx)
    assert loaded is not None and tuple(loaded.signature.args) == INT  # asked for float64, got int64 code
    assert numba.njit(cache=True)(kernel.py_func)(1.5) == 2  # a new process's dispatcher: silently wrong


def test_the_locked_index_keeps_each_signature_with_its_machine_code(kernel: Any) -> None:
    """With analysis.compiled_index, a save reads and writes the index under an exclusive lock (a second
    process cannot take it meanwhile), so B reads the index only after A wrote it; both entries survive, each
    naming its own machine code."""
    a, b = caching.FunctionCache(kernel.py_func), caching.FunctionCache(kernel.py_func)
    assert isinstance(a._cache_file, LockedIndexDataCacheFile)
    lock = a._cache_file._index_path + ".lock"
    held = []

    def probe(step: Callable[..., Any]) -> Callable[..., Any]:
        def probed(*args: Any) -> Any:
            fd = os.open(lock, os.O_RDWR)
            try:
                with pytest.raises(BlockingIOError):
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                held.append(step.__name__)
            finally:
                os.close(fd)
            return step(*args)
        return probed

    for cache in (a, b):
        for step in ("_load_index", "_save_index", "_save_data"):
            setattr(cache._cache_file, step, probe(getattr(cache._cache_file, step)))
    # A reads the index only once B has begun its save: B then waits for the lock until A is done
    b_began = threading.Event()
    b_save, a_load = b._cache_file.save, a._cache_file._load_index
    b._cache_file.save = lambda *args: (b_began.set(), b_save(*args))[1]
    a._cache_file._load_index = lambda: (b_began.wait(), a_load())[1]
    _save_at_once(kernel, a, b)
    assert sorted(held) == sorted(["_load_index", "_save_data", "_save_index"] * 2)
    later = caching.FunctionCache(kernel.py_func)
    for sig in (INT, FLOAT):
        loaded = later.load_overload(sig, kernel.targetctx)
        assert loaded is not None and tuple(loaded.signature.args) == sig
    fresh = numba.njit(cache=True)(kernel.py_func)
    assert fresh(1.5) == 3.0 and fresh(3) == 6
    assert fresh.stats.cache_hits  # loaded, not compiled again


def test_a_new_source_starts_the_index_afresh_and_removes_the_old_machine_code(kernel: Any) -> None:
    cache = caching.FunctionCache(kernel.py_func)
    cache.save_overload(INT, kernel.overloads[INT])
    cache.save_overload(FLOAT, kernel.overloads[FLOAT])
    folder = Path(cache.cache_path)
    assert len(list(folder.glob("*.nbc"))) == 2
    cache._cache_file._source_stamp = b"an edited source"
    cache.save_overload(INT, kernel.overloads[INT])
    assert len(list(folder.glob("*.nbc"))) == 1
    assert cache.load_overload(FLOAT, kernel.targetctx) is None
    loaded = cache.load_overload(INT, kernel.targetctx)
    assert loaded is not None and tuple(loaded.signature.args) == INT


def test_the_lock_excludes_a_second_holder(tmp_path: Path) -> None:
    path = str(tmp_path / "x.nbi.lock")
    with exclusive(path):
        fd = os.open(path, os.O_RDWR)
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)
    fd = os.open(path, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # released when the block ends
    finally:
        os.close(fd)


def test_every_kernel_of_the_packages_is_defined_with_the_locked_njit() -> None:
    """A kernel defined with numba's ``njit`` before analysis.compiled_index is imported would save with numba's
    own index: every module of the packages takes ``njit`` from analysis.compiled_index."""
    offenders = []
    for package in ("analysis", "protocols", "drivers", "sim_table", "rig"):
        for path in sorted((ROOT / package).rglob("*.py")):
            source = path.read_text()
            if path.name == "compiled_index.py" or "numba" not in source:
                continue
            for node in ast.walk(ast.parse(source, str(path))):
                if isinstance(node, ast.ImportFrom) and node.module == "numba" and any(
                        alias.name in ("njit", "jit") for alias in node.names):
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
                if isinstance(node, ast.Attribute) and node.attr in ("njit", "jit") and isinstance(
                        node.value, ast.Name) and node.value.id == "numba":
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert not offenders, f"use `from analysis.compiled_index import njit`: {offenders}"
