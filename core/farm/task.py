"""The task a farm worker runs: one batch job in a subprocess, with a timeout, that dies with its
worker and stops when the farm is stopped. Standard library only, and shipped to the workers by
value (the workers need not import this package), so a crash, a kill, a hang or a memory
blow-up of the job costs only its task."""
from __future__ import annotations


def run_job(cmd: list[str], out: str, timeout: float = 0.0, stop_event: str | None = None) -> dict:
    """Run ``cmd`` (a batch job writing into ``out``) and return what its report says:
    ``{"status", "message", "warnings", "seconds", "code", "host"}``. ``status`` is the report's
    (``ok``, ``bad_input``, ``error``, ``cancelled``), or ``timeout`` (killed after ``timeout``
    seconds; 0: no limit), ``cancelled`` (the farm's ``stop_event`` was set) or ``error`` (the job
    died before its report said how it ended)."""
    import json
    import os
    import signal
    import socket
    import subprocess
    import time

    def die_with_parent():                       # Linux: the job gets SIGKILL when its worker dies
        try:
            import ctypes
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(signal.SIGKILL))     # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    os.makedirs(out, exist_ok=True)
    event = None
    if stop_event:
        try:
            from distributed import Event
            event = Event(stop_event)
        except Exception:                          # outside a Dask worker: no stop flag
            event = None
    t0 = time.monotonic()
    p = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         preexec_fn=die_with_parent)
    ended = None
    while True:
        try:
            p.wait(timeout=1.0)
            break
        except subprocess.TimeoutExpired:
            pass
        if timeout and time.monotonic() - t0 > timeout:
            ended = "timeout"
        elif event is not None and event.is_set():
            ended = "cancelled"
        if ended:
            p.kill()
            p.wait()
            break
    seconds = round(time.monotonic() - t0, 3)
    report = None
    try:
        with open(os.path.join(out, "report.json"), encoding="utf-8") as fh:
            report = json.load(fh)
    except (OSError, ValueError):
        pass
    result: dict = {"code": p.returncode, "seconds": seconds, "host": socket.gethostname(), "warnings": [],
              "status": "error", "message": None}
    if ended == "timeout":
        result["message"] = f"killed after {timeout:g} s (--job-timeout)"
        result["status"] = "timeout"
    elif ended == "cancelled":
        result.update(status="cancelled", message="the farm was stopped")
    elif isinstance(report, dict) and report.get("status") not in (None, "running"):
        result.update(status=report["status"], message=report.get("message"),
                      warnings=list(report.get("warnings") or []))
    else:
        result["message"] = f"the job ended (exit code {p.returncode}) before its report said how"
    return result
