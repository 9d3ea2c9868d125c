"""Data-parallel PPO: the batch as fixed shards, their sums, and a second process for one of them.

PPO's batch is computed as ``shards`` (1 or 2) fixed parts, each its own
:class:`~wfbench.train.collection.Collector` (its environments, seeds, sampling generator
and reward normalizers) and its own part of every minibatch's loss. What crosses the shards
is a sum of two: every minibatch's gradient (with its loss statistics) and the advantages
whose mean and std normalize it. A sum of two floats is commutative, so one process
computing both shards (``a + b``) and two processes computing one each (``all_reduce``:
``a + b`` on one, ``b + a`` on the other) give the same bits: ``procs`` chooses the speed,
never the weights. In the manner of CleanRL's ``ppo_atari_multigpu.py`` (gradients summed
by ``torch.distributed.all_reduce``, every process the same optimizer step).

:class:`ShardGroup` is that choice: the shards a process computes and the sums over all
of them. :class:`Worker` is the second process (``python -m wfbench.train.shards``,
started by the first; no ``__main__`` guard needed in the caller's script): it gets its
work over a :mod:`multiprocessing.connection` on 127.0.0.1, and the two join one
``torch.distributed`` group (gloo, a TCPStore on 127.0.0.1). ``docs/rl.md``, "Shards and
processes"; the speed: ``docs/performance.md``, "Training across the training split".
"""

from __future__ import annotations

import atexit
import datetime
import importlib
import os
import pickle
import secrets
import subprocess
import sys
from contextlib import contextmanager
from multiprocessing.connection import Client, Connection, Listener

import torch
import torch.distributed as dist

from wfbench.train import standby

HOST = "127.0.0.1"
TIMEOUT = datetime.timedelta(minutes=10)  # a collective waits at most this long for the other process
LOOPBACK = "lo0" if sys.platform == "darwin" else "lo"  # gloo's interface: the machine itself, nothing else


class ShardGroup:
    """The shards of a run's batch and the processes computing them: ``procs`` 1 (all here) or one per shard.

    ``rank``: this process's place (0: the run's own process, which writes everything;
    1: the :class:`Worker`). ``local``: the shards this process computes, in shard order.
    """

    def __init__(self, shards: int, procs: int, rank: int = 0):
        self.shards, self.procs, self.rank = shards, procs, rank
        self.local = list(range(shards)) if procs == 1 else [rank]
        self.store: dist.TCPStore | None = None

    def sum(self, local: list[torch.Tensor]) -> torch.Tensor:
        """The sum over every shard of a tensor each local shard computed (the same bits with 1 or 2 processes)."""
        if self.procs == 1:
            total = local[0]
            for t in local[1:]:
                total = total + t
            return total
        total = local[0].clone()
        dist.all_reduce(total)
        return total

    def gather(self, local: list[torch.Tensor]) -> list[torch.Tensor]:
        """Every shard's tensor (of one shape), in shard order."""
        if self.procs == 1:
            return local
        out = [torch.empty_like(local[0]) for _ in range(self.procs)]
        dist.all_gather(out, local[0].contiguous())
        return out

    # -- the process group --------------------------------------------------------------------
    def listen(self) -> int:
        """Rank 0: the rendezvous store on 127.0.0.1 (a free port, which the worker is told)."""
        if dist.is_initialized():
            raise ValueError("procs = 2: another two-process trainer is running in this process (close() it "
                             "first); allowed: one at a time, or procs = 1")
        self.store = dist.TCPStore(HOST, 0, 2, is_master=True, timeout=TIMEOUT, wait_for_workers=False)
        return self.store.port

    def join(self, port: int | None = None) -> None:
        """Join the two-process gloo group (rank 0 on its own store, the worker on rank 0's ``port``)."""
        store = self.store if self.rank == 0 else dist.TCPStore(HOST, port, 2, is_master=False, timeout=TIMEOUT)
        with _loopback():
            dist.init_process_group("gloo", store=store, rank=self.rank, world_size=2, timeout=TIMEOUT)

    def leave(self) -> None:
        if self.procs > 1 and dist.is_initialized():
            dist.destroy_process_group()
        self.store = None


@contextmanager
def _loopback():
    """Gloo on the loopback interface (``GLOO_SOCKET_IFNAME``), unless the caller chose another."""
    if "GLOO_SOCKET_IFNAME" in os.environ:
        yield
        return
    os.environ["GLOO_SOCKET_IFNAME"] = LOOPBACK
    try:
        yield
    finally:
        del os.environ["GLOO_SOCKET_IFNAME"]


class Worker:
    """A second Python process running ``target(conn, *args)`` (``"module:function"``), with a connection to it.

    Started with ``python -m wfbench.train.shards``: it listens on 127.0.0.1 with a one-time
    key it reads on stdin, prints its port, and takes ``(target, args)`` from the first
    message. :meth:`recv` raises :class:`RuntimeError` with the worker's traceback when it
    sends ``("error", text)`` or when it is gone.
    """

    def __init__(self, target: str, *args):
        key = secrets.token_bytes(32)
        # the standby that wfbench train started ahead (its imports done meanwhile), else a new process
        self.proc = standby.take() or subprocess.Popen([sys.executable, "-m", "wfbench.train.shards"],
                                                       stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.proc.stdin.write(key.hex() + "\n")
        self.proc.stdin.close()
        port = self.proc.stdout.readline().strip()
        if not port.isdigit():
            self.proc.wait()
            raise RuntimeError(f"the second training process did not start (exit status {self.proc.returncode}; "
                               "its error above); procs = 1 trains in this process alone")
        self.conn: Connection = Client((HOST, int(port)), authkey=key)
        send(self.conn, (target, args))

    def send(self, message) -> None:
        send(self.conn, message)

    def recv(self):
        try:
            kind, value = receive(self.conn)
        except (EOFError, OSError):
            raise RuntimeError(f"the second training process ended (exit status {self.proc.poll()}); its error "
                               "above") from None
        if kind == "error":
            raise RuntimeError(f"the second training process failed:\n{value}")
        return value

    def stop(self) -> None:
        """Tell the worker to stop (it may be gone already)."""
        try:
            send(self.conn, ("stop", None))
            self.conn.close()
        except OSError:
            pass

    def wait(self) -> None:
        """Wait for the worker to end (a minute at most, then kill it)."""
        try:
            self.proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def send(conn: Connection, message) -> None:
    """``message`` pickled whole (tensors too: torch's pickler for a connection would share their memory instead)."""
    conn.send_bytes(pickle.dumps(message))


def receive(conn: Connection):
    return pickle.loads(conn.recv_bytes())


def _serve(argv: list[str]) -> None:
    """The worker's side of :class:`Worker`: listen, say the port, run the target the first message names.

    ``--preload MODULE`` (a standby, :mod:`wfbench.train.standby`): import it first, then wait
    for the key; an empty stdin (the standby let go) ends the process.
    """
    if argv[:1] == ["--preload"]:
        importlib.import_module(argv[1])
    line = sys.stdin.readline().strip()
    if not line:
        return
    key = bytes.fromhex(line)
    with Listener((HOST, 0), authkey=key) as listener:
        print(listener.address[1], flush=True)
        sys.stdout = sys.stderr  # nobody reads the pipe after the port
        conn = listener.accept()
    target, args = receive(conn)
    module, name = target.split(":")
    getattr(importlib.import_module(module), name)(conn, *args)


def _leave() -> None:
    """End the worker once its target has returned: exit handlers and output flushed, finalization skipped.

    The target has left the process group and the worker writes nothing, but the
    interpreter's finalization (torch's, numba's and gloo's objects torn down one by one)
    took 1.7-1.8 s on the 2-core VM, which the first process waited for at the end of
    every two-process run (``Worker.wait``); the system frees the process's memory at once.
    """
    atexit._run_exitfuncs()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


if __name__ == "__main__":
    _serve(sys.argv[1:])
    _leave()
