"""A Python client driving a serving executive (``tdl serve``) through a program's life.

Usage: serve_client.py [--port P] [--system S] [--client NAME] BROKEN.tdl WATCH.tdl

With ``tdl serve`` listening on ``tcp/127.0.0.1:<port>``, it loads ``BROKEN.tdl`` (a program with
an error: refused, with the error located in the file, and nothing loaded), then ``WATCH.tdl``
(a program whose default task runs until it is stopped) as the program ``watch``; starts it, sees
the run running, raises the event ``door_open`` in it, stops it, waits until it has ended
``terminated``, sees a second stop refused, and unloads the program; last, it asks an executive
named ``nobody``, which no one answers. It prints what it sees, one line each, ``trace: FILE``
with the run's trace file, and ``ok`` at the end; it exits 1 at the first answer that is not the
one expected, 2 when the executive does not answer.

    tdl serve --port 7447 &
    PYTHONPATH=python python3 python/examples/serve_client.py \\
        crates/tdl-cli/tests/data/serve/broken.tdl crates/tdl-cli/tests/data/serve/watch.tdl
"""

from __future__ import annotations

import argparse
import re
import sys

import tdl_agent


class Unexpected(Exception):
    pass


def check(ok: bool, what: str) -> None:
    if not ok:
        raise Unexpected(what)


def drive(c: tdl_agent.Client, port: int, broken: str, watch: str) -> None:
    try:
        c.load("watch", [broken])
        raise Unexpected(f"{broken} was loaded")
    except tdl_agent.Refused as e:
        located = re.search(re.escape(broken) + r":\d+", e.reason)
        check(located is not None, f"the refusal locates no error in {broken}: {e.reason}")
        print(f"refused at {located.group(0) if located else '?'}")
    check(c.programs() == [], "a refused program was loaded")

    loaded = c.load("watch", [watch])
    check(loaded["version"].startswith("watch@"), f"loaded {loaded}")
    print(f"loaded {loaded['version']}")
    (program,) = c.programs()
    check(program["loaded_by"] == c.name, f"loaded by {program['loaded_by']}")

    run = c.start("watch")
    print(f"started run {run}")
    (info,) = c.status(run)
    check(info["running"] and info["outcome"] is None, f"not running: {info}")
    print(f"running {info['task']} of {info['version']}")

    c.raise_event(run, "door_open")
    print("raised door_open")
    c.stop(run)
    print("stopped")
    ended = c.wait_ended(run, timeout=20.0)
    check(ended["outcome"].startswith("terminated"), f"ended {ended['outcome']}")
    print(f"ended {ended['outcome'].splitlines()[0]}")
    print(f"trace: {ended['trace']}")

    try:
        c.stop(run)
        raise Unexpected("a run that ended was stopped again")
    except tdl_agent.Refused as e:
        print(f"second stop refused: {e.reason}")
    c.unload("watch")
    check(c.programs() == [], "unloaded, yet listed")
    print("unloaded")

    with tdl_agent.Client(c.system, c.name, port=port, executive="nobody", timeout=0.5) as other:
        try:
            other.status()
            raise Unexpected("an executive no one runs answered")
        except tdl_agent.NoAnswer as e:
            print(f"no answer: {e}")


def main(argv: "list[str]") -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, default=7447)
    p.add_argument("--system", default="tdl")
    p.add_argument("--client", default="py_client")
    p.add_argument("broken")
    p.add_argument("watch")
    a = p.parse_args(argv)
    try:
        with tdl_agent.Client(a.system, a.client, port=a.port, timeout=10.0) as c:
            drive(c, a.port, a.broken, a.watch)
    except tdl_agent.NoAnswer as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except (Unexpected, tdl_agent.ClientError, TimeoutError) as e:
        print(f"error: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    print("ok")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
