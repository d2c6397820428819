"""A farm of batch jobs on Dask (core/farm/, cli_farm.py; issue 34): a real ``dask scheduler``
and two ``dask worker`` processes started here on localhost, and the local cluster, each run a
folder of sample videos (one corrupt, one done already): the new ones ok, the corrupt one
bad_input, the done one skipped, farm.json right, exit 1. A worker killed mid-job: its job runs
again elsewhere and finishes. SIGINT to the farm: no process of it is left, finished reports
stay. Every report is checked against the schema."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import pytest
from job_report import check_report

from tree_from_video.core.farm import inputs

from samples import ROOT, committed

BATCH = os.path.join(ROOT, "batch.py")
DASK = os.path.join(os.path.dirname(sys.executable), "dask")
QUICK = ["--frames", "0:24", "--no-video", "--levels", "4", "--twigs", "0"]


def _folder(tmp_path, names=("a", "b", "c", "d"), corrupt=("c",)):
    src = tmp_path / "clips"
    src.mkdir()
    for n in names:
        if n in corrupt:
            (src / f"{n}.mp4").write_text("not a video")
        else:
            shutil.copy(os.path.join(committed("broad" if n != "b" else "sparse"), "video.mp4"), src / f"{n}.mp4")
        shutil.copy(os.path.join(committed("broad"), "outline.json"), src / f"{n}.outline.json")
    (src / "notes.txt").write_text("not a clip")
    return src


def _farm(src, out, *extra, timeout=600):
    p = subprocess.run([sys.executable, BATCH, "--farm", str(src), "--out", str(out), *QUICK, *map(str, extra)],
                       capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stderr


@pytest.fixture
def cluster(tmp_path):
    """A real scheduler and two single-threaded workers (no nanny: each pid is the worker)."""
    sched_file = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([DASK, "scheduler", "--port", "0", "--no-dashboard", "--scheduler-file", str(sched_file)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    deadline = time.monotonic() + 60
    while not sched_file.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    address = json.loads(sched_file.read_text())["address"]
    workers = [subprocess.Popen([DASK, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for _ in range(2)]
    procs += workers
    from distributed import Client
    with Client(address, timeout="30s") as c:
        c.wait_for_workers(2, timeout=60)
    yield address, workers
    for p in procs:
        if p.poll() is None:
            p.kill()
        p.wait()


def _check_folder_farm(out, code, err):
    assert code == 1, err
    farm = json.loads((out / "farm.json").read_text())
    status = {j["name"]: j["status"] for j in farm["jobs"]}
    assert status == {"a": "ok", "b": "ok", "c": "bad_input", "d": "skipped"}, err
    assert farm["counts"] == {"ok": 2, "bad_input": 1, "skipped": 1}
    for n in "abc":
        doc = check_report(out / n)
        assert doc["status"] == status[n]
    assert "cannot be read" in check_report(out / "c")["message"]
    assert not (out / "notes").exists()


def _done_d(src, out):
    """d done already: its job run by itself with the farm's options."""
    p = subprocess.run([sys.executable, BATCH, str(src / "d.mp4"), "--outline", str(src / "d.outline.json"),
                        "--out", str(out / "d"), *QUICK, "--quiet"], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    return (out / "d" / "report.json").read_bytes()


def test_a_folder_on_a_real_scheduler_and_two_workers(tmp_path, cluster):
    address, _ = cluster
    src, out = _folder(tmp_path), tmp_path / "out"
    before = _done_d(src, out)
    code, err = _farm(src, out, "--scheduler", address)
    _check_folder_farm(out, code, err)
    assert (out / "d" / "report.json").read_bytes() == before          # the done job was not touched
    # again: everything done is skipped before any worker starts, the corrupt one runs again
    p = subprocess.run([sys.executable, BATCH, "--farm", str(src), "--out", str(out), *QUICK, "--dry-run",
                        "--scheduler", address], capture_output=True, text=True, timeout=300)
    lines = sorted(p.stdout.splitlines())
    assert [ln.split(":")[0] for ln in lines] == ["redo", "skip", "skip", "skip"], lines


def test_a_folder_on_the_local_cluster(tmp_path):
    src, out = _folder(tmp_path), tmp_path / "out"
    _done_d(src, out)
    code, err = _farm(src, out, "--workers", 2)
    _check_folder_farm(out, code, err)


def test_a_killed_worker_costs_one_attempt(tmp_path, cluster):
    address, workers = cluster
    src, out = _folder(tmp_path, names=("a", "b"), corrupt=()), tmp_path / "out"
    p = subprocess.Popen([sys.executable, BATCH, "--farm", str(src), "--out", str(out), "--no-video", "--levels", "4",
                          "--scheduler", address], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not all((out / n / "report.json").exists() for n in "ab"):
        time.sleep(0.05)
    workers[0].send_signal(signal.SIGKILL)                  # both jobs are running: one loses its worker
    workers[0].wait()
    _, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    farm = json.loads((out / "farm.json").read_text())
    assert [j["status"] for j in farm["jobs"]] == ["ok", "ok"], err
    for n in "ab":
        assert check_report(out / n)["status"] == "ok"
    assert not _running_with(str(out)), "the killed worker's job outlived it"


def _running_with(text: str) -> list[int]:
    """Live processes whose command line holds ``text``."""
    pids = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/cmdline", "rb") as fh:
                    if text.encode() in fh.read() and _alive(int(d)):
                        pids.append(int(d))
            except OSError:
                continue
    return pids


def _descendants(pid: int) -> set[int]:
    children: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(d))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_sigint_stops_the_farm_and_leaves_no_process(tmp_path):
    src, out = _folder(tmp_path, names=("a", "b", "e"), corrupt=()), tmp_path / "out"
    p = subprocess.Popen([sys.executable, BATCH, "--farm", str(src), "--out", str(out), "--no-video", "--levels", "4",
                          "--workers", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    seen: set[int] = set()
    while time.monotonic() < deadline:                       # the first job finished, the second running
        seen |= _descendants(p.pid)
        done = [n for n in "abe" if (out / n / "report.json").exists()
                and json.loads((out / n / "report.json").read_text())["status"] == "ok"]
        if done and len([n for n in "abe" if (out / n / "report.json").exists()]) >= 2:
            break
        time.sleep(0.1)
    seen |= _descendants(p.pid)
    assert done, "no job finished"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 1 and "cancelled" in err, err
    time.sleep(2)
    assert not [pid for pid in seen if _alive(pid)], "processes of the farm outlived it"
    for n in done:
        assert check_report(out / n)["status"] == "ok"           # finished reports kept
    farm = json.loads((out / "farm.json").read_text())
    assert {j["name"]: j["status"] for j in farm["jobs"]}[done[0]] == "ok"


def test_inputs_of_a_folder_a_list_and_a_jobs_file(tmp_path):
    src = _folder(tmp_path, names=("a", "b"), corrupt=())
    (src / "b.outline.json").unlink()
    (src / "b.mask.png").write_bytes(b"x")
    sub = tmp_path / "other"
    sub.mkdir()
    shutil.copy(src / "a.mp4", sub / "a.MOV")
    entries = inputs.read_source(str(src))
    assert [os.path.basename(e["video"]) for e in entries] == ["a.mp4", "b.mp4"]
    lst = tmp_path / "list.txt"
    lst.write_text(f"# clips\n{src / 'a.mp4'}\nother/a.MOV\n\n")
    jobs = inputs.plan_jobs(inputs.read_source(str(lst)), str(tmp_path / "out"), "auto", lambda e: [e["video"]])
    assert [j.name for j in jobs] == ["a", "a-2"]                           # a name collision made unique
    assert jobs[0].outline == str(src / "a.outline.json") and jobs[1].outline == "auto"
    assert jobs[1].video == str(tmp_path / "other" / "a.MOV")
    jobs = inputs.plan_jobs(entries, str(tmp_path / "out"), None, lambda e: [])
    assert jobs[1].outline == str(src / "b.mask.png")
    jf = tmp_path / "jobs.json"
    jf.write_text(json.dumps([{"video": str(src / "a.mp4"), "bones": 64}]))
    assert inputs.read_source(str(jf)) == [{"video": str(src / "a.mp4"), "bones": 64}]


@pytest.mark.parametrize("case", ["missing folder", "empty folder", "bad scheduler", "zero workers", "video beside"])
def test_bad_farm_arguments_exit_2(tmp_path, case):
    empty = tmp_path / "empty"
    empty.mkdir()
    src = _folder(tmp_path, names=("a",), corrupt=())
    args = {"missing folder": ["--farm", tmp_path / "nope"], "empty folder": ["--farm", empty],
            "bad scheduler": ["--farm", src, "--scheduler", "tcp://127.0.0.1:9"],
            "zero workers": ["--farm", src, "--workers", 0],
            "video beside": [src / "a.mp4", "--farm", src]}[case]
    p = subprocess.run([sys.executable, BATCH, *map(str, args), "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=120)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip() and not ln.startswith("[farm]")]
    assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith("error:"), (case, p.stderr)
