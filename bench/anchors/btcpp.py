#!/usr/bin/env python3
"""W1-W3 in BehaviorTree.CPP 4.x through the `behaviortreepy` package (C++ core, Python binding).

The tree is written as v4 XML with the library's built-in nodes and built by
`BehaviorTreeFactory.create_tree_from_text`; it is ticked once by `Tree.tick_exactly_once`
(`tick_once` would add a wake-up wait per call). Both happen in C++: Python makes one call for
the build and one for the tick, so the interpreter adds nothing per node. The XML text is made
before the clock starts.

  W1        a Sequence of N AlwaysSuccess                       (N nodes counted)
  W2        a Parallel (success_count=-1: all must succeed) of N AlwaysSuccess
  W3        Sequences nested D deep, each holding one AlwaysSuccess and the next Sequence
            (2 × D nodes counted, as tcm-bench counts a goal and a command per level).
            TinyXML2 refuses XML nested deeper than 500 elements, so D ≤ 496 here.
  W1-scale  W1 at the size given by --n (for the per-node cost and peak RSS at 1M).

ns_per_node is build + tick; teardown (destroying the tree) is reported apart.
"""

import gc
import sys
import time

from common import best, emit, parse_args, peak_rss_kb, rounded, rss_now_kb

HEAD = '<root BTCPP_format="4"><BehaviorTree ID="Main">'
TAIL = "</BehaviorTree></root>"


def xml_for(workload, n, depth):
    if workload in ("W1", "W1-scale"):
        return HEAD + "<Sequence>" + "<AlwaysSuccess/>" * n + "</Sequence>" + TAIL, n
    if workload == "W2":
        return (HEAD + '<Parallel success_count="-1" failure_count="1">'
                + "<AlwaysSuccess/>" * n + "</Parallel>" + TAIL), n
    if workload == "W3":
        return (HEAD + "<Sequence><AlwaysSuccess/>" * depth + "</Sequence>" * depth + TAIL,
                2 * depth)
    raise ValueError(workload)


def main():
    args = parse_args(__doc__, ["W1", "W2", "W3", "W1-scale"])
    import behaviortreepy as bt

    factory = bt.BehaviorTreeFactory()
    xml, nodes = xml_for(args.workload, args.n, args.depth)
    gc.collect()
    base = rss_now_kb()
    samples = []
    for _ in range(args.repeats):
        t0 = time.perf_counter_ns()
        tree = factory.create_tree_from_text(xml)
        t1 = time.perf_counter_ns()
        status = tree.tick_exactly_once()
        t2 = time.perf_counter_ns()
        del tree
        t3 = time.perf_counter_ns()
        if status != bt.NodeStatus.SUCCESS:
            print(f"btcpp {args.workload}: the tree ended {status}", file=sys.stderr)
            sys.exit(1)
        samples.append({"build": t1 - t0, "tick": t2 - t1, "teardown": t3 - t2})
    s = best(samples)
    emit(workload=args.workload, system="btcpp", n=nodes,
         ns_per_node=rounded((s["build"] + s["tick"]) / nodes),
         build_ns_per_node=rounded(s["build"] / nodes),
         tick_ns_per_node=rounded(s["tick"] / nodes),
         teardown_ns_per_node=rounded(s["teardown"] / nodes),
         peak_rss_kb=peak_rss_kb(), rss_base_kb=base)


if __name__ == "__main__":
    main()
