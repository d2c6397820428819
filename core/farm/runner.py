"""A farm on Dask (``dask.distributed``): every job a task on a worker (:func:`.task.run_job`, a
subprocess with a timeout), a task that crashed, hung or lost its worker run once more, progress
over the whole set, ``farm.json`` at the end. Without a scheduler address, a local cluster of
worker processes; with one, the user's cluster (``dask scheduler`` / ``dask worker``,
dask-jobqueue, Kubernetes). Dask is imported only here, and only when a farm runs."""
from __future__ import annotations

import builtins
import os
import time
import types
import uuid
from dataclasses import dataclass, field
from typing import Callable

from ..errors import InputError
from ..fileio import atomic_write_json
from . import task
from .inputs import FarmJob

FARM = "farm.json"
#: task statuses that earn one more attempt (the job's own verdict on its input does not)
RETRIED = ("error", "timeout")


@dataclass
class JobOutcome:
    """How one job of a farm ended: ``status`` (``ok``, ``skipped``, ``bad_input``, ``error``,
    ``timeout``, ``cancelled``), its ``seconds`` (the last attempt's), ``attempts``, warnings and
    the one-line ``message`` of a failure."""

    job: FarmJob
    status: str
    seconds: float = 0.0
    attempts: int = 0
    warnings: list[str] = field(default_factory=list)
    message: str | None = None
    host: str | None = None

    def to_json(self) -> dict:
        return {"name": self.job.name, "video": self.job.video, "out": self.job.out, "status": self.status,
                "seconds": self.seconds, "attempts": self.attempts, "warnings": self.warnings,
                "message": self.message, "host": self.host}


def open_client(scheduler: str | None, workers: int, connect_timeout: float = 10.0):
    """``(client, cluster)``: the user's scheduler (cluster None), or a local cluster of
    ``workers`` single-threaded worker processes. :class:`InputError` when the scheduler cannot be
    reached."""
    from distributed import Client, LocalCluster
    if scheduler:
        try:
            return Client(scheduler, timeout=f"{connect_timeout}s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler '{scheduler}' ({exc.__class__.__name__}); start one "
                             "with `dask scheduler` or fix --scheduler") from None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    return Client(cluster), cluster


def portable(fn):
    """``fn`` (its imports inside its body) re-made under a module name no process imports, so Dask
    ships its code by value and the workers need not import this package."""
    g = {"__builtins__": builtins, "__name__": "tree_from_video_farm_task"}
    return types.FunctionType(fn.__code__, g, fn.__name__, fn.__defaults__)


def run_farm(client, jobs: list[FarmJob], commands: list[list[str]], timeout: float,
             progress: Callable[[str], None]) -> tuple[list[JobOutcome], bool]:
    """Run every job (``commands[i]`` runs ``jobs[i]``) on ``client``'s workers, each retried once
    when it crashed, hung or lost its worker; ``progress`` gets a line as each ends. Returns the
    outcomes and whether Ctrl-C (KeyboardInterrupt) stopped the farm: then the running jobs are
    killed and every job not finished is ``cancelled``."""
    from distributed import Event, as_completed
    run_job = portable(task.run_job)
    stop = f"tree_from_video-stop-{uuid.uuid4().hex[:8]}"
    outcomes = [JobOutcome(j, "error") for j in jobs]

    def submit(i: int):
        outcomes[i].attempts += 1
        return client.submit(run_job, commands[i], jobs[i].out, timeout, stop, pure=False,
                             key=f"tree-{jobs[i].name}-{outcomes[i].attempts}-{uuid.uuid4().hex[:6]}")

    index = {}
    pending = as_completed()
    for i in range(len(jobs)):
        f = submit(i)
        index[f.key] = i
        pending.add(f)
    done = 0
    finished: set[int] = set()
    try:
        for f in pending:
            i = index[f.key]
            try:
                r = f.result()
            except Exception as exc:                   # the worker died under it (KilledWorker) or the task failed
                r = {"status": "error", "message": f"{exc.__class__.__name__}: {exc}", "seconds": 0.0,
                     "warnings": [], "host": None}
            o = outcomes[i]
            o.status, o.message, o.seconds = r["status"], r.get("message"), float(r.get("seconds") or 0.0)
            o.warnings, o.host = list(r.get("warnings") or []), r.get("host")
            if o.status in RETRIED and o.attempts < 2:
                progress(f"[farm] {o.job.name}: {o.status} ({o.message}); running it once more")
                g = submit(i)
                index[g.key] = i
                pending.add(g)
                continue
            done += 1
            finished.add(i)
            progress(f"[farm] {done}/{len(jobs)} {o.job.name}: {o.status} in {o.seconds:.1f} s"
                     + (f" ({o.message})" if o.message and o.status != "ok" else ""))
    except KeyboardInterrupt:
        Event(stop, client=client).set()               # running jobs kill their subprocess within a second
        client.cancel(list(pending.futures) if hasattr(pending, "futures") else [])
        time.sleep(1.5)
        for i, o in enumerate(outcomes):
            if i not in finished:
                o.status, o.message = "cancelled", "the farm was stopped"
        return outcomes, True
    return outcomes, False


def write_farm(out_dir: str, source: str, outcomes: list[JobOutcome], seconds: float, scheduler: str | None,
               workers: int) -> str:
    """``out_dir/farm.json``: every job's outcome and the counts per status; its path."""
    counts: dict[str, int] = {}
    for o in outcomes:
        counts[o.status] = counts.get(o.status, 0) + 1
    path = os.path.join(out_dir, FARM)
    atomic_write_json(path, {"schema": "tree_from_video/farm/1", "source": os.path.abspath(source),
                             "out": os.path.abspath(out_dir), "scheduler": scheduler, "workers": workers,
                             "seconds": round(seconds, 3), "counts": counts,
                             "jobs": [o.to_json() for o in outcomes]})
    return path
