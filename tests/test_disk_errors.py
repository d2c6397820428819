"""A full disk and a read-only output folder are the user's to fix (issue 34): one line naming
the problem and the fix, exit 2, nothing half-written under a final name (a size-limited tmpfs
and a read-only one, mounted in a private mount namespace with ``unshare -m``, as root)."""
import os
import shutil
import subprocess
import sys

import pytest

from samples import ROOT, committed

BATCH = os.path.join(ROOT, "batch.py")
VIDEO = os.path.join(committed("broad"), "video.mp4")
OUTLINE = os.path.join(committed("broad"), "outline.json")
#: after the run, inside the namespace: every file left, and whether each .npz and .png opens whole
CHECK = """
import os, sys, zipfile, cv2
for root, _, files in os.walk(sys.argv[1]):
    for f in sorted(files):
        p = os.path.join(root, f)
        ok = True
        if f.endswith(".npz"):
            ok = zipfile.ZipFile(p).testzip() is None
        elif f.endswith(".png"):
            ok = cv2.imread(p) is not None
        print("FILE", os.path.relpath(p, sys.argv[1]), os.path.getsize(p), ok)
"""


def _in_namespace(mount_opts: str, out_rel: str, *extra: str):
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        pytest.fail("these tests mount a tmpfs in a private namespace: run them as root with util-linux's unshare")
    d = f"/tmp/tfv-disk-{os.getpid()}"
    cmd = " ".join([sys.executable, BATCH, VIDEO, "--outline", OUTLINE, "--out", f"{d}/{out_rel}", "--frames", "0:24",
                    "--levels", "4", "--twigs", "0", "--quiet", *extra])
    script = (f"mkdir -p {d} && mount -t tmpfs -o {mount_opts} tmpfs {d} && "
              + (f"mkdir -p {d}/{out_rel} && " if "ro" not in mount_opts.split(",") else "")
              + f"{cmd} 2>{d}.err; echo RC=$?; cat {d}.err; rm -f {d}.err; "
              + f"{sys.executable} -c '{CHECK}' {d}")
    p = subprocess.run(["unshare", "-m", "--propagation", "private", "sh", "-c", script],
                       capture_output=True, text=True, timeout=600)
    lines = p.stdout.splitlines()
    rc = int(next(ln for ln in lines if ln.startswith("RC="))[3:])
    err = [ln for ln in lines if not ln.startswith(("RC=", "FILE "))]
    files = {ln.split()[1]: ln.split()[3] == "True" for ln in lines if ln.startswith("FILE ")}
    return rc, err, files


def test_a_full_disk_is_one_line_and_nothing_half_written():
    rc, err, files = _in_namespace("size=400k", "out")           # skeleton and tree fit, the overlays do not
    assert rc == 2 and len(err) == 1 and err[0].startswith("error: cannot write"), err
    assert "No space left" in err[0] and "free space" in err[0]
    assert not [f for f in files if os.path.basename(f).startswith((".tmp-", "tmp"))], files
    assert all(files.values()), files                             # every file under a final name is whole
    assert "out/overlay.png" not in files and "out/overlay.mp4" not in files


def test_a_read_only_output_folder_is_one_line():
    rc, err, files = _in_namespace("ro,size=1m", "out")
    assert rc == 2 and len(err) == 1 and "is not writable; choose another --out" in err[0], err
    assert files == {}
