"""Generate the project's MAVLink 2 dialect from ``shaketable.xml`` with pymavlink's mavgen, cache it, import it.

The Python code of the dialect is never committed and never edited by hand: :func:`dialect` runs
``pymavlink.generator.mavgen.mavgen`` (MAVLink 2.0 wire protocol, Python 3, XML schema validation with strict
units) on first use and imports the result. The generated module lives in a per-user cache,
``$XDG_CACHE_HOME/shaketable-rig/mavlink/<key>/shaketable.py`` (``~/.cache`` when ``XDG_CACHE_HOME`` is unset),
where ``<key>`` hashes the dialect XML, the XML files it includes (``common.xml`` and its includes, taken from
the copies bundled with pymavlink) and the pymavlink version. Any edit to the XML, or another pymavlink, gives a
new key and a fresh generation; an unchanged one reuses the module.

Its byte code is written beside it (``__pycache__``, as ``py_compile`` does) when the module is generated, or when a
cached module has none, whatever ``PYTHONDONTWRITEBYTECODE`` says: compiling the 1.8 MB module takes about 0.4 s
of CPU holding the interpreter lock, which every process would otherwise pay on its first MAVLink use (its other
threads — heartbeats, the stream, the receiver — stopped meanwhile: over a second on a busy 2-core host); loading
the byte code takes milliseconds. A cache that cannot be written just compiles on import, as before.

Generation is atomic: mavgen writes into a private staging directory that is renamed to ``<key>`` only once
the module is complete, so no process ever imports a partial module; when two processes race, the first rename
wins and the other discards its own copy. Cache directories unused for :data:`KEEP_DAYS` are pruned.

:func:`dialect` also registers the module as ``pymavlink.dialects.v20.shaketable``, the name pymavlink's
``mavutil.set_dialect`` / ``mavutil.mavlink_connection(..., dialect="shaketable")`` import (see
:mod:`protocols.mavlink.link`).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.metadata
import importlib.util
import io
import os
import py_compile
import shutil
import sys
import tempfile
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from types import ModuleType

DIALECT_NAME = "shaketable"
"""The dialect's name: the generated module's ``DIALECT`` and its name under ``pymavlink.dialects.v20``."""

XML_PATH = Path(__file__).with_name(f"{DIALECT_NAME}.xml")
"""The dialect's definition, shipped as package data."""

KEEP_DAYS = 30
"""Cache directories of other keys unused for this many days are removed whenever a dialect is built or reused."""

_GENERATOR = "mavgen wire=2.0 language=Python3 validate strict_units"
"""Folded into the cache key: a change of how we call mavgen must not reuse modules made the old way."""

_lock = threading.Lock()
_loaded: dict[Path, ModuleType] = {}


class DialectError(RuntimeError):
    """The dialect could not be generated or loaded (invalid XML, missing include, unwritable cache)."""


def cache_root() -> Path:
    """``$XDG_CACHE_HOME/shaketable-rig/mavlink`` (``~/.cache/...`` when unset), read at every call."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "shaketable-rig" / "mavlink"


def _bundled_definitions() -> Path:
    """pymavlink's MAVLink 2 message definitions: ``common.xml`` and the files it includes."""
    import pymavlink.dialects.v20 as v20

    return Path(v20.__file__).parent


def _includes(xml_bytes: bytes, source: str) -> list[str]:
    """The ``<include>`` file names of one MAVLink XML definition, in document order."""
    try:
        root = ET.fromstring(xml_bytes)
    except ET.ParseError as exc:
        raise DialectError(f"{source}: not well-formed XML: {exc}") from exc
    return [(inc.text or "").strip() for inc in root.findall("include")]


def _sources(xml_path: Path) -> dict[str, bytes]:
    """The dialect XML (under the name ``shaketable.xml``) and every file it includes, transitively.

    Includes are resolved in pymavlink's bundled definitions, whatever directory ``xml_path`` is in.
    """
    try:
        files = {f"{DIALECT_NAME}.xml": xml_path.read_bytes()}
    except OSError as exc:
        raise DialectError(f"cannot read the dialect definition {xml_path}: {exc}") from exc
    bundled = _bundled_definitions()
    pending = _includes(files[f"{DIALECT_NAME}.xml"], str(xml_path))
    while pending:
        name = pending.pop(0)
        if name in files:
            continue
        try:
            files[name] = (bundled / name).read_bytes()
        except OSError as exc:
            raise DialectError(f"{xml_path} includes {name!r}, which pymavlink does not bundle ({bundled})") from exc
        pending.extend(_includes(files[name], name))
    return files


def _key(sources: dict[str, bytes]) -> str:
    digest = hashlib.sha256()
    for part in (_GENERATOR, importlib.metadata.version("pymavlink")):
        digest.update(part.encode() + b"\0")
    for name, data in sorted(sources.items()):
        digest.update(name.encode() + b"\0" + len(data).to_bytes(8, "little") + data)
    return digest.hexdigest()[:16]


def cache_key(xml_path: Path = XML_PATH) -> str:
    """16 hex digits naming the generated module of ``xml_path``: a hash of the XML, the files it includes, the
    pymavlink version and the mavgen options."""
    return _key(_sources(Path(xml_path)))


def _run_mavgen(sources: dict[str, bytes], module_path: Path) -> None:
    """Write ``sources`` into a scratch directory and generate ``module_path`` from ``shaketable.xml``."""
    from pymavlink.generator import mavgen, mavparse

    with tempfile.TemporaryDirectory(prefix="mavgen-src-") as src:
        for name, data in sources.items():
            (Path(src) / name).write_bytes(data)
        opts = mavgen.Opts(str(module_path), wire_protocol=mavparse.PROTOCOL_2_0, language="Python3",
                           validate=True, strict_units=True)
        log = io.StringIO()
        try:
            # mavgen reports on stdout/stderr and ends a failed schema validation with sys.exit
            with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
                ok = mavgen.mavgen(opts, [str(Path(src) / f"{DIALECT_NAME}.xml")])
        except (SystemExit, mavparse.MAVParseError) as exc:
            raise DialectError(f"mavgen rejected the dialect: {exc}\n{log.getvalue()}") from exc
    if not ok or not module_path.is_file():
        raise DialectError(f"mavgen rejected the dialect:\n{log.getvalue()}")


def build(xml_path: Path = XML_PATH) -> Path:
    """The generated module for ``xml_path``: reused from the cache, or generated into it atomically."""
    sources = _sources(Path(xml_path))
    root = cache_root()
    target = root / _key(sources)
    module_path = target / f"{DIALECT_NAME}.py"
    if not module_path.is_file():
        _generate(sources, root, target)
    _byte_code(module_path)
    _prune(target)
    return module_path


def _byte_code(module_path: Path) -> None:
    """Write ``module_path``'s byte code where the import system looks for it, unless it is there (module
    docstring); a cache that cannot be written is left as it is."""
    cached = Path(importlib.util.cache_from_source(str(module_path)))
    if not cached.is_file():
        with contextlib.suppress(OSError, py_compile.PyCompileError):
            py_compile.compile(str(module_path), cfile=str(cached), doraise=True)


def _generate(sources: dict[str, bytes], root: Path, target: Path) -> None:
    """Generate ``target/shaketable.py`` in a staging directory under ``root``, then rename it to ``target``."""
    module_path = target / f"{DIALECT_NAME}.py"
    try:
        root.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".staging-", dir=root))
    except OSError as exc:
        raise DialectError(f"cannot write the MAVLink cache {root} ({exc}); point XDG_CACHE_HOME elsewhere") from exc
    try:
        staged = staging / module_path.name
        _run_mavgen(sources, staged)
        with staged.open("rb") as f:
            os.fsync(f.fileno())
        try:
            staging.rename(target)
        except OSError as exc:
            if not module_path.is_file():  # not a race lost to another process: a real error
                raise DialectError(f"cannot move the generated dialect into {target}: {exc}") from exc
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _prune(keep: Path) -> None:
    """Touch ``keep``; remove its siblings (other keys, abandoned staging directories) older than KEEP_DAYS."""
    with contextlib.suppress(OSError):
        os.utime(keep)
        for other in keep.parent.iterdir():
            if other != keep and time.time() - other.stat().st_mtime > KEEP_DAYS * 86400:
                shutil.rmtree(other, ignore_errors=True)


def load(xml_path: Path = XML_PATH) -> ModuleType:
    """Generate (or reuse) and import the dialect defined by ``xml_path``; one module object per cache key.

    The module is imported as ``shaketable_mavlink_<key>``, so dialects from different XML files (tests build
    modified copies) coexist in one process.
    """
    with _lock:
        module_path = build(xml_path)
        module = _loaded.get(module_path)
        if module is None:
            name = f"{DIALECT_NAME}_mavlink_{module_path.parent.name}"
            spec = importlib.util.spec_from_file_location(name, module_path)
            if spec is None or spec.loader is None:
                raise DialectError(f"cannot import {module_path}")
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            try:
                spec.loader.exec_module(module)
            except Exception:
                del sys.modules[name]
                raise
            _loaded[module_path] = module
        return module


@functools.cache
def dialect() -> ModuleType:
    """The project's dialect module (``shaketable.xml``), generated on first use, then the same object for the
    life of the process (later changes of ``XDG_CACHE_HOME`` or of the XML do not affect it).

    It holds everything mavgen makes: the ``MAVLink`` encoder/decoder class, ``MAVLink_<name>_message`` classes
    (each with ``msgname``, ``id``, ``crc_extra``), ``mavlink_map`` (id → class), enums and constants
    (``MAV_CMD_SHAKETABLE_ARM``, ``SHAKETABLE_STATE_STREAMING``, ...), plus all of ``common.xml``. The module is
    also registered as ``pymavlink.dialects.v20.shaketable`` for pymavlink's ``mavutil``.
    """
    import pymavlink.dialects.v20 as v20

    module = load(XML_PATH)  # one module per key even if two threads get here at once
    sys.modules[f"pymavlink.dialects.v20.{DIALECT_NAME}"] = module
    setattr(v20, DIALECT_NAME, module)
    return module
