"""A Python agent for the tests of crates/tcm-zenoh/tests/it/python.rs, built on tdl_agent.

Usage: python_agent.py <system> <agent> [<executive port>] [<port>...] (other peers on 127.0.0.1
to connect to as well). With ``TDL_AGENT_TLS=<authority>:<certificate>:<key>`` (PEM files) in the
environment, it connects over mutual TLS; with ``TDL_AGENT_LISTEN=<port>``, it listens on that
port of 127.0.0.1 for executives to connect to; with ``TDL_AGENT_HOLD=<seconds>``, it holds the
bodies of an executive that went for that long (``Agent(hold=...)``).

It joins the system on 127.0.0.1 and prints one line per event on stdout (``ready``,
``start <task> <node>``, ``cleanup <task> <args>``) until it is killed or gets SIGTERM. Offered:

- ``add`` (a list of numbers): a command returning their sum;
- ``greet`` (a name): a goal that only runs, returning a greeting;
- ``grasp`` (a number x): a command failing with ``NoGrasp {x}``, whose ancestor is ``ArmFailure``;
- ``crash`` (anything): a command raising a plain Python exception;
- ``sleep`` (milliseconds): an async command that sleeps, with a cleanup;
- ``spin`` (milliseconds): a plain-function command that sleeps in its thread, with a cleanup.
"""

from __future__ import annotations

import asyncio
import os
import sys
import threading
import time
from typing import Any, List

import tdl_agent


_out = threading.Lock()


def say(line: str) -> None:
    """Prints one whole line (bodies print from the loop's thread and from worker threads)."""
    with _out:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


class ArmFailure(tdl_agent.TaskFailure):
    """The arm failed (an ancestor, for handlers)."""


class NoGrasp(ArmFailure):
    """Nothing to grasp at x."""

    def __init__(self, x: int) -> None:
        super().__init__(f"no grasp at {x}")
        self.x = x


def main(argv: List[str]) -> int:
    listen = os.environ.get("TDL_AGENT_LISTEN")
    if len(argv) < 3 and not (len(argv) == 2 and listen):
        print("usage: python_agent.py <system> <agent> <executive port> [<port>...]", file=sys.stderr)
        return 2
    system, name, ports = argv[0], argv[1], [int(p) for p in argv[2:]]
    agent = tdl_agent.Agent(system, name, hold=float(os.environ.get("TDL_AGENT_HOLD", "0")))

    @agent.command("add")
    def add(ctx: tdl_agent.TaskContext, xs: List[float]) -> float:
        say(f"start add {ctx.node}")
        return sum(xs)

    @agent.goal("greet")
    async def greet(ctx: tdl_agent.TaskContext, who: str) -> str:
        say(f"start greet {ctx.node}")
        return f"hello {who}"

    @agent.command("grasp")
    def grasp(ctx: tdl_agent.TaskContext, x: int) -> None:
        say(f"start grasp {ctx.node}")
        raise NoGrasp(x)

    @agent.command("sense")
    def sense(ctx: tdl_agent.TaskContext, values: List[float]) -> None:
        say(f"start sense {ctx.node}")
        for v in values:
            ctx.set_state("battery", v)
            time.sleep(0.02)

    @agent.command("crash")
    def crash(ctx: tdl_agent.TaskContext, _: Any) -> None:
        raise KeyError("nothing here")

    async def sleep(ctx: tdl_agent.TaskContext, ms: int) -> int:
        say(f"start sleep {ctx.node}")
        await asyncio.sleep(ms / 1000)
        return ms

    async def sleep_cleanup(ms: int) -> None:
        await asyncio.sleep(0.01)
        say(f"cleanup sleep {ms}")

    agent.command("sleep", sleep, on_terminate=sleep_cleanup)

    def spin(ctx: tdl_agent.TaskContext, ms: int) -> int:
        say(f"start spin {ctx.node}")
        end = time.monotonic() + ms / 1000
        while time.monotonic() < end and not ctx.cancelled.is_set():
            ctx.heartbeat()
            time.sleep(0.01)
        return ms

    agent.command("spin", spin, on_terminate=lambda ms: say(f"cleanup spin {ms}"))

    tls = os.environ.get("TDL_AGENT_TLS")
    if tls:
        authority, certificate, key = tls.split(os.pathsep)
        config = tdl_agent.with_mtls(
            tdl_agent.peer_config([], [f"tls/127.0.0.1:{p}" for p in ports]), authority, certificate, key
        )
    else:
        config = tdl_agent.peer_config(
            [f"tcp/127.0.0.1:{listen}"] if listen else [], [f"tcp/127.0.0.1:{p}" for p in ports]
        )
    agent.start(config)
    say("ready")
    agent.run()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
