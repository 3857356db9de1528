"""Many independent FMU runs on dask.distributed: an in-process LocalCluster by default
(one worker process per core), any running dask cluster by its scheduler address, or a
plain loop in this process (``client=None``).

Each run is a top-level function of one picklable point (a dict); dask ships the point
and the function's name, the worker imports the ``ehsv`` package, and the worker's
process keeps its extracted archive and its FMU instance between runs
(fmu.pooled_instance). A run that raises is recorded as ``{"error": "..."}`` in its
place: one failing point never loses the others.
"""

from __future__ import annotations

import functools
import os
import traceback
from collections.abc import Callable, Sequence


def local_cluster_client(workers: int | None = None):
    """A dask Client on a new LocalCluster of ``workers`` single-threaded worker
    processes (default: one per core), no dashboard."""
    from dask.distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=workers or os.cpu_count() or 1,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
    )
    return Client(cluster)


def client_for(scheduler: str | None = None, workers: int | None = None):
    """The Client of an existing cluster (``scheduler`` = "tcp://host:port", or a
    scheduler file written by ``dask scheduler --scheduler-file``), else a LocalCluster."""
    if not scheduler:
        return local_cluster_client(workers)
    from dask.distributed import Client

    if os.path.isfile(scheduler):
        return Client(scheduler_file=scheduler)
    return Client(scheduler)


def close(client) -> None:
    """Closes the client and, if the client made it, its LocalCluster."""
    if client is None:
        return
    cluster = client.cluster
    client.close()
    if cluster is not None:
        cluster.close()


def _capture(func: Callable, point):
    try:
        return func(point)
    except Exception as e:  # noqa: BLE001 -- recorded with the point, the sweep goes on
        last = traceback.extract_tb(e.__traceback__)[-1]
        return {"error": f"{type(e).__name__}: {e} ({os.path.basename(last.filename)}:{last.lineno})"}


def map_points(func: Callable, points: Sequence, *, client=None, progress: bool = True, desc: str = "runs"):
    """[func(p) for p in points], on the client's workers (in this process if client is
    None), in the order of ``points``, with a progress bar (tqdm) on stderr."""
    from tqdm import tqdm

    safe = functools.partial(_capture, func)
    if client is None:
        return [safe(p) for p in tqdm(points, desc=desc, disable=not progress)]
    from dask.distributed import as_completed

    futures = client.map(safe, list(points), pure=False)
    for _ in tqdm(as_completed(futures), total=len(futures), desc=desc, disable=not progress):
        pass
    return client.gather(futures)
