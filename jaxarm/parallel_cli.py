"""The scale-out options of the batch commands (``--devices``, ``--networks-at-once``, ``--coordinator``,
``--num-processes``, ``--process-id``, ``--coordinator-timeout``) and :func:`jaxarm.parallel.start` from them.

The command line's side of :mod:`jaxarm.parallel`, which holds the device mesh, the sharding and the set-up itself.
"""
from __future__ import annotations

import argparse

from jaxarm import parallel
from jaxarm.parallel import COORDINATOR_TIMEOUT_S, CPU_NETWORKS_AT_ONCE, usable_cores


def add_arguments(ap: argparse.ArgumentParser) -> None:
    """The scale-out options every batch command takes."""
    g = ap.add_argument_group("devices and machines (default: every core of this machine)")
    g.add_argument("--devices", type=int, default=None, metavar="N",
                   help="CPU devices of this process, one network-kernel thread each (default: every usable core, "
                        f"{usable_cores()} here); accelerators: all of them are used")
    g.add_argument("--networks-at-once", type=int, default=None, metavar="K",
                   help=f"networks each device steps together, the rest of its share after them (default: "
                        f"{CPU_NETWORKS_AT_ONCE} on CPUs, where one network stays in the caches; all on accelerators; "
                        "0 = all); every value gives the networks the same state")
    g.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                   help="several processes (machines): process 0's address; give every process the same command with "
                        "its own --process-id (not needed under SLURM or Open MPI, which JAX detects)")
    g.add_argument("--num-processes", type=int, default=None, metavar="N", help="number of processes (with --coordinator)")
    g.add_argument("--process-id", type=int, default=None, metavar="I", help="this process, 0 .. N-1 (with --coordinator)")
    g.add_argument("--coordinator-timeout", type=float, default=None, metavar="S",
                   help=f"seconds to wait for every process to join (default {COORDINATOR_TIMEOUT_S:g}); then "
                        "one line naming the address, exit status 2")


def start_from_arguments(args) -> None:
    """:func:`jaxarm.parallel.start` from the parsed options of :func:`add_arguments` (``--devices``, ``--coordinator``,
    ``--num-processes``, ``--process-id``)."""
    parallel.start(args.devices, args.coordinator, args.num_processes, args.process_id,
                   getattr(args, "networks_at_once", None), getattr(args, "coordinator_timeout", None))


__all__ = ["add_arguments", "start_from_arguments"]
