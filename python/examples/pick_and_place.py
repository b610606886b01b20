"""A robot arm's commands in Python, for a mission that is a `.tdl` file run by `tdl run`.

Usage: pick_and_place.py [port] [system]

An agent named ``arm`` of system ``system`` (default ``tdl``) offering ``move_to(x, y)`` (the
distance travelled, after the time the move takes), ``grasp()`` (whether something was grasped:
every third grasp misses, so the mission's handler retries) and ``release()``. It connects to the
executive ``tdl run`` opens on ``tcp/127.0.0.1:<port>`` (default 7447). Prints ``ready`` once it
serves; exits on SIGTERM or when its standard input closes.

    pip install eclipse-zenoh==1.10.2        # and PYTHONPATH=python for tdl_agent
    python3 python/examples/pick_and_place.py &
    tdl run python/examples/pick_and_place.tdl --args 3
"""

from __future__ import annotations

import math
import signal
import sys
import threading

import tdl_agent

SPEED = 0.5  # metres per second


def main(argv: "list[str]") -> int:
    port = int(argv[0]) if argv else 7447
    system = argv[1] if len(argv) > 1 else "tdl"
    agent = tdl_agent.Agent(system, "arm")
    at = [0.0, 0.0]
    grasps = [0]

    @agent.command("move_to")
    def move_to(ctx: tdl_agent.TaskContext, args: "list[float]") -> float:
        x, y = args
        distance = math.hypot(x - at[0], y - at[1])
        print(f"move_to {x:.2f} {y:.2f}", flush=True)
        # The move takes its time; a terminated node stops the arm where it is.
        if ctx.cancelled.wait(distance / SPEED):
            return 0.0
        at[0], at[1] = x, y
        return distance

    @agent.command("grasp")
    def grasp(ctx: tdl_agent.TaskContext, args: None) -> bool:
        grasps[0] += 1
        held = grasps[0] % 3 != 0
        print(f"grasp {'held' if held else 'missed'}", flush=True)
        return held

    @agent.command("release")
    def release(ctx: tdl_agent.TaskContext, args: None) -> None:
        print("release", flush=True)

    agent.start(tdl_agent.loopback_config(port))
    print("ready", flush=True)

    def watch_stdin() -> None:
        while sys.stdin.read(64):
            pass
        agent.close()

    threading.Thread(target=watch_stdin, daemon=True).start()
    signal.signal(signal.SIGTERM, lambda *_: agent.close())
    agent.run()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
