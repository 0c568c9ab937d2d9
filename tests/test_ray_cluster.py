"""A Ray sweep on a real two-node cluster that loses a node mid-sweep, and Ray kept on loopback.

Two ``ray start`` nodes on this machine, one CPU each, each with its own working and
temporary directories. Where mount namespaces are available, both nodes run in one of their
own in which the driver's directory is an empty read-only tmpfs: no Ray task can read or write
the sweep's ``--out``, as on a cluster whose nodes do not share the driver's filesystem. The
second node is killed (its raylet, then the rest of it) while it runs a chunk of a run that had
already stored a checkpoint; the sweep must finish, retrying that run from the driver's
checkpoint, with the very files the local backend writes.

Tests talk to loopback only. The nodes start with ``--node-ip-address=127.0.0.1``, but a Ray
that allows multi-node clusters replaces a loopback address by the machine's network address
(and its servers then listen on every interface), so the nodes and the driver also run in a
network namespace of their own whose only interface is loopback: there the machine's address
is 127.0.0.1. ``sweep --ray local`` starts its instance on loopback itself
(:func:`evolution.lab.sweep.init_local_ray`). The tests read the listening sockets of every
process Ray started (``/proc``) and fail on any address but 127.0.0.1 or ::1.

Run with ``pytest -m slow -s tests/test_ray_cluster.py`` to see the nodes start, the kill and
the sweep's output.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import re
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import pytest

pytestmark = pytest.mark.slow

RAY = Path(sys.executable).with_name("ray")
#: The sweep: both methods, two seeds, three generations of a small population, so each run
#: has several chunks (one generation each) and a node can be lost between checkpoints.
SWEEP = [
    "sweep", "--methods", "ee,ce", "--seeds", "0-1", "--generations", "3", "--no-progress",
    "--set", "evolution.population_size=8", "--set", "evolution.lifetime_steps=40",
    "--set", "evolution.time_sharing_steps=20",
]  # fmt: skip
#: The ``ray start`` options naming a port, each given a free one.
PORT_OPTIONS = (
    "--dashboard-agent-listen-port",
    "--dashboard-agent-grpc-port",
    "--runtime-env-agent-port",
    "--metrics-export-port",
    "--node-manager-port",
    "--object-manager-port",
)
#: Worker ports per node: its workers and, on the head, the driver.
WORKER_PORTS = 12


def say(message: str) -> None:
    print(f"[ray cluster] {message}", flush=True)


def free_ports(n: int) -> list[int]:
    """``n`` distinct ports nothing listens on now."""
    with contextlib.ExitStack() as stack:
        ports = []
        for _ in range(n):
            sock = stack.enter_context(socket.socket())
            sock.bind(("", 0))
            ports.append(sock.getsockname()[1])
    return ports


def hiding_prefix(hidden: Path) -> list[str] | None:
    """A command prefix that runs a command in a mount namespace of its own in which
    ``hidden`` is an empty read-only directory; None where this machine allows none."""
    unshare = shutil.which("unshare")
    if unshare is None:
        return None
    (hidden / "probe").write_text("the driver's")
    try:
        for flags in (["--mount"], ["--user", "--map-root-user", "--mount"]):
            prefix = [
                unshare, *flags, "--propagation", "private", "sh", "-c",
                'mount -o ro -t tmpfs none "$0" && exec "$@"', str(hidden),
            ]  # fmt: skip
            probe = [*prefix, "sh", "-c", f'test ! -e "{hidden}/probe"']
            if subprocess.run(probe, capture_output=True, timeout=30).returncode == 0:
                return prefix
        return None
    finally:
        (hidden / "probe").unlink()


#: Run by a process that holds a network namespace: brings its loopback interface up (ioctl
#: SIOCGIFFLAGS, then SIOCSIFFLAGS with IFF_UP), says so, and waits to be killed.
HOLD_NETWORK = """
import fcntl, signal, socket, struct
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
flags = struct.unpack("16sH22x", fcntl.ioctl(sock, 0x8913, struct.pack("16sH22x", b"lo", 0)))[1]
fcntl.ioctl(sock, 0x8914, struct.pack("16sH22x", b"lo", flags | 1))
print("up", flush=True)
signal.pause()
"""
#: Run inside it: the namespace has no interface but loopback, and loopback works.
PROBE_NETWORK = """
import socket
names = [name for _, name in socket.if_nameindex()]
assert names == ["lo"], names
server = socket.create_server(("127.0.0.1", 0))
socket.create_connection(server.getsockname(), timeout=5).close()
"""


@contextlib.contextmanager
def private_network() -> Iterator[list[str] | None]:
    """A network namespace whose only interface is loopback, held by a process of its own for
    the duration; yields the command prefix that runs a command in it (None where this machine
    allows none)."""
    unshare, nsenter = shutil.which("unshare"), shutil.which("nsenter")
    if unshare is None or nsenter is None:
        yield None
        return
    for create, enter in (
        (["--net"], ["--net"]),
        (["--user", "--map-root-user", "--net"], ["--user", "--net", "--preserve-credentials"]),
    ):
        holder = subprocess.Popen(
            [unshare, *create, sys.executable, "-c", HOLD_NETWORK], stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, start_new_session=True,
        )  # fmt: skip
        try:
            assert holder.stdout is not None
            if holder.stdout.readline().strip() == b"up":
                prefix = [nsenter, f"--target={holder.pid}", *enter, "--"]
                probe = [*prefix, sys.executable, "-c", PROBE_NETWORK]
                if subprocess.run(probe, capture_output=True, timeout=60).returncode == 0:
                    yield prefix
                    return
        finally:
            holder.kill()
            holder.wait()
    yield None


def listening(pids: list[int]) -> dict[int, list[tuple[str, int]]]:
    """The TCP addresses each of ``pids`` listens on (from /proc, in each one's own network
    namespace): pid -> [(address, port)]."""
    found: dict[int, list[tuple[str, int]]] = {}
    for pid in pids:
        sockets = set()
        with contextlib.suppress(OSError):
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                with contextlib.suppress(OSError):
                    link = os.readlink(fd)
                    if link.startswith("socket:["):
                        sockets.add(link[len("socket:[") : -1])
        for table in ("tcp", "tcp6"):
            try:
                rows = Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]
            except OSError:
                continue
            for row in rows:
                fields = row.split()
                if fields[3] == "0A" and fields[9] in sockets:  # TCP_LISTEN, ours
                    found.setdefault(pid, []).append(_socket_address(fields[1]))
    return found


def _socket_address(text: str) -> tuple[str, int]:
    """``0100007F:1F90`` or its 32-digit IPv6 form, as /proc/net/tcp* writes it."""
    host, port = text.split(":")
    raw = bytes.fromhex(host)
    words = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))  # per 32-bit word
    return str(ipaddress.ip_address(words)), int(port, 16)


def is_loopback(address: str) -> bool:
    """127.0.0.0/8 or ::1, an IPv4-mapped IPv6 address included (a dual-stack socket)."""
    ip = ipaddress.ip_address(address)
    mapped = getattr(ip, "ipv4_mapped", None)
    return (mapped or ip).is_loopback


def assert_loopback_only(
    processes: dict[int, str], what: str, servers: frozenset[str] = frozenset({"raylet"})
) -> None:
    """Every listening socket of ``processes`` (pid -> name) is on loopback, and ``servers``
    are among the processes that listen (so the check looked at the right ones)."""
    found = listening(list(processes))
    shown = {f"{processes[pid]}[{pid}]": sorted(set(found[pid])) for pid in sorted(found)}
    say(f"{what} listens on: {shown}")
    names = {processes[pid] for pid in found}
    assert servers <= names, f"{what}: {sorted(servers - names)} not found listening: {shown}"
    exposed = {name: [a for a in addresses if not is_loopback(a[0])] for name, addresses in
               shown.items()}  # fmt: skip
    exposed = {name: addresses for name, addresses in exposed.items() if addresses}
    assert not exposed, f"{what} listens beyond loopback: {exposed}"


def descendants(pid: int) -> dict[int, str]:
    """Live processes descended from ``pid``: pid -> name."""
    parents: dict[int, tuple[int, str]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] != "Z":
            parents[int(entry.name)] = (int(fields[1]), name)
    found: dict[int, str] = {}
    frontier = [pid]
    while frontier:
        parent = frontier.pop()
        for child, (ppid, name) in parents.items():
            if ppid == parent and child not in found:
                found[child] = name
                frontier.append(child)
    return found


def session_processes(session: int) -> dict[int, str]:
    """Live processes of a session (a node started by one ``ray start``): pid -> name."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        if int(fields[3]) == session and fields[0] != "Z":
            found[int(entry.name)] = name
    return found


def kill_session(session: int, timeout: float = 20.0) -> list[int]:
    """SIGKILL every process of ``session`` (ours: one node) until none is left."""
    killed: list[int] = []
    deadline = time.monotonic() + timeout
    while (alive := session_processes(session)) and time.monotonic() < deadline:
        for pid in alive:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
        time.sleep(0.1)
    return killed


class Node:
    """One ``ray start`` node: its directories, its session and its log."""

    def __init__(self, name: str, root: Path) -> None:
        self.name = name
        self.cwd = root / name
        self.tmp = self.cwd / "tmp"  # TMPDIR of its processes: where tasks run their chunks
        self.ray_temp = self.cwd / "ray"
        for path in (self.tmp, self.ray_temp):
            path.mkdir(parents=True)
        self.session: int | None = None

    def start(self, options: list[str], prefix: list[str], env: dict[str, str]) -> None:
        ports = free_ports(len(PORT_OPTIONS) + WORKER_PORTS)
        command = [
            *prefix, str(RAY), "start", *options, "--num-cpus=1", f"--temp-dir={self.ray_temp}",
            "--disable-usage-stats", "--include-log-monitor=false",
            "--object-store-memory=100000000",
            *(f"{option}={port}" for option, port in zip(PORT_OPTIONS, ports, strict=False)),
            "--worker-port-list=" + ",".join(map(str, ports[len(PORT_OPTIONS) :])),
        ]  # fmt: skip
        log = self.cwd / "ray-start.log"
        with log.open("w") as out:
            process = subprocess.Popen(
                command, cwd=self.cwd, env={**env, "TMPDIR": str(self.tmp)}, stdout=out,
                stderr=subprocess.STDOUT, start_new_session=True,
            )  # fmt: skip
            self.session = process.pid
            code = process.wait(timeout=180)
        assert code == 0, f"ray start of the {self.name} node failed:\n{log.read_text()}"
        said = [line for line in log.read_text().splitlines() if re.search(r"IP|started", line)]
        say(f"{self.name} node: {' '.join(command[len(prefix) :])}\n" + "\n".join(said))
        say(f"  its processes: {sorted(set(session_processes(process.pid).values()))}")

    def raylet(self) -> int:
        assert self.session is not None
        pids = [pid for pid, name in session_processes(self.session).items() if name == "raylet"]
        assert len(pids) == 1, f"{self.name} node: raylets {pids}"
        return pids[0]

    def stop(self) -> None:
        """Kill every process of the node (once: a session id is reused after its end)."""
        if self.session is not None:
            killed = kill_session(self.session)
            self.session = None
            say(f"{self.name} node stopped ({len(killed)} processes killed)")


class ChunkWatch:
    """Watches the chunks a node runs, in the temporary directories its tasks make."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.fresh: set[Path] = set()  # seen before any checkpoint was in them: new runs
        self.since: dict[Path, float] = {}

    def resumed(self) -> Path | None:
        """The checkpoint a chunk under way resumed from (a generation >= 1), if any: one
        seen there for a while before the chunk wrote any result (a new run's first chunk
        writes its own gen_00001.ckpt just before its tables)."""
        now = time.monotonic()
        for chunk in self.node.tmp.glob("cyber-rodent-run-*"):
            found = sorted(chunk.glob("checkpoints/gen_*.ckpt"))
            if not found:
                self.fresh.add(chunk)
            elif chunk not in self.fresh and not (chunk / "statistics.csv").exists():
                first = self.since.setdefault(found[0], now)
                if now - first >= 0.1 and int(found[0].name[4:-5]) >= 1:
                    return found[0]
        return None


def run_files(out: Path) -> dict[str, bytes]:
    """Every file of every run directory under ``out`` (not the sweep's record or figures)."""
    return {
        path.relative_to(out).as_posix(): path.read_bytes()
        for path in sorted(out.rglob("*"))
        if path.is_file() and path.relative_to(out).parts[0] not in ("sweep.json", "figures")
    }


def comparable(name: str, data: bytes) -> object:
    """A file's content; run.json without the source commit (the two sweeps run apart)."""
    if not name.endswith("run.json"):
        return data
    record = json.loads(data)
    record["versions"].pop("git_commit")
    return record


class Cluster(NamedTuple):
    """A two-node cluster and the driver's directory, which its nodes cannot see.

    ``network`` runs a command in the cluster's network namespace, where a driver reaches it.
    """

    address: str
    head: Node
    worker: Node
    driver: Path
    env: dict[str, str]
    network: list[str]


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[Cluster]:
    """Start the head and a worker node (one CPU each) on loopback, in a network namespace of
    their own; kill both whatever happens."""
    pytest.importorskip("ray")
    with private_network() as network:
        if network is None:
            pytest.skip(
                "a multi-node Ray cluster stays on loopback only in a network namespace of its "
                "own, and this machine allows none (unshare --net, nsenter)"
            )
        say(f"the nodes and the driver run in a network namespace with loopback only ({network})")
        yield from _cluster(tmp_path, network)


def _cluster(tmp_path: Path, network: list[str]) -> Iterator[Cluster]:
    driver = tmp_path / "driver"  # the driver's filesystem: --out of both sweeps
    driver.mkdir()
    env = {
        **os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32),
        "RAY_USAGE_STATS_ENABLED": "0", "LP_NUM_THREADS": "1", "MUJOCO_GL": "egl",
    }  # fmt: skip
    prefix = hiding_prefix(driver) or []
    if not prefix:
        say("no mount namespaces here: the nodes see the driver's directory (and must not use it)")
    else:
        say(
            f"the nodes run where {driver} is an empty read-only tmpfs ({prefix[0]} "
            f"{' '.join(prefix[1:-4])}, mount -o ro -t tmpfs)"
        )
    # Short: Ray's socket paths under its temp dir must fit a Unix socket name.
    root = Path(tempfile.mkdtemp(prefix="cr-ray-", dir="/tmp" if Path("/tmp").is_dir() else None))
    head, worker = Node("head", root), Node("worker", root)
    # Both nodes on loopback; a driver in the same network namespace attaches to the head node.
    loopback = "--node-ip-address=127.0.0.1"
    port = free_ports(1)[0]
    address = f"127.0.0.1:{port}"
    try:
        dashboard = free_ports(1)[0]
        head_options = ["--head", loopback, f"--port={port}", "--include-dashboard=false"]
        head.start([*head_options, f"--dashboard-port={dashboard}"], [*network, *prefix], env)
        worker.start([f"--address={address}", loopback], [*network, *prefix], env)
        yield Cluster(address, head, worker, driver, env, network)
    finally:
        worker.stop()
        head.stop()
        shutil.rmtree(root, ignore_errors=True)


def test_sweep_on_two_nodes_survives_losing_one(tmp_path: Path, cluster: Cluster) -> None:
    out = cluster.driver / "ray"
    command = [
        *cluster.network, sys.executable, "-m", "evolution.cli", *SWEEP, "--ray",
        cluster.address,
    ]  # fmt: skip
    say(f"driver: {' '.join(command[len(cluster.network) + 2 :])} --out {out}")
    log = tmp_path / "sweep.log"
    started = time.monotonic()
    with log.open("w") as output:
        sweep = subprocess.Popen(
            [*command, "--out", str(out)], env=cluster.env, stdout=output,
            stderr=subprocess.STDOUT,
        )  # fmt: skip
        try:
            resumed, watch = None, ChunkWatch(cluster.worker)
            while resumed is None and sweep.poll() is None:
                assert time.monotonic() - started < 300, "no chunk resumed on the worker node"
                resumed = watch.resumed()
                time.sleep(0.02)
            assert resumed is not None, "the sweep ended before the worker node could be lost"
            raylet = cluster.worker.raylet()
            os.kill(raylet, signal.SIGKILL)
            say(
                f"killed the worker node's raylet (pid {raylet}) "
                f"{time.monotonic() - started:.1f} s into the sweep, while it ran a chunk "
                f"resumed from {resumed.name}"
            )
            cluster.worker.stop()  # the rest of that node: a lost machine takes it all along
            code = sweep.wait(timeout=600)
        finally:
            if sweep.poll() is None:
                sweep.kill()
                sweep.wait()
    text = log.read_text()
    say(f"sweep finished in {time.monotonic() - started:.1f} s, exit {code}:\n{text}")
    assert code == 0
    assert cluster.head.session is not None
    servers = frozenset({"gcs_server", "raylet"})
    assert_loopback_only(session_processes(cluster.head.session), "the head node", servers)
    retries = re.findall(r"retry \d+ of \d+ from generation (\d+)", text)
    assert retries, "no run was retried after the node was lost"
    assert max(int(g) for g in retries) >= 1  # continued from a checkpoint, not from scratch
    assert list((out / "figures").glob("fig6*"))  # drawn by the driver
    left = sorted(p.name for p in cluster.worker.tmp.glob("cyber-rodent-run-*"))
    say(f"the lost node's own temporary directory holds the chunk it was running: {left}")
    assert left and not list(cluster.head.tmp.glob("cyber-rodent-run-*"))  # the head's cleaned

    reference = cluster.driver / "local"
    r = subprocess.run(
        [sys.executable, "-m", "evolution.cli", *SWEEP, "--workers", "2", "--out",
         str(reference)],
        env=cluster.env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    ours, theirs = run_files(out), run_files(reference)
    say(f"comparing {len(ours)} files with the local backend's: {sorted(ours)}")
    assert sorted(ours) == sorted(theirs)
    for run in ("ee-seed000", "ce-seed000", "ee-seed001", "ce-seed001"):
        for name in ("statistics.csv", "events.csv"):
            assert ours[f"{run}/{name}"] == theirs[f"{run}/{name}"], f"{run}/{name}"
    for name in ours:
        assert comparable(name, ours[name]) == comparable(name, theirs[name]), name
    say("every run's files equal the local backend's, byte for byte (run.json but its commit)")


def test_cluster_listens_on_loopback_only(cluster: Cluster) -> None:
    """Both nodes, their workers and a driver listen on 127.0.0.1 or ::1 only."""
    driver = """
import json, os, sys, ray
ray.init(address=sys.argv[1], log_to_driver=False)
where = ray.remote(lambda: ray.util.get_node_ip_address())
print(json.dumps(ray.get([where.remote() for _ in range(4)])))
print(os.getpid(), flush=True)
sys.stdin.read()  # until the test has looked at this driver's sockets
"""
    process = subprocess.Popen(
        [*cluster.network, sys.executable, "-c", driver, cluster.address], env=cluster.env,
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert process.stdout is not None and process.stdin is not None
        nodes = json.loads(process.stdout.readline())
        say(f"the tasks ran on nodes {nodes}")
        pid = int(process.stdout.readline())
        for node in (cluster.head, cluster.worker):
            assert node.session is not None
            servers = frozenset({"gcs_server", "raylet"} if node is cluster.head else {"raylet"})
            assert_loopback_only(session_processes(node.session), f"the {node.name} node", servers)
        driver_processes = {pid: "driver"} | descendants(pid)
        assert_loopback_only(driver_processes, "the driver", frozenset({"driver"}))
        assert set(nodes) == {"127.0.0.1"}
        process.stdin.close()
        assert process.wait(timeout=60) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_local_ray_listens_on_loopback_only() -> None:
    """``sweep --ray local``'s Ray instance: every process it starts listens on loopback."""
    ray = pytest.importorskip("ray")
    from evolution.lab.sweep import init_local_ray

    if ray.is_initialized():
        ray.shutdown()
    init_local_ray(ray, num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        where = ray.remote(lambda: ray.util.get_node_ip_address())
        nodes = ray.get([where.remote() for _ in range(2)])  # a worker process listens too
        processes = {os.getpid(): "driver"} | descendants(os.getpid())
        servers = frozenset({"driver", "gcs_server", "raylet"})
        assert_loopback_only(processes, "the local Ray instance", servers)
        assert set(nodes) == {"127.0.0.1"}
    finally:
        ray.shutdown()
