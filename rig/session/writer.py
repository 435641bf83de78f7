"""The background writer of a run: appended blocks → HDF5 datasets (SWMR), flushed every ``interval`` seconds.

Producers call `BlockWriter.put` from any thread; it only appends to a deque (no HDF5 call, no disk I/O).
The writer thread wakes every ``interval`` s, takes everything queued, resizes each dataset once and writes
the rows, then calls ``H5Fflush``: with the file in SWMR-write mode HDF5 writes the raw data and then the
metadata that makes it visible in dependency order, so a reader (or a file left by a killed writer) sees
each dataset as a prefix of what was appended. Samples at risk on a crash: those queued since the last flush
(at most ``interval`` plus the flush's own duration; `WriterStats.max_latency_s` measures it).

With a ``checksums`` table (`rig.session.checksums`), each block written gets its CRC-32 row there in the next
pass (before that pass's new rows), or in one more flush at `BlockWriter.stop`: a checksum row never reaches the
disk before the rows it covers.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field

import h5py
import numpy as np

from . import checksums as crc
from . import failpoints


@dataclass
class WriterStats:
    """Counters of one run's writer. Times in seconds."""

    flushes: int = 0
    rows: dict[str, int] = field(default_factory=dict)
    #: Largest time from a block's `put` to the end of the flush that put it on disk.
    max_latency_s: float = 0.0
    #: Largest duration of one write-and-flush pass.
    max_flush_s: float = 0.0
    #: Largest time between the ends of two consecutive flushes (while data was waiting).
    max_flush_gap_s: float = 0.0
    #: Total time spent writing and flushing.
    busy_s: float = 0.0
    #: Of ``busy_s``, the time spent computing checksums and appending them to the checksum table.
    checksum_s: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)


class BlockWriter:
    """Owns ``h5`` (open in SWMR-write mode) and its growing ``datasets`` while the run lasts; ``checksums``: the
    run's checksum table (`rig.session.checksums`; None: blocks are not checksummed)."""

    def __init__(self, h5: h5py.File, datasets: Mapping[str, h5py.Dataset], interval: float,
                 checksums: h5py.Dataset | None = None) -> None:
        self._h5 = h5
        self._datasets = dict(datasets)
        self._checksums = checksums
        self._pending: list[tuple[bytes, int, int, int]] = []  # checksum rows of the blocks of the last flush
        self._rows = {key: ds.shape[0] for key, ds in self._datasets.items()}
        self._interval = interval
        self._queue: deque[tuple[str, np.ndarray, float]] = deque()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="session-writer", daemon=True)
        self.stats = WriterStats(rows=dict.fromkeys(self._datasets, 0))
        self.error: BaseException | None = None
        self._last_flush = time.monotonic()

    def start(self) -> None:
        self._thread.start()

    def put(self, key: str, rows: np.ndarray) -> None:
        """Queue ``rows`` for dataset ``key`` (thread-safe, O(1), no I/O)."""
        self._queue.append((key, rows, time.monotonic()))

    def _run(self) -> None:
        deadline = time.monotonic() + self._interval
        try:
            while not self._stop.wait(max(0.0, deadline - time.monotonic())):
                self._flush_once()
                deadline += self._interval
                now = time.monotonic()
                if deadline < now:  # a slow flush: start the next period now rather than bursting
                    deadline = now + self._interval
        except BaseException as exc:  # kept for the producers and `stop` to report
            self.error = exc

    def _flush_once(self) -> None:
        queue = self._queue
        blocks: dict[str, list[np.ndarray]] = {}
        oldest = None
        while True:
            try:
                key, rows, t_put = queue.popleft()
            except IndexError:
                break
            blocks.setdefault(key, []).append(rows)
            oldest = t_put if oldest is None else min(oldest, t_put)
        if oldest is None and not self._pending:
            self._last_flush = time.monotonic()
            return
        t0 = time.monotonic()
        self._write_pending()
        for key, parts in blocks.items():
            block = parts[0] if len(parts) == 1 else np.concatenate(parts)
            ds, start = self._datasets[key], self._rows[key]
            ds.resize(start + len(block), axis=0)
            ds[start:] = block
            self._rows[key] = start + len(block)
            self.stats.rows[key] += len(block)
            if self._checksums is not None:
                c0 = time.monotonic()
                self._pending.append(crc.entry(key, start, np.asarray(block, dtype=ds.dtype)))
                self.stats.checksum_s += time.monotonic() - c0
        self._h5.flush()
        done = time.monotonic()
        failpoints.hit("writer:flushed")
        s = self.stats
        s.flushes += 1
        if oldest is not None:
            s.max_latency_s = max(s.max_latency_s, done - oldest)
        s.max_flush_s = max(s.max_flush_s, done - t0)
        s.busy_s += done - t0
        s.max_flush_gap_s = max(s.max_flush_gap_s, done - self._last_flush)
        self._last_flush = done

    def _write_pending(self) -> None:
        """Append the checksum rows of the blocks that the last flush put on disk."""
        if self._checksums is None or not self._pending:
            return
        c0 = time.monotonic()
        rows = np.array(self._pending, dtype=crc.CHECKSUM)
        table = self._checksums
        start = table.shape[0]
        table.resize(start + len(rows), axis=0)
        table[start:] = rows
        self._pending.clear()
        self.stats.checksum_s += time.monotonic() - c0

    def stop(self) -> WriterStats:
        """Stop the thread after a last write-and-flush of everything queued, and one more flush for the checksums
        of that last write."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        if self.error is None:
            try:
                self._flush_once()
                self._flush_once()
            except BaseException as exc:
                self.error = exc
        return self.stats
