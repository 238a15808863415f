"""The ``jaxarm`` command line.

Subcommands are registered by dotted path and imported only when used, so ``jaxarm --help`` is instant and one
subsystem's heavy imports (MuJoCo, sockets) never slow another. Each target is ``main(argv: list[str]) -> int``.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

# name -> (module:function, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("jaxarm.demo:main",
             "simulate both arms from the start posture under each muscle group; write a plot and a summary"),
    "train": ("jaxarm.experiment:train_main", "train networks to reach a target, test them, write results.json"),
    "test": ("jaxarm.experiment:test_main", "re-test networks trained by `jaxarm train`"),
    "evolve": ("jaxarm.evolve.cli:evolve_main",
               "search the metaparameters with an evosax strategy (CMA-ES, GA, ...) in compiled, checkpointed chunks"),
    "reproduce": ("jaxarm.paper.reproduce:reproduce_main",
                  "the paper's success table: a preset's best set x 30 seeds and its top 30 sets, per target"),
    "rerank": ("jaxarm.paper.rerank:rerank_main",
               "rank a pool of metaparameter sets (presets, earlier rankings) by how often they reach, on fresh seeds"),
    "figures": ("jaxarm.viz.figures:main",
                "the paper's figures (raster, rates, reach, jerk, muscles, robot) from a run folder, PNG + data"),
    "video": ("jaxarm.viz.video:main", "an MP4 of one network reaching: the arm, the target, a scrolling raster"),
    "wam-sim": ("jaxarm.robot.cli:wam_sim_main", "run the simulated Barrett WAM behind a UDP receiver"),
    "export": ("jaxarm.robot.cli:export_main",
               "stream a joint trajectory to a WAM (UDP, simulated or real), or write it offline or as a ROS 2 bag"),
}


def _usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: jaxarm COMMAND [options]", "", "commands:"]
    lines += [f"  {name:<{width}}  {help_}" for name, (_, help_) in COMMANDS.items()]
    lines += ["", "Run `jaxarm COMMAND --help` for a command's options."]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from_command_line = argv is None
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(_usage())
        return 0
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"jaxarm: unknown command {name!r}\n\n{_usage()}", file=sys.stderr)
        return 2
    if name in SCALE_OUT_COMMANDS:
        error = _start_devices(name, rest)
        if error:
            return error
    module, func = COMMANDS[name][0].split(":")
    try:
        return int(getattr(importlib.import_module(module), func)(rest) or 0)
    except Exception as e:
        from jaxarm.config.validate import ConfigError

        if isinstance(e, ConfigError):
            # a bad value or a fault of the output folder (in use, full, read-only, a failed checkpoint write)
            # found after the command's own option checks: one line, never a traceback
            print(f"jaxarm {name}: {e}", file=sys.stderr, flush=True)
            if from_command_line:   # the process ends now: orbax's writes left pending by a failed checkpoint
                sys.unraisablehook = lambda _unraisable: None   # would complain as it shuts down
            return 2
        gl = os.environ.get("MUJOCO_GL")
        if gl is None or not _raised_in_mujoco(e):
            raise
        # MuJoCo sets up its OpenGL at import, from MUJOCO_GL: a bad value, or egl/osmesa without their libraries
        print(f"jaxarm {name}: MuJoCo cannot be imported with MUJOCO_GL={gl} ({type(e).__name__}: "
              f"{str(e).splitlines()[0] if str(e) else ''}); unset MUJOCO_GL (only offscreen rendering needs it) or "
              "set egl or osmesa with their libraries", file=sys.stderr)
        return 2


class _Caught(Exception):
    """Raised in place of a command's ``parse_args`` by :func:`parser`."""


def parser(name: str) -> argparse.ArgumentParser:
    """The argument parser of command ``name`` as its main function builds it, caught at its ``parse_args`` before
    the command does anything: the command-line reference (docs/hooks.py) is made from these, so it lists exactly the
    options each command accepts."""
    from unittest import mock

    module, func = COMMANDS[name][0].split(":")
    main_function = getattr(importlib.import_module(module), func)
    caught = []

    def catch(self, args=None, namespace=None):
        caught.append(self)
        raise _Caught

    with mock.patch.object(argparse.ArgumentParser, "parse_args", catch):
        try:
            main_function([])
        except _Caught:
            pass
    if not caught:
        raise RuntimeError(f"jaxarm {name}: its main function returned without parsing its arguments")
    return caught[0]


def _raised_in_mujoco(e: BaseException) -> bool:
    """Whether the exception was raised inside the mujoco package (e.g. at its import)."""
    tb = e.__traceback__
    while tb is not None:
        if f"{os.sep}mujoco{os.sep}" in tb.tb_frame.f_code.co_filename:
            return True
        tb = tb.tb_next
    return False


#: Commands that split their batch over every device of every process (``--devices``, ``--coordinator``, ...).
SCALE_OUT_COMMANDS = ("train", "test", "evolve", "reproduce", "rerank")


def _start_devices(name: str, argv: list[str]) -> int:
    """Set up this process's devices (and join the other processes) before the command's module is imported: some
    libraries (evosax) compute at import, after which JAX's devices are fixed. Returns an exit code on bad options."""
    from jaxarm import parallel_cli
    from jaxarm.config.validate import ConfigError

    # no abbreviations: this parser sees the command's other options too, and `--networks 30` is not
    # `--networks-at-once 30`
    ap = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    parallel_cli.add_arguments(ap)
    try:
        known, _ = ap.parse_known_args(argv)
        parallel_cli.start_from_arguments(known)
    except SystemExit as e:   # argparse already said what is wrong with the option
        return int(e.code or 2)
    except ConfigError as e:
        print(f"jaxarm {name}: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
