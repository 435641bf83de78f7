"""``study_dask``: the study of :func:`analysis.study.study` on a Dask cluster, equal to it scene by scene.

The records are split into contiguous blocks; each block is shipped to the cluster once
(``Client.scatter``), and one task per block runs the same fast engine (:func:`analysis.study.study`)
on every body × record of the block × sign × angle. The blocks' outcomes are gathered and put back in
the local study's scene order, so the result is a :class:`~analysis.study.StudyResult` whose per-scene
arrays (``direction``, ``t_overturn``, ...) equal the local ones element by element: every scene is
computed by the same compiled kernel from the same inputs, whichever block it is in. (Workers on another
kind of CPU compile the kernel for their CPU; a rounding difference could then tip a scene on the edge
of overturning, as running the local study on that machine would.)

On a worker, one block runs at a time per worker process (numba's default threading layer does not
allow two parallel kernels at once) with as many numba threads as the worker has Dask threads, so a
``dask worker --nthreads 8`` uses its 8 cores on each block and a 1-thread worker does not oversubscribe.

``distributed`` is imported only when a cluster is used.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.body import Body
from analysis.errors import AnalysisInputError
from analysis.simulate import (
    DEFAULT_FRICTION,
    DEFAULT_STEP,
    Criterion,
    Model,
)
from analysis.study import RecordLike, StudyResult, check_study_inputs, checked_records, study

if TYPE_CHECKING:
    from distributed import Client

SCENE_FIELDS = ("direction", "t_overturn", "theta_max", "impacts", "status", "steps", "prescreened")
"""Per-scene outcome arrays of a :class:`StudyResult` that the workers return."""

BLOCKS_PER_THREAD = 4
"""Default number of record blocks per Dask thread of the cluster (load balance against per-task cost)."""

_KERNEL_LOCK = threading.Lock()


class ClusterError(AnalysisInputError):
    """The Dask scheduler cannot be reached or has no workers; the message names the address."""


@dataclass(frozen=True)
class ShippedRecord:
    """What a worker receives of a record: its name, step [s] and accelerations [g] (no provenance)."""

    name: str
    dt: float
    acc_h: np.ndarray
    acc_v: np.ndarray | None


def record_blocks(n_records: int, n_blocks: int) -> list[tuple[int, int]]:
    """Contiguous ``[start, stop)`` index ranges splitting ``n_records`` into ``n_blocks`` near-equal blocks
    (fewer when there are fewer records; none empty)."""
    if n_records < 1 or n_blocks < 1:
        raise AnalysisInputError(f"record_blocks: need ≥ 1 record and ≥ 1 block, got {n_records}, {n_blocks}")
    edges = np.linspace(0, n_records, min(n_blocks, n_records) + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in itertools.pairwise(edges) if b > a]


def _worker_threads() -> int:
    """Dask threads of the worker this runs on (numba's current thread count outside a worker)."""
    import numba

    try:
        from distributed import get_worker

        return int(get_worker().state.nthreads)
    except (ImportError, ValueError):
        return int(numba.get_num_threads())


def run_block(records: list[ShippedRecord], bodies: list[Body], angles: np.ndarray, model: Model,
              options: dict[str, Any]) -> dict[str, Any]:
    """Run one block on a worker: :func:`study` on ``records``; returns its per-scene outcome arrays
    (``SCENE_FIELDS``) and ``seconds`` (the kernel's wall time [s])."""
    import numba

    most = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # numba.config sets its names at run time
    threads = max(1, min(_worker_threads(), int(most)))
    with _KERNEL_LOCK:
        before = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            res = study(bodies, records, angles, model, **options)
        finally:
            numba.set_num_threads(before)
    return {**{name: getattr(res, name) for name in SCENE_FIELDS}, "seconds": res.seconds, "threads": threads}


def warm_up(client: Client, model: Model = "rocking") -> dict[str, int]:
    """Load (or compile) ``model``'s kernel on every worker of ``client`` with a one-scene study; returns the
    numba threads each worker runs a block with, by worker address."""
    rec = ShippedRecord("warm-up", 0.01, np.zeros(8), None)
    addresses = list(client.nthreads())
    futures = [client.submit(run_block, [rec], [Body(0.1, 0.5)], np.zeros(1), model, {"signs": (1,)},
                             workers=[address], allow_other_workers=False, pure=False)
               for address in addresses]
    return {address: int(part["threads"]) for address, part in zip(addresses, client.gather(futures), strict=True)}




def _connect(scheduler: str | Client, timeout: float) -> tuple[Client, bool]:
    """A client for ``scheduler`` (an address or a client) and whether this module opened it."""
    from distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    try:
        return Client(scheduler, timeout=timeout, set_as_default=False), True
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"cannot reach a Dask scheduler at {scheduler} within {timeout:g} s "
                           f"({type(exc).__name__}: {exc}); expected the address of a running one, "
                           f"e.g. tcp://HOST:8786") from None


def _address(client: Client) -> str:
    return str(getattr(client.scheduler, "address", None) or client.scheduler_info().get("address", "dask"))


def study_dask(
    bodies: Sequence[Body],
    records: Sequence[RecordLike],
    angles: Sequence[float],
    model: Model = "rocking",
    *,
    scheduler: str | Client,
    signs: Sequence[int] = (1, -1),
    restitution: float | str = 0.0,
    friction: float = DEFAULT_FRICTION,
    criterion: Criterion = "fall",
    t_after: float = 60.0,
    step: float = DEFAULT_STEP,
    use_vertical: bool = True,
    blocks: int | None = None,
    timeout: float = 30.0,
) -> StudyResult:
    """:func:`analysis.study.study` on the Dask cluster at ``scheduler`` (``tcp://HOST:PORT`` or a ``Client``).

    Arguments as :func:`analysis.study.study` (angles β [rad], friction μ, ``t_after`` [s], ``step`` p·h).
    ``blocks``: how many record blocks (tasks) to make, default ``BLOCKS_PER_THREAD`` per Dask thread of the
    cluster, at most one per record. ``timeout`` [s]: for connecting to a scheduler given by address.
    The result equals the local study's scene by scene; its ``seconds`` is the wall time from shipping
    the records to having gathered every block (the local study times its kernel only), and
    ``settings`` adds ``where`` (the scheduler's address), ``blocks``, ``workers`` and ``kernel_seconds``
    (the blocks' kernel times added up). Raises :class:`ClusterError` when the scheduler cannot be reached
    or has no worker, :class:`AnalysisInputError` for input the local study would refuse.
    """
    angles_arr = np.asarray(angles, dtype=float)
    check_study_inputs(bodies, records, angles_arr, model, signs, restitution, criterion)
    signs_t = tuple(int(s) for s in signs)
    shipped = [ShippedRecord(rec.name, dt, acc_h, acc_v)
               for rec, (acc_h, dt, acc_v) in zip(records, checked_records(records, use_vertical), strict=True)]
    options = {"signs": signs_t, "restitution": restitution, "friction": friction, "criterion": criterion,
               "t_after": t_after, "step": step, "use_vertical": True}
    client, owned = _connect(scheduler, timeout)
    try:
        nthreads = client.nthreads()
        if not nthreads:
            raise ClusterError(f"the Dask scheduler at {_address(client)} has no workers")
        ranges = record_blocks(len(shipped), blocks or BLOCKS_PER_THREAD * sum(nthreads.values()))
        t0 = time.perf_counter()
        data = client.scatter([shipped[a:b] for a, b in ranges])
        futures = client.map(run_block, data, bodies=list(bodies), angles=angles_arr, model=model,
                             options=options, pure=False)
        parts = client.gather(futures)
        seconds = time.perf_counter() - t0
        where = _address(client)
    finally:
        if owned:
            client.close()
    return _stitch(parts, list(bodies), [rec.name for rec in records], angles_arr, signs_t, model, seconds, {
        "restitution": restitution, "friction": friction, "criterion": criterion, "t_after": t_after,
        "step": step, "signs": list(signs_t), "records": len(records), "where": where, "blocks": len(ranges),
        "workers": len(nthreads), "kernel_seconds": float(sum(p["seconds"] for p in parts)),
    })


def _stitch(parts: list[dict[str, Any]], bodies: list[Body], names: list[str], angles: np.ndarray,
            signs: tuple[int, ...], model: str, seconds: float, settings: dict[str, Any]) -> StudyResult:
    """The blocks' outcomes (each in its own study's scene order) in the scene order of the whole study:
    body-major, then record, sign, angle — as :func:`analysis.study.study` orders them."""
    nb, ns, na = len(bodies), len(signs), angles.size

    def joined(name: str) -> np.ndarray:
        return np.concatenate([p[name].reshape(nb, -1, ns, na) for p in parts], axis=1).ravel()

    outcome = {name: joined(name) for name in SCENE_FIELDS}
    n_series = len(names) * ns
    j, q, a = np.meshgrid(np.arange(nb), np.arange(n_series), np.arange(na), indexing="ij")
    if outcome["direction"].size != j.size:
        raise AnalysisInputError(f"study_dask: gathered {outcome['direction'].size} scenes, expected {j.size}")
    return StudyResult(
        bodies=bodies, records=names, angles=angles, signs=signs, model=model,
        body=j.ravel(), record=q.ravel() // ns, sign=np.array(signs)[q.ravel() % ns], angle=angles[a.ravel()],
        seconds=seconds, settings=settings, **outcome,
    )

