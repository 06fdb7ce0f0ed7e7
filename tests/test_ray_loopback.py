"""A ``--ray local`` cluster listens on the loopback interface only.

Referee: the kernel's own socket tables (``/proc/net/tcp``, ``/proc/net/tcp6``), matched to
the sockets held by the Ray processes started for the sweep; without geosyn's switch Ray's
GCS and raylet listen on every interface with the machine's address.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

# Ray clusters on one machine find each other (/tmp/ray): with `pytest -n`, one worker
# runs every test that starts one.
pytestmark = pytest.mark.xdist_group("ray")

_PROBE = textwrap.dedent(
    """
    import json, os, re
    from geosyn.experiments.sweep.executors import _loopback_only_local_cluster
    _loopback_only_local_cluster()
    import ray

    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    ray.get(ray.remote(lambda: 1).remote())

    def children(pid):
        out = {pid}
        for task in os.listdir("/proc"):
            if task.isdigit():
                try:
                    stat = open(f"/proc/{task}/stat").read()
                except OSError:
                    continue
                ppid = int(stat.rsplit(")", 1)[1].split()[1])
                if ppid in out or ppid == pid:
                    out.add(int(task))
        return out

    pids = children(os.getpid())
    for _ in range(3):  # grandchildren (raylet -> workers)
        for p in list(pids):
            pids |= children(p)
    inodes = set()
    for p in pids:
        try:
            for fd in os.listdir(f"/proc/{p}/fd"):
                link = os.readlink(f"/proc/{p}/fd/{fd}")
                m = re.fullmatch(r"socket:\\[(\\d+)\\]", link)
                if m:
                    inodes.add(m.group(1))
        except OSError:
            continue
    listening = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in open(table).read().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A" and cols[9] in inodes:  # 0A: LISTEN
                listening.append(cols[1].split(":")[0])
    ray.shutdown()
    print(json.dumps(listening))
    """
)

_LOOPBACK = {
    "0100007F",  # 127.0.0.1 (tcp, little-endian hex)
    "0000000000000000FFFF00000100007F",  # ::ffff:127.0.0.1 (tcp6)
    "00000000000000000000000001000000",  # ::1
}


@pytest.mark.slow
def test_local_ray_cluster_listens_on_loopback_only():
    import os

    env = {k: v for k, v in os.environ.items() if k != "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"}
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=180, env=env
    )
    assert out.returncode == 0, out.stderr[-2000:]
    listening = json.loads(out.stdout.strip().splitlines()[-1])
    assert len(listening) >= 2, listening  # GCS and raylet at least: the probe sees them
    assert set(listening) <= _LOOPBACK, listening
