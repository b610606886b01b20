#!/usr/bin/env python3
"""W1-W4 in py_trees (pure Python).

  W1        a Sequence (memory=True) of N `Success` behaviours        (N nodes counted)
  W2        a Parallel with the SuccessOnAll policy of N `Success` behaviours
  W3        Sequences nested D deep, each holding one `Success` and the next Sequence
            (2 × D nodes counted). Ticking recurses through Python generators, so Python's
            default recursion limit (1000) stops it past D = 992; the default D is 496, the
            depth BehaviorTree.CPP's XML parser copes with, so all systems run the same tree.
  W1-scale  W1 at the size given by --n.
  W4        a 1 ms tick loop for 2 s over a tree holding one condition behaviour. The loop
            sleeps to absolute deadlines (start + k × 1 ms) and the condition records when it
            runs; lateness is measured against the ideal schedule from its first run, as
            tcm-bench's W4 measures its monitor. `--tick-tock` uses py_trees' own
            `BehaviourTree.tick_tock(1 ms)` instead, which sleeps 1 ms *after* each tick.

For W1-W3, ns_per_node is build + one tick (`tick_once` on the root); teardown (dropping the
tree and collecting its reference cycles) is reported apart.
"""

import gc
import sys
import time

from common import best, emit, parse_args, peak_rss_kb, rounded, rss_now_kb


def build(workload, n, depth):
    import py_trees
    from py_trees.behaviours import Success
    from py_trees.composites import Parallel, Sequence

    if workload in ("W1", "W1-scale"):
        return Sequence("plan", memory=True, children=[Success("step") for _ in range(n)]), n
    if workload == "W2":
        policy = py_trees.common.ParallelPolicy.SuccessOnAll()
        return Parallel("checks", policy=policy,
                        children=[Success("check") for _ in range(n)]), n
    if workload == "W3":
        root = Sequence("level", memory=True)
        cur = root
        for _ in range(depth - 1):
            nxt = Sequence("level", memory=True)
            cur.add_children([Success("step"), nxt])
            cur = nxt
        cur.add_child(Success("step"))
        return root, 2 * depth
    raise ValueError(workload)


def trees(args):
    import py_trees

    gc.collect()
    base = rss_now_kb()
    samples = []
    nodes = 0
    for _ in range(args.repeats):
        t0 = time.perf_counter_ns()
        root, nodes = build(args.workload, args.n, args.depth)
        t1 = time.perf_counter_ns()
        try:
            root.tick_once()
        except RecursionError:
            print(f"py_trees {args.workload}: Python's recursion limit ({sys.getrecursionlimit()}) "
                  f"stops a tick at depth {args.depth}; py_trees copes with depth 992 at most",
                  file=sys.stderr)
            sys.exit(1)
        t2 = time.perf_counter_ns()
        status = root.status
        del root
        gc.collect()
        t3 = time.perf_counter_ns()
        if status != py_trees.common.Status.SUCCESS:
            print(f"py_trees {args.workload}: the tree ended {status}", file=sys.stderr)
            sys.exit(1)
        samples.append({"build": t1 - t0, "tick": t2 - t1, "teardown": t3 - t2})
    s = best(samples)
    emit(workload=args.workload, system="py_trees", n=nodes,
         ns_per_node=rounded((s["build"] + s["tick"]) / nodes),
         build_ns_per_node=rounded(s["build"] / nodes),
         tick_ns_per_node=rounded(s["tick"] / nodes),
         teardown_ns_per_node=rounded(s["teardown"] / nodes),
         peak_rss_kb=peak_rss_kb(), rss_base_kb=base)


def stats(v):
    v = sorted(v)
    if not v:
        return 0.0, 0, 0
    return sum(v) / len(v), v[len(v) * 99 // 100], v[-1]


def w4(tick_tock):
    import py_trees

    count = 2000
    period = 1_000_000  # ns
    starts = []

    class BumperClear(py_trees.behaviour.Behaviour):
        """The condition a fast monitor polls: succeeds while the bumper is not pressed."""

        def __init__(self):
            super().__init__("bumper_clear")
            self.pressed = False

        def update(self):
            starts.append(time.perf_counter_ns())
            return (py_trees.common.Status.FAILURE if self.pressed
                    else py_trees.common.Status.SUCCESS)

    tree = py_trees.trees.BehaviourTree(BumperClear())
    if tick_tock:
        tree.tick_tock(period_ms=1, number_of_iterations=count)
    else:
        t0 = time.perf_counter_ns()
        for k in range(count):
            deadline = t0 + k * period
            wait = deadline - time.perf_counter_ns()
            if wait > 0:
                time.sleep(wait / 1e9)
            tree.tick()
    late = [max(0, t - (starts[0] + k * period)) for k, t in enumerate(starts)][1:]
    mean, p99, mx = stats(late)
    emit(workload="W4", system="py_trees-tick_tock" if tick_tock else "py_trees",
         n=len(starts), mean_late_ns=round(mean), p99_late_ns=p99, max_late_ns=mx,
         peak_rss_kb=peak_rss_kb())


def main():
    if "--tick-tock" in sys.argv:
        sys.argv.remove("--tick-tock")
        tick_tock = True
    else:
        tick_tock = False
    args = parse_args(__doc__, ["W1", "W2", "W3", "W4", "W1-scale"])
    if args.workload == "W4":
        w4(tick_tock)
    else:
        trees(args)


if __name__ == "__main__":
    main()
