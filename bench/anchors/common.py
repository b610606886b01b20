"""Shared helpers of the anchor scripts: argument parsing, memory readings and JSON output.

Every script prints one JSON object per line with the field names of `tcm-bench` where they
exist (`workload`, `n`, `ns_per_node`) plus `system`, `build_ns_per_node`, `tick_ns_per_node`,
`teardown_ns_per_node`, `peak_rss_kb` (this process's high-water mark, from getrusage) and
`rss_base_kb` (resident size after the imports, before any tree was built).
"""

import argparse
import json
import os
import resource


def parse_args(description, workloads):
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--workload", required=True, choices=workloads)
    p.add_argument("--n", type=int, default=100_000, help="nodes for W1, W2 and W1-scale")
    p.add_argument("--depth", type=int, default=496, help="recursion depth for W3")
    p.add_argument("--repeats", type=int, default=3,
                   help="measurements in this process; the best is kept, as tcm-bench does")
    return p.parse_args()


def rss_now_kb():
    """Resident set size right now, from /proc (Linux); 0 where that is not available."""
    try:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") // 1024
    except (OSError, ValueError, IndexError):
        return 0


def peak_rss_kb():
    # ru_maxrss is in kilobytes on Linux.
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def emit(**fields):
    print(json.dumps(fields), flush=True)


def best(samples):
    """The sample whose end-to-end time is least (the least disturbed by the machine)."""
    return min(samples, key=lambda s: s["build"] + s["tick"])


def rounded(x):
    return round(x, 1)
