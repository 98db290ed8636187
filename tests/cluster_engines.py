"""Real engines for the cluster tests (tests/pipeline/test_engines_cluster.py, `-m cluster`).

- `Slurm`: a one-host SLURM with accounting (slurmctld, slurmd, slurmdbd and a MariaDB of its
  own), started by hand without systemd, all state, logs and pid files under one folder, and
  SLURM_CONF pointing at it. No munge: auth/none and cred/none (both ship with Debian's SLURM).
- `two_node_ray()`: a Ray head and a second node (ray.cluster_utils.Cluster) with fast health
  checks, so a removed node is seen dead in about a second.

Every process is stopped by its own process id, never with `ray stop` or `pkill` (both match by
name over the whole host, and would stop other people's engines). Facts measured on this kind of
machine: /work/shared/reference/engines.md (and docs/engines.md).
"""
from __future__ import annotations

import os
import pwd
import shutil
import signal
import socket
import subprocess
import time
from pathlib import Path

SLURM_PACKAGES = ("slurmctld", "slurmd", "slurm-client", "slurmdbd", "mariadb-server")
SLURM_BINARIES = ("slurmctld", "slurmd", "slurmdbd", "sbatch", "squeue", "sacct", "scancel",
                  "mariadbd", "mariadb-install-db")
MYSQL_DEFAULT_SOCKET = Path("/run/mysqld/mysqld.sock")  # where slurmdbd's client library looks


def slurm_missing() -> str | None:
    """Why a one-host SLURM cannot start here (None: it can)."""
    missing = [b for b in SLURM_BINARIES if shutil.which(b) is None
               and not Path("/usr/sbin", b).exists()]
    if missing:
        return (f"SLURM not installed ({', '.join(missing)} missing): as root, "
                f"apt-get install --no-install-recommends {' '.join(SLURM_PACKAGES)} "
                "(make test-cluster does)")
    if os.geteuid() != 0:
        return "a one-host SLURM needs root (its daemons run as SlurmUser=root)"
    return None


def _binary(name: str) -> str:
    return shutil.which(name) or str(Path("/usr/sbin", name))


def wait(what: str, ok, timeout: float = 60.0, every: float = 0.2, error=RuntimeError):
    """ok()'s first true value, polled every `every` seconds; `error` after `timeout`."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = ok()
        if got:
            return got
        time.sleep(every)
    raise error(f"{what}: not ready after {timeout:.0f} s")


def stop_pids(pids, timeout: float = 15.0) -> None:
    """SIGTERM each process, then SIGKILL what is left after `timeout` (by process id only)."""
    pids = [p for p in pids if p]
    for p in pids:
        try:
            os.kill(p, signal.SIGTERM)
        except ProcessLookupError:
            pass
    end = time.monotonic() + timeout
    for p in pids:
        while time.monotonic() < end and _alive(p):
            time.sleep(0.1)
        if _alive(p):
            try:
                os.kill(p, signal.SIGKILL)
            except ProcessLookupError:
                pass


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie of ours counts as gone
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


class Slurm:
    """A one-host SLURM cluster with accounting, in `folder`. start() returns self; stop() ends
    every daemon it started (and the jobs' processes, through slurmd)."""

    def __init__(self, folder: Path, cpus: int = 2):
        self.dir = Path(folder)
        self.host = socket.gethostname().split(".")[0]
        self.cpus = cpus
        self.procs: dict[str, subprocess.Popen] = {}
        self.pids: dict[str, int] = {}
        self.env = dict(os.environ, SLURM_CONF=str(self.dir / "slurm.conf"))
        self.linked_socket = False
        self.started_s = None

    # --- configuration ---
    def write_conf(self) -> None:
        d = self.dir
        for sub in ("state", "spool", "log", "run", "db"):
            (d / sub).mkdir(parents=True, exist_ok=True)
        (d / "slurm.conf").write_text(f"""\
ClusterName=gbtest
SlurmctldHost={self.host}(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/none
CredType=cred/none
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=5
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
AccountingStoragePort=16819
JobCompType=jobcomp/none
ReturnToService=2
SlurmctldPort=16817
SlurmdPort=16818
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldLogFile={d}/log/slurmctld.log
SlurmdLogFile={d}/log/slurmd.log
SlurmctldPidFile={d}/run/slurmctld.pid
SlurmdPidFile={d}/run/slurmd.pid
MinJobAge=30
KillWait=5
InactiveLimit=0
NodeName={self.host} NodeAddr=127.0.0.1 CPUs={self.cpus} RealMemory=4000 State=UNKNOWN
PartitionName=debug Nodes={self.host} Default=YES MaxTime=INFINITE State=UP
""")
        dbd = d / "slurmdbd.conf"  # slurmdbd reads it beside SLURM_CONF; mode 600 or it refuses
        dbd.write_text(f"""\
AuthType=auth/none
DbdHost=localhost
DbdPort=16819
SlurmUser=root
LogFile={d}/log/slurmdbd.log
PidFile={d}/run/slurmdbd.pid
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=root
StorageLoc=slurm_gbtest
""")
        dbd.chmod(0o600)

    # --- start / stop ---
    def _spawn(self, name: str, argv: list[str], **kw) -> subprocess.Popen:
        log = open(self.dir / "log" / f"{name}.out", "ab")
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                start_new_session=True, **kw)
        self.procs[name] = proc
        self.pids[name] = proc.pid
        return proc

    def start(self) -> "Slurm":
        t0 = time.monotonic()
        self.write_conf()
        d = self.dir
        sock = d / "run" / "mysqld.sock"
        if not (d / "db" / "mysql").exists():
            shutil.chown(d / "db", "mysql", "mysql")
            subprocess.run([_binary("mariadb-install-db"), "--user=mysql", f"--datadir={d}/db",
                            "--auth-root-authentication-method=socket", "--skip-test-db"],
                           check=True, capture_output=True)
        shutil.chown(d / "run", "mysql", "mysql")
        self._spawn("mariadbd", [_binary("mariadbd"), "--user=mysql", f"--datadir={d}/db",
                                 f"--socket={sock}", "--skip-networking",
                                 f"--pid-file={d}/run/mariadb.pid", "--skip-log-error"])
        wait("mariadbd", sock.exists, 60)
        if not MYSQL_DEFAULT_SOCKET.exists():
            MYSQL_DEFAULT_SOCKET.parent.mkdir(parents=True, exist_ok=True)
            if MYSQL_DEFAULT_SOCKET.is_symlink():
                MYSQL_DEFAULT_SOCKET.unlink()
            MYSQL_DEFAULT_SOCKET.symlink_to(sock)
            self.linked_socket = True
        os.chmod(d / "run", 0o777)
        self._spawn("slurmdbd", [_binary("slurmdbd"), "-D"])
        wait("slurmdbd", lambda: _port_open(16819), 60)
        self._spawn("slurmctld", [_binary("slurmctld"), "-D", "-i"])
        self._spawn("slurmd", [_binary("slurmd"), "-D"])
        wait("slurm node idle", lambda: "idle" in self.run("sinfo", "-h", "-o", "%T",
                                                             check=False).stdout, 60)
        self.started_s = time.monotonic() - t0
        return self

    def stop(self) -> None:
        for name in ("slurmd", "slurmctld", "slurmdbd", "mariadbd"):  # pids read before: see
            proc = self.procs.get(name)                               # engines.md
            if proc is not None:
                stop_pids([proc.pid])
                proc.wait(timeout=30)
        if self.linked_socket and MYSQL_DEFAULT_SOCKET.is_symlink():
            MYSQL_DEFAULT_SOCKET.unlink()

    def run(self, *argv: str, check: bool = True) -> subprocess.CompletedProcess:
        return subprocess.run(list(argv), env=self.env, capture_output=True, text=True,
                              check=check, timeout=60)

    def jobs(self) -> dict[str, str]:
        """job id -> state of this user's jobs, as squeue lists them (array tasks expanded)."""
        out = self.run("squeue", "-h", "-r", "-o", "%i %T", "-u", pwd.getpwuid(os.getuid())[0],
                       check=False).stdout
        return dict(line.split()[:2] for line in out.splitlines() if line.strip())


def _port_open(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


# --- Ray ---------------------------------------------------------------------------------------

RAY_FAST_HEALTH = {"health_check_period_ms": 500, "health_check_failure_threshold": 3}
OBJECT_STORE = 100 * 1000**2


def two_node_ray():
    """A head (no CPUs, so every trial runs on a worker node) and two one-CPU worker nodes, each
    with a custom resource naming it ("node1", "node2"). Returns the Cluster; stop it with
    stop_ray(cluster)."""
    from ray.cluster_utils import Cluster

    cluster = Cluster(initialize_head=True, connect=False, head_node_args=dict(
        num_cpus=0, object_store_memory=OBJECT_STORE, include_dashboard=False,
        _system_config=RAY_FAST_HEALTH))
    for i in (1, 2):
        cluster.add_node(num_cpus=1, object_store_memory=OBJECT_STORE, resources={f"node{i}": 1})
    cluster.wait_for_nodes()
    return cluster


def ray_node_pids(node) -> list[int]:
    """Every process a Ray node started (raylet, log monitor, ...), by process id."""
    pids = []
    for procs in node.all_processes.values():
        pids += [p.process.pid for p in procs if p.process is not None]
    return pids


def stop_ray(cluster) -> None:
    """Shut a Cluster down by its nodes' process ids (Cluster.shutdown kills its own processes;
    what survives it, like a log monitor, is killed by pid)."""
    import ray

    nodes = [cluster.head_node, *cluster.worker_nodes] if cluster.head_node else \
        list(cluster.worker_nodes)
    pids = [p for n in nodes for p in ray_node_pids(n)]
    if ray.is_initialized():
        ray.shutdown()
    try:
        cluster.shutdown()
    finally:
        stop_pids([p for p in pids if _alive(p)], timeout=5)
