"""Xavier's voice for ``xavier --distributed`` (docs/distributed.md, "The distributed Xavier").

Usage: xavier_voice.py <system> <executive port> <robot agent port>

A Python agent named ``voice`` offering ``speak``: the robot agent's world must hear what is said
(rooms near the robot hear the announcement), so the body asks the robot agent's query
``tdl/<system>/xavier/hear`` with the text; the answer is how long saying it takes on the
agent's clock, which the body then takes (cut short when the node is terminated). Prints
``ready`` once it serves; exits when its standard input closes (the demo that started it ended)
or on SIGTERM.
"""

from __future__ import annotations

import json
import sys
import threading

import tdl_agent


def main(argv: "list[str]") -> int:
    if len(argv) != 3:
        print("usage: xavier_voice.py <system> <executive port> <robot agent port>", file=sys.stderr)
        return 2
    system, port, robot_port = argv[0], int(argv[1]), int(argv[2])
    agent = tdl_agent.Agent(system, "voice")

    @agent.command("speak")
    def speak(ctx: tdl_agent.TaskContext, text: str) -> None:
        session = agent.session
        if session is None:
            raise RuntimeError("the agent is closed")
        replies = session.get(f"tdl/{system}/xavier/hear", payload=text.encode("utf-8"), timeout=10.0)
        seconds = None
        for reply in replies:
            if reply.ok is not None:
                seconds = float(json.loads(reply.ok.payload.to_bytes()))
                break
        if seconds is None:
            raise RuntimeError("the robot did not hear the speech")
        # Speaking takes its time; a terminated node stops talking.
        ctx.cancelled.wait(seconds)

    # Connected to the executive (to serve) and to the robot agent (to query its world): zenoh
    # peers do not route for each other.
    agent.start(tdl_agent.peer_config([], [f"tcp/127.0.0.1:{port}", f"tcp/127.0.0.1:{robot_port}"]))
    print("ready", flush=True)

    def watch_stdin() -> None:
        while sys.stdin.read(64):
            pass
        agent.close()

    threading.Thread(target=watch_stdin, daemon=True).start()
    agent.run()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
