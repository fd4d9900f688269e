#!/usr/bin/python3
"""Plots agent-steps per second against the agent count for 1 and T threads from bench_suite's JSON.

    build/bench_suite --agents 10000,100000,1000000 > bench.json
    tools/plot_bench.py bench.json docs/images/throughput.png

Needs matplotlib (Debian's python3-matplotlib: FM_WITH_PEERS=1 tools/setup.sh installs it); uses Debian's
/usr/bin/python3.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        bench = json.load(f)
    runs = sorted(bench["runs"], key=lambda r: r["agents"])
    n = [r["agents"] for r in runs]
    threads = runs[0]["threads"]
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=120)
    ax.plot(n, [r["one_thread"]["agent_steps_per_second"] for r in runs], "o-", label="1 thread")
    ax.plot(n, [r["agent_steps_per_second"] for r in runs], "s-", label=f"{threads} threads")
    ax.axhline(3e7, color="grey", ls="--", lw=1, label="target at 10^6 (30 steps/s)")
    ax.axhline(2.6e6, color="grey", ls=":", lw=1, label="FM paper, 2009 dual-core")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("agents (tets in flight)")
    ax.set_ylabel("agent-steps per second")
    ax.set_title(f"full tetra-morph step + synthesis, {bench['machine']['cpu']}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2])


if __name__ == "__main__":
    main()
